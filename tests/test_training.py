"""Training and placement: a tiny run learns a fixed offset; same seed, same numbers."""

import math
from dataclasses import replace

import pytest
import torch

from scenescore import Scene, SceneObject
from scenescore.encoders import FootprintEncoder
from scenescore.errors import ConfigError
from scenescore.learn import RAW_EDGES, NetworkConfig, Run, TrainConfig, fit
from scenescore.planning.placement import PLACE as PLACE_DEFAULT
from scenescore.planning.placement import place
from scenescore.solvers.kernel import LangevinConfig


def _offset_scenes(n, seed):
    """A red box and a blue box 0.2 m ahead of it along its heading, same heading."""
    g = torch.Generator().manual_seed(seed)
    out = []
    for _ in range(n):
        x, y = (torch.rand(2, generator=g) * 0.6 - 0.3).tolist()
        t = float(torch.rand(1, generator=g) * 2 * math.pi - math.pi)
        a = SceneObject("a", "red", (0.1, 0.05), (x, y, t), (200, 30, 30))
        b = SceneObject(
            "b", "blue", (0.08, 0.08), (x + 0.2 * math.cos(t), y + 0.2 * math.sin(t), t), (30, 30, 200)
        )
        out.append(Scene([a, b]))
    return out


CFG = TrainConfig(
    members=1, iterations=150, batch_scenes=8, negatives=8, network=NetworkConfig(hidden=32, layers=2)
)
PLACE = replace(
    PLACE_DEFAULT,
    particles=64,
    chain=LangevinConfig(steps=60, step_init=0.05, step_final=5e-4, final_descent=10),
)


@pytest.mark.slow
def test_tiny_training_learns_a_fixed_offset():
    torch.set_num_threads(1)
    model = fit(_offset_scenes(24, 0), CFG, seed=0, progress=False)
    assert model.info.final_loss < model.info.chance_loss
    errs = []
    for s in _offset_scenes(6, 99):
        truth = s["b"].pose
        got = place(model, s.without("b"), PLACE, seed=0)["b"].pose
        errs.append(math.hypot(got[0] - truth[0], got[1] - truth[1]))
    assert sum(errs) / len(errs) < 0.05, errs  # 5 cm, against ~0.35 m for a random guess


def test_same_seed_same_numbers():
    torch.set_num_threads(1)
    cfg = TrainConfig(
        members=1, iterations=10, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
    )
    scenes = _offset_scenes(6, 1)
    m1 = fit(scenes, cfg, seed=5, progress=False)
    m2 = fit(scenes, cfg, seed=5, progress=False)
    for (k, a), b in zip(m1.net.state_dict().items(), m2.net.state_dict().values()):
        assert torch.equal(a, b), k
    q = scenes[0].without("b")
    small = replace(PLACE_DEFAULT, particles=8, chain=LangevinConfig(steps=5))
    assert place(m1, q, small, seed=3)["b"].pose == place(m2, q, small, seed=3)["b"].pose
    m3 = fit(scenes, cfg, seed=6, progress=False)
    assert not torch.equal(next(m1.net.parameters()), next(m3.net.parameters()))


def test_fixed_objects_never_move():
    torch.manual_seed(0)
    from scenescore.encoders import FootprintEncoder
    from scenescore.models import ScoreModel

    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    s = _offset_scenes(1, 3)[0]
    out = place(
        model, s.without("b"), replace(PLACE_DEFAULT, particles=4, chain=LangevinConfig(steps=5)), seed=0
    )
    assert out["a"].pose == s["a"].pose
    (x0, y0), (x1, y1) = s.bounds
    x, y, _ = out["b"].pose
    assert x0 <= x <= x1 and y0 <= y <= y1


def test_feature_noise_is_seeded_and_changes_training():
    torch.set_num_threads(1)
    scenes = _offset_scenes(6, 1)
    cfg = TrainConfig(
        members=1, iterations=5, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
    )
    quiet = TrainConfig(**{**cfg.to_dict(), "feature_noise": 0.0})
    a, b = (fit(scenes, cfg, seed=2, progress=False) for _ in range(2))
    c = fit(scenes, quiet, seed=2, progress=False)
    pa, pb, pc = (next(m.net.parameters()) for m in (a, b, c))
    assert torch.equal(pa, pb) and not torch.equal(pa, pc)


def test_size_noise_is_seeded_and_changes_training():
    torch.set_num_threads(1)
    scenes = _offset_scenes(6, 1)
    cfg = TrainConfig(
        members=1,
        iterations=5,
        batch_scenes=4,
        negatives=4,
        feature_noise=0.0,
        network=NetworkConfig(hidden=16, layers=1),
    )
    assert cfg.size_noise > 0  # on by default
    quiet = TrainConfig(**{**cfg.to_dict(), "size_noise": 0.0})
    a, b = (fit(scenes, cfg, seed=2, progress=False) for _ in range(2))
    c = fit(scenes, quiet, seed=2, progress=False)
    pa, pb, pc = (next(m.net.parameters()) for m in (a, b, c))
    assert torch.equal(pa, pb) and not torch.equal(pa, pc)
    with pytest.raises(ConfigError, match="size_noise"):
        TrainConfig(size_noise=-0.1)


def test_the_trained_model_is_the_moving_average_of_the_second_half(monkeypatch):
    from scenescore.learn import loop

    torch.set_num_threads(1)
    scenes = _offset_scenes(6, 1)
    cfg = TrainConfig(
        members=1,
        iterations=8,
        batch_scenes=4,
        negatives=4,
        average=0.5,
        network=NetworkConfig(hidden=16, layers=1),
    )
    seen = []  # the weights after each averaged iteration

    def record(shadow, params, decay):
        assert decay == 0.25  # 0.5 lowered to 1 - 3 / 4 for a run that averages 4 iterations
        seen.append([p.detach().clone() for p in params])
        return average(shadow, params, decay)

    average = loop.moving_average
    monkeypatch.setattr(loop, "moving_average", record)
    model = fit(scenes, cfg, seed=2, progress=False)
    assert len(seen) == 4  # iterations 4 .. 7
    decay = 0.25
    want = seen[0]
    for w in seen[1:]:
        want = [decay * a + (1 - decay) * b for a, b in zip(want, w)]
    for got, exp in zip(model.net.parameters(), want):
        torch.testing.assert_close(got, exp)
    assert not torch.equal(next(model.net.parameters()), seen[-1][0])  # not the last iterate
    monkeypatch.undo()
    last = fit(scenes, replace(cfg, average=0.0), seed=2, progress=False)
    torch.testing.assert_close(next(last.net.parameters()), seen[-1][0])  # averaging off: the last iterate
    again = fit(scenes, cfg, seed=2, progress=False)
    assert torch.equal(next(again.net.parameters()), next(model.net.parameters()))
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(ConfigError, match="average"):
            TrainConfig(average=bad)


def test_default_network_has_the_edge_encoder_and_raw_edges_has_none():
    scenes = _offset_scenes(4, 1)
    small = {"iterations": 2, "batch_scenes": 2, "negatives": 2}
    assert fit(scenes, TrainConfig(members=1, **small), seed=0, progress=False).config.edge_encoder == 32
    raw = fit(scenes, TrainConfig(members=1, **small, **RAW_EDGES), seed=0, progress=False)
    assert raw.config.edge_encoder is None and raw.info.train_config["size_noise"] == 0.0


def test_batches_of_mixed_sizes_are_evaluated_cropped_by_size():
    """Scenes of 3 to 20 objects in one batch: the grouped, cropped pass gives the padded pass's energies
    to float rounding (padding adds only zeros), in several groups, and so do their gradients."""
    from scenescore.learn.size_groups import SizeGroups, best_cuts

    def row(n: int, shift: float) -> Scene:
        objs = [
            SceneObject(f"b{i}", "book", (0.02, 0.2), (-0.4 + 0.04 * i + shift, 0.0, 0.0)) for i in range(n)
        ]
        return Scene(objs, ((-0.6, -0.3), (0.6, 0.3)))

    scenes = [row(n, 0.001 * n) for n in (3, 4, 5, 8, 9, 12, 19, 20)]
    model = fit(
        scenes, TrainConfig(members=1, iterations=2, batch_scenes=4, negatives=2), seed=0, progress=False
    )
    st = model.tensors(scenes)
    by = SizeGroups(st.mask.sum(dim=1))
    assert len(by.groups) > 1 and sorted(i for g, _ in by.groups for i in g) == list(range(8))
    k = 3
    rep = st.repeat(k)
    x = rep.poses + 0.01 * torch.randn(rep.poses.shape, generator=torch.Generator().manual_seed(0))
    padded, grouped = model.energy(x, rep), by.bound(model, rep, k)(x)
    assert torch.allclose(padded, grouped, rtol=1e-5, atol=1e-5)
    w = model.net.layers[0].w_i.weight
    (g1,) = torch.autograd.grad(padded.sum(), w)
    (g2,) = torch.autograd.grad(by.bound(model, rep, k)(x).sum(), w)
    assert torch.allclose(g1, g2, rtol=1e-4, atol=1e-5 * float(g1.abs().max()))
    # one size, or grouping turned off: one group; the cuts minimise the padded edges
    assert len(SizeGroups(torch.tensor([6, 6, 6, 6])).groups) == 1
    assert len(SizeGroups(st.mask.sum(dim=1), enabled=False).groups) == 1
    with pytest.raises(ConfigError, match="group_sizes"):
        TrainConfig(group_sizes="yes")  # type: ignore[arg-type]
    assert best_cuts([2, 2, 10, 10], 4) in ([2, 4], [1, 2, 3, 4], [2, 3, 4], [1, 2, 4])


def _row(n: int = 4) -> Scene:
    """Books in a row along x, each 0.05 m after the last, headings along y."""
    objs = [
        SceneObject(f"b{k}", "book", (0.2, 0.04), (0.05 * k, 0.1, math.pi / 2), (200, 30, 30))
        for k in range(n)
    ]
    return Scene(objs, bounds=((-0.5, -0.3), (0.5, 0.3)))


def test_reanchored_negatives_move_one_object_next_to_another_anchor():
    from scenescore.learn.negatives import reanchored_negatives
    from scenescore.models import ScoreModel

    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    st = model.tensors([_row()])
    x, marked = reanchored_negatives(st, 12, torch.Generator().manual_seed(0))
    assert x.shape == (12, 4, 3) and bool((marked.sum(dim=1) == 1).all())
    truth = st.poses[0]
    for row, mark in zip(x, marked):
        moved = (row - truth).abs().sum(dim=-1) > 1e-9
        assert torch.equal(moved, mark)  # one object, the one marked; the rest where they were
        i = int(moved.nonzero())
        # its offset to some other object is the 0.05 m step it had to its nearest neighbour, and that
        # object is not the neighbour it had (nor does the object keep its place)
        steps = (row[:, :2] - row[i, :2]).norm(dim=-1)
        assert torch.isclose(steps, torch.tensor(0.05), atol=1e-6).any()
        assert row[i, 2] == pytest.approx(math.pi / 2)
    pair = model.tensors([Scene(_row(2).objects, bounds=((-0.5, -0.3), (0.5, 0.3)))])
    same, ok = reanchored_negatives(pair, 3, torch.Generator().manual_seed(0))
    assert not bool(ok.any()) and torch.equal(same, pair.repeat(3).poses)  # no third object to anchor to


def test_reanchored_counter_examples_are_seeded_and_change_training():
    torch.set_num_threads(1)
    scenes = [_row(4) for _ in range(4)]
    cfg = TrainConfig(
        members=1, iterations=4, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
    )
    a, b = (fit(scenes, replace(cfg, reanchored=3), seed=2, progress=False) for _ in range(2))
    c = fit(scenes, replace(cfg, reanchored=0), seed=2, progress=False)
    pa, pb, pc = (next(m.net.parameters()) for m in (a, b, c))
    assert torch.equal(pa, pb) and not torch.equal(pa, pc)
    assert a.info.chance_loss == pytest.approx(math.log(4 + 3 + 1))
    with pytest.raises(ConfigError, match="reanchored"):
        TrainConfig(reanchored=-1)


def test_reanchor_restart_starts_chains_from_one_object_on_another_anchor():
    from scenescore.learn.negatives import ChainBuffer
    from scenescore.models import ScoreModel

    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    data = model.tensors([_row(5)] * 2)
    cfg = TrainConfig(reanchor_restart=1.0)
    buf = ChainBuffer(data, 6, cfg, torch.Generator().manual_seed(0))
    moved = (buf.poses != data.poses[:, None]).any(dim=-1)  # (S, K, N)
    assert torch.equal(moved, buf.movable)  # the object put on another anchor, and it alone, moves
    assert bool((moved.sum(dim=-1) == 1).all())
    assert bool((buf.age == cfg.chain.steps // 2).all())  # halfway through the schedule
    plain = ChainBuffer(data, 6, TrainConfig(reanchor_restart=0.0), torch.Generator().manual_seed(0))
    assert bool((plain.age == 0).all()) and int(plain.movable.sum(dim=-1).max()) > 1
    with pytest.raises(ConfigError, match="reanchor_restart"):
        TrainConfig(reanchor_restart=1.5)


def test_model_cache_trains_each_model_once_and_only_where_asked(tmp_path, monkeypatch):
    from scenescore.learn import loop

    scenes = _offset_scenes(6, 0)
    cfg = replace(CFG, iterations=3)
    folder = tmp_path / "m"
    first = fit(scenes, cfg, seed=1, progress=False, run=Run(cache=folder))
    assert len(list(folder.glob("*.ckpt"))) == 1
    real = loop._fit

    def never(*a, **k):
        raise AssertionError("trained again")

    monkeypatch.setattr(loop, "_fit", never)
    again = fit(scenes, cfg, seed=1, progress=False, run=Run(cache=folder))  # loaded, not trained
    x = torch.stack([torch.as_tensor(s.poses(), dtype=torch.float32) for s in scenes])
    st = first.tensors(scenes)
    assert torch.equal(first.energy(x, st), again.energy(x, again.tensors(scenes)))
    monkeypatch.setattr(loop, "_fit", real)
    fit(scenes, cfg, seed=2, progress=False, run=Run(cache=folder))  # another seed: another model
    fit(
        scenes, cfg, encoder=FootprintEncoder(), seed=1, progress=False, run=Run(cache=folder)
    )  # an encoder: not kept
    assert len(list(folder.glob("*.ckpt"))) == 2
    threads = torch.get_num_threads()
    torch.set_num_threads(threads + 1)  # the weights do not depend on the thread count: the same model
    monkeypatch.setattr(loop, "_fit", never)
    try:
        fit(scenes, cfg, seed=1, progress=False, run=Run(cache=folder))
    finally:
        torch.set_num_threads(threads)
    assert len(list(folder.glob("*.ckpt"))) == 2
    monkeypatch.setattr(loop, "_fit", never)
    with pytest.raises(AssertionError, match="trained again"):
        fit(scenes, cfg, seed=1, progress=False)  # without a cache nothing is read
    from scenescore.learn import cache

    monkeypatch.setattr(cache, "code_version", lambda: "other code")
    with pytest.raises(AssertionError, match="trained again"):
        fit(scenes, cfg, seed=1, progress=False, run=Run(cache=folder))  # other code: not read
