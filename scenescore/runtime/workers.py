"""Worker processes that never outlive the run that started them, nor hang it when one dies.

:func:`worker_pool` is a pool of ``jobs`` fresh processes (loky's executor): a failure or Ctrl-C in the
parent terminates them at once (not after their current task), and each watches its parent and exits
within a second when the parent is gone, even when it was killed outright (``kill -9``), so that
stopping a long experiment never leaves orphans computing on a shared machine (neither loky nor
``concurrent.futures`` stops a worker in the middle of its task when its parent dies). A worker that
dies in its task (killed by the system for memory, say) ends the run with :class:`WorkerDied` instead
of leaving it waiting.
"""

from __future__ import annotations

import heapq
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, TypeVar

from loky import ProcessPoolExecutor

__all__ = [
    "worker_pool",
    "map_in_workers",
    "default_jobs",
    "balanced_jobs",
    "longest_first",
    "map_balanced",
    "SOONER",
    "WorkerDied",
    "GPU_WORKER_BYTES",
    "PARENT_POLL_S",
]

T = TypeVar("T")
#: :func:`map_balanced` runs more processes than cores where the items then end in at most this share
#: of the time that one process per core would take
SOONER = 0.9
Log = Callable[[str], None]

PARENT_POLL_S = 0.5  # how often a worker checks that its parent still runs


def _exit_with_parent(parent: int) -> None:
    """In a worker: a daemon thread that ends the process once ``parent`` is no longer its parent."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


#: GPU memory one worker process is given on a shared CUDA device: its CUDA context and the batches of
#: one training or placement at the defaults, with room to spare
GPU_WORKER_BYTES = 2 * 1024**3


def default_jobs(device: Any = None) -> int:
    """Worker processes an experiment runs in when not told: one per usable core on the CPU; on a CUDA
    device, processes sharing it, as many as its free memory holds at :data:`GPU_WORKER_BYTES` each and
    at most one per usable core (each drives the device from its own core: one process's small batches
    leave a GPU idle); one on any other accelerator."""
    from .cores import usable_cores

    kind = "cpu" if device is None else getattr(device, "type", str(device))
    if kind == "cpu":
        return usable_cores()
    if kind == "cuda":
        import torch

        free, _ = torch.cuda.mem_get_info(device)
        return max(1, min(usable_cores(), int(free // GPU_WORKER_BYTES)))
    return 1


def balanced_jobs(tasks: int | Sequence[float], cores: int, sooner: float = 1.0) -> int:
    """Worker processes for ``tasks`` on ``cores`` cores: a number of tasks of about equal length, or each
    task's expected length (any unit), the longest handed out first (:func:`longest_first`). Of the
    counts from ``min(n, cores)`` to ``min(n, 2 * cores)`` for ``n`` tasks, the one that ends the tasks
    first when processes beyond the cores share them (each then runs at ``cores / n`` of a core), the
    fewest on a tie. Three trainings on two cores run side by side and end in 1.5 trainings' time, where
    two and then one take two (the third alone, one core idle); four on two take two rounds either way,
    so two processes; nine trainings and eighteen tasks of seconds, three. ``sooner``: more processes
    than ``min(n, cores)`` only where the tasks then end in at most that share of its time
    (:data:`SOONER` where the lengths are estimates)."""
    lengths = [1.0] * tasks if isinstance(tasks, int) else sorted((float(x) for x in tasks), reverse=True)
    if not lengths or cores < 1 or min(lengths) < 0:
        raise ValueError(f"need at least one task of a length >= 0 and a core, got {tasks} and {cores}")
    low, high = min(len(lengths), cores), min(len(lengths), 2 * cores)
    ends = {n: _ends(lengths, n, cores) for n in range(low, high + 1)}
    tie = 1e-9 * max(1.0, ends[low])  # equal ends computed along different sums
    best = min(n for n, end in ends.items() if end <= min(ends.values()) + tie)
    return best if ends[best] <= sooner * ends[low] + tie else low


def _ends(lengths: Sequence[float], n: int, cores: int) -> float:
    """When tasks of ``lengths``, handed out in that order, end in ``n`` processes on ``cores`` cores,
    each task to the first process free and every process at ``min(1, cores / n)`` of a core."""
    free = [0.0] * n  # when each process is next free, at full speed
    for length in lengths:
        heapq.heappush(free, heapq.heappop(free) + length)
    return max(free) * max(1.0, n / cores)


def longest_first(lengths: Sequence[float] | None, count: int) -> list[int]:
    """The order to hand out ``count`` items in: the longest of ``lengths`` first, items of equal length
    in their own order (``None``: their own order)."""
    if lengths is None:
        return list(range(count))
    if len(lengths) != count:
        raise ValueError(f"{len(lengths)} lengths for {count} items")
    return sorted(range(count), key=lambda k: -float(lengths[k]))


class WorkerDied(RuntimeError):
    """A worker process ended in the middle of a task without an error of its own: killed by a signal,
    most often by the system when memory ran out."""


@contextmanager
def worker_pool(jobs: int) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``jobs`` fresh processes: shut down when the block ends, its workers terminated when
    it raises (``KeyboardInterrupt`` included); its workers exit when this process dies."""
    pool = ProcessPoolExecutor(jobs, initializer=_exit_with_parent, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=True, kill_workers=True)
        raise
    finally:
        pool.shutdown(wait=True)


def map_in_workers(
    fn: Callable[..., T],
    items: Sequence[Any],
    jobs: int = 1,
    log: Log = print,
    bar: str | None = None,
    done: Callable[[int, T], None] | None = None,
    lengths: Sequence[float] | None = None,
) -> list[T]:
    """``fn(item, log=log)`` for each of ``items``, in order. With ``jobs > 1``, in that many worker
    processes of one torch thread each (``fn`` must pickle: a module-level function or a
    :func:`functools.partial` of one), handed out longest first where ``lengths`` gives each item's
    expected length (so that short ones fill the last round); each item's log lines are printed when it
    finishes, and its result does not depend on ``jobs``. ``bar``: with workers, a progress bar of the
    items done under that name (on a terminal; the log lines print above it). ``done(k, result)``: called in this process
    as item ``k`` finishes (a sweep keeps each result then, so an interrupted run loses none it had)."""
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    finished = done or (lambda k, value: None)
    if jobs == 1 or len(items) <= 1:
        out = []
        for k, item in enumerate(items):
            out.append(fn(item, log=log))
            finished(k, out[-1])
        return out
    from tqdm.auto import tqdm

    results: dict[int, T] = {}
    with (
        worker_pool(min(jobs, len(items))) as pool,
        tqdm(
            total=len(items), desc=bar, disable=None if bar else True, unit="task", dynamic_ncols=True
        ) as shown,
    ):
        futures: list[Future] = [
            pool.submit(_one, (fn, k, items[k])) for k in longest_first(lengths, len(items))
        ]
        for future in as_completed(futures):
            try:
                k, value, lines = future.result()
            except BrokenProcessPool:
                raise WorkerDied(
                    f"a worker process died in the middle of its task ({len(results)} of {len(items)} "
                    "done), killed by a signal: most often the system's, when memory runs out; run again "
                    "with fewer worker processes (--jobs)"
                ) from None
            with shown.external_write_mode():
                for line in lines:
                    log(line)
            shown.update()
            results[k] = value
            finished(k, value)
    return [results[k] for k in range(len(items))]


def map_balanced(
    fn: Callable[..., T],
    items: Sequence[Any],
    jobs: int = 1,
    log: Log = print,
    bar: str | None = None,
    done: Callable[[int, T], None] | None = None,
    lengths: Sequence[float] | None = None,
) -> list[T]:
    """:func:`map_in_workers` for ``jobs`` cores: in :func:`balanced_jobs` worker processes, up to two per
    core where ``items`` then end sooner (three of about equal length on two cores: three processes,
    together in one and a half items' time, where two would leave one core idle for the third); its
    choice logged where it differs from ``jobs``. ``lengths``: each item's expected length, where they
    differ (nine trainings and eighteen tasks of seconds: three processes, as for nine trainings). More
    processes than cores only where the items would end at least :data:`SOONER` as soon: lengths are
    estimates, and a smaller gain is lost to their errors."""
    n = (
        balanced_jobs(len(items) if lengths is None else lengths, jobs, SOONER)
        if items and jobs > 1
        else jobs
    )
    if n > jobs:
        log(f"{n} worker processes for {len(items)} tasks on {jobs} cores")
    return map_in_workers(fn, items, n, log, bar, done, lengths)


def _one(task: tuple[Callable[..., Any], int, Any]) -> tuple[int, Any, list[str]]:
    """One item of :func:`map_in_workers` in a worker, on one torch thread; its log lines returned."""
    import torch

    torch.set_num_threads(1)
    fn, k, item = task
    lines: list[str] = []
    return k, fn(item, log=lines.append), lines
