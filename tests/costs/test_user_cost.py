"""A cost written by a user: one class and one registration, used from Python, from YAML and by every
solver; and the three bugs the redesign fixed (each failed on the old main)."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import pytest
import torch
from torch import Tensor

import scenescore as ss
from scenescore.costs import ConstraintCost, Cost, CostSpec, SpecContext, register_cost_type
from scenescore.problem.files import load_problem


class KeepLeftOf(ConstraintCost):
    """Object ``a`` at least ``gap`` metres left of object ``b``: one row ``x_b - x_a - gap >= 0``."""

    def __init__(self, a: str, b: str, gap: float, name: str = "keep_left"):
        self.a, self.b, self.gap, self.name = a, b, float(gap), name

    def _on_bind(self) -> None:
        self._i, self._j = (self.binding.scene.index(n) for n in (self.a, self.b))

    def constraints(self, poses: Tensor) -> Tensor:
        return (poses[:, self._j, 0] - poses[:, self._i, 0] - self.gap)[:, None]

    def labels(self) -> list[str]:
        return [f"{self.a} left of {self.b} by {self.gap:g} m"]

    def support(self) -> list[tuple[int, ...]]:
        return [(self._i, self._j)]


class KeepLeftSpec(CostSpec):
    type: Literal["keep_left"]
    a: str
    b: str
    gap: float

    def build(self, ctx: SpecContext) -> Cost:
        return KeepLeftOf(ctx.object(self.a, ("a",)), ctx.object(self.b, ("b",)), self.gap, **self.named())


register_cost_type("keep_left", KeepLeftSpec)


def _scene() -> ss.Scene:
    box = dict(category="box", size=(0.1, 0.06), color=(200, 60, 60))
    return ss.Scene(
        [ss.SceneObject("a", pose=(0.2, 0.0, 0.3), **box), ss.SceneObject("b", pose=(-0.2, 0.1, 0.0), **box)],
        bounds=((-0.5, -0.5), (0.5, 0.5)),
    )


def _cost() -> ss.costs.Sum:
    return (
        ss.costs.PoseTarget("a", (0.0, 0.0), name="pull_a")
        + ss.costs.PoseTarget("b", (0.0, 0.0), name="pull_b")
        + 10.0 * KeepLeftOf("a", "b", gap=0.2)
    )


def test_a_violated_user_constraint_is_infeasible():
    """Bug 1: the default exact check comes from the cost's rows (the old check ignored unknown costs)."""
    p = ss.Problem(_scene(), _cost(), movable=["a", "b"])
    f = p.check(p.base_poses())  # a at x = 0.2, b at x = -0.2: 0.6 m short of the 0.2 m gap
    assert not f.feasible
    (v,) = f.violations
    assert v.term == "keep_left" and v.amount == pytest.approx(0.6)
    assert "a left of b" in f.describe()
    ok = p.base_poses().clone()
    ok[0, 0], ok[1, 0] = -0.15, 0.15
    assert p.check(ok).feasible


@pytest.mark.parametrize("solver", ["langevin", "osqp", "casadi", "langevin>osqp", "langevin>casadi"])
def test_user_cost_works_with_every_solver(solver):
    """Bug 1: the casadi solver takes the user's rows through its default CasADi form (it raised a bare
    ValueError); every solver respects the constraint. The optimum: a at x = -0.1, b at x = 0.1."""
    torch.manual_seed(0)
    p = ss.Problem(_scene(), _cost(), movable=["a", "b"])
    r = ss.solve(p, solver, seed=0, options={"langevin": {"particles": 32, "steps": 60}})
    xa, xb = r.poses[0, 0], r.poses[1, 0]
    if solver == "langevin":  # a sampler with a penalty: near the optimum, not at it
        assert abs(xa + 0.1) < 0.05 and abs(xb - 0.1) < 0.05
    else:
        assert r.feasible and r.success, r.summary()
        assert xa == pytest.approx(-0.1, abs=1e-3) and xb == pytest.approx(0.1, abs=1e-3)
        assert r.terms["keep_left"]["violation"] <= 1e-4


def test_user_cost_from_yaml(tmp_path):
    text = """
scene:
  bounds: [[-0.5, -0.5], [0.5, 0.5]]
  objects:
    - {name: a, category: box, size: [0.1, 0.06], pose: [0.2, 0.0, 0.3]}
    - {name: b, category: box, size: [0.1, 0.06], pose: [-0.2, 0.1, 0.0]}
movable: [a, b]
costs:
  - {type: target, object: a, xy: [0, 0], name: pull_a}
  - {type: target, object: b, xy: [0, 0], name: pull_b}
  - {type: keep_left, a: a, b: b, gap: 0.2, weight: 10}
solver: casadi
"""
    lp = load_problem(tmp_path / "p.yaml", text=text)
    assert isinstance(lp.problem.cost["keep_left"], KeepLeftOf)
    r = ss.solve(lp.problem, lp.solver, seed=lp.seed)
    assert r.feasible and r.poses[1, 0] - r.poses[0, 0] == pytest.approx(0.2, abs=1e-4)
    bad = text.replace("b: b, gap", "b: bb, gap")
    with pytest.raises(ss.ProblemError, match=r"p\.yaml:\d+: costs\[2\]\.b: no object named 'bb'"):
        load_problem(tmp_path / "p.yaml", text=bad)
    with pytest.raises(ss.ProblemError, match=r"costs\[2\]\.gapp: unknown key 'gapp'; did you mean 'gap'"):
        load_problem(tmp_path / "p.yaml", text=text.replace("gap: 0.2", "gapp: 0.2"))


_SPEC_FILE = """
from __future__ import annotations
from scenescore.costs import CostSpec, register_cost_type

class NearWallSpec(CostSpec):
    type: Literal["near_wall"]
    object: str

register_cost_type("near_wall", NearWallSpec)
"""


def test_a_spec_is_complete_when_registered_or_the_error_names_the_missing_type(own_registries):
    """A spec written with postponed annotations in a namespace pydantic cannot import (a
    snippet run by exec) is resolved at registration with the caller's names, so that reading a YAML file
    never meets a half-defined spec; a name defined nowhere is a CostError at registration."""
    code = compile(_SPEC_FILE, "cell", "exec", dont_inherit=True)
    exec(code, {"__name__": "cell", "Literal": Literal})
    spec = ss.costs.cost_types()["near_wall"]
    assert spec.model_validate({"type": "near_wall", "object": "cup"}).object == "cup"
    with pytest.raises(
        ss.costs.CostError,
        match=r"register_cost_type\('near_wall'\): a field of NearWallSpec names 'Literal', which is not defined",
    ):
        exec(code, {"__name__": "cell"})


def test_target_without_heading_leaves_the_heading_free():
    """Bug 3: ``PoseTarget(theta=None)`` pulled the heading towards 0, in torch and in CasADi alike."""
    scene = _scene()
    p = ss.Problem(scene, ss.costs.PoseTarget("a", (0.1, 0.0)), movable=["a"])
    x = p.base_poses()[None].repeat(2, 1, 1)
    x[1, 0, 2] = 1.0
    e = p.evaluate(x)
    assert float(e[0]) == float(e[1])
    start = p.base_poses().clone()
    start[0, 2] = 1.0
    r = ss.solve(p, "casadi", init=start)
    assert r.poses[0, 0] == pytest.approx(0.1, abs=1e-6)
    assert r.poses[0, 2] == pytest.approx(1.0, abs=1e-6)  # not pulled to 0
    with_heading = ss.Problem(scene, ss.costs.PoseTarget("a", (0.1, 0.0), theta=0.5), movable=["a"])
    r = ss.solve(with_heading, "casadi", init=start)
    assert r.poses[0, 2] == pytest.approx(0.5, abs=1e-4)


def test_solve_leaves_torchs_thread_setting_as_it_found_it():
    """A solve runs torch on one thread (a large population's energy in pieces within the run's budget)
    and restores the caller's setting; the thread count is the run's budget, not a solver option."""
    outer = torch.get_num_threads()
    torch.set_num_threads(2)  # other test modules pin one thread; this one needs a pool
    p = ss.Problem(_scene(), _cost(), movable=["a", "b"])
    opts = {"langevin": {"particles": 256, "steps": 2, "final_descent": 0}}
    with ss.thread_budget(2):
        ss.solve(p, "langevin", options=opts)
        assert torch.get_num_threads() == 2
    ss.solve(p, "langevin", options=opts)
    assert torch.get_num_threads() == 2  # nothing leaks into the process
    with pytest.raises(ss.ProblemError, match="threads"):
        ss.solve(p, "langevin", options={"langevin": {"particles": 8, "threads": 1}})
    torch.set_num_threads(outer)


def test_result_fields_are_declared_and_status_serialises():
    p = ss.Problem(_scene(), _cost(), movable=["a", "b"])
    r = ss.solve(p, "osqp")
    assert isinstance(r.status, ss.solvers.Status) and r.status == "converged"
    assert r.to_dict()["status"] == "converged"
    assert set(vars(r)) == set(r.__dataclass_fields__)  # no undeclared attribute was set on it
    assert r.qp_time_mean is not None and r.wall_time is not None and math.isfinite(r.wall_time)
    assert np.isfinite(r.poses).all()
