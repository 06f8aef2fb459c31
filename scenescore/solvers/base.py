"""The solver protocol, the base of the built-in stages, and what stages share (start poses)."""

from __future__ import annotations

from typing import Any, ClassVar, Protocol

import torch
from torch import Tensor

from ..problem.problem import Problem
from ..runtime import generator, torch_threads
from .result import Result

__all__ = ["Solver", "StageSolver", "start_poses"]


class Solver(Protocol):
    """One protocol for every solver: ``solve(problem, init=None, seed=0) -> Result``."""

    @property
    def name(self) -> str: ...

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result: ...


class StageSolver:
    """Base of the built-in solvers: options from keyword arguments (``options_cls``), and ``solve`` run
    on one torch thread, the learned energy's large batches in pieces side by side within the run's
    thread budget (:func:`~scenescore.runtime.in_parallel`, ``ss.thread_budget``)."""

    name: ClassVar[str] = "stage"
    options_cls: ClassVar[type]
    # in a chain: seeded with every sample of the stage before, not its best
    takes_batch: ClassVar[bool] = False

    def __init__(self, **options: Any):
        self.options = self.options_cls(**options)

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result:
        """``solve(problem, init=None, seed=0) -> Result``."""
        with torch_threads(1):
            return self._solve(problem, init, seed)

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:  # pragma: no cover
        raise NotImplementedError


def start_poses(problem: Problem, init: Tensor | None, seed: int) -> Tensor:
    """A refinement's start ``(1, N, 3)``: ``init`` (its lowest-cost row when a batch) or the scene's
    poses with the unknown ones drawn uniformly (``seed``)."""
    if init is None:
        return problem.initial(1, generator(seed, problem.device), keep_known=True)
    x = problem.full(init)
    if x.shape[0] > 1:
        with torch.no_grad():
            x = x[int(torch.argmin(problem.evaluate(x)))][None]
    return x.clone()
