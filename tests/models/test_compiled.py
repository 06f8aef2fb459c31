"""Compiled training (``TrainConfig.compile``): the same function as eager to float rounding, a seed
naming one model in compiled mode whatever the threads, and ``auto`` compiling only where it pays."""

from __future__ import annotations

import os
from dataclasses import replace

import pytest
import torch

import scenescore as ss
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.learn.config import COMPILE_FROM, compiled_placements, compiles, derive, shared_compile

TINY = TrainConfig(
    members=1,
    iterations=3,
    negatives=4,
    batch_scenes=4,
    network=NetworkConfig(hidden=8, embed_dim=8, layers=1),
)


def _weights(model: ss.models.ScoreModel) -> list[torch.Tensor]:
    return [p.detach().clone() for p in model.net.parameters()]


@pytest.mark.slow
@pytest.mark.float_order
def test_compiled_training_is_eagers_function_and_a_seed_names_its_model(monkeypatch):
    from scenescore.models import compiled, network

    # small pieces on two cores, whatever this machine has: the chains' and the loss's pieces side by side
    monkeypatch.setattr(network, "PIECE_EDGES", 512)
    monkeypatch.setattr(network, "usable_cores", lambda: 2)
    # a compiled function keeps a graph per network and way of calling it, beyond torch's default room
    monkeypatch.setattr(torch._dynamo.config, "recompile_limit", 1)
    in_pieces = []
    apply = compiled.CompiledEnergy.apply
    monkeypatch.setattr(compiled.CompiledEnergy, "apply", lambda *a: in_pieces.append(a[2]) or apply(*a))
    scenes = ss.scenarios.get("dining").generate(6, 0)
    eager = ss.learn.fit(scenes, replace(TINY, compile="off"), seed=0, progress=False)
    once = ss.learn.fit(scenes, replace(TINY, compile="on"), seed=0, progress=False)
    assert once.info.compiled and not eager.info.compiled
    assert in_pieces  # the loss's passes went in one call, in pieces
    # the same function: the losses and weights agree to float rounding, not bit for bit
    assert once.info.history == pytest.approx(eager.info.history, rel=1e-4)
    for a, b in zip(_weights(once), _weights(eager), strict=True):
        assert torch.allclose(a, b, rtol=1e-3, atol=1e-4)
    # within the compiled mode a seed names a model, however many pieces run at once
    with ss.thread_budget(2):
        twice = ss.learn.fit(scenes, replace(TINY, compile="on"), seed=0, progress=False)
    assert all(torch.equal(a, b) for a, b in zip(_weights(once), _weights(twice), strict=True))
    # placing with the trained model is eager again: the same answer as the same weights trained eagerly
    hole = scenes[0].without(scenes[0].objects[1].name)
    opts = ss.solvers.langevin.LangevinOptions(
        particles=8, chain=replace(ss.solvers.kernel.PLACEMENT, steps=4)
    )
    copy = ss.models.ScoreModel(type(once.net)(once.net.cfg), once.encoder)
    copy.net.load_state_dict(once.net.state_dict())
    copy.info = once.info
    eager_pose = ss.place(once, hole, opts, seed=0).objects[1].pose
    assert eager_pose == ss.place(copy, hole, opts, seed=0).objects[1].pose
    # an experiment's placements within compiled_chains: the compiled pose gradient, the same placement
    # to float rounding; a pass with the weights' gradient stays eager
    calls = []
    pose_grad = compiled.CompiledPoseGrad.apply
    monkeypatch.setattr(compiled.CompiledPoseGrad, "apply", lambda *a: calls.append(1) or pose_grad(*a))
    with once.compiled_chains():
        assert compiled.compiled_of(once.net) is not None and not compiled.compiled_of(once.net).loss
        compiled_pose = ss.place(once, hole, opts, seed=0).objects[1].pose
        monkeypatch.setattr(compiled.Compiled, "energy", lambda *a: pytest.fail("loss pass compiled"))
        st = once.tensors([scenes[0]])
        once.energy(st.poses.clone().requires_grad_(True), st).sum().backward()
    assert calls and compiled.compiled_of(once.net) is None
    assert compiled_pose == pytest.approx(eager_pose, abs=1e-4)
    with eager.compiled_chains():  # a model that trained eager places eager
        assert compiled.compiled_of(eager.net) is None


def test_auto_compiles_from_the_work_where_a_compiler_is_there(monkeypatch):
    from scenescore.learn import config

    small = derive(TINY, ss.scenarios.get("dining").generate(4, 0))
    large = replace(small, work=COMPILE_FROM)
    auto = replace(TINY, compile="auto")
    assert not compiles(auto, small, "cpu") and compiles(replace(TINY, compile="on"), small, "cpu")
    monkeypatch.setattr(config, "compiler_available", lambda device_type: True)
    assert compiles(auto, large, "cpu") and not compiles(auto, small, "cpu")
    assert compiles(auto, large, "cuda") and not compiles(auto, small, "cuda")
    assert not compiles(replace(TINY, compile="off"), large, "cpu")
    monkeypatch.setattr(config, "compiler_available", lambda device_type: False)
    assert not compiles(auto, large, "cpu")  # no compiler: eager, not an error
    with pytest.raises(ss.errors.ConfigError, match="compile: expected 'auto', 'on' or 'off'"):
        TrainConfig(compile="yes")  # type: ignore[arg-type]


def test_an_experiments_trainings_compile_together_where_their_work_pays(monkeypatch):
    from scenescore.learn import config

    monkeypatch.setattr(config, "compiler_available", lambda device_type: True)
    scenes = ss.scenarios.get("dining").generate(4, 0)
    work = derive(TINY, scenes).work
    enough = int(COMPILE_FROM // work) + 1  # trainings whose work together reaches COMPILE_FROM
    auto = replace(TINY, compile="auto")
    assert shared_compile(auto, scenes, enough, "cpu").compile == "on"
    assert shared_compile(auto, scenes, enough - 1, "cpu") == auto  # each then decides on its own work
    assert shared_compile(replace(TINY, compile="off"), scenes, enough, "cpu").compile == "off"
    # the one change is the choice: the cache's key then names it, and nothing else moves
    on = shared_compile(auto, scenes, enough, "cpu")
    assert replace(on, compile="auto") == auto
    # those trainings' placements run compiled too; a training that decides on its own places eager
    assert compiled_placements(on) and not compiled_placements(auto) and not compiled_placements(None)
    monkeypatch.setattr(config, "compiler_available", lambda device_type: False)
    assert shared_compile(auto, scenes, enough, "cpu") == auto  # no compiler: eager, as ever


def test_the_paper_experiments_compile_their_seeds_networks_together(monkeypatch):
    from scenescore.experiments import missing, novel
    from scenescore.learn import config

    monkeypatch.setattr(config, "compiler_available", lambda device_type: True)
    # a dining network is half the work that pays for a compile: three seeds pay for one, one does not
    assert missing.train_config(seeds=3).compile == "on"
    assert missing.train_config(seeds=1).compile == "auto"
    assert missing.train_config(quick=True, seeds=3).compile == "auto"  # a quick run stays eager
    assert novel.train_config(trainings=9).compile == "on"
    assert novel.train_config(quick=True, trainings=9).compile == "auto"
    # tidy's dining network is Table 1's, so that `experiment all` trains it once for both
    dining = ss.scenarios.get("dining").split(0)[0]
    shared = shared_compile(TrainConfig(members=1), dining, 3, "cpu")
    assert shared == missing.train_config(seeds=3)


def test_the_work_grows_with_the_objects_each_reads_and_the_iterations():
    scenes = ss.scenarios.get("dining").generate(4, 0)
    d = derive(TINY, scenes)
    rows = 4 * (4 * TINY.chain_steps + 4 + TINY.reanchored + 1)  # chains' steps, then the loss's passes
    assert d.work == pytest.approx(TINY.iterations * rows * sum(len(s) ** 2 for s in scenes) / len(scenes))
    assert derive(replace(TINY, iterations=6), scenes).work == pytest.approx(2 * d.work)


def test_compiled_kernels_are_kept_in_the_users_cache_folder(monkeypatch, tmp_path):
    from scenescore.runtime import compiling

    monkeypatch.setattr(compiling, "_USER_CACHE", False)
    monkeypatch.setenv("SCENESCORE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv(compiling.INDUCTOR_CACHE_ENV, raising=False)
    compiling.compile_fn(lambda x: x + 1, "cpu")  # not called: nothing compiled yet
    assert os.environ[compiling.INDUCTOR_CACHE_ENV] == str(tmp_path / "inductor")
    monkeypatch.setattr(compiling, "_USER_CACHE", True)  # a folder the user named stays theirs
    monkeypatch.setenv(compiling.INDUCTOR_CACHE_ENV, str(tmp_path / "theirs"))
    compiling.compile_fn(lambda x: x + 1, "cpu")
    assert os.environ[compiling.INDUCTOR_CACHE_ENV] == str(tmp_path / "theirs")
    assert compiling.compile_settings("cuda") == {"mode": "reduce-overhead"}
    # a CPU's graphs run their kernels from C++, without the GIL, so that pieces run side by side
    assert compiling.compile_settings("cpu") == {"options": {"cpp_wrapper": True}}
    assert compiling.compile_settings("mps") == {}


def test_processes_starting_alike_compile_a_graph_once_between_them(monkeypatch, tmp_path):
    import threading
    import time

    from scenescore.runtime import compiling

    monkeypatch.setattr(compiling, "_USER_CACHE", True)
    monkeypatch.setenv(compiling.INDUCTOR_CACHE_ENV, str(tmp_path))
    entered, log = threading.Event(), []

    def compiles(key: str, hold: float) -> None:  # a lock of the file is a process's own: threads stand in
        with compiling.first_compile(key):
            log.append(("in", key))
            entered.set()
            time.sleep(hold)
            log.append(("out", key))

    first = threading.Thread(target=compiles, args=("graph a", 0.5))
    first.start()
    entered.wait()
    # another graph's first compile does not wait; the same graph's waits for the first to be done
    other = threading.Thread(target=compiles, args=("graph b", 0.0))
    same = threading.Thread(target=compiles, args=("graph a", 0.0))
    other.start()
    other.join()
    same.start()
    same.join()
    first.join()
    assert log.index(("out", "graph b")) < log.index(("out", "graph a"))
    assert log[-2:] == [("in", "graph a"), ("out", "graph a")]
    # once compiled, no process waits: not even while another holds the graph's lock
    from contextlib import ExitStack

    from filelock import FileLock

    locks = sorted((tmp_path / "scenescore-graphs").glob("*.lock"))
    assert len(locks) == 2
    with ExitStack() as held:
        for lock in locks:
            held.enter_context(FileLock(str(lock)))
        again = threading.Thread(target=compiles, args=("graph a", 0.0))
        again.start()
        again.join(timeout=10)
        assert not again.is_alive()


def test_pooled_of_the_resolved_inputs_is_the_networks_own_pass():
    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=1, neighbours=3, radius=4.0)
    st = model.tensors(ss.scenarios.get("zoo-bedroom").generate(2, 0))
    args = (st.poses, st.feats, st.sizes, st.mask, None, st.round)
    assert torch.equal(model.net.pooled(*model.net.resolve(*args)), model.net._pooled(*args))


class EagerStandIn:
    """A network's compiled passes stood in for by its own (nothing compiled)."""

    def __init__(self, net: ss.models.EnergyNet):
        self.net, self.device_type = net, "cpu"
        self.traced = self.energy_traced = False

    def pose_grad(self, resolved):  # noqa: ANN001, ANN201
        with torch.enable_grad():
            x = resolved[0].detach().requires_grad_(True)
            e = self.net.readout(self.net.pooled(x, *resolved[1:]))
            (g,) = torch.autograd.grad(e.sum(), x)
        return e.detach(), g.detach()

    def energy(self, resolved):  # noqa: ANN001, ANN201
        return self.net.readout(self.net.pooled(*resolved))


@pytest.fixture
def side_by_side(monkeypatch) -> list[int]:
    """The number of pieces each call of the compiled passes' ``in_parallel`` was given (run in turn)."""
    from scenescore.models import compiled

    counts: list[int] = []

    def in_parallel(work, parallel=True):  # noqa: ANN001, ANN202
        counts.append(len(work))
        return [w() for w in work]

    monkeypatch.setattr(compiled, "in_parallel", in_parallel)
    return counts


def _eight_pose_sets() -> tuple[ss.models.EnergyNet, ss.models.SceneTensors]:
    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=1)
    return model.net, model.tensors(ss.scenarios.get("dining").generate(2, 0)).repeat(4)


def test_the_compiled_pose_gradients_pieces_run_side_by_side_once_traced(side_by_side):
    from scenescore.models import compiled

    net, st = _eight_pose_sets()
    stand_in = EagerStandIn(net)
    for _ in range(2):
        x = st.poses.clone().requires_grad_(True)
        e = compiled.CompiledPoseGrad.apply(net, stand_in, 2, x, st.feats, st.sizes, st.mask, None, st.round)
        (g,) = torch.autograd.grad(e.sum(), x)
        assert torch.allclose(e, net(st.poses, st.feats, st.sizes, st.mask, round=st.round), atol=1e-6)
        assert g.shape == x.shape
    # the first call traces the graph with one piece alone, then every piece goes side by side
    assert side_by_side == [3, 4] and stand_in.traced


def test_the_compiled_losss_pieces_give_the_whole_batchs_energies_and_weight_gradients(side_by_side):
    from scenescore.models import compiled

    net, st = _eight_pose_sets()
    args = (st.poses, st.feats, st.sizes, st.mask, None, st.round)
    weights = list(net.parameters())
    whole = net(*args)
    want = torch.autograd.grad((whole * torch.arange(8.0)).sum(), weights)
    stand_in = EagerStandIn(net)
    for _ in range(2):
        e = compiled.CompiledEnergy.apply(net, stand_in, 3, *args, *weights)
        got = torch.autograd.grad((e * torch.arange(8.0)).sum(), weights)
        assert torch.allclose(e, whole, atol=1e-6)
        for a, b in zip(got, want, strict=True):
            assert torch.allclose(a, b, rtol=1e-5, atol=1e-6)
    # three pieces: the first call's first alone, then every forward and backward side by side
    assert side_by_side == [2, 3, 3, 3] and stand_in.energy_traced


def test_the_losss_passes_in_one_call_give_each_passs_energies(monkeypatch):
    from scenescore.learn import loop
    from scenescore.learn.size_groups import SizeGroups

    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=1)
    batch = model.tensors(ss.scenarios.get("zoo-books").generate(4, 0))  # 4 to 24 objects: size groups
    sizes = SizeGroups(batch.mask.sum(dim=1))
    assert len(sizes.groups) > 1
    g = torch.Generator().manual_seed(0)
    passes = [(batch.poses, batch, 1)]
    for k in (3, 2):
        st = batch.repeat(k)
        passes.append((st.poses + 0.05 * torch.randn(st.poses.shape, generator=g), st, k))
    apart = loop._pass_energies(model, batch, sizes, passes)
    monkeypatch.setattr(loop, "compiled_of", lambda net: object())  # as training's compiled passes call it
    together = loop._pass_energies(model, batch, sizes, passes)
    assert [e.shape for e in together] == [e.shape for e in apart] == [(4, 1), (4, 3), (4, 2)]
    for a, b in zip(together, apart, strict=True):
        assert torch.allclose(a, b, rtol=1e-5, atol=1e-5)
