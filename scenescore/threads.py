"""Threads: the run's budget, work in pieces side by side, and the scoped torch setting.

The library's own work runs on one torch thread. Most of its tensors are tiny (a few pose sets of a dozen
objects), where torch's intra-op pool costs far more than it saves: its threads wait for each other at
every operation, and on a busy machine they wait for the cores too (measured: a 32-element ``min`` takes
11 ms with 2 threads on a busy 2-core machine, 3 us with 1). And torch's results depend on its thread
count: an elementwise function (``silu``) rounds differently where a thread's share of a tensor ends,
so a model trained on two threads is not the model trained on one. Large batches of the learned energy
are cut instead into pieces fixed by the batch and the machine's core count, which run side by side on
worker threads, each piece on one torch thread (:func:`in_parallel`): as fast on free cores, and the
same numbers however many run at once, so a result never depends on the load.

- :func:`thread_budget` sets the run's budget (``--threads`` on the command line, ``ss.thread_budget``
  in scripts): the most pieces that run at once. Without one the budget is torch's own setting.
- :func:`workers` is how many run at once: the budget when given, else the budget capped by the cores
  other processes leave free (measured from ``/proc/stat``, Linux; elsewhere the budget);
  :func:`threads_for` is one below :data:`POOL_ROWS` pose sets, else :func:`workers`.
- :func:`torch_threads` runs a block on ``n`` torch threads and restores the caller's setting.
- :class:`Ahead` computes work ahead on a second core (one worker thread, one torch thread), where the
  caller can guess what it will need before it knows.

Nothing here changes torch's process-wide setting beyond the block that asked for it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any, TypeVar, cast

import torch

from .errors import check_number

T = TypeVar("T")

__all__ = [
    "POOL_ROWS",
    "MAX_THREADS",
    "thread_budget",
    "budget",
    "threads_for",
    "torch_threads",
    "free_cores",
    "usable_cores",
    "in_parallel",
    "workers",
    "Ahead",
]

#: cores left idle by other processes from which :meth:`Ahead.worth` starts a worker
AHEAD_FREE = 1.5
#: pose sets from which a batch's tensors are big enough to pay for torch's thread pool
POOL_ROWS = 256
MAX_THREADS = 1024  # more is a typo, not a plan
PROBE_SECONDS = 1.0  # the free-core estimate is re-measured at most this often, over the time since
FIRST_PROBE = 0.1  # seconds to measure over when there is no recent sample
STALE_SECONDS = 10.0  # a sample older than this says nothing about now: measure afresh

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


def threads_for(rows: int) -> int:
    """Threads for a batch of ``rows`` pose sets: one below :data:`POOL_ROWS` rows, else :func:`workers`."""
    return 1 if rows < POOL_ROWS else workers()


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


# ---- the free-core estimate ---------------------------------------------------------------------------

_sample: tuple[float, int, int, int] | None = None  # (time, total ticks, busy ticks, own ticks)
_estimate: float | None = None


def _cpus() -> set[int] | None:
    try:
        return set(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity where the system says, else every core)."""
    return len(_cpus() or ()) or os.cpu_count() or 1


def _read_sample() -> tuple[float, int, int, int] | None:
    """``(time, total, busy, own)``: clock ticks of this process's CPUs in ``/proc/stat`` (all, and busy)
    and this process's own CPU time (``/proc/self/stat``); None where they cannot be read."""
    cpus = _cpus()
    try:
        with open("/proc/stat", encoding="ascii") as f:
            lines = [ln.split() for ln in f if ln.startswith("cpu") and ln[3:4].isdigit()]
        with open("/proc/self/stat", encoding="ascii") as f:
            own_fields = f.read().rsplit(")", 1)[1].split()
        own = int(own_fields[11]) + int(own_fields[12])  # utime, stime (fields 14 and 15)
        total = busy = 0
        for ln in lines:
            if cpus is not None and int(ln[0][3:]) not in cpus:
                continue
            ticks = [int(v) for v in ln[1:9]]  # user nice system idle iowait irq softirq steal
            total += sum(ticks)
            busy += sum(ticks) - ticks[3] - ticks[4]
    except (OSError, ValueError, IndexError):
        return None
    return (time.monotonic(), total, busy, own) if total > 0 else None


def free_cores() -> float | None:
    """Cores of this process's CPUs that other processes leave idle, measured over the last second or so
    (re-measured at most every :data:`PROBE_SECONDS`); None where it cannot be measured (not Linux)."""
    global _sample, _estimate
    now = time.monotonic()
    if _sample is not None and now - _sample[0] < PROBE_SECONDS and _estimate is not None:
        return _estimate
    if _sample is None or now - _sample[0] > STALE_SECONDS:
        _sample = _read_sample()
        if _sample is None:
            return None
        time.sleep(FIRST_PROBE)
    new = _read_sample()
    if new is None:
        return None
    d_total, d_busy, d_own = new[1] - _sample[1], new[2] - _sample[2], new[3] - _sample[3]
    if d_total <= 0:  # too short a window to tell: keep the last estimate
        return _estimate
    ncpu = usable_cores()
    others = min(max((d_busy - d_own) / d_total, 0.0), 1.0)  # share of the CPUs' time others used
    _sample, _estimate = new, ncpu * (1.0 - others)
    return _estimate


# ---- work computed ahead on a second core ------------------------------------------------------------


class Ahead:
    """Work computed ahead on a second core: each :meth:`submit` hands a keyed zero-argument callable to
    one worker thread, which runs it on one torch thread while the caller goes on; :meth:`result` returns
    a key's answer, waited for when the worker has started it, else computed in the caller's thread. A newer
    submission cancels an older one that has not started (a guess the caller has moved past).

    Torch's thread setting and MKL's are shared between threads, so the answers are those of calling the
    work directly only when it and the caller's own work both run on one torch thread; the caller checks
    that (every batch below :data:`POOL_ROWS` rows, where :func:`threads_for` gives one) before it submits. Use it as a context manager: leaving
    cancels what has not started and waits for what has.
    """

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(
            1, "scenescore-ahead", initializer=torch.set_num_threads, initargs=(1,)
        )
        self._futures: dict[Hashable, Future[Any]] = {}

    @staticmethod
    def worth() -> bool:
        """Whether a second core is there to use: a thread budget of 2 or more (not ``--threads 1``), two
        usable cores, and :data:`AHEAD_FREE` of them left idle by other processes."""
        if budget() < 2 or usable_cores() < 2:
            return False
        free = free_cores()
        return free is None or free >= AHEAD_FREE

    def submit(self, key: Hashable, work: Callable[[], Any]) -> None:
        """Start ``work`` for ``key`` on the worker (once per key), cancelling the submissions still waiting."""
        if key in self._futures:
            return
        for f in self._futures.values():
            f.cancel()
        self._futures[key] = self._pool.submit(work)

    def result(self, key: Hashable, work: Callable[[], Any]) -> Any:
        """``key``'s answer: the submitted work's once it has started (waited for; its exception raised
        here), else ``work()`` here and now; every other submission still waiting is cancelled."""
        for k, other in self._futures.items():
            if k != key:
                other.cancel()
        f = self._futures.get(key)
        if f is None or f.cancel():  # never submitted, or still waiting (behind a guess that was wrong)
            return work()
        return f.result()

    def close(self) -> None:
        """Cancel what has not started and wait for what has."""
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> Ahead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
