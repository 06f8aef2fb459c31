"""Errors in settings (configuration dataclasses, options, command-line values) and their range checks.

Errors in scenes, problems, costs and checkpoints live beside what they check (``SceneError``,
``ProblemError``, ``CostError``, ``CheckpointError``); all are ``ValueError``s that the command line prints
as one line.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable

__all__ = ["ConfigError", "check_number", "nearest_name"]


def nearest_name(name: str, valid: Iterable[str], cutoff: float = 0.6) -> str | None:
    """The valid name closest to a misspelt ``name`` (difflib's ratio at least ``cutoff``; 0: always the
    closest), for the "did you mean" of an error; None when none is close enough."""
    near = difflib.get_close_matches(name, list(valid), n=1, cutoff=cutoff)
    return near[0] if near else None


class ConfigError(ValueError):
    """A setting out of its range: names the owner, the setting, what was expected and what was given."""


def check_number(
    owner: str,
    name: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    integer: bool = False,
    open_lo: bool = False,
) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a finite number (an integer if ``integer``) in
    ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    kind = "an integer" if integer else "a finite number"
    ok = isinstance(value, int) if integer else isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and not isinstance(value, bool)
    if ok and lo is not None:
        ok = value > lo if open_lo else value >= lo  # type: ignore[operator]
    if ok and hi is not None:
        ok = value <= hi  # type: ignore[operator]
    if not ok:
        rng = []
        if lo is not None:
            rng.append(f"{'>' if open_lo else '>='} {lo:g}")
        if hi is not None:
            rng.append(f"<= {hi:g}")
        raise ConfigError(
            f"{owner}: {name}: expected {kind}{' ' + ' and '.join(rng) if rng else ''}, got {value!r}"
        )
