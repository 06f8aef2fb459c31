"""The memory budget: how much one run may allocate, checked before a large allocation is made.

The budget is :data:`DEFAULT_FRACTION` of the machine's physical memory unless the environment
variable ``SCENESCORE_MEMORY_GB`` sets it (gigabytes, 10^9 bytes); the command line's ``--memory-gb``
sets it for one run (:func:`set_budget`), ahead of both. Every size that a user controls and memory
grows with (particles, candidates, heatmap grids, image sizes, network widths) is estimated and passed
to :func:`check` before anything is allocated: over the budget it raises :class:`MemoryBudgetError`,
which says what would be allocated, the budget and where it came from, and what to lower. Work that
can go in pieces (the energy of many pose sets) goes in chunks of :func:`chunk_rows` rows, each about
:data:`CHUNK_BYTES` or less.
"""

from __future__ import annotations

import ctypes
import math
import os
import sys

from ..errors import ConfigError

__all__ = [
    "ENV",
    "DEFAULT_FRACTION",
    "CHUNK_BYTES",
    "MemoryBudgetError",
    "total_memory",
    "budget",
    "budget_bytes",
    "set_budget",
    "check",
    "chunk_rows",
    "format_gb",
    "return_freed_memory",
]

ENV = "SCENESCORE_MEMORY_GB"
DEFAULT_FRACTION = 0.5  # of the machine's physical memory
CHUNK_BYTES = 128 * 2**20  # the working set of one chunk of a batched evaluation (at most budget / 8)
GB = 1e9
_FALLBACK_TOTAL = 8 * 2**30  # when the machine's memory cannot be read

_override: float | None = None  # GB, set by set_budget (--memory-gb)
# glibc: blocks this large or larger are mapped on their own and given back to the system when freed
MMAP_THRESHOLD = 16 * 2**20
_M_MMAP_THRESHOLD = -3  # mallopt's parameter number
_freed_returned = False


class MemoryBudgetError(ConfigError):
    """An allocation that would exceed the memory budget: names what, how much, the budget, what to lower."""


def total_memory() -> int:
    """The machine's physical memory in bytes (``os.sysconf``, else ``/proc/meminfo``, else 8 GiB)."""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
        if pages > 0 and size > 0:
            return int(pages * size)
    except (AttributeError, OSError, ValueError):
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return _FALLBACK_TOTAL


def _parse_gb(value: object, source: str) -> float:
    try:
        gb = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        gb = math.nan
    if isinstance(value, bool) or not math.isfinite(gb) or gb <= 0:
        raise ConfigError(f"{source}: expected a number of gigabytes > 0 (such as 4 or 0.5), got {value!r}")
    return gb


def set_budget(gb: float | None) -> None:
    """Set the budget to ``gb`` gigabytes for this process (``None``: back to the environment or default)."""
    global _override
    _override = None if gb is None else _parse_gb(gb, "--memory-gb")


def budget() -> tuple[int, str]:
    """The budget in bytes and where it comes from (for messages)."""
    if _override is not None:
        return int(_override * GB), "--memory-gb"
    raw = os.environ.get(ENV)
    if raw is not None and raw.strip():
        return int(_parse_gb(raw.strip(), ENV) * GB), ENV
    total = total_memory()
    return int(
        total * DEFAULT_FRACTION
    ), f"{DEFAULT_FRACTION:g} of the machine's {format_gb(total)} GB; set {ENV}"


def budget_bytes() -> int:
    """The budget in bytes."""
    return budget()[0]


def format_gb(nbytes: float) -> str:
    """Bytes as gigabytes with three significant digits (``"0.0123"``, ``"5.4"``, ``"1.2e+03"``)."""
    return f"{nbytes / GB:.3g}"


def check(nbytes: float, what: str, lower: str) -> None:
    """Raise :class:`MemoryBudgetError` when ``nbytes`` is over the budget. ``what`` says what would be
    allocated (``"langevin: 60000 particles x 200 objects"``), ``lower`` what to lower (``"particles"``)."""
    limit, source = budget()
    if nbytes > limit:
        raise MemoryBudgetError(
            f"{what} would need ~{format_gb(nbytes)} GB, over the memory budget of {format_gb(limit)} GB "
            f"({source}); lower {lower}"
        )


def chunk_rows(row_bytes: float, what: str, lower: str, roomy: bool = False) -> int:
    """How many rows of ``row_bytes`` each to evaluate at once: about :data:`CHUNK_BYTES` (``roomy``: as
    much as an eighth of the budget; never more) per chunk, at least one row, which must itself fit the
    budget (:func:`check`)."""
    check(row_bytes, what, lower)
    target = budget_bytes() // 8 if roomy else min(CHUNK_BYTES, budget_bytes() // 8)
    return max(1, int(target // max(row_bytes, 1.0)))


def return_freed_memory() -> None:
    """Have freed large blocks go back to the system at once (glibc's ``mallopt``; elsewhere nothing).

    Chunked evaluation allocates and frees tensors of a few tens of MB hundreds of times; glibc's
    default raises its mapping threshold after the first frees and then serves them from the heap,
    which fragments and grows without bound. With a
    fixed threshold below the chunks' tensors they are mapped, and unmapped when freed. Called once,
    by the first chunked evaluation; it costs page faults, so one pass that fits is left as it is."""
    global _freed_returned
    if _freed_returned:
        return
    _freed_returned = True
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None).mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass
