"""Which categories a handful of examples pin down, and which they leave free.

An object's place is pinned when another example shows its category at nearly the same place relative
to something: an object of some category (itself included: a chair beside a chair) or the bounds. For
each category and each such anchor, every object of the category is read in the frame of the nearest
anchor of its scene (x, y in length scales; a round anchor, which has no heading, by its distance
alone; the bounds by the offset from their centre), and the anchor's spread is the median, over those
objects, of the distance to the nearest such reading from another scene. The category's spread is its
tightest anchor's: the examples pin the category down when it is at most :data:`FREE_SPREAD` length
scales, and leave it free otherwise (a vase that stands somewhere else on every table, or a category
that one scene alone shows). Pure geometry of scenes: no model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from ..geometry.poses import relative_poses
from ..scene.scene import Scene

__all__ = ["BOUNDS", "FREE_SPREAD", "Spread", "spreads", "describe_spreads"]

BOUNDS = "the bounds"  # the anchor name of a place read from the bounds' centre
FREE_SPREAD = 1.0  # length scales: a category whose examples disagree by more is free


@dataclass(frozen=True)
class Spread:
    """How far the examples disagree on where a category goes (length scales) and the anchor they
    agree best relative to; ``inf`` when no two scenes show the category."""

    spread: float
    anchor: str

    @property
    def free(self) -> bool:
        return not self.spread <= FREE_SPREAD


Readings = dict[tuple[str, str], list[tuple[int, np.ndarray]]]


def _readings(scenes: Sequence[Scene], length: float) -> Readings:
    """``{(category, anchor): [(scene index, reading (2,)), ...]}``: every object read relative to the
    nearest object of each anchor category in its scene, and to the bounds (see the module's
    description), each scene's relative poses and distances computed once."""
    out: Readings = {}
    for k, s in enumerate(scenes):
        p = s.poses()
        t = torch.as_tensor(p, dtype=torch.float64)
        frames = relative_poses(t[:, None], t[None, :]).numpy()  # (anchor, object, 3)
        dist = np.hypot(*(p[None, :, :2] - p[:, None, :2]).transpose(2, 0, 1))
        np.fill_diagonal(dist, np.inf)
        cats = np.array([o.category for o in s.objects])
        centre = (np.asarray(s.bounds[0]) + np.asarray(s.bounds[1])) / 2
        for i, c in enumerate(cats):
            out.setdefault((str(c), BOUNDS), []).append((k, (p[i, :2] - centre) / length))
            for a in dict.fromkeys(cats):
                js = np.flatnonzero(cats == a)
                js = js[js != i]
                if not len(js):
                    continue
                j = int(js[np.argmin(dist[i, js])])
                if s.objects[j].round:
                    reading = np.array([dist[i, j], 0.0]) / length
                else:
                    reading = frames[j, i, :2] / length
                out.setdefault((str(c), str(a)), []).append((k, reading))
    return out


def _spread(readings: list[tuple[int, np.ndarray]]) -> float:
    """The median over readings of the distance to the nearest reading of another scene (inf: none)."""
    if len({k for k, _ in readings}) < 2:
        return math.inf
    keys = np.array([k for k, _ in readings])
    pts = np.stack([r for _, r in readings])
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    d[keys[:, None] == keys[None]] = np.inf
    return float(np.median(d.min(axis=1)))


def spreads(scenes: Sequence[Scene], length: float) -> dict[str, Spread]:
    """Each category's :class:`Spread` in ``scenes`` (every pose known), ``length``: the data's length
    scale. Ties between anchors go to the bounds, then to the anchor category first in sorted order."""
    cats = sorted({o.category for s in scenes for o in s.objects})
    readings = _readings(scenes, length)
    out = {}
    for c in cats:
        best = Spread(math.inf, BOUNDS)
        for a in [BOUNDS, *cats]:
            v = _spread(readings.get((c, a), []))
            if v < best.spread:
                best = Spread(v, a)
        out[c] = best
    return out


def describe_spreads(table: dict[str, Spread], length: float, unit: str) -> list[str]:
    """Two lines for ``train``'s summary: the categories the examples pin down (each with its anchor and
    spread) and those they leave free; ``length`` converts length scales to ``unit``."""

    def said(c: str, s: Spread) -> str:
        if not math.isfinite(s.spread):
            return f"{c} (in one scene only)"
        if s.free:
            return f"{c} (varies by {s.spread * length:.3g} {unit}, least beside {s.anchor})"
        return f"{c} (by {s.anchor}, within {s.spread * length:.3g} {unit})"

    pinned = [said(c, s) for c, s in table.items() if not s.free]
    free = [said(c, s) for c, s in table.items() if s.free]
    return [
        "the examples pin down: " + (", ".join(pinned) or "no category"),
        "they leave free: "
        + (", ".join(free) or "no category")
        + (" (a placement of one says so in its confidence)" if free else ""),
    ]
