"""The ``alm`` batched refinement: feasibility by the exact check, fixed objects, per-particle statuses,
determinism, chains that hand it every particle, the registry, options and their errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from scenescore.costs import Bounds, HingeCollision, PoseTarget
from scenescore.problem.files import load_problem
from scenescore.problem.problem import Problem, ProblemError
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers import available, get, option_names, solve
from scenescore.solvers.alm import ALMOptions, ALMSolver

pytestmark = pytest.mark.float_order


FAST_LANGEVIN = {"particles": 16, "steps": 30, "noise": 0.2, "step_init": 0.02, "step_final": 0.002}
STATUSES = {"converged", "max_iterations", "infeasible", "failed"}


def _boxes() -> Problem:
    """Two moving boxes pulled onto a fixed box (and onto each other): the penalty alone lets them overlap."""
    scene = Scene(
        [
            SceneObject("table", "box", (0.3, 0.2), (0.0, 0.0, 0.3), fixed=True),
            SceneObject("a", "box", (0.2, 0.1), None),
            SceneObject("b", "box", (0.15, 0.15), None),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )
    cost = (
        10.0 * PoseTarget("a", (0.02, 0.0))
        + 10.0 * PoseTarget("b", (-0.02, 0.03))
        + 1.0 * HingeCollision(margin=0.0)
        + Bounds()
    )
    return Problem(scene, cost)


def _overlapping(problem: Problem, rows: int = 12, seed: int = 0) -> torch.Tensor:
    """``rows`` starts ``(B, N, 3)`` with both moving boxes on top of the fixed one, at random angles."""
    gen = torch.Generator().manual_seed(seed)
    x = problem.base_poses()[None].repeat(rows, 1, 1)
    x[:, 1:, :2] = (torch.rand(rows, 2, 2, generator=gen, dtype=torch.float64) - 0.5) * 0.1
    x[:, 1:, 2] = (torch.rand(rows, 2, generator=gen, dtype=torch.float64) - 0.5) * 6
    return x


def test_overlapping_boxes_end_feasible_by_the_exact_check_and_fixed_objects_stay():
    p = _boxes()
    x0 = _overlapping(p)
    assert not any(p.check(x).feasible for x in x0)
    r = solve(p, "alm", init=x0)
    assert r.samples.shape == x0.shape and r.sample_costs.shape == (12,)
    assert all(p.check(x).feasible for x in r.samples), [p.check(x).describe() for x in r.samples]
    assert np.all(r.sample_violations <= 1e-4)
    assert set(r.sample_status) <= {"converged", "max_iterations"}
    assert r.feasible and r.success and r.status == "converged", r.summary()
    assert np.array_equal(r.poses, r.samples[0])
    assert np.array_equal(r.samples[:, 0], np.repeat(x0[:1, 0].numpy(), 12, 0))  # the fixed box, exactly


def test_objects_the_problem_does_not_move_stay_put():
    p0 = _boxes()
    scene = p0.scene.with_poses(_overlapping(p0, 1)[0].numpy())
    p = Problem(scene, p0.cost, movable=["a"])  # b has a pose and is not listed: it stays
    x0 = p.full(scene.poses())
    r = solve(p, "alm", init=x0.repeat(3, 1, 1))
    assert np.array_equal(r.samples[:, 2], np.repeat(x0[:, 2].numpy(), 3, 0))
    assert np.array_equal(r.samples[:, 0], np.repeat(x0[:, 0].numpy(), 3, 0))
    assert not np.allclose(r.samples[:, 1], x0[:, 1].numpy())


def test_per_particle_statuses_and_best_first_order():
    p = _boxes()
    good = p.full(p.base_poses().numpy().copy())
    good[0, 1, :2] = torch.tensor([0.4, 0.4])
    good[0, 2, :2] = torch.tensor([-0.4, -0.4])  # far from everything: feasible from the start
    x0 = torch.cat([_overlapping(p, 3), good])
    r = solve(p, "alm", init=x0, options={"alm": {"iterations": 0}})  # no iteration: statuses of the starts
    assert list(r.sample_status) == ["max_iterations", "infeasible", "infeasible", "infeasible"]
    assert r.sample_violations[0] == 0 and np.all(r.sample_violations[1:] > 1e-3)
    assert np.all(np.diff(r.sample_costs[1:]) >= 0)  # infeasible ones after the feasible, by cost
    assert r.to_dict()["sample_status"] == {"infeasible": 3, "max_iterations": 1}
    full = solve(p, "alm", init=x0)
    assert set(full.sample_status) <= STATUSES and len(full.sample_status) == 4
    feasible = full.sample_violations <= 1e-4
    assert np.all(feasible[: feasible.sum()])  # feasible first
    ok = np.isin(full.sample_status, ["converged", "max_iterations"])
    assert np.array_equal(ok, feasible)


def test_repair_leaves_feasible_samples_alone_and_repairs_the_rest():
    p = _boxes()
    good = p.full(p.base_poses().numpy().copy())
    good[0, 1, :2] = torch.tensor([0.4, 0.4])
    good[0, 2, :2] = torch.tensor([-0.4, -0.4])
    x0 = torch.cat([good, _overlapping(p, 5)])
    r = solve(p, "alm", init=x0, options={"alm": {"polish": False}})
    assert all(p.check(x).feasible for x in r.samples) and set(r.sample_status) == {"converged"}
    assert any(np.array_equal(x, good[0].numpy()) for x in r.samples)  # not moved at all
    polished = solve(p, "alm", init=x0)
    assert not any(np.array_equal(x, good[0].numpy()) for x in polished.samples)  # pulled to its targets
    # a looser stationarity test (the targets pull at about 8 per metre where the good start is): every
    # particle still takes one outer iteration of descent, then stops short of the minimum
    loose = solve(p, "alm", init=x0, options={"alm": {"tol_grad": 50.0}})
    assert all(p.check(x).feasible for x in loose.samples)
    assert set(loose.sample_status) == {"converged"} and loose.iterations <= polished.iterations
    assert not any(np.array_equal(x, good[0].numpy()) for x in loose.samples)


def test_same_seed_same_numbers():
    p = _boxes()
    a = solve(p, "langevin>alm", seed=3, options={"langevin": FAST_LANGEVIN})
    b = solve(p, "langevin>alm", seed=3, options={"langevin": FAST_LANGEVIN})
    c = solve(p, "langevin>alm", seed=4, options={"langevin": FAST_LANGEVIN})
    assert np.array_equal(a.samples, b.samples) and np.array_equal(a.sample_costs, b.sample_costs)
    assert list(a.sample_status) == list(b.sample_status)
    assert not np.array_equal(a.samples, c.samples)
    alone = solve(p, "alm", seed=5)  # no init: the scene's poses, the unknown ones drawn by the seed
    assert alone.samples.shape == (1, 3, 3) and np.array_equal(alone.samples, solve(p, "alm", seed=5).samples)


def test_chain_hands_every_particle_to_alm_and_keeps_them_all():
    p = _boxes()
    r = solve(p, "langevin>alm", seed=0, options={"langevin": FAST_LANGEVIN})
    lang = r.stages[0]
    assert [s.solver for s in r.stages] == ["langevin", "alm"]
    assert r.samples.shape == lang.samples.shape == (16, 3, 3)
    assert len(r.sample_status) == 16 and r.sample_violations.shape == (16,)
    assert np.all(r.sample_violations <= 1e-4) and all(p.check(x).feasible for x in r.samples)
    # every refined sample starts from a Langevin particle: the multiset of starts is the population
    refined = ALMSolver(iterations=0).solve(p, init=torch.as_tensor(lang.samples))
    assert np.allclose(np.sort(refined.samples, 0), np.sort(lang.samples, 0))
    assert np.array_equal(r.poses, r.samples[0]) and r.feasible
    # a stage that takes one start still gets the best pose set, and the chain keeps the sampler's
    # particles, as before
    osqp = solve(p, "langevin>osqp", seed=0, options={"langevin": FAST_LANGEVIN})
    assert np.array_equal(osqp.samples, lang.samples) and osqp.sample_status is None
    twice = solve(p, "langevin>langevin", seed=0, options={"langevin": FAST_LANGEVIN})
    assert np.array_equal(twice.samples, lang.samples)


def test_registry_lists_alm_and_reads_options():
    assert "alm" in available()
    assert {"iterations", "tolerance", "penalty"} <= set(option_names("alm"))
    assert "threads" not in option_names("alm")  # the run's thread budget, not a solver's option
    s = get("alm", iterations=3, penalty=100.0)
    assert isinstance(s, ALMSolver) and s.options == ALMOptions(iterations=3, penalty=100.0)
    assert get("langevin>alm").name == "langevin>alm"


@pytest.mark.parametrize(
    "options, match",
    [
        ({"iterations": -1}, r"alm: iterations: expected an integer >= 0"),
        ({"iterations": 2.5}, r"alm: iterations: expected an integer"),
        ({"penalty": 0.0}, r"alm: penalty: expected a finite number > 0"),
        ({"tolerance": float("nan")}, r"alm: tolerance: expected a finite number"),
        ({"slack": 1.0}, r"alm: slack: expected a finite number >= 0 and <= 0.0001"),
        ({"penalty_growth": 0.5}, r"alm: penalty_growth: expected a finite number >= 1"),
        ({"polish": "yes"}, r"alm: polish: expected true or false, got 'yes'"),
        ({"iteratons": 3}, r"unknown option 'iteratons'; did you mean 'iterations'"),
    ],
)
def test_bad_options_name_the_option(options, match):
    with pytest.raises(ProblemError, match=match):
        get("alm", **options)


def test_yaml_problem_file_options(tmp_path):
    scene = {
        "objects": [
            {"name": "box", "category": "box", "size": [0.3, 0.3], "pose": [0, 0, 0], "fixed": True},
            {"name": "mug", "category": "mug", "size": [0.1, 0.1], "pose": None, "shape": "disk"},
        ],
        "bounds": [[-0.6, -0.6], [0.6, 0.6]],
    }
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    text = (
        "scene: scene.json\ncosts:\n  - {type: target, object: mug, xy: [0.1, 0.05], weight: 100.0}\n"
        "  - {type: collision, weight: 1.0, margin: 0.01}\n  - {type: bounds}\n"
        "solver: langevin>alm\noptions:\n  langevin: {particles: 8, steps: 20}\n  alm: {iterations: 20}\nseed: 0\n"
    )
    (tmp_path / "p.yaml").write_text(text)
    lp = load_problem(tmp_path / "p.yaml")
    assert lp.options["alm"] == {"iterations": 20}
    r = solve(lp.problem, lp.solver, seed=0, options=lp.options)
    assert r.samples.shape == (8, 2, 3) and r.feasible
    assert np.allclose(r.poses[1, :2], [0.21, 0.05], atol=2e-3)  # box face + margin + mug radius
    (tmp_path / "p.yaml").write_text(text.replace("iterations: 20", "penalty: -1"))
    with pytest.raises(ProblemError, match=r"options\.alm\.penalty.*alm: penalty: expected"):
        load_problem(tmp_path / "p.yaml")
