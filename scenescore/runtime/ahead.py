"""Work computed ahead on a second core, where the caller can guess what it will need before it knows
(:class:`Ahead`; the tidy planner places the objects chosen so far while its selection goes on)."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import torch

from .cores import free_cores, usable_cores
from .threads import budget

__all__ = ["Ahead", "AHEAD_FREE"]

#: cores left idle by other processes from which :meth:`Ahead.worth` starts a worker
AHEAD_FREE = 1.5


class Ahead:
    """Work computed ahead on a second core: each :meth:`submit` hands a keyed zero-argument callable to
    one worker thread, which runs it on one torch thread while the caller goes on; :meth:`result` returns
    a key's answer, waited for when the worker has started it, else computed in the caller's thread. A newer
    submission cancels an older one that has not started (a guess the caller has moved past).

    Torch's thread setting and MKL's are shared between threads, so the answers are those of calling the
    work directly only when it and the caller's own work both run on one torch thread; the caller checks
    that (every batch below :data:`~scenescore.runtime.threads.POOL_ROWS` rows, which runs on one)
    before it submits. Use it as a context manager: leaving cancels what has not started and waits for
    what has.
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
