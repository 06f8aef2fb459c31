"""Whether a cost term's values are finite, checked without waiting on the device inside a chain.

Called directly, a :class:`~scenescore.costs.base.Sum` reads every term's values back and names a term
that is NaN or inf at once. Inside :func:`watching` (a Langevin chain's steps) it records each term's
flag on the device instead, and the chain reads them once, at its end (:meth:`FiniteWatch.first_bad`):
on a GPU a read waits for every queued kernel, so a read per step would keep the device idle while the
CPU queues the next step.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import torch
from torch import Tensor

__all__ = ["FiniteWatch", "current", "watching"]


class FiniteWatch:
    """Each cost term's first evaluation (counted per term) with a value that is not finite, kept on the
    device: a term that goes NaN makes the poses NaN, and then every term after it. One per
    :func:`watching` block, in the thread (context) that opened it: the library's worker threads start
    without it and check at once."""

    def __init__(self) -> None:
        self._first: dict[str, Tensor] = {}  # per term: the index of its first bad evaluation, or inf
        self._count: dict[str, int] = {}

    def record(self, name: str, values: Tensor) -> None:
        ok = torch.isfinite(values.detach()).all()
        k = self._count.get(name, 0)
        self._count[name] = k + 1
        mark = torch.where(ok, math.inf, float(k))
        old = self._first.get(name)
        self._first[name] = mark if old is None else torch.minimum(old, mark)

    def all_finite(self, device: torch.device) -> Tensor:
        """One flag on ``device``: every recorded value was finite (not read here)."""
        out = torch.ones((), dtype=torch.bool, device=device)
        for first in self._first.values():
            out = out & torch.isinf(first).to(device)
        return out

    def first_bad(self) -> str | None:
        """The term that was not finite first (ties: the first evaluated), or None; reads each record."""
        firsts = [(float(f), k, name) for k, (name, f) in enumerate(self._first.items())]
        bad = [b for b in firsts if not math.isinf(b[0])]
        return min(bad)[2] if bad else None


_WATCH: ContextVar[FiniteWatch | None] = ContextVar("scenescore_finite_watch", default=None)


@contextmanager
def watching() -> Iterator[FiniteWatch]:
    """Within the block, a sum's terms record their flags in the watch instead of reading them (nested
    blocks share the outer watch, so one read at the outer end covers them)."""
    outer = _WATCH.get()
    if outer is not None:
        yield outer
        return
    watch = FiniteWatch()
    token = _WATCH.set(watch)
    try:
        yield watch
    finally:
        _WATCH.reset(token)


def current() -> FiniteWatch | None:
    """The watch of the enclosing :func:`watching` block, if any."""
    return _WATCH.get()
