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

import numpy as np
import osqp
import scipy.sparse as sp
import torch
from torch import Tensor

from ..errors import ConfigError, check_number
from ..problem import FEASIBILITY_TOL, Problem
from .base import StageSolver, start_poses
from .projection import ANGLE_WEIGHT
from .result import Result, Status, make_result

__all__ = ["SQPOptions", "OSQPSolver"]

MAX_ITER = 1_000_000  # more is a typo, not a plan


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
    threads: int | None = None  # torch threads; None: one (tiny tensors)

    def __post_init__(self) -> None:
        check_number("osqp", "max_iter", self.max_iter, 0, MAX_ITER, integer=True)
        for name in ("trust_init", "trust_max", "trust_min", "tol_step", "tol_kkt", "elastic"):
            check_number("osqp", name, getattr(self, name), 0, open_lo=True)
        for name in ("slack", "merit_tol"):
            check_number("osqp", name, getattr(self, name), 0)
        if not self.trust_min <= self.trust_init <= self.trust_max:
            raise ConfigError(
                f"osqp: trust_init: expected trust_min <= trust_init <= trust_max, got {self.trust_min:g}, "
                f"{self.trust_init:g}, {self.trust_max:g}"
            )
        if self.threads is not None:
            check_number("osqp", "threads", self.threads, 1, 1024, integer=True)


class _Model:
    """The problem seen by a refinement solver: objective terms and constraint rows on the movable variables."""

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


class OSQPSolver(StageSolver):
    """Refinement stage: ``solve(problem, init=None, seed=0) -> Result``."""

    name = "osqp"
    options_cls = SQPOptions

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        o = self.options
        t0 = time.perf_counter()
        mdl = _Model(problem)
        n, m = mdl.n, mdl.m
        x0 = start_poses(problem, init, seed)
        base = x0[0].clone()
        z = x0[0, mdl.var_obj].reshape(-1).cpu().numpy().copy()
        scale = np.tile(
            [1.0, 1.0, 1.0 / np.sqrt(ANGLE_WEIGHT)], len(mdl.var_obj)
        )  # trust region per coordinate

        # the QP over [d (n), s (m)]: min 1/2 d'Hd + q'd + elastic * sum(s)  s.t.  J d + s >= slack - g,
        # -trust <= d <= trust, s >= 0. Sparsity is fixed; values are updated each iteration.
        col = {int(ob): k for k, ob in enumerate(mdl.var_obj)}
        jr_list: list[int] = []
        jc_list: list[int] = []
        for r, objs in enumerate(mdl.support):
            for ob in objs:
                if ob in col:
                    jr_list += [r] * 3
                    jc_list += [3 * col[ob] + a for a in range(3)]
        jr, jc = np.array(jr_list, dtype=int), np.array(jc_list, dtype=int)
        rows = np.concatenate([jr, np.arange(m), m + np.arange(n), m + n + np.arange(m)])
        cols = np.concatenate([jc, n + np.arange(m), np.arange(n), n + np.arange(m)])
        a_order = np.lexsort((rows, cols))
        a_mat = sp.csc_matrix(
            (np.ones(len(rows))[a_order], (rows[a_order], cols[a_order])), shape=(2 * m + n, n + m)
        )
        iu, ju = np.triu_indices(n)
        p_order = np.lexsort((iu, ju))
        iu, ju = iu[p_order], ju[p_order]
        p_mat = sp.csc_matrix((np.ones(len(iu)), (iu, ju)), shape=(n + m, n + m))
        qp = osqp.OSQP()
        qp.setup(
            p_mat,
            np.zeros(n + m),
            a_mat,
            np.zeros(2 * m + n),
            np.zeros(2 * m + n) + 1.0,
            verbose=False,
            eps_abs=1e-6,
            eps_rel=1e-6,
            polishing=True,
            max_iter=4000,
            warm_starting=True,
        )
        t1 = time.perf_counter()

        def evaluate(zz: np.ndarray, derivs: bool = True):
            x = mdl.poses(zz, base)
            f, gf = mdl.objective(x, derivs)
            g, jg = mdl.constraints(x, derivs)
            return f, gf, g, jg

        f, gf, g, jg = evaluate(z)
        h = np.eye(n)
        mu = 10.0
        trust = o.trust_init
        status, it, msg = Status.MAX_ITERATIONS, 0, ""
        qp_times = []

        def merit(fv: float, gv: np.ndarray) -> float:
            return fv + mu * float(np.sum(np.maximum(-gv - o.merit_tol, 0.0)))

        for it in range(1, o.max_iter + 1):
            tr = trust * scale
            a_vals = np.concatenate([jg[jr, jc], np.ones(m), np.ones(n), np.ones(m)])[a_order]
            lo = np.concatenate([o.slack - g, -tr, np.zeros(m)])
            hi = np.concatenate([np.full(m, np.inf), tr, np.full(m, np.inf)])
            tq = time.perf_counter()
            qp.update(Px=h[iu, ju], Ax=a_vals, q=np.concatenate([gf, np.full(m, o.elastic)]), l=lo, u=hi)
            res = qp.solve(raise_error=False)
            qp_times.append(time.perf_counter() - tq)
            if (
                res.info.status not in ("solved", "solved inaccurate", "maximum iterations reached")
                or res.x is None
                or not np.all(np.isfinite(res.x))
            ):
                status, msg = Status.FAILED, f"QP failed at iteration {it}: {res.info.status}"
                break
            d = res.x[:n]
            lam_qp = np.maximum(-res.y[:m], 0.0)
            mu = max(mu, 1.5 * float(lam_qp.max(initial=0.0)) + 1.0)
            pred_f = -(gf @ d + 0.5 * d @ h @ d)
            viol_now = np.sum(np.maximum(-g - o.merit_tol, 0.0))
            viol_lin = np.sum(np.maximum(-(g + jg @ d) - o.merit_tol, 0.0))
            pred = pred_f + mu * (viol_now - viol_lin)
            step = float(np.max(np.abs(d) / scale)) if n else 0.0
            kkt = float(np.max(np.abs(gf - jg.T @ lam_qp), initial=0.0))
            if g.size == 0 or g.min() >= -o.slack:
                if step < o.tol_step or kkt < o.tol_kkt:
                    status = Status.CONVERGED
                    break
            z_new = z + d
            f2, gf2, g2, jg2 = evaluate(z_new)
            ared = merit(f, g) - merit(f2, g2)
            ratio = ared / pred if pred > 1e-14 else (1.0 if ared >= -1e-12 else -1.0)
            if ratio > 0.1:
                # damped BFGS on the Lagrangian's gradient
                s = d
                y = (gf2 - jg2.T @ lam_qp) - (gf - jg.T @ lam_qp)
                hs = h @ s
                shs = float(s @ hs)
                sy = float(s @ y)
                if shs > 1e-16:
                    theta = 1.0 if sy >= 0.2 * shs else 0.8 * shs / (shs - sy)
                    r = theta * y + (1 - theta) * hs
                    h = h - np.outer(hs, hs) / shs + np.outer(r, r) / float(s @ r)
                z, f, gf, g, jg = z_new, f2, gf2, g2, jg2
                if ratio > 0.75 and step > 0.9 * trust:
                    trust = min(2 * trust, o.trust_max)
            else:
                trust *= 0.25
                if trust < o.trust_min:
                    ok = g.size == 0 or g.min() >= -FEASIBILITY_TOL
                    status = Status.CONVERGED if ok else Status.INFEASIBLE
                    msg = (
                        "converged: no step improves the merit function (the trust region fell below "
                        f"{o.trust_min:g})"
                        if ok
                        else "stopped infeasible: the trust region fell below "
                        f"{o.trust_min:g} with constraints still violated"
                    )
                    break
        t2 = time.perf_counter()
        if status == Status.MAX_ITERATIONS:
            msg = f"stopped after {o.max_iter} iterations"
        x = mdl.poses(z, base)[0]
        result = make_result(problem, self.name, x, status, it, t1 - t0, t2 - t1, message=msg)
        if result.status == Status.CONVERGED and not result.success:
            result.status = Status.INFEASIBLE
        result.qp_time_mean = float(np.mean(qp_times)) if qp_times else 0.0
        return result
