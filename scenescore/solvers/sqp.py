"""The ``osqp`` solver: SQP refinement with raw OSQP.

Each iteration linearises every constraint row (per-pair collision depth, footprint bounds, reach) as a
hard inequality ``g + J d >= slack``, models the objective (the cost's terms that are not constraints:
the learned energy, targets, user functions) by its gradient and a damped-BFGS Hessian of the
Lagrangian, and bounds the step by a trust region. The QP is set up once (fixed sparsity: a pair's row
touches only its two objects) and only values are updated. Elastic slacks keep every QP feasible.
Steps are accepted on an l1 merit function whose tolerance is looser than the QP's target (a QP aims
``slack`` inside the constraints; the merit ignores violations below ``merit_tol``), otherwise steps are
rejected over and over on the linearisation error.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import osqp
import scipy.sparse as sp
import torch
from torch import Tensor

from ..errors import ConfigError, check_number
from ..problem.problem import FEASIBILITY_TOL, Problem
from .base import StageSolver, start_poses
from .projection import ANGLE_WEIGHT
from .result import Result, Status, make_result

__all__ = ["SQPOptions", "OSQPSolver"]

MAX_ITER = 1_000_000  # more is a typo, not a plan
# the trust region: a step is accepted when the merit function falls by more than ACCEPT of the QP's
# prediction; the region doubles after a step that used most of it and fell by more than EXPAND, and
# shrinks by SHRINK after a rejected step
ACCEPT = 0.1
EXPAND = 0.75
SHRINK = 0.25


@dataclass
class SQPOptions:
    """Options of the ``osqp`` SQP refinement."""

    max_iter: int = 100
    trust_init: float = 0.05  # metres (angles: trust / sqrt(ANGLE_WEIGHT) rad)
    trust_max: float = 0.5
    trust_min: float = 1e-7
    slack: float = 1e-5  # the QP aims this far inside every constraint (metres)
    merit_tol: float = 1e-4  # violations below this are not penalised by the merit function
    elastic: float = 1e4  # price of an elastic slack in the QP
    tol_step: float = 1e-7  # converged when the step is this small (metres) ...
    tol_kkt: float = 1e-5  # ... or the Lagrangian's gradient this small, with violations within slack
    # the merit function's first price of a violation; raised to 1.5 x the QP's largest multiplier + 1
    # whenever that is higher, so a step never buys objective with violation the QP would not
    penalty_init: float = 10.0
    qp_eps_abs: float = 1e-6  # OSQP's absolute tolerance for each step's QP
    qp_eps_rel: float = 1e-6  # OSQP's relative tolerance for each step's QP
    qp_max_iter: int = 4000  # OSQP's iterations per QP (its answer is used when it runs out)

    def __post_init__(self) -> None:
        check_number("osqp", "max_iter", self.max_iter, 0, MAX_ITER, integer=True)
        check_number("osqp", "qp_max_iter", self.qp_max_iter, 1, MAX_ITER, integer=True)
        for name in (
            "trust_init",
            "trust_max",
            "trust_min",
            "tol_step",
            "tol_kkt",
            "elastic",
            "penalty_init",
            "qp_eps_abs",
            "qp_eps_rel",
        ):
            check_number("osqp", name, getattr(self, name), 0, open_lo=True)
        for name in ("slack", "merit_tol"):
            check_number("osqp", name, getattr(self, name), 0)
        if not self.trust_min <= self.trust_init <= self.trust_max:
            raise ConfigError(
                f"osqp: trust_init: expected trust_min <= trust_init <= trust_max, got {self.trust_min:g}, "
                f"{self.trust_init:g}, {self.trust_max:g}"
            )


class _Refinement:
    """The problem seen by a refinement solver: objective terms and constraint rows on the movable
    variables ``z`` (the moving objects' poses, flat)."""

    def __init__(self, problem: Problem):
        self.problem = problem
        self.var_obj = np.flatnonzero(problem.movable_mask)
        self.n = 3 * len(self.var_obj)
        self.obj_items = problem.cost.objective_items
        self.con_terms = problem.cost.constraint_terms
        self.support: list[tuple[int, ...]] = []
        for c in self.con_terms:
            self.support += c.support()
        self.m = len(self.support)

    def poses(self, z: np.ndarray, base: Tensor) -> Tensor:
        x = base.clone()
        x[self.var_obj] = torch.as_tensor(z, dtype=torch.float64, device=base.device).reshape(-1, 3)
        return x[None]

    def objective(self, x: Tensor, grad: bool = True) -> tuple[float, np.ndarray | None]:
        with torch.enable_grad():
            x = x.detach().clone().requires_grad_(grad)
            f = x.new_zeros(1)
            for w, c in self.obj_items:
                f = f + w * c(x)
            if not torch.isfinite(f).all():
                raise FloatingPointError("the objective is not finite (NaN or inf)")
            if not grad:
                return float(f.detach()), None
            (g,) = torch.autograd.grad(f.sum(), x) if f.requires_grad else (torch.zeros_like(x),)
        return float(f.detach()), g[0, self.var_obj].reshape(-1).cpu().numpy()

    def constraints(self, x: Tensor, jac: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        if not self.con_terms:
            return np.zeros(0), np.zeros((0, self.n))
        if not jac:
            with torch.no_grad():
                return torch.cat([c.constraints(x) for c in self.con_terms], 1)[0].cpu().numpy(), None
        gs, js = [], []
        for c in self.con_terms:
            g, j = c.jacobian(x)
            gs.append(g[0])
            js.append(j[0])
        j = torch.cat(js, 0)[:, self.var_obj].reshape(self.m, self.n)
        return torch.cat(gs).cpu().numpy(), j.cpu().numpy()

    def at(self, z: np.ndarray, base: Tensor) -> _Point:
        """The objective, its gradient, the rows and their Jacobian at ``z`` (the rest of the poses: ``base``)."""
        x = self.poses(z, base)
        f, grad = self.objective(x)
        rows, jac = self.constraints(x)
        return _Point(z, f, cast(np.ndarray, grad), rows, cast(np.ndarray, jac))


@dataclass
class _Point:
    """An SQP iterate: the variables, the objective and its gradient, the rows and their Jacobian."""

    z: np.ndarray  # (n,)
    f: float
    grad: np.ndarray  # (n,)
    rows: np.ndarray  # (m,) g(z) >= 0 where feasible
    jac: np.ndarray  # (m, n)

    def lagrangian_grad(self, lam: np.ndarray) -> np.ndarray:
        """The Lagrangian's gradient ``grad f - J' lam``."""
        return self.grad - self.jac.T @ lam

    def violation(self, tol: float, step: np.ndarray | None = None) -> float:
        """The l1 violation beyond ``tol`` of the rows, or of their linearisation after ``step``."""
        g = self.rows if step is None else self.rows + self.jac @ step
        return float(np.sum(np.maximum(-g - tol, 0.0)))


class _StepQP:
    """The QP of one SQP step over ``[d (n), s (m)]``: ``min 1/2 d'Hd + q'd + elastic * sum(s)`` s.t.
    ``J d + s >= slack - g``, ``-trust <= d <= trust``, ``s >= 0``. Its sparsity is fixed at setup (a
    row touches only its objects' variables); each step updates the values."""

    def __init__(self, model: _Refinement, o: SQPOptions):
        n, m = model.n, model.m
        self.n, self.m, self.options = n, m, o
        self.jac_rows, self.jac_cols = _jacobian_pattern(model)
        rows = np.concatenate([self.jac_rows, np.arange(m), m + np.arange(n), m + n + np.arange(m)])
        cols = np.concatenate([self.jac_cols, n + np.arange(m), np.arange(n), n + np.arange(m)])
        self.a_order = np.lexsort((rows, cols))  # OSQP takes CSC values in column order
        a_mat = sp.csc_matrix(
            (np.ones(len(rows))[self.a_order], (rows[self.a_order], cols[self.a_order])),
            shape=(2 * m + n, n + m),
        )
        hess_rows, hess_cols = np.triu_indices(n)
        p_order = np.lexsort((hess_rows, hess_cols))
        self.hess_rows, self.hess_cols = hess_rows[p_order], hess_cols[p_order]
        p_mat = sp.csc_matrix(
            (np.ones(len(self.hess_rows)), (self.hess_rows, self.hess_cols)), shape=(n + m, n + m)
        )
        self.qp = osqp.OSQP()
        self.qp.setup(
            p_mat,
            np.zeros(n + m),
            a_mat,
            np.zeros(2 * m + n),
            np.zeros(2 * m + n) + 1.0,
            verbose=False,
            eps_abs=o.qp_eps_abs,
            eps_rel=o.qp_eps_rel,
            polishing=True,
            max_iter=o.qp_max_iter,
            warm_starting=True,
        )
        self.times: list[float] = []  # seconds per solve

    def solve(self, point: _Point, hess: np.ndarray, radius: np.ndarray) -> Any:
        """OSQP's answer for the step from ``point`` with the model Hessian ``hess`` and the trust
        region ``radius (n,)``; ``.x[:n]`` is the step, ``-.y[:m]`` the rows' multipliers."""
        n, m, o = self.n, self.m, self.options
        a_vals = np.concatenate([point.jac[self.jac_rows, self.jac_cols], np.ones(m), np.ones(n), np.ones(m)])
        lo = np.concatenate([o.slack - point.rows, -radius, np.zeros(m)])
        hi = np.concatenate([np.full(m, np.inf), radius, np.full(m, np.inf)])
        q = np.concatenate([point.grad, np.full(m, o.elastic)])
        t = time.perf_counter()
        self.qp.update(Px=hess[self.hess_rows, self.hess_cols], Ax=a_vals[self.a_order], q=q, l=lo, u=hi)
        res = self.qp.solve(raise_error=False)
        self.times.append(time.perf_counter() - t)
        return res


def _jacobian_pattern(model: _Refinement) -> tuple[np.ndarray, np.ndarray]:
    """The nonzeros ``(rows, cols)`` of the constraint Jacobian: each row's objects' three variables."""
    col = {int(ob): k for k, ob in enumerate(model.var_obj)}
    rows: list[int] = []
    cols: list[int] = []
    for r, objs in enumerate(model.support):
        for ob in objs:
            if ob in col:
                rows += [r] * 3
                cols += [3 * col[ob] + a for a in range(3)]
    return np.array(rows, dtype=int), np.array(cols, dtype=int)


def _qp_failed(res: Any) -> bool:
    """A QP answer with no usable step."""
    return (
        res.info.status not in ("solved", "solved inaccurate", "maximum iterations reached")
        or res.x is None
        or not np.all(np.isfinite(res.x))
    )


def _damped_bfgs(hess: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Powell's damped BFGS update of ``hess`` for the step ``s`` and the gradient change ``y``: ``y``
    blended towards ``hess @ s`` where the curvature ``s'y`` is too small, so ``hess`` stays positive
    definite; unchanged when ``s'Hs`` is 0."""
    hs = hess @ s
    shs = float(s @ hs)
    sy = float(s @ y)
    if not shs > 1e-16:
        return hess
    theta = 1.0 if sy >= 0.2 * shs else 0.8 * shs / (shs - sy)
    r = theta * y + (1 - theta) * hs
    return hess - np.outer(hs, hs) / shs + np.outer(r, r) / float(s @ r)


class OSQPSolver(StageSolver):
    """Refinement stage: ``solve(problem, init=None, seed=0) -> Result``."""

    name = "osqp"
    options_cls = SQPOptions

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        o = self.options
        t0 = time.perf_counter()
        model = _Refinement(problem)
        x0 = start_poses(problem, init, seed)
        base = x0[0].clone()
        z = x0[0, model.var_obj].reshape(-1).cpu().numpy().copy()
        # the trust region per coordinate: metres for positions, radians scaled like the projection's
        scale = np.tile([1.0, 1.0, 1.0 / np.sqrt(ANGLE_WEIGHT)], len(model.var_obj))
        qp = _StepQP(model, o)
        t1 = time.perf_counter()
        point, status, it, msg = self._iterate(model, qp, model.at(z, base), base, scale)
        t2 = time.perf_counter()
        result = make_result(
            problem, self.name, model.poses(point.z, base)[0], status, it, t1 - t0, t2 - t1, message=msg
        )
        if result.status == Status.CONVERGED and not result.success:
            result.status = Status.INFEASIBLE
        result.qp_time_mean = float(np.mean(qp.times)) if qp.times else 0.0
        return result

    def _iterate(
        self, model: _Refinement, qp: _StepQP, point: _Point, base: Tensor, scale: np.ndarray
    ) -> tuple[_Point, Status, int, str]:
        """SQP steps from ``point`` until converged, stalled, failed or out of iterations: the last
        accepted point, the status, the iterations taken and a message."""
        o, n, m = self.options, model.n, model.m
        hess = np.eye(n)
        penalty = o.penalty_init
        trust = o.trust_init
        for it in range(1, o.max_iter + 1):
            res = qp.solve(point, hess, trust * scale)
            if _qp_failed(res):
                return point, Status.FAILED, it, f"QP failed at iteration {it}: {res.info.status}"
            d = res.x[:n]
            lam = np.maximum(-res.y[:m], 0.0)
            penalty = max(penalty, 1.5 * float(lam.max(initial=0.0)) + 1.0)
            step = float(np.max(np.abs(d) / scale)) if n else 0.0
            if self._converged(point, lam, step):
                return point, Status.CONVERGED, it, ""
            trial = model.at(point.z + d, base)
            ratio = self._ratio(point, trial, d, hess, penalty)
            if ratio > ACCEPT:
                hess = _damped_bfgs(hess, d, trial.lagrangian_grad(lam) - point.lagrangian_grad(lam))
                point = trial
                if ratio > EXPAND and step > 0.9 * trust:
                    trust = min(2 * trust, o.trust_max)
            else:
                trust *= SHRINK
                if trust < o.trust_min:
                    status, msg = self._stalled(point)
                    return point, status, it, msg
        return point, Status.MAX_ITERATIONS, o.max_iter, f"stopped after {o.max_iter} iterations"

    def _converged(self, point: _Point, lam: np.ndarray, step: float) -> bool:
        """Every row within ``slack``, and the step or the Lagrangian's gradient below its tolerance."""
        o = self.options
        kkt = float(np.max(np.abs(point.lagrangian_grad(lam)), initial=0.0))
        feasible = point.rows.size == 0 or point.rows.min() >= -o.slack
        return bool(feasible and (step < o.tol_step or kkt < o.tol_kkt))

    def _ratio(self, point: _Point, trial: _Point, d: np.ndarray, hess: np.ndarray, penalty: float) -> float:
        """The l1 merit function's actual fall from ``point`` to ``trial`` over the fall the QP's model
        predicts for the step ``d`` (a prediction of about 0: 1 if the merit did not rise, else -1)."""
        tol = self.options.merit_tol
        pred_f = -(point.grad @ d + 0.5 * d @ hess @ d)
        pred = pred_f + penalty * (point.violation(tol) - point.violation(tol, d))
        ared = _merit(point, penalty, tol) - _merit(trial, penalty, tol)
        return ared / pred if pred > 1e-14 else (1.0 if ared >= -1e-12 else -1.0)

    def _stalled(self, point: _Point) -> tuple[Status, str]:
        """The status and message when the trust region fell below ``trust_min``: converged if the
        rows hold within the feasibility tolerance, else infeasible."""
        o = self.options
        if point.rows.size == 0 or point.rows.min() >= -FEASIBILITY_TOL:
            return Status.CONVERGED, (
                f"converged: no step improves the merit function (the trust region fell below {o.trust_min:g})"
            )
        return Status.INFEASIBLE, (
            f"stopped infeasible: the trust region fell below {o.trust_min:g} with constraints still violated"
        )


def _merit(point: _Point, penalty: float, tol: float) -> float:
    """The l1 merit function: the objective plus ``penalty`` times the violation beyond ``tol``."""
    return point.f + penalty * point.violation(tol)
