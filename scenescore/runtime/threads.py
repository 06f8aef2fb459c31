"""Threads: the run's budget, work in pieces side by side, and the scoped torch setting.

The library's own work runs on one torch thread: its tensors are mostly tiny, where torch's intra-op
pool costs more than it saves (its threads wait for each other, and on a busy machine for the cores),
and torch's results depend on its thread count (an elementwise function rounds differently where a
thread's share of a tensor ends). Large batches of the learned energy are cut instead into pieces fixed
by the batch and the machine's core count, which run side by side on worker threads, each on one torch
thread (:func:`in_parallel`): as fast on free cores, and the same numbers however many run at once, so
a result never depends on the load.

- :func:`thread_budget` sets the run's budget (``--threads`` on the command line, ``ss.thread_budget``
  in scripts): the most pieces that run at once. Without one the budget is torch's own setting.
- :func:`workers` is how many run at once: the budget when given, else the budget capped by the cores
  other processes leave free (:func:`~scenescore.runtime.cores.free_cores`).
- :func:`torch_threads` runs a block on ``n`` torch threads and restores the caller's setting. It sets
  torch's own count (``torch.set_num_threads``), not threadpoolctl's OpenMP limit, which leaves torch's
  per-thread MKL setting and its own count as they were.

Nothing here changes torch's process-wide setting beyond the block that asked for it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar, cast

import torch

from ..errors import check_number
from .cores import free_cores

T = TypeVar("T")

__all__ = [
    "POOL_ROWS",
    "MAX_THREADS",
    "thread_budget",
    "budget",
    "torch_threads",
    "in_parallel",
    "workers",
]

#: pose sets from which a batch of the learned energy is taken to keep every core busy (below it, work
#: computed ahead on a second core can pay: :mod:`~scenescore.runtime.ahead`)
POOL_ROWS = 256
MAX_THREADS = 1024  # more is a typo, not a plan

_budget: int | None = None  # set by thread_budget (--threads)
_outer: int | None = None  # torch's setting outside the outermost torch_threads block


def _checked(n: object, owner: str) -> int:
    check_number(owner, "threads", n, 1, MAX_THREADS, integer=True)
    return int(n)  # type: ignore[call-overload]


def budget() -> int:
    """The run's thread budget: the one :func:`thread_budget` set, else torch's setting outside the
    library's own :func:`torch_threads` blocks."""
    if _budget is not None:
        return _budget
    return _outer if _outer is not None else torch.get_num_threads()


@contextmanager
def thread_budget(n: int | None = None) -> Iterator[int]:
    """Run the block under a budget of ``n`` torch threads (``None``: automatic, torch's own setting).

    With ``n`` given, torch runs on ``n`` threads inside the block, the heavy work (large batches) uses
    all ``n`` and the automatic choices never exceed it; the caller's setting and budget are restored on
    the way out. ``with ss.thread_budget(1): ss.solve(...)`` is ``--threads 1``. Yields the budget.
    """
    global _budget
    if n is None:
        yield budget()
        return
    n = _checked(n, "thread_budget")
    old_budget, old_threads = _budget, torch.get_num_threads()
    _budget = n
    torch.set_num_threads(n)
    try:
        yield n
    finally:
        _budget = old_budget
        torch.set_num_threads(old_threads)


def workers() -> int:
    """Pieces of work to run at once: the budget when :func:`thread_budget` gave one, else the budget
    capped by :func:`free_cores` (at least 1)."""
    if _budget is not None:
        return _budget
    free = free_cores()
    return budget() if free is None else max(1, min(budget(), int(free + 0.25)))


@contextmanager
def torch_threads(n: int) -> Iterator[int]:
    """Run torch on ``n`` intra-op threads inside the block, then restore the caller's setting."""
    global _outer
    old, outermost = torch.get_num_threads(), _outer is None
    if outermost:
        _outer = old
    torch.set_num_threads(max(1, int(n)))
    try:
        yield torch.get_num_threads()
    finally:
        torch.set_num_threads(old)
        if outermost:
            _outer = None


# ---- independent pieces of work on worker threads ------------------------------------------------------

_pool: ThreadPoolExecutor | None = None
_pool_size = 0


def _pool_of(n: int) -> ThreadPoolExecutor:
    """The process's pool of at least ``n`` worker threads, each on one torch thread (made on first use)."""
    global _pool, _pool_size
    if _pool is None or _pool_size < n:
        if _pool is not None:
            _pool.shutdown(wait=True)
        _pool = ThreadPoolExecutor(n, "scenescore-piece", initializer=torch.set_num_threads, initargs=(1,))
        _pool_size = n
    return _pool


def in_parallel(work: Sequence[Callable[[], T]], parallel: bool = True) -> list[T]:
    """Each of ``work``'s callables' answers, in order, computed on up to :func:`workers` threads at once
    (``parallel=False``: one after the other, in the caller's thread).

    Every piece runs on one torch thread, in the caller's thread or a worker's, so the answers are the
    same whatever number of workers the budget and the load give: a result never depends on the machine
    being busy. Grad mode is per thread: each callable sets the one it needs."""
    n = min(len(work), workers()) if parallel and len(work) > 1 else 1
    if n <= 1:
        return [w() for w in work]
    with torch_threads(1):
        pool = _pool_of(n)
        lanes = [pool.submit(_lane, work[k::n]) for k in range(1, n)]
        out: list[T | None] = [None] * len(work)
        out[0::n] = _lane(work[0::n])
        for k, lane in enumerate(lanes, start=1):
            out[k::n] = lane.result()
    return cast(list[T], out)


def _lane(work: Sequence[Callable[[], T]]) -> list[T]:
    return [w() for w in work]
