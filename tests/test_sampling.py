"""Screened starts, population resampling, heading sweeps, an energy that sees some objects, feature noise
in training."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import CostError, CostFn, LearnedEnergy
from scenescore.problem.files import load_problem
from scenescore.problem.problem import Problem, ProblemError
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers import solve
from scenescore.solvers.kernel import (
    PLACEMENT,
    LangevinConfig,
    Limits,
    chain,
    resample,
    screen,
    sweep_headings,
)

pytestmark = pytest.mark.float_order


def _pull(poses: torch.Tensor) -> torch.Tensor:
    """Two basins for the mug: a shallow one at x = -0.3, a deep one at x = +0.3."""
    x = poses[:, 1, 0]
    return torch.minimum((x + 0.3) ** 2 * 50, (x - 0.3) ** 2 * 50 - 1.0) + 5 * poses[:, 1, 1] ** 2


def _scene() -> Scene:
    return Scene(
        [
            SceneObject("box", "box", (0.1, 0.1), (0.0, 0.0, 0.0), fixed=True),
            SceneObject("mug", "mug", (0.08, 0.08), None, shape="disk"),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )


def test_screen_keeps_the_lowest():
    draws = torch.randn(100, 2, 3, generator=torch.Generator().manual_seed(0))
    e = draws[:, 0, 0] ** 2
    kept = screen(lambda x: x[:, 0, 0] ** 2, draws, 10, chunk=7)
    assert kept.shape == (10, 2, 3)
    assert torch.equal(kept, draws[e.argsort()[:10]])


def test_resample_copies_low_cost_particles_within_groups():
    gen = torch.Generator().manual_seed(0)
    x = torch.arange(8, dtype=torch.float64)[:, None, None].expand(8, 1, 3).clone()
    e = torch.tensor([0.0, 50, 50, 50, 50, 50, 0, 50], dtype=torch.float64)  # two groups of four
    out = resample(x, e, temperature=1.0, groups=2, generator=gen)
    assert out[:4, 0, 0].tolist() == [0, 0, 0, 0]  # group 1: only particle 0 is any good
    assert out[4:, 0, 0].tolist() == [6, 6, 6, 6]  # group 2 draws from its own particles only
    flat = resample(x, torch.zeros(8, dtype=torch.float64), 1.0, 1, gen)
    assert sorted(flat[:, 0, 0].tolist()) == list(range(8))  # equal weights: systematic resampling keeps all


def test_resampled_population_ends_in_the_deep_basin():
    p = Problem(_scene(), CostFn(_pull, name="pull") + ss.costs.Bounds())
    base = {"particles": 64, "steps": 40, "step_init": 0.01, "step_final": 1e-3, "noise": 0.5}
    plain = solve(p, "langevin", seed=0, options={"langevin": base})
    pop = solve(p, "langevin", seed=0, options={"langevin": {**base, "resample": 3, "temperature": 0.3}})
    deep = lambda r: float(np.mean(np.abs(r.samples[:, 1, 0] - 0.3) < 0.05))  # noqa: E731
    assert deep(pop) > 0.9 and deep(pop) > deep(plain) + 0.2, (deep(plain), deep(pop))
    with pytest.raises(ValueError, match="temperature"):
        solve(p, "langevin", options={"langevin": {"temperature": 0.0}})
    with pytest.raises(ValueError, match="age=None"):
        cfg = LangevinConfig(steps=4, resample=1)
        x = torch.zeros(2, 1, 3)
        limits = Limits(torch.ones(1, dtype=torch.bool), -torch.ones(2), torch.ones(2))
        chain(lambda x: x.sum((1, 2)), x, limits, cfg, age=torch.zeros(2))


def _face(poses: torch.Tensor) -> torch.Tensor:
    """A narrow well (about 6 degrees wide) for the mug's heading at 1 rad, a slope away from it elsewhere:
    a chain that starts far from the well never finds it by the gradient alone."""
    off = torch.remainder(poses[:, 1, 2] - 1.0 + np.pi, 2 * np.pi) - np.pi
    return -5 * torch.exp(-(off**2) / (2 * 0.05**2)) - 0.1 * off.abs()


def test_heading_sweep_finds_a_narrow_well_wherever_the_chain_left_the_heading():
    p = Problem(_scene(), CostFn(_face, name="face") + ss.costs.Bounds())
    base = {"particles": 32, "steps": 20, "step_init": 0.01, "noise": 0.2}
    plain = solve(p, "langevin", seed=0, options={"langevin": base})
    swept = solve(p, "langevin", seed=0, options={"langevin": {**base, "heading_sweep": 36}})
    near = lambda r: float(np.mean(np.abs(r.samples[:, 1, 2] - 1.0) < 0.05))  # noqa: E731
    assert near(swept) == 1.0 and near(plain) < 0.5, (near(plain), near(swept))
    assert np.allclose(swept.samples[:, 0], plain.samples[:, 0])  # the fixed box never turns


def test_heading_sweep_keeps_the_heading_on_a_tie_and_moves_only_movable_objects():
    x = torch.tensor([[[0.0, 0.0, 0.3], [0.1, 0.0, -2.0]]], dtype=torch.float64).repeat(2, 1, 1)
    flat = sweep_headings(lambda y: y.new_zeros(y.shape[0]), x, torch.ones(2, 2, dtype=torch.bool), 8)
    assert torch.equal(flat, x)
    to_zero = lambda y: (y[..., 2] ** 2).sum(-1)  # noqa: E731 - every heading wants 0
    movable = torch.tensor([[True, False], [False, True]])
    out = sweep_headings(to_zero, x, movable, 8)
    assert out[0, 0, 2] == 0.0 and out[0, 1, 2] == -2.0  # row 0 turns only its first object
    assert out[1, 0, 2] == 0.3 and out[1, 1, 2] == 0.0
    assert torch.equal(out[..., :2], x[..., :2])


def test_candidates_screen_the_start_by_cost():
    p = Problem(_scene(), CostFn(_pull, name="pull") + ss.costs.Bounds())
    opts = {"particles": 16, "steps": 0, "final_descent": 0}
    uni = solve(p, "langevin", seed=0, options={"langevin": opts})
    scr = solve(p, "langevin", seed=0, options={"langevin": {**opts, "candidates": 1024}})
    assert scr.sample_costs.max() < np.median(uni.sample_costs)
    again = solve(p, "langevin", seed=0, options={"langevin": {**opts, "candidates": 1024}})
    assert np.array_equal(scr.samples, again.samples)


@pytest.fixture(scope="module")
def model():
    torch.manual_seed(0)
    return ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=16, layers=2)


def test_learned_energy_sees_only_the_named_objects(model):
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    seen = scene.names[:3]
    sub = Scene([scene[n] for n in seen], scene.bounds)
    x = torch.tensor(scene.poses())[None]
    p = Problem(scene, LearnedEnergy(model, objects=seen), movable=seen)
    e_sub = model.energy_fn(sub)(torch.tensor(sub.poses(), dtype=torch.float32)[None])
    assert float(p.cost(x).detach()) == pytest.approx(float(e_sub.detach()), rel=1e-5)
    moved = x.clone()
    moved[0, 5, :2] += 0.2  # an object the energy does not see
    assert float(p.cost(moved).detach()) == pytest.approx(float(p.cost(x).detach()), rel=1e-6)
    assert float(Problem(scene, LearnedEnergy(model), movable=seen).cost(moved).detach()) != pytest.approx(
        float(Problem(scene, LearnedEnergy(model), movable=seen).cost(x).detach()), rel=1e-6
    )
    with pytest.raises(CostError, match="no object named 'cup'"):
        Problem(scene, LearnedEnergy(model, objects=["plate_0", "cup"]))
    with pytest.raises(CostError, match="non-empty list"):
        LearnedEnergy(model, objects="plate_0")


def test_casadi_uses_the_visible_objects_only(model):
    """IPOPT's optimum is stationary for the torch cost that sees three objects (not for one that sees all)."""
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    seen = scene.names[:4]
    cost = LearnedEnergy(model.double(), objects=seen) + ss.costs.PoseTarget(
        "bowl_0", scene["bowl_0"].pose[:2]
    )
    p = Problem(scene.without("bowl_0"), cost)
    r = solve(p, "casadi", init=scene.poses())
    assert r.status == "converged", r.summary()
    x = torch.tensor(r.poses)[None].requires_grad_(True)
    (g,) = torch.autograd.grad(p.cost(x).sum(), x)
    assert g[0, 3].abs().max() < 1e-5, g[0, 3]
    full = Problem(
        scene.without("bowl_0"),
        LearnedEnergy(model) + ss.costs.PoseTarget("bowl_0", scene["bowl_0"].pose[:2]),
    )
    x = torch.tensor(r.poses)[None].requires_grad_(True)
    (g_full,) = torch.autograd.grad(full.cost(x).sum(), x)
    assert g_full[0, 3].abs().max() > 1e-3


def test_yaml_energy_objects_key(tmp_path, model):
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    (tmp_path / "scene.json").write_text(scene.without("bowl_0").to_json())
    model.save(tmp_path / "m.ckpt")
    text = "scene: scene.json\nmodel: m.ckpt\ncosts:\n  - {{type: energy, objects: [bowl_0, plate_0, {}]}}\n"
    (tmp_path / "p.yaml").write_text(text.format("fork_0"))
    loaded = load_problem(tmp_path / "p.yaml")
    energy = next(c for _, c in loaded.problem.cost.objective_items)
    assert energy.objects == ["bowl_0", "plate_0", "fork_0"]
    (tmp_path / "p.yaml").write_text(text.format("cup_0"))
    with pytest.raises(ProblemError, match=r"costs\[0\]\.objects\[2\].*no object named 'cup_0'"):
        load_problem(tmp_path / "p.yaml")


@pytest.mark.parametrize(
    "field, value",
    [
        ("step_init", 0.0),
        ("step_final", -1e-3),
        ("max_delta", float("inf")),
        ("noise", -1.0),
        ("power", float("nan")),
        ("heading_sweep", -1),
        ("heading_sweep", 2.5),
    ],
)
def test_langevin_config_refuses_nonsense(field, value):
    with pytest.raises(ValueError, match=field):
        replace(PLACEMENT, **{field: value})
