"""Interchangeable solvers over one cost: a registry, chains, and ``solve``.

Every solver has ``solve(problem, init=None, seed=0) -> Result``. ``available()`` lists the names;
``"langevin>osqp"`` is a chain in which the best result of one stage seeds the next (cuRobo style:
a sampling stage seeds a gradient stage); a batched stage (``"langevin>alm"``) is seeded with every
particle. One module per solver:

- ``langevin`` (:mod:`.langevin`): batched projected Langevin dynamics (all particles in ``result.samples``).
- ``osqp`` (:mod:`.sqp`): SQP refinement with raw OSQP (linearised constraints, BFGS, trust region).
- ``casadi`` (:mod:`.casadi`): IPOPT refinement through CasADi (each cost's symbolic form).
- ``alm`` (:mod:`.alm`): augmented Lagrangian refinement of every particle at once (all kept, best first).
"""

from __future__ import annotations

from .base import Solver, StageSolver, start_poses
from .chain import Chain
from .registry import available, get, option_names, register, solve
from .result import Result, Samples, Status, make_result

__all__ = [
    "Solver",
    "StageSolver",
    "Chain",
    "Result",
    "Samples",
    "Status",
    "available",
    "option_names",
    "get",
    "register",
    "solve",
    "make_result",
    "start_poses",
]
