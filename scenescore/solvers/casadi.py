"""The ``casadi`` solver: IPOPT refinement through CasADi.

Every term enters the NLP through its CasADi form (:mod:`scenescore.costs.symbolic`): constraint terms
as hard constraints, the others as the objective. The learned energy is a symbolic MX rebuild of the
network from its weights (``energy="mx"``, the default: exact Hessians), or a ``casadi.Callback`` that
evaluates the network and its gradient in torch (``energy="callback"``, with IPOPT's limited-memory
Hessian). The MX rebuild is the default: its exact Hessians make IPOPT converge in fewer, surer
iterations (``benchmarks/bench_solvers.py`` times both). Terms without a symbolic form (a user's cost) go through a Callback.
The NLP of a problem is built once and kept on the solver.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass

import casadi as ca
import numpy as np
from torch import Tensor

from ..costs.symbolic import SymbolicProblem, casadi_form
from ..errors import ConfigError, check_number
from ..problem.problem import Problem
from .base import StageSolver, start_poses
from .result import Result, Status, make_result

__all__ = ["CasadiOptions", "CasadiSolver"]


@dataclass
class CasadiOptions:
    """Options of the ``casadi`` (IPOPT) refinement."""

    energy: str = "mx"  # "mx": symbolic rebuild of the network; "callback": torch through casadi.Callback
    max_iter: int = 300
    tol: float = 1e-8
    constr_viol_tol: float = 1e-7

    def __post_init__(self) -> None:
        if self.energy not in ("mx", "callback"):
            raise ConfigError(f"casadi: energy: expected 'mx' or 'callback', got {self.energy!r}")
        check_number("casadi", "max_iter", self.max_iter, 0, 1_000_000, integer=True)
        check_number("casadi", "tol", self.tol, 0, open_lo=True)
        check_number("casadi", "constr_viol_tol", self.constr_viol_tol, 0, open_lo=True)


class _Built:
    """The NLP of one problem, built once from each term's CasADi form and reused across solves."""

    def __init__(self, problem: Problem, opts: CasadiOptions):
        nlp = SymbolicProblem(
            problem.scene, problem.movable_mask, problem.base_poses(), {"energy": opts.energy}
        )
        for w, c in problem.cost:
            casadi_form(c)(c, w, nlp)
        self.nlp = nlp
        self.var_obj = nlp.var_obj
        self.nz = nlp.nz
        self.lbg, self.ubg = np.array(nlp.lbg, dtype=float), np.array(nlp.ubg, dtype=float)
        ipopt: dict[str, int | float | str] = {
            "print_level": 0,
            "max_iter": opts.max_iter,
            "tol": opts.tol,
            "constr_viol_tol": opts.constr_viol_tol,
            "sb": "yes",
        }
        if not nlp.exact_hessian:
            ipopt["hessian_approximation"] = "limited-memory"
        self.exact_hessian = nlp.exact_hessian
        xs = ca.vertcat(nlp.z, *[sym for sym, _ in nlp.extra])
        g = ca.vertcat(*nlp.g) if nlp.g else ca.MX(0, 1)
        f = nlp.objective if not isinstance(nlp.objective, (int, float)) else ca.MX(float(nlp.objective))
        self.solver = ca.nlpsol(
            "scenescore",
            "ipopt",
            {"x": xs, "p": ca.vec(nlp.p), "f": f, "g": g},
            {"ipopt": ipopt, "print_time": False},
        )

    def start(self, x0: np.ndarray) -> np.ndarray:
        """Initial values of every variable: the movable poses, then each form's extra variables."""
        return np.concatenate([x0[self.var_obj].reshape(-1), *[start(x0) for _, start in self.nlp.extra]])


class CasadiSolver(StageSolver):
    """Refinement stage: ``solve(problem, init=None, seed=0) -> Result``."""

    name = "casadi"
    options_cls = CasadiOptions

    def __init__(self, **options: object):
        super().__init__(**options)
        self._built: weakref.WeakKeyDictionary[Problem, _Built] = weakref.WeakKeyDictionary()

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        t0 = time.perf_counter()
        built = self._built.get(problem)
        if built is None:
            built = self._built[problem] = _Built(problem, self.options)
        x0 = start_poses(problem, init, seed)[0].cpu().numpy()
        t1 = time.perf_counter()
        sol = built.solver(x0=built.start(x0), p=x0.reshape(-1, order="F"), lbg=built.lbg, ubg=built.ubg)
        t2 = time.perf_counter()
        stats = built.solver.stats()
        x = x0.copy()
        xz = np.asarray(sol["x"]).ravel()[: built.nz]
        x[built.var_obj] = xz.reshape(-1, 3)
        ret = stats.get("return_status", "")
        status = (
            Status.CONVERGED
            if stats.get("success")
            else (
                Status.MAX_ITERATIONS
                if ret == "Maximum_Iterations_Exceeded"
                else Status.INFEASIBLE
                if "Infeasible" in ret
                else Status.FAILED
            )
        )
        msg = "" if stats.get("success") else f"IPOPT: {ret}"
        r = make_result(
            problem, self.name, x, status, int(stats.get("iter_count", 0)), t1 - t0, t2 - t1, message=msg
        )
        if r.status == Status.CONVERGED and not r.success:
            r.status = Status.INFEASIBLE
        return r
