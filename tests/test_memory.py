"""The memory budget: parsed from the environment or --memory-gb, checked before large allocations with
an error that says what to lower; the energy evaluated in chunks gives the same numbers as in one pass."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import torch
from conftest import assert_close_to_rounding

import scenescore.runtime.memory as mem
from scenescore.cli import main
from scenescore.costs import Bounds
from scenescore.encoders import FootprintEncoder
from scenescore.errors import ConfigError
from scenescore.models import ScoreModel, load
from scenescore.models.network import EnergyConfig, EnergyNet, parameter_count
from scenescore.planning.placement import PLACE, place
from scenescore.problem.problem import Problem
from scenescore.runtime.memory import MemoryBudgetError
from scenescore.scenarios import DiningScenario
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers.langevin import LangevinSolver

pytestmark = pytest.mark.float_order


@pytest.fixture
def model():
    torch.manual_seed(0)
    return ScoreModel.create(FootprintEncoder(), walls=True, edge_range=3.0, round_invariant=True)


def tiny_budget(monkeypatch, gb: float = 0.001) -> None:
    monkeypatch.setenv(mem.ENV, str(gb))


# -- the budget -------------------------------------------------------------------------------------


def test_budget_default_is_half_the_machine(monkeypatch):
    monkeypatch.delenv(mem.ENV, raising=False)
    limit, source = mem.budget()
    assert limit == int(mem.total_memory() * 0.5)
    assert mem.ENV in source and "of the machine's" in source


def test_budget_from_env_and_override(monkeypatch):
    monkeypatch.setenv(mem.ENV, " 2.5 ")
    assert mem.budget() == (2_500_000_000, mem.ENV)
    mem.set_budget(0.5)
    try:
        assert mem.budget() == (500_000_000, "--memory-gb")
    finally:
        mem.set_budget(None)
    assert mem.budget_bytes() == 2_500_000_000


@pytest.mark.parametrize("bad", ["abc", "-1", "0", "nan", "inf", "1e400", "2GB"])
def test_malformed_env_is_a_clear_error(monkeypatch, bad):
    monkeypatch.setenv(mem.ENV, bad)
    with pytest.raises(
        ConfigError, match=rf"SCENESCORE_MEMORY_GB: expected a number of gigabytes > 0 .*got '{bad}'"
    ):
        mem.budget()


@pytest.mark.parametrize("bad", [-1.0, 0, math.nan, True])
def test_malformed_override_is_a_clear_error(bad):
    with pytest.raises(ConfigError, match="--memory-gb: expected a number of gigabytes > 0"):
        mem.set_budget(bad)
    assert mem.budget()[1] != "--memory-gb"


def test_check_message_says_what_budget_and_what_to_lower(monkeypatch):
    tiny_budget(monkeypatch, 1)
    mem.check(0.9e9, "x", "y")  # within
    with pytest.raises(MemoryBudgetError) as e:
        mem.check(5.4e9, "langevin: 100 particles x 12 objects", "particles")
    msg = str(e.value)
    assert msg == (
        "langevin: 100 particles x 12 objects would need ~5.4 GB, over the memory budget of 1 GB "
        "(SCENESCORE_MEMORY_GB); lower particles"
    )
    assert isinstance(e.value, ValueError)


def test_chunk_rows(monkeypatch):
    monkeypatch.delenv(mem.ENV, raising=False)
    assert mem.chunk_rows(mem.CHUNK_BYTES // 10, "w", "l") == 10
    assert mem.chunk_rows(mem.CHUNK_BYTES * 3, "w", "l") == 1  # at least one row
    tiny_budget(monkeypatch, 0.008)  # an eighth of it per chunk: 1 MB
    assert mem.chunk_rows(1e5, "w", "l") == 10
    with pytest.raises(MemoryBudgetError, match="one row would need ~0.01 GB.*lower l"):
        mem.chunk_rows(1e7, "one row", "l")


# -- checks at each boundary ----------------------------------------------------------------------


def small_problem(n: int = 10) -> Problem:
    objs = [SceneObject(f"o{i}", "box", (0.05, 0.05), None) for i in range(n)]
    return Problem(Scene(objs, ((-1, -1), (1, 1))), Bounds())


def test_absurd_particles_and_candidates_are_refused_before_drawing(monkeypatch):
    tiny_budget(monkeypatch)
    with pytest.raises(
        MemoryBudgetError, match=r"langevin: 60000 particles x 10 objects would need .*lower particles"
    ):
        LangevinSolver(particles=60000, steps=1).solve(small_problem())
    with pytest.raises(
        MemoryBudgetError, match=r"langevin: 1000000 candidates x 10 objects .*lower candidates"
    ):
        LangevinSolver(particles=4, candidates=1_000_000, steps=1).solve(small_problem())
    LangevinSolver(particles=4, steps=1).solve(small_problem())  # a small population fits


def test_heatmap_grid_over_the_budget(monkeypatch, model):
    from scenescore.planning.heatmap import energy_grid

    scene = DiningScenario().generate(1, 0)[0]
    tiny_budget(monkeypatch)
    with pytest.raises(
        MemoryBudgetError,
        match=r"heatmap: resolution 0.001 m gives 1.44e\+06 grid cells.*lower the resolution",
    ):
        energy_grid(model, scene, "bowl_0", resolution=0.001)


def net_terms(model: ScoreModel, n: int) -> int:
    """The terms an energy's float rounding accumulates over, for :func:`assert_close_to_rounding`: per
    message layer, a sum over the ``n`` neighbours and the products of two dense layers."""
    cfg = model.net.cfg
    return cfg.layers * (n + cfg.hidden + (cfg.edge_hidden or cfg.hidden))


def test_heatmap_unchanged_by_chunking(monkeypatch, model):
    """The grid's energies in chunks of three pose sets are those of one pass, to the rounding of the
    matrix products (another batch size may take another kernel); the grid itself exactly."""
    import scenescore.planning.heatmap as hm

    scene = DiningScenario().generate(1, 0)[0]
    xs, ys, e = hm.energy_grid(model, scene, "bowl_0", resolution=0.05)
    monkeypatch.setattr(mem, "CHUNK_BYTES", 3 * model.net.row_bytes(len(scene) + 4, False))
    xs2, ys2, e2 = hm.energy_grid(model, scene, "bowl_0", resolution=0.05)
    assert np.array_equal(xs, xs2) and np.array_equal(ys, ys2)
    assert_close_to_rounding(
        torch.as_tensor(e2), torch.as_tensor(e), net_terms(model, len(scene) + 4), model.dtype
    )


def test_render_ppm_over_the_budget(monkeypatch):
    from scenescore.vision import render_scene

    scene = DiningScenario().generate(1, 0)[0]
    tiny_budget(monkeypatch, 0.01)
    with pytest.raises(
        MemoryBudgetError, match=r"render: ppm 5000 gives a 6000 x 6000 image of 8 objects.*lower the ppm"
    ):
        render_scene(scene, ppm=5000)
    render_scene(scene, ppm=50)  # small enough


def test_large_png_refused_from_its_header(monkeypatch, tmp_path):
    import zlib

    from scenescore.vision.render import read_image

    def chunk(kind: bytes, data: bytes) -> bytes:
        return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")

    w = h = 40_000  # a few hundred bytes on disk, 4.8 GB decoded
    ihdr = w.to_bytes(4, "big") + h.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    png = (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b"")
    )
    path = tmp_path / "bomb.png"
    path.write_bytes(png)
    tiny_budget(monkeypatch, 1)
    with pytest.raises(
        MemoryBudgetError, match=r"bomb.png: a 40000 x 40000 image through the vision pipeline"
    ):
        read_image(path)


def test_checkpoint_declaring_huge_widths_is_refused_before_building(tmp_path, model):
    from scenescore.models.checkpoint import write_checkpoint

    cfg = {**model.config.to_dict(), "hidden": 8192, "edge_hidden": 8192, "layers": 64}
    path = tmp_path / "wide.ckpt"
    write_checkpoint(path, model.net.state_dict(), cfg, {"name": "footprint", "config": {}}, {})
    count = parameter_count(EnergyConfig(**cfg))
    assert count > 10**10
    # the default budget (half of this machine) is far below 80 GB of weights
    with pytest.raises(
        MemoryBudgetError,
        match=rf"wide.ckpt: the network it declares \(hidden 8192, edge_hidden 8192, 64 layers.*{count:,} weights\).*lower the widths",
    ):
        load(path)


def test_parameter_count_matches_the_network():
    for kw in (
        {},
        {"hidden": 16, "edge_hidden": 24, "layers": 2},
        {"message": "linear", "embed_dim": 8},
        {"absolute": True, "layers": 1},
    ):
        cfg = EnergyConfig(feat_dim=7, **kw)
        with torch.device("meta"):
            net = EnergyNet(cfg)
        assert parameter_count(cfg) == sum(p.numel() for p in net.parameters()), kw


def test_network_too_wide_to_build(monkeypatch):
    tiny_budget(monkeypatch, 0.001)
    with pytest.raises(MemoryBudgetError, match=r"energy network: .* weights \(hidden 1024.*lower hidden"):
        EnergyNet(EnergyConfig(feat_dim=4, hidden=1024))


def test_scene_too_large_for_one_pose_set(monkeypatch, model):
    objs = [
        SceneObject(f"o{i}", "box", (0.01, 0.01), (0.02 * (i % 40), 0.02 * (i // 40), 0.0))
        for i in range(400)
    ]
    scene = Scene(objs, ((-0.1, -0.1), (1, 1)))
    fn = model.energy_fn(scene)
    tiny_budget(monkeypatch, 0.01)
    with pytest.raises(
        MemoryBudgetError, match=r"energy network: one pose set of 404 objects .*lower the number of objects"
    ):
        with torch.no_grad():
            fn(torch.as_tensor(scene.poses(), dtype=torch.float32)[None])


# -- chunked evaluation: the same numbers --------------------------------------------------------


def test_chunked_energy_and_gradient_match_one_pass(monkeypatch, model):
    """In chunks of 1 to 49 pose sets the energies and the gradient for the poses (taken piece by piece,
    see EnergyNet.forward) are those of one pass: in float64 to a few units of rounding, in float32 to
    the rounding of the matrix products (a piece of one pose set multiplies through the head as a vector,
    not a matrix, and another batch size may take another kernel)."""
    scene = DiningScenario(settings=4).generate(1, 0)[0]
    n = len(scene) + 4  # with the walls
    x32 = torch.randn(50, len(scene), 3, generator=torch.Generator().manual_seed(1))
    default_bytes = mem.CHUNK_BYTES
    for net in (model, copy.deepcopy(model).double()):  # float32, then the same weights in float64
        fn, x = net.energy_fn(scene), x32.to(net.dtype)
        terms = 16 if net.dtype == torch.float64 else net_terms(net, n)
        monkeypatch.setattr(mem, "CHUNK_BYTES", default_bytes)
        with torch.no_grad():
            e = fn(x)
        xr = x.clone().requires_grad_(True)
        (g,) = torch.autograd.grad(fn(xr).sum(), xr)
        for rows in (1, 7, 49):
            monkeypatch.setattr(mem, "CHUNK_BYTES", rows * net.net.row_bytes(n, False, x.element_size()))
            assert net.net.chunk_rows(n, False, x.element_size()) == rows
            with torch.no_grad():
                assert_close_to_rounding(fn(x), e, terms)
            monkeypatch.setattr(mem, "CHUNK_BYTES", rows * net.net.row_bytes(n, True, x.element_size()))
            xr = x.clone().requires_grad_(True)
            (gc,) = torch.autograd.grad(fn(xr).sum(), xr)
            assert_close_to_rounding(gc, g, terms)


def test_chunked_training_gradients_match(monkeypatch, model):
    """Through the chunked path the weights get their gradients too (summed over chunks: close, not
    bit-equal)."""
    scenes = DiningScenario().generate(6, 0)
    st = model.tensors(scenes)
    n = st.poses.shape[1]

    def grads():
        model.zero_grad()
        x = st.poses.clone().requires_grad_(True)
        e = model.energy(x, st)
        (e**2).sum().backward()
        return e.detach(), [p.grad.clone() for p in model.parameters()]

    e, g = grads()
    monkeypatch.setattr(mem, "CHUNK_BYTES", 2 * model.net.row_bytes(n, True))
    e2, g2 = grads()
    assert_close_to_rounding(e2, e, net_terms(model, n))
    for a, b in zip(g, g2):  # a weight's gradient also sums over the chunks' pose sets and edges
        assert_close_to_rounding(b, a, net_terms(model, n) + len(scenes) * n * n)


def test_placement_the_same_when_chunked(monkeypatch, model):
    """Chunking changes the order of the network's sums, not what it computes: in float64 the placement
    is the one-pass placement to float64 rounding. (A seed names a placement for one memory budget and
    thread count; across budgets, float32 placements agree to float32 rounding, amplified by the chain.)"""
    from dataclasses import replace

    model = model.double()
    scene = DiningScenario(settings=3).generate(1, 2)[0]
    k = scene.index("bowl_1")
    q = Scene(
        [*scene.objects[:k], replace(scene.objects[k], pose=None), *scene.objects[k + 1 :]], scene.bounds
    )
    opts = replace(PLACE, particles=16, candidates=64, chain=replace(PLACE.chain, steps=5, final_descent=2))
    a = place(model, q, opts, seed=3)
    monkeypatch.setattr(mem, "CHUNK_BYTES", 3 * model.net.row_bytes(len(q) + 4, True, 8))
    assert model.net.chunk_rows(len(q) + 4, True, 8) == 3
    b = place(model, q, opts, seed=3)
    np.testing.assert_allclose(b.poses(), a.poses(), rtol=0, atol=1e-9)


# -- the command line -----------------------------------------------------------------------------


def test_cli_memory_gb_and_env(monkeypatch, tmp_path, capsys):
    out = tmp_path / "imgs"
    rc = main(
        [
            "generate",
            "dining",
            "--n",
            "1",
            "--images",
            str(out),
            "--ppm",
            "5000",
            "--memory-gb",
            "0.05",
            "--quiet",
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "render: ppm 5000 gives a 6000 x 6000 image" in err and "(--memory-gb); lower the ppm" in err
    assert (
        main(["generate", "dining", "--n", "1", "--out", str(tmp_path / "s.jsonl"), "--memory-gb", "-2"]) == 2
    )
    assert "--memory-gb: expected a number of gigabytes > 0" in capsys.readouterr().err
    monkeypatch.setenv(mem.ENV, "lots")
    assert main(["generate", "dining", "--n", "1", "--out", str(tmp_path / "s.jsonl")]) == 2
    assert "SCENESCORE_MEMORY_GB: expected a number of gigabytes > 0" in capsys.readouterr().err


def test_collision_in_chunks_is_identical(monkeypatch):
    from scenescore.costs import HingeCollision, collision

    objs = [
        SceneObject(f"o{i}", "box", (0.1, 0.05), (0.2 * (i % 5) - 0.4, 0.2 * (i // 5) - 0.4, 0.3 * i))
        for i in range(20)
    ]
    scene = Scene(objs, ((-1, -1), (1, 1)))
    prob = Problem(scene, HingeCollision(margin=0.01), movable=["o3", "o7", "o11"])
    (_, term), *_ = prob.cost.items
    x = prob.initial(100, torch.Generator().manual_seed(0))
    full = term(x)
    xr = x.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(term(xr).sum(), xr)
    pairs = len(term.support())
    for rows in (1, 7, 64):
        monkeypatch.setattr(mem, "CHUNK_BYTES", rows * collision.PAIR_BYTES * pairs)
        assert torch.equal(term(x), full)
        xr = x.clone().requires_grad_(True)
        (gc,) = torch.autograd.grad(term(xr).sum(), xr)
        assert torch.equal(gc, g)


def test_energy_in_pieces_matches_one_pass(monkeypatch, model):
    """A batch over CACHE_EDGES edges is taken in pieces on the CPU: the same energies and gradient for
    the poses to float rounding, none for the weights; with weight gradients it stays one pass."""
    import scenescore.models.network as network

    scene = DiningScenario(settings=2).generate(1, 0)[0]
    fn = model.energy_fn(scene)
    n = len(scene) + 4  # with the walls
    x = torch.randn(30, len(scene), 3, generator=torch.Generator().manual_seed(2))

    def pose_grad() -> tuple[torch.Tensor, torch.Tensor]:
        xr = x.clone().requires_grad_(True)
        e = fn(xr)
        (g,) = torch.autograd.grad(e.sum(), xr)
        return e.detach(), g

    with torch.no_grad():
        e = fn(x)
    e1, g = pose_grad()
    pieces = []
    real = network.PoseGradInPieces.apply

    def counting(net, rows, *inputs):
        pieces.append(rows)
        return real(net, rows, *inputs)

    monkeypatch.setattr(network.PoseGradInPieces, "apply", counting)
    monkeypatch.setattr(network, "CACHE_EDGES", 4 * n * n)  # pieces of 4 pose sets
    terms = net_terms(model, n)  # pieces of another batch size may take other kernels: to rounding
    with torch.no_grad():
        assert_close_to_rounding(fn(x), e, terms)
    e2, g2 = pose_grad()
    assert pieces == [4]
    assert_close_to_rounding(e2, e1, terms)
    assert_close_to_rounding(g2, g, terms)
    model.zero_grad()
    st = model.tensors([scene]).repeat(30)
    model.energy(st.poses.clone().requires_grad_(True), st).sum().backward()  # training: one pass
    assert pieces == [4] and all(p.grad is not None for p in model.net.layers.parameters())


def test_even_pieces_keep_every_lane_busy():
    """A batch cut for ``lanes`` threads: pieces of at most ``most`` rows (or as few as the lanes need),
    no more rounds of pieces than ``most`` needs, and no lane (every ``lanes``-th piece, as
    ``in_parallel`` hands them out) holding more than its share of the rows plus one per round;
    one lane keeps ``most``."""
    import math

    from scenescore.models.chunks import even_piece

    assert even_piece(256, 49, 1) == 49 and even_piece(256, 49, 0) == 49
    for b in range(2, 300, 7):
        for most in (1, 3, 16, 49, 128, 1000):
            for lanes in (2, 3, 4):
                p = even_piece(b, most, lanes)
                sizes = [min(p, b - a) for a in range(0, b, p)]
                rounds = math.ceil(math.ceil(b / most) / lanes)
                share = math.ceil(b / lanes)
                assert p <= max(most, share) and len(sizes) <= rounds * lanes
                assert max(sum(sizes[k::lanes]) for k in range(lanes)) <= share + rounds, (b, most, lanes)
    assert even_piece(256, 49, 2) == 43  # 6 pieces, 129 and 127 rows a lane, not 147 and 109
