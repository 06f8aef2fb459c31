"""The solver protocol, the base of the built-in stages, and what stages share (start poses, threads)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, ClassVar, Protocol

import torch
from torch import Tensor

from ..devices import generator
from ..problem import Problem
from .result import Result

__all__ = ["Solver", "StageSolver", "start_poses", "threads_for", "torch_threads"]


class Solver(Protocol):
    """One protocol for every solver: ``solve(problem, init=None, seed=0) -> Result``."""

    @property
    def name(self) -> str: ...

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result: ...


#: pose sets from which a batch's tensors are big enough to pay for torch's thread pool
POOL_ROWS = 256


def threads_for(rows: int) -> int:
    """Torch threads for a batch of ``rows`` pose sets: all of them from :data:`POOL_ROWS` rows, else one."""
    return torch.get_num_threads() if rows >= POOL_ROWS else 1


@contextmanager
def torch_threads(n: int) -> Iterator[int]:
    """Run torch on ``n`` intra-op threads inside the block, then restore the caller's setting.

    The built-in solvers work on tiny tensors, where torch's thread pool costs far more than it saves
    (measured: a 32-element ``min`` takes 11 ms with 2 threads on a busy 2-core machine, 3 us with 1);
    large particle populations pay for it.
    """
    old = torch.get_num_threads()
    torch.set_num_threads(max(1, int(n)))
    try:
        yield torch.get_num_threads()
    finally:
        torch.set_num_threads(old)


class StageSolver:
    """Base of the built-in solvers: options from keyword arguments (``options_cls``, which has a
    ``threads`` field: ``None`` lets the solver choose), and ``solve`` run on that many torch threads."""

    name: ClassVar[str] = "stage"
    options_cls: ClassVar[type]
    # in a chain: seeded with every sample of the stage before, not its best
    takes_batch: ClassVar[bool] = False

    def __init__(self, **options: Any):
        self.options = self.options_cls(**options)

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result:
        """``solve(problem, init=None, seed=0) -> Result``."""
        n = self.options.threads if self.options.threads is not None else self.default_threads(problem, init)
        with torch_threads(n) as used:
            r = self._solve(problem, init, seed)
        r.threads = used
        return r

    def default_threads(self, problem: Problem, init: Tensor | None = None) -> int:
        """Threads when the options leave it open: one (tiny tensors); batched stages override."""
        return 1

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
