"""Interchangeable solvers over one cost: a registry, chains, and ``solve``.

Every solver has ``solve(problem, init=None, seed=0) -> Result``. ``available()`` lists the names;
``"langevin>osqp"`` is a chain in which the best result of one stage seeds the next (cuRobo style:
a sampling stage seeds a gradient stage).

- ``langevin``: batched projected Langevin dynamics (sampling; all particles in ``result.samples``).
- ``osqp``: SQP refinement with raw OSQP (linearised constraints, BFGS, trust region).
- ``casadi``: IPOPT refinement through CasADi (the network rebuilt symbolically: exact Hessians).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from torch import Tensor

from ..problem import Problem, ProblemError
from .langevin import LangevinConfig, best_of, langevin, uniform_init
from .result import Result, Status, few_threads, make_result

__all__ = [
    "Solver",
    "Chain",
    "Result",
    "Status",
    "available",
    "get",
    "register",
    "solve",
    "make_result",
    "LangevinConfig",
    "langevin",
    "uniform_init",
    "best_of",
]


class Solver(Protocol):
    """One protocol for every solver."""

    name: str

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result: ...


def _langevin(**o: Any) -> Solver:
    from .sampling import LangevinSolver

    return LangevinSolver(**o)


def _osqp(**o: Any) -> Solver:
    from .sqp import OSQPSolver

    return OSQPSolver(**o)


def _casadi(**o: Any) -> Solver:
    from .ipopt import CasadiSolver

    return CasadiSolver(**o)


_REGISTRY: dict[str, Callable[..., Solver]] = {"langevin": _langevin, "osqp": _osqp, "casadi": _casadi}


def register(name: str, factory: Callable[..., Solver]) -> None:
    """Add a solver under ``name`` (``factory(**options) -> Solver``)."""
    if ">" in name or "," in name:
        raise ValueError(f"solver name {name!r} may not contain '>' or ','")
    _REGISTRY[name] = factory


def available() -> list[str]:
    """The registered solver names (chain them with ``>``)."""
    return sorted(_REGISTRY)


def get(name: str, **options: Any) -> Solver:
    """A solver or a chain by name; an unknown name lists the valid ones, bad options name the solver."""
    stages = [s.strip() for s in name.split(">")]
    if len(stages) > 1:
        return Chain([get(s, **(options.get(s) or {})) for s in stages])
    if name not in _REGISTRY:
        import difflib

        near = difflib.get_close_matches(name, available(), n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ProblemError(
            f"unknown solver {name!r}{hint}; available: {', '.join(available())}; chain them with '>'"
        )
    try:
        return _REGISTRY[name](**options)
    except TypeError as e:
        raise ProblemError(f"solver {name!r}: bad option: {e}") from None
    except ValueError as e:
        raise ProblemError(f"solver {name!r}: {e}") from None


class Chain:
    """Stages run in turn; the best poses of one stage seed the next. The result is the last stage's, with
    every stage in ``stages``, timings summed, and the sampling stage's particles kept."""

    def __init__(self, stages: list[Solver]):
        if not stages:
            raise ProblemError("a chain needs at least one stage")
        self.stages = stages
        self.name = ">".join(s.name for s in stages)

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result:
        results: list[Result] = []
        x = init
        for k, s in enumerate(self.stages):
            r = s.solve(problem, init=x, seed=seed + k)
            results.append(r)
            x = r.poses
        last = results[-1]
        best = last
        samples = next((r.samples for r in results if r.samples is not None), None)
        costs = next((r.sample_costs for r in results if r.samples is not None), None)
        out = make_result(
            problem,
            self.name,
            best.poses,
            last.status,
            sum(r.iterations for r in results),
            sum(r.time_setup for r in results),
            sum(r.time_solve for r in results),
            message=last.message,
            samples=samples,
            sample_costs=costs,
        )
        out.stages = results
        return out


def solve(
    problem: Problem,
    solver: str | Solver = "langevin>osqp",
    init: Tensor | np.ndarray | None = None,
    seed: int = 0,
    options: dict[str, dict[str, Any]] | None = None,
) -> Result:
    """Solve ``problem`` with a solver or chain (``options``: per stage name, e.g. ``{"langevin": {"steps": 50}}``)."""
    if isinstance(solver, str):
        options = options or {}
        stages = solver.split(">")
        solver = get(solver, **options) if len(stages) > 1 else get(solver, **options.get(solver, {}))
    x = None if init is None else problem.full(init)
    t = time.perf_counter()
    with few_threads():
        r = solver.solve(problem, init=x, seed=seed)
    r.wall_time = time.perf_counter() - t  # type: ignore[attr-defined]
    return r
