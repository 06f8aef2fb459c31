"""Solvers on hand-built problems with known optima; chains, registry, determinism, the projection QP."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import Bounds, CostFn, HingeCollision, PoseTarget
from scenescore.errors import ConfigError
from scenescore.problem.problem import Problem, ProblemError
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers import available, get, option_names, solve
from scenescore.solvers.kernel import LangevinConfig
from scenescore.solvers.projection import LinearisedProjection, project_cvxpy
from scenescore.solvers.sqp import SQPOptions

pytestmark = pytest.mark.float_order


OPTIMUM = np.array([0.15 + 0.01 + 0.05, 0.05])  # box face + margin + mug radius; y of the target
FAST_LANGEVIN = {
    "particles": 16,
    "steps": 40,
    "noise": 0.2,
    "final_descent": 20,
    "step_init": 0.02,
    "step_final": 0.002,
}


def _scene() -> Scene:
    return Scene(
        [
            SceneObject("box", "box", (0.3, 0.3), (0.0, 0.0, 0.0), fixed=True),
            SceneObject("mug", "mug", (0.1, 0.1), None, shape="disk"),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )


def _problem(hinge_weight: float = 100.0, target=(0.1, 0.05)) -> Problem:
    """A quadratic pull toward a target inside a fixed box; the optimum is on the box's face, a margin away."""
    cost = 100.0 * PoseTarget("mug", target) + hinge_weight * HingeCollision(margin=0.01) + Bounds()
    return Problem(_scene(), cost)


@pytest.mark.parametrize("solver", ["osqp", "casadi", "langevin>osqp", "langevin>casadi"])
def test_refinement_reaches_the_known_optimum(solver):
    r = solve(_problem(), solver, seed=0, options={"langevin": FAST_LANGEVIN})
    assert r.success and r.feasible and r.status == "converged", r.summary()
    assert np.allclose(r.poses[1, :2], OPTIMUM, atol=1e-4), r.poses
    assert r.max_violation <= 1e-4
    assert r.objective == pytest.approx(100 * float(((OPTIMUM - [0.1, 0.05]) ** 2).sum()), abs=1e-3)
    assert r.terms["collision"]["violation"] <= 1e-4
    assert np.allclose(r.poses[0], [0, 0, 0])  # the fixed box never moves


def test_langevin_reaches_the_optimum_approximately_and_returns_all_particles():
    r = solve(_problem(), "langevin", seed=0, options={"langevin": FAST_LANGEVIN})
    assert r.status == "sampled"
    assert np.linalg.norm(r.poses[1, :2] - OPTIMUM) < 0.03, r.poses  # a sampler: near, not at, the optimum
    assert r.samples.shape == (16, 2, 3) and r.sample_costs.shape == (16,)
    assert np.allclose(r.samples[:, 0], 0.0)  # fixed object, every particle


def test_refinement_removes_the_overlap_langevin_leaves():
    # a weak hinge against a strong pull: the penalty optimum overlaps the box
    p = _problem(hinge_weight=1.0, target=(0.05, 0.05))
    lang = solve(p, "langevin", seed=0, options={"langevin": FAST_LANGEVIN})
    assert (
        lang.max_violation > 1e-3 and not lang.feasible and lang.violated.startswith("collision: box / mug")
    )
    assert "collision: box / mug" in lang.message
    for chain in ("langevin>osqp", "langevin>casadi"):
        r = solve(p, chain, seed=0, options={"langevin": FAST_LANGEVIN})
        assert r.max_violation <= 1e-4 and r.feasible and r.success, r.summary()
        assert [s.solver for s in r.stages] == ["langevin", chain.split(">")[1]]
        assert np.allclose(r.stages[0].poses, lang.poses)  # same seed, same first stage


def test_casadi_callback_path_for_user_functions():
    target = torch.tensor([0.1, 0.05], dtype=torch.float64)

    def pull(poses):
        return ((poses[:, 1, :2] - target) ** 2).sum(-1) + 0.01 * (1 - torch.cos(poses[:, 1, 2]))

    p = Problem(_scene(), CostFn(pull, name="pull") + HingeCollision(0.01) + Bounds())
    for s in ("casadi", "osqp"):
        r = solve(
            p, s, init=np.array([[0, 0, 0], [0.3, 0.0, 0.2]])
        )  # a local solver: start on the target's side
        assert r.success and np.allclose(r.poses[1, :2], OPTIMUM, atol=1e-4), r.summary()


def test_casadi_mx_rebuild_matches_torch_energy():
    import casadi as ca

    from scenescore.models.casadi import energy_mx

    torch.manual_seed(0)
    configs = [{"activation": a} for a in ("silu", "softplus", "leaky_relu")]
    configs.append({"edge_range": 3.0, "walls": True, "length_scale": 0.07})  # saturating edges, walls
    configs += [{"round_invariant": True}, {"round_invariant": True, "absolute": True, "walls": True}]
    configs.append({"edge_encoder": 8, "round_invariant": True, "edge_range": 3.0})  # the edge encoder
    # walls read near them, with an edge range too
    configs.append(
        {"edge_encoder": 8, "round_invariant": True, "walls": True, "wall_range": 1.5, "edge_range": 6.0}
    )
    configs.append({"edge_encoder": 8, "round_invariant": True, "walls": True, "wall_lines": True})
    for extra in configs:
        model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=16, layers=2, **extra).double()
        scene = ss.scenarios.get("dining").generate(1, 0)[0]
        x = np.random.default_rng(0).uniform(-0.5, 0.5, (len(scene), 3))
        e_torch = float(model.energy_fn(scene)(torch.tensor(x)[None]).detach())
        assert float(ca.DM(energy_mx(model, scene, ca.DM(x)))) == pytest.approx(e_torch, rel=1e-9, abs=1e-9)


def test_same_seed_same_numbers_and_different_seed_different_numbers():
    p = _problem()
    a = solve(p, "langevin", seed=3, options={"langevin": FAST_LANGEVIN})
    b = solve(p, "langevin", seed=3, options={"langevin": FAST_LANGEVIN})
    c = solve(p, "langevin", seed=4, options={"langevin": FAST_LANGEVIN})
    assert np.array_equal(a.samples, b.samples) and not np.array_equal(a.samples, c.samples)


def test_registry_and_errors():
    assert {"langevin", "osqp", "casadi"} <= set(available())
    with pytest.raises(
        ProblemError,
        match="unknown solver 'osq'.*did you mean 'osqp'.*available: alm, casadi, langevin, osqp",
    ):
        get("osq")
    with pytest.raises(ProblemError, match="unknown solver 'nope'"):
        get("langevin>nope")
    with pytest.raises(ProblemError, match="solver 'langevin'.*particle"):
        get("langevin", particle=3)
    with pytest.raises(ProblemError, match=r"init: expected poses of shape \(N, 3\)"):
        solve(_problem(), "osqp", init=np.zeros((3, 3)))
    assert get("langevin>osqp").name == "langevin>osqp"


def test_option_names_are_read_from_each_solvers_options_class():
    assert option_names("osqp") == sorted(f.name for f in fields(SQPOptions))
    langevin = option_names("langevin")
    assert langevin is not None and {"steps", "particles", "proposals", "trusted_first"} <= set(langevin)
    assert "chain" not in langevin and {f.name for f in fields(LangevinConfig)} <= set(langevin)
    with pytest.raises(ProblemError, match="unknown option 'qp_eps'.*did you mean 'qp_eps_"):
        get("osqp", qp_eps=1e-3)


def test_osqp_tolerances_are_options():
    o = SQPOptions()
    assert (o.qp_eps_abs, o.qp_eps_rel, o.qp_max_iter, o.penalty_init) == (1e-6, 1e-6, 4000, 10.0)
    with pytest.raises(ConfigError, match="qp_max_iter"):
        SQPOptions(qp_max_iter=0)
    r = solve(_problem(), "osqp", options={"osqp": {"qp_max_iter": 50, "qp_eps_abs": 1e-5}})
    assert r.status in ("converged", "max_iterations")


def test_failures_report_status_and_the_violated_constraint():
    r = solve(
        _problem(target=(0.0, 0.0)),
        "osqp",
        init=np.array([[0, 0, 0], [0.02, 0.0, 0.0]]),
        options={"osqp": {"max_iter": 1}},
    )
    assert r.status == "max_iterations" and not r.success
    assert r.poses.shape == (2, 3)  # the best poses found, also on failure
    text = r.summary()
    assert "max_iterations" in text and "collision" in text and "violation" in text
    d = r.to_dict()
    assert d["status"] == "max_iterations" and set(d["poses"]) == {"box", "mug"}


def test_projection_qp_osqp_matches_cvxpy_and_langevin_qp_projection_removes_overlaps():
    p = _problem(hinge_weight=1.0, target=(0.05, 0.05))
    x = torch.tensor([[[0, 0, 0], [0.1, 0.02, 0.3]]], dtype=torch.float64)
    a = LinearisedProjection(p)(x)[0]
    b = project_cvxpy(p, x[0])
    assert torch.allclose(a, b, atol=1e-5)
    assert float(p.violation(a[None])) < 2e-3 < float(p.violation(x))
    r = solve(p, "langevin", seed=0, options={"langevin": {**FAST_LANGEVIN, "projection": "qp", "steps": 20}})
    assert r.max_violation <= 1e-4, r.summary()


def test_problem_validates_movable():
    with pytest.raises(ProblemError, match="no object named 'cup'"):
        Problem(_scene(), PoseTarget("mug", (0, 0)), movable=["cup"])
    with pytest.raises(ProblemError, match="'box' is fixed"):
        Problem(_scene(), PoseTarget("mug", (0, 0)), movable=["box"])
    assert Problem(_scene(), PoseTarget("mug", (0, 0))).movable == ["mug"]  # pose null: moves


def test_casadi_solves_a_local_graph_model_through_torch():
    """A local graph's neighbour lists have no symbolic form: IPOPT reads its energy through torch."""
    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(
        ss.FootprintEncoder(), hidden=8, layers=1, neighbours=3, radius=4.0
    ).double()
    scene = ss.scenarios.get("dining").generate(1, 0)[0]  # 8 objects: lists of 3 leave some out
    name = scene.objects[0].name
    p = ss.planning.placement.placement_problem(model, scene.without(name), energy_only=True)
    x0 = p.full(scene.poses())
    r = solve(p, "casadi", init=x0)
    with torch.no_grad():
        before, after = float(p.evaluate(x0)[0]), float(p.evaluate(p.full(r.poses))[0])
    assert r.success and np.isfinite(r.poses).all() and after < before - 1e-3
