"""The solver registry: names to factories, chains written ``"a>b"``, and ``solve``."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np
from torch import Tensor

from ..errors import nearest_name
from ..problem.problem import Problem, ProblemError
from .alm import ALMSolver
from .base import Solver
from .casadi import CasadiSolver
from .chain import Chain
from .langevin import LangevinSolver
from .result import Result
from .sqp import OSQPSolver

__all__ = ["register", "available", "get", "option_names", "solve", "RUN_SETTINGS", "run_setting_note"]

# name -> factory(**options) -> Solver; a solver class with an ``options_cls`` is its own factory
_REGISTRY: dict[str, Callable[..., Solver]] = {
    "langevin": LangevinSolver,
    "osqp": OSQPSolver,
    "casadi": CasadiSolver,
    "alm": ALMSolver,
}


def register(name: str, factory: Callable[..., Solver]) -> None:
    """Add a solver under ``name`` (``factory(**options) -> Solver``). A factory with an ``options_cls``
    dataclass (a :class:`~scenescore.solvers.base.StageSolver` subclass) has its option names checked."""
    if ">" in name or "," in name:
        raise ValueError(f"solver name {name!r} may not contain '>' or ','")
    _REGISTRY[name] = factory


def available() -> list[str]:
    """The registered solver names (chain them with ``>``)."""
    return sorted(_REGISTRY)


def option_names(name: str) -> list[str] | None:
    """The option names the solver registered as ``name`` takes, read from its ``options_cls``: the
    names its ``flat_names()`` gives where it has one (options given flat beside nested ones), else its
    dataclass fields; ``None`` for a factory without one (not known ahead)."""
    cls = getattr(_REGISTRY.get(name), "options_cls", None)
    if cls is None:
        return None
    flat = getattr(cls, "flat_names", None)
    if flat is not None:
        return sorted(flat())
    if not is_dataclass(cls):
        return None
    return sorted(f.name for f in fields(cls))


#: settings of the whole run that users reach for as a solver's option, and where they are set instead
RUN_SETTINGS = {
    "threads": "the run's thread budget: --threads on the command line, ss.thread_budget in Python"
}


def run_setting_note(option: str) -> str:
    """For an unknown option that is a setting of the whole run (:data:`RUN_SETTINGS`), where it is set;
    else nothing."""
    where = RUN_SETTINGS.get(option)
    return f"; {option} is not a solver's option but {where}" if where else ""


def get(name: str, **options: Any) -> Solver:
    """A solver by name with its options, or a chain ``"a>b"`` with options per stage name
    (``get("langevin>osqp", langevin={"steps": 50})``); an unknown name lists the valid ones."""
    stages = [s.strip() for s in name.split(">")]
    if len(stages) > 1:
        return Chain([get(s, **(options.get(s) or {})) for s in stages])
    if name not in _REGISTRY:
        near = nearest_name(name, available())
        hint = f" (did you mean {near!r}?)" if near else ""
        raise ProblemError(
            f"unknown solver {name!r}{hint}; available: {', '.join(available())}; chain them with '>'"
        )
    valid = option_names(name)
    unknown = [k for k in options if valid is not None and k not in valid]
    if unknown and valid is not None:
        near = nearest_name(str(unknown[0]), valid)
        hint = f"; did you mean {near!r}?" if near else ""
        hint += run_setting_note(str(unknown[0]))
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
