"""Projection onto linearised constraints: ``min |d|_W^2  s.t.  g + J d >= 0`` per particle.

The "projected gradients" of the design card: after a Langevin step, each particle that violates a
non-overlap (or bounds) row is moved to the nearest point of the linearised feasible set. Two
implementations of the same QP: raw OSQP, set up once per problem with only the values updated
(the one Langevin uses), and a declarative cvxpy model (clearer; the benchmark times both).
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp
import torch
from torch import Tensor

from ..costs import ConstraintCost
from ..problem.problem import Problem

__all__ = ["LinearisedProjection", "project_cvxpy", "ANGLE_WEIGHT"]

ANGLE_WEIGHT = 0.01  # m^2 per rad^2: turning an object by 1 rad costs as much as moving it 10 cm


def _rows(
    problem: Problem, terms: list[ConstraintCost], x: Tensor
) -> tuple[Tensor, Tensor, list[tuple[int, ...]]]:
    gs, js, sup = [], [], []
    for c in terms:
        g, j = c.jacobian(x)
        gs.append(g)
        js.append(j)
        sup += c.support()
    return torch.cat(gs, 1), torch.cat(js, 1), sup


class LinearisedProjection:
    """Batched projection of particles ``(B, N, 3)`` onto the linearised constraints of ``problem``."""

    def __init__(self, problem: Problem, terms: list[ConstraintCost] | None = None, slack: float = 1e-4):
        self.problem = problem
        self.terms = terms if terms is not None else problem.cost.constraint_terms
        self.slack = (
            slack  # aim a little inside, so the linearisation error does not leave a sliver of overlap
        )
        self.var_obj = np.flatnonzero(problem.movable_mask)  # objects that are variables
        self.n = 3 * len(self.var_obj)
        self._solver: osqp.OSQP | None = None
        self.qp_solves = 0

    def _setup(self, support: list[tuple[int, ...]]) -> None:
        col = {int(o): k for k, o in enumerate(self.var_obj)}
        rows, cols = [], []
        for r, objs in enumerate(support):
            for o in objs:
                if o in col:
                    for a in range(3):
                        rows.append(r)
                        cols.append(3 * col[o] + a)
        m = len(support)
        self._pattern = (np.array(rows), np.array(cols))
        a = sp.csc_matrix((np.ones(len(rows)), self._pattern), shape=(m, self.n))
        a.sort_indices()
        # order of the pattern's entries inside the CSC data array
        order = np.lexsort((self._pattern[0], self._pattern[1]))
        self._order = order
        w = np.tile([1.0, 1.0, ANGLE_WEIGHT], len(self.var_obj))
        p = sp.diags(w).tocsc()
        self._solver = osqp.OSQP()
        self._solver.setup(
            p,
            np.zeros(self.n),
            a,
            -np.ones(m),
            np.full(m, np.inf),
            verbose=False,
            eps_abs=1e-7,
            eps_rel=1e-7,
            polishing=True,
            max_iter=4000,
        )

    def __call__(self, x: Tensor) -> Tensor:
        if not self.terms or self.n == 0:
            return x
        g, jac, support = _rows(self.problem, self.terms, x)
        if self._solver is None:
            self._setup(support)
        assert self._solver is not None
        out = x.clone()
        bad = (g < 0).any(dim=1)
        g, jac = g.cpu(), jac.cpu()  # OSQP works on the CPU
        for b in torch.nonzero(bad).flatten().tolist():
            j = jac[b][:, self.var_obj].reshape(len(support), self.n).numpy()  # (M, n)
            vals = j[self._pattern][self._order]
            self._solver.update(Ax=vals, l=self.slack - g[b].numpy())
            res = self._solver.solve(raise_error=False)
            self.qp_solves += 1
            if res.info.status not in ("solved", "solved inaccurate"):
                continue  # leave the particle as it is; the cost's penalty still acts on it
            d = torch.as_tensor(res.x, dtype=x.dtype, device=x.device).reshape(-1, 3)
            out[b, self.var_obj] = x[b, self.var_obj] + d
        return out


def project_cvxpy(problem: Problem, x: Tensor, slack: float = 1e-4) -> Tensor:
    """The same projection for one particle ``(N, 3)``, written as a declarative cvxpy model (reference)."""
    import cvxpy as cp

    terms = problem.cost.constraint_terms
    g, jac, support = _rows(problem, terms, x.reshape(1, problem.n, 3))
    var_obj = np.flatnonzero(problem.movable_mask)
    n = 3 * len(var_obj)
    j = jac[0][:, var_obj].reshape(len(support), n).cpu().numpy()
    d = cp.Variable(n)
    w = np.tile([1.0, 1.0, ANGLE_WEIGHT], len(var_obj))
    prob = cp.Problem(
        cp.Minimize(cp.sum(cp.multiply(w, cp.square(d)))), [j @ d >= slack - g[0].cpu().numpy()]
    )
    prob.solve(solver=cp.OSQP, eps_abs=1e-7, eps_rel=1e-7)
    out = x.reshape(problem.n, 3).clone()
    out[var_obj] += torch.as_tensor(d.value, dtype=x.dtype, device=x.device).reshape(-1, 3)
    return out
