"""The machine's cores: how many this process may use, and how many other processes leave idle.

The CPU times (per CPU, and this process's own) are read through psutil, so they work wherever psutil
does; where a figure cannot be read, the answer says so (None) and callers fall back to the thread
budget.
"""

from __future__ import annotations

import os
import time

import psutil

__all__ = ["usable_cores", "free_cores", "PROBE_SECONDS"]

PROBE_SECONDS = 1.0  # the free-core estimate is re-measured at most this often, over the time since
FIRST_PROBE = 0.1  # seconds to measure over when there is no recent sample
STALE_SECONDS = 10.0  # a sample older than this says nothing about now: measure afresh

_sample: tuple[float, float, float, float] | None = None  # (time, total, busy, own) in CPU seconds
_estimate: float | None = None


def _cpus() -> list[int] | None:
    """This process's CPUs: the kernel's affinity call where there is one (it is asked before every large
    batch, and costs a fraction of a microsecond), else psutil's; None where neither says."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        pass
    try:
        return list(psutil.Process().cpu_affinity())
    except (AttributeError, psutil.Error, OSError):
        return None


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity where the system says, else every core)."""
    return len(_cpus() or ()) or os.cpu_count() or 1


def _read_sample() -> tuple[float, float, float, float] | None:
    """``(time, total, busy, own)``: CPU seconds of this process's CPUs (all, and busy) and this process's
    own CPU time; None where they cannot be read."""
    try:
        per_cpu = psutil.cpu_times(percpu=True)
        own_times = psutil.Process().cpu_times()  # this process's, made afresh: a fork has its own
    except (psutil.Error, OSError):
        return None
    cpus = _cpus()
    total = busy = 0.0
    for k, t in enumerate(per_cpu):
        if cpus is not None and k not in cpus:
            continue
        idle = t.idle + getattr(t, "iowait", 0.0)
        all_ = sum(
            getattr(t, f)
            for f in ("user", "nice", "system", "idle", "iowait", "irq", "softirq", "steal")
            if hasattr(t, f)
        )
        total += all_
        busy += all_ - idle
    own = own_times.user + own_times.system
    return (time.monotonic(), total, busy, own) if total > 0 else None


def free_cores() -> float | None:
    """Cores of this process's CPUs that other processes leave idle, measured over the last second or so
    (re-measured at most every :data:`PROBE_SECONDS`); None where it cannot be measured."""
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
    others = min(max((d_busy - d_own) / d_total, 0.0), 1.0)  # share of the CPUs' time others used
    _sample, _estimate = new, usable_cores() * (1.0 - others)
    return _estimate
