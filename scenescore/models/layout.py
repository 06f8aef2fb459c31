"""What the training data's arrangements look like, in the terms the trust reference stores them
(:mod:`scenescore.models.trust`): where each category stands relative to each other one
(:func:`relations`), how far it stands from the nearest of each (:func:`apart_limits`), which categories
overlap (:func:`overlapping_categories`), and how near a footprint comes to the bounds
(:func:`bound_gap`, :func:`touching_bound`). Pure geometry of scenes: no model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from ..geometry.exact import collides, footprint_extents
from ..geometry.poses import relative_poses
from ..scene.scene import Scene, SceneObject, wrap_angle

__all__ = [
    "ALL_PAIRS",
    "BOUND_TOL",
    "MAX_RELATIONS",
    "NEAR_RELATIONS",
    "OVERLAP_TOL",
    "RELATIONS_PER_PAIR",
    "apart_limits",
    "bound_gap",
    "bounds_touched",
    "evenly",
    "nearest_distances",
    "overlapping_categories",
    "relations",
    "side_gaps",
    "touching_bound",
]

BOUND_TOL = 0.05  # length scales: a footprint this close to a bound touches it
OVERLAP_TOL = 0.1  # length scales of penetration before two objects of the data count as overlapping
RELATIONS_PER_PAIR = 32  # relative poses kept per (category, anchor category), evenly subsampled
MAX_RELATIONS = 4096  # relative poses kept in all (fewer per pair when the pairs are many)
#: in a scene of more than ALL_PAIRS objects an object's relations are kept to its NEAR_RELATIONS nearest
#: objects only: in a room, a chair's pose in the frame of a table across the room says nothing of where
#: chairs go, and among every pair's relations kept, few were to the chair's own table
ALL_PAIRS = 32
NEAR_RELATIONS = 8


def apart_limits(scenes: Sequence[Scene], length: float) -> dict[str, dict[str, float]]:
    """For each category and each category beside it in ``scenes``: the farthest any object of the first
    stands from the nearest object of the second (its own category: the nearest other one), in ``length``
    units, over the scenes that hold both. A chair is never more than a step from a table in a cafe,
    however far it may stand from the nearest chair."""
    out: dict[str, dict[str, float]] = {}
    for s in scenes:
        p = s.poses()
        cats = np.array([o.category for o in s.objects])
        d = np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=-1)
        np.fill_diagonal(d, np.inf)
        for c in sorted(set(cats.tolist())):
            nearest = d[:, cats == c].min(axis=1) / length
            for a, v in zip(cats.tolist(), nearest.tolist()):
                if math.isfinite(v):
                    row = out.setdefault(a, {})
                    row[c] = max(row.get(c, 0.0), v)
    return out


def nearest_distances(poses: np.ndarray) -> np.ndarray:
    """Each centre's distance to the nearest other centre ``(N,)`` (inf for a lone object)."""
    d = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=-1)
    np.fill_diagonal(d, np.inf)
    return d.min(axis=1)


def side_gaps(obj: SceneObject, poses: np.ndarray, bounds: Any) -> np.ndarray:
    """How far ``obj``'s footprint keeps from each side of ``bounds`` (``x >= x0``, ``y >= y0``, ``x <= x1``,
    ``y <= y1``) at each pose of ``poses (B, 3)``: ``(B, 4)`` metres, negative beyond the side."""
    lo, hi = footprint_extents(obj, poses)
    (x0, y0), (x1, y1) = bounds
    return np.stack([lo[:, 0] - x0, lo[:, 1] - y0, x1 - hi[:, 0], y1 - hi[:, 1]], 1)


def bounds_touched(
    obj: SceneObject, poses: np.ndarray, bounds: Any, tol: float
) -> tuple[list[str], np.ndarray]:
    """The bounds' four sides by name (``"x >= -0.6"``, ...) and which of them ``obj``'s footprint touches
    at each pose of ``poses (B, 3)``: ``(B, 4)`` bool."""
    (x0, y0), (x1, y1) = bounds
    names = [f"x >= {x0:g}", f"y >= {y0:g}", f"x <= {x1:g}", f"y <= {y1:g}"]
    return names, side_gaps(obj, poses, bounds) <= tol


def bound_gap(obj: SceneObject, pose: Sequence[float], bounds: Any) -> float:
    """The smallest distance from ``obj``'s footprint at ``pose`` to a side of ``bounds`` (metres)."""
    return float(side_gaps(obj, np.asarray(pose, dtype=float)[None, :3], bounds).min())


def touching_bound(obj: SceneObject, pose: Sequence[float], bounds: Any, tol: float) -> str | None:
    """The bound the placed footprint touches (``"x >= -0.6"``), or None."""
    names, hit = bounds_touched(obj, np.asarray(pose, dtype=float)[None, :3], bounds, tol)
    return next((n for n, h in zip(names, hit[0]) if h), None)


def overlapping_categories(scenes: Sequence[Scene], tol: float) -> list[list[str]]:
    """Sorted category pairs ``[a, b]`` whose footprints overlap by more than ``tol`` metres of
    penetration in some scene (exact, shapely; pairs whose bounding circles are apart are skipped)."""
    found: set[tuple[str, str]] = set()
    for s in scenes:
        p = s.poses()
        reach = np.array([float(np.hypot(*o.size)) / 2 for o in s.objects])
        d = np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=-1)
        near = np.argwhere(np.triu(d < reach[:, None] + reach[None, :] - tol, k=1))
        for i, j in near:
            a, b = s.objects[i], s.objects[j]
            pair = (min(a.category, b.category), max(a.category, b.category))
            if pair not in found and collides(a, p[i], b, p[j], tol):
                found.add(pair)
    return [list(pr) for pr in sorted(found)]


def evenly(rows: list[Any], keep: int) -> list[Any]:
    """At most ``keep`` of ``rows``, evenly spaced (all of them when there are no more)."""
    if len(rows) <= keep:
        return list(rows)
    return [rows[int(k)] for k in np.linspace(0, len(rows) - 1, keep).round()]


def relations(scenes: Sequence[Scene], length: float) -> dict[str, dict[str, list[list[float]]]]:
    """Each category's poses relative to each other category's in ``scenes``: ``{category: {anchor
    category: [[x, y, heading], ...]}}``, the pose of every object in the frame of every other object
    of the scene (x, y divided by ``length``, the heading wrapped to [-pi, pi)); in a scene of more than
    :data:`ALL_PAIRS` objects, in the frames of its :data:`NEAR_RELATIONS` nearest only. At most
    :data:`RELATIONS_PER_PAIR` per pair evenly subsampled, fewer when the pairs are many (at most
    :data:`MAX_RELATIONS` in all)."""
    found: dict[tuple[str, str], list[list[float]]] = {}
    for s in scenes:
        p = torch.as_tensor(s.poses(), dtype=torch.float64)
        rel = relative_poses(p[:, None], p[None, :])  # (anchor, object, 3)
        rel[..., :2] /= length
        rel[..., 2] = wrap_angle(rel[..., 2])
        rows = rel.tolist()
        pairs = torch.ones(len(s), len(s), dtype=torch.bool)  # (anchor, object)
        if len(s) > ALL_PAIRS:  # each object's nearest, by centre distance (itself first)
            near = torch.cdist(p[:, :2], p[:, :2]).argsort(dim=0)[1 : NEAR_RELATIONS + 1]
            pairs = torch.zeros_like(pairs).scatter_(0, near, True)
        kept = pairs.tolist()
        for a, anchor in enumerate(s.objects):
            for o, obj in enumerate(s.objects):
                if a != o and kept[a][o]:
                    found.setdefault((obj.category, anchor.category), []).append(rows[a][o])
    keep = max(1, min(RELATIONS_PER_PAIR, MAX_RELATIONS // max(1, len(found))))
    out: dict[str, dict[str, list[list[float]]]] = {}
    for (cat, around), rows in sorted(found.items()):
        out.setdefault(cat, {})[around] = evenly(rows, keep)
    return out
