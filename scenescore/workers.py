"""Worker processes that never outlive the run that started them.

:func:`worker_pool` is a ``spawn`` pool of ``jobs`` processes: a failure or Ctrl-C in the parent
terminates them at once (not after their current task), and each watches its parent and exits within a
second when the parent is gone, even when it was killed outright (``kill -9``), so that stopping a long
experiment never leaves orphans computing on a shared machine.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing import get_context
from multiprocessing.pool import Pool

__all__ = ["worker_pool", "PARENT_POLL_S"]

PARENT_POLL_S = 0.5  # how often a worker checks that its parent still runs


def _exit_with_parent(parent: int) -> None:
    """In a worker: a daemon thread that ends the process once ``parent`` is no longer its parent."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


@contextmanager
def worker_pool(jobs: int) -> Iterator[Pool]:
    """A pool of ``jobs`` spawned processes: closed and joined when the block ends, terminated when it
    raises (``KeyboardInterrupt`` included); its workers exit when this process dies."""
    pool = get_context("spawn").Pool(jobs, initializer=_exit_with_parent, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        pool.terminate()
        raise
    else:
        pool.close()
    finally:
        pool.join()
