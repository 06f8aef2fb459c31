"""The length unit a dataset names, and how reports say lengths in it.

Lengths in scenes are in the data's own unit: a model learns at the data's scale and never needs to
know which unit that is. A scene may name it in its ``meta`` (``"meta": {"unit": "mm"}``; ``scenescore
generate`` names metres). Reports then give lengths in it (metres as centimetres); data that names no
unit has its lengths given in its own unit, and the report says so rather than guessing.

Figures are stored under ``*_cm`` keys as 100 times the data's length: centimetres for data in metres,
the unit every built-in scenario uses, so that every results file has one schema whatever its data's
unit; :class:`ShownUnit` turns such a figure into the length a report prints in the data's own unit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from .scene import Scene, SceneError

__all__ = ["UNITS", "declared_unit", "length_unit", "ShownUnit"]

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # the units a scene may name: metres per unit


def declared_unit(scenes: Sequence[Scene]) -> str | None:
    """The unit the scenes' ``meta.unit`` names (scenes that name none are taken to share it), or None
    when none names one. An unknown unit, or two scenes naming different ones, raises
    :class:`~scenescore.scene.scene.SceneError` naming the scene."""
    found: tuple[str, str] | None = None  # (unit, the scene that named it first)
    for k, s in enumerate(scenes):
        unit = s.meta.get("unit")
        if unit is None:
            continue
        if unit not in UNITS:
            raise SceneError(f"{s.label(k)}: key 'meta.unit': expected one of {sorted(UNITS)}, got {unit!r}")
        if found is None:
            found = (unit, s.label(k))
        elif unit != found[0]:
            raise SceneError(
                f"{s.label(k)}: key 'meta.unit': {unit!r}, but {found[1]} names {found[0]!r}; "
                "a dataset has one unit"
            )
    return None if found is None else found[0]


def length_unit(scene: Scene) -> str:
    """How a message says a length of ``scene``: the unit its ``meta`` names, else ``data units``."""
    unit = scene.meta.get("unit")
    return unit if unit in UNITS else "data units"


@dataclass(frozen=True)
class ShownUnit:
    """How a report prints a length stored as a ``*_cm`` figure, for data in ``unit`` (None: undeclared)."""

    unit: str | None

    @property
    def label(self) -> str:
        """The unit printed: ``cm`` for metres, the named unit otherwise, ``units`` (the data's own) when
        none is named."""
        if self.unit is None:
            return "units"
        return "cm" if self.unit == "m" else self.unit

    @property
    def words(self) -> str:
        """The unit as a sentence says it (``cm``, ``mm``, ``data units``)."""
        return "data units" if self.unit is None else self.label

    def value(self, t_cm: float) -> float:
        """A stored ``*_cm`` figure (100 times the data's length) in :attr:`label`'s unit."""
        return t_cm if self.unit == "m" else t_cm / 100

    def decimals(self, typical_cm: float) -> int:
        """Decimals to print: 2 in a named unit; in the data's own unit, enough to give ``typical_cm``
        (a stored figure, e.g. the mean error) three significant digits (at least 2, at most 8)."""
        v = abs(self.value(typical_cm))
        if self.unit is not None or not math.isfinite(v) or v == 0:
            return 2
        return min(8, max(2, 2 - math.floor(math.log10(v))))

    def note(self) -> str | None:
        """The line a table adds when the data names no unit, else None."""
        if self.unit is not None:
            return None
        return (
            "t: in the data's own length unit (its scenes name none; "
            '"meta": {"unit": "m"}, "cm" or "mm" in a scene names it)'
        )
