"""The solver registry: names to factories, chains written ``"a>b"``, and ``solve``."""

from __future__ import annotations

import difflib
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from torch import Tensor

from ..problem import Problem, ProblemError
from .base import Solver
from .chain import Chain
from .result import Result

__all__ = ["register", "available", "get", "option_names", "solve"]


def _langevin(**o: Any) -> Solver:
    from .langevin import LangevinSolver

    return LangevinSolver(**o)


def _osqp(**o: Any) -> Solver:
    from .sqp import OSQPSolver

    return OSQPSolver(**o)


def _casadi(**o: Any) -> Solver:
    from .casadi import CasadiSolver

    return CasadiSolver(**o)


def _alm(**o: Any) -> Solver:
    from .alm import ALMSolver

    return ALMSolver(**o)


_REGISTRY: dict[str, Callable[..., Solver]] = {
    "langevin": _langevin,
    "osqp": _osqp,
    "casadi": _casadi,
    "alm": _alm,
}


def register(name: str, factory: Callable[..., Solver]) -> None:
    """Add a solver under ``name`` (``factory(**options) -> Solver``)."""
    if ">" in name or "," in name:
        raise ValueError(f"solver name {name!r} may not contain '>' or ','")
    _REGISTRY[name] = factory


def available() -> list[str]:
    """The registered solver names (chain them with ``>``)."""
    return sorted(_REGISTRY)


def option_names(name: str) -> list[str] | None:
    """The option names a built-in solver takes (``None`` for a registered solver: not known ahead)."""
    from dataclasses import fields

    if name == "langevin":
        from ..sampling import LangevinConfig
        from .langevin import LangevinOptions

        own = {f.name for f in fields(LangevinOptions)} - {"chain"}
        return sorted(own | {f.name for f in fields(LangevinConfig)})
    if name == "osqp":
        from .sqp import SQPOptions

        return sorted(f.name for f in fields(SQPOptions))
    if name == "casadi":
        from .casadi import CasadiOptions

        return sorted(f.name for f in fields(CasadiOptions))
    if name == "alm":
        from .alm import ALMOptions

        return sorted(f.name for f in fields(ALMOptions))
    return None


def get(name: str, **options: Any) -> Solver:
    """A solver by name with its options, or a chain ``"a>b"`` with options per stage name
    (``get("langevin>osqp", langevin={"steps": 50})``); an unknown name lists the valid ones."""
    stages = [s.strip() for s in name.split(">")]
    if len(stages) > 1:
        return Chain([get(s, **(options.get(s) or {})) for s in stages])
    if name not in _REGISTRY:
        near = difflib.get_close_matches(name, available(), n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ProblemError(
            f"unknown solver {name!r}{hint}; available: {', '.join(available())}; chain them with '>'"
        )
    valid = option_names(name)
    unknown = [k for k in options if valid is not None and k not in valid]
    if unknown and valid is not None:
        near = difflib.get_close_matches(str(unknown[0]), valid, n=1)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise ProblemError(
            f"solver {name!r}: unknown option {unknown[0]!r}{hint} (valid: {', '.join(valid)})"
        )
    try:
        return _REGISTRY[name](**options)
    except TypeError as e:
        raise ProblemError(f"solver {name!r}: bad option: {e}") from None
    except ValueError as e:
        raise ProblemError(f"solver {name!r}: {e}") from None


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
        stages = [s.strip() for s in solver.split(">")]
        solver = get(solver, **options) if len(stages) > 1 else get(solver, **options.get(solver, {}))
    x = None if init is None else problem.full(init)
    t = time.perf_counter()
    r = solver.solve(problem, init=x, seed=seed)
    r.wall_time = time.perf_counter() - t
    return r
