"""Exact footprint geometry in numpy and shapely: placed cores, extents, overlap; python-fcl signed distance.

Footprints are the same sphere-swept convex cores as in :mod:`scenescore.geometry.footprints`: a disk is
its centre grown by its radius (exact circles, not polygons), a box its rectangle, a polygon its hull.
The extents (:func:`footprint_extent` at one pose, :func:`footprint_extents` at many) and the overlap
tests (:func:`collides` at a penetration tolerance, :func:`footprints_overlap` with touching not
counted) are the one numpy/shapely form that the scenarios, the trust checks, tidying and the costs'
exact checks call; :mod:`scenescore.geometry.footprints` holds the batched torch form the costs differentiate.
fcl sees footprints as prisms far taller than they are wide, so its depth is the footprint's depth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from ..scene.scene import SceneObject
from .footprints import footprint_core

__all__ = [
    "placed_core",
    "shapely_core",
    "footprint_extent",
    "footprint_extents",
    "overlap_depth_exceeds",
    "collides",
    "footprints_overlap",
    "fcl_signed_distance",
    "fcl_object",
    "PRISM_HEIGHT",
]

PRISM_HEIGHT = 2.0  # metres: far taller than a tabletop footprint is wide (taller loses precision in fcl)


def _place(core: np.ndarray, pose: Sequence[float]) -> np.ndarray:
    x, y, t = pose
    c, s = math.cos(t), math.sin(t)
    return core @ np.array([[c, s], [-s, c]]) + np.array([x, y])


def placed_core(obj: SceneObject, pose: Sequence[float]) -> tuple[np.ndarray, float]:
    """``(vertices (K, 2), radius)``: the core's vertices at ``pose`` and the radius grown around them."""
    core, r = footprint_core(obj)
    return _place(core, pose), r


def shapely_core(obj: SceneObject, pose: Sequence[float]):
    """``(geometry, radius)``: the placed core (a shapely Point or Polygon) and the radius grown around it."""
    pts, r = placed_core(obj, pose)
    return (Point(pts[0]) if len(pts) == 1 else Polygon(pts)), r


def footprint_extent(obj: SceneObject, pose: Sequence[float]) -> tuple[float, float, float, float]:
    """``(xmin, ymin, xmax, ymax)`` of ``obj``'s footprint at ``pose``: its placed core's vertices grown by
    the radius (exact for boxes, round disks and polygons)."""
    pts, r = placed_core(obj, pose)
    return (
        float(pts[:, 0].min() - r),
        float(pts[:, 1].min() - r),
        float(pts[:, 0].max() + r),
        float(pts[:, 1].max() + r),
    )


def footprint_extents(obj: SceneObject, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned extent ``lo, hi (B, 2)`` of ``obj``'s footprint at each pose of ``poses (B, 3)``."""
    core, r = footprint_core(obj)
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    rot = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], 1)  # (B, 2, 2): row-vector rotation
    pts = core[None] @ rot + poses[:, None, :2]  # (B, K, 2)
    return pts.min(1) - r, pts.max(1) + r


def collides(
    a: SceneObject, pa: Sequence[float], b: SceneObject, pb: Sequence[float], tol: float = 0.0
) -> bool:
    """Whether the footprints overlap by more than ``tol`` metres of penetration (exact, shapely)."""
    return overlap_depth_exceeds(shapely_core(a, pa), shapely_core(b, pb), tol)


def overlap_depth_exceeds(ga, gb, tol: float) -> bool:
    (ca, ra), (cb, rb) = ga, gb
    if ra + rb > tol:
        return bool(ca.distance(cb) < ra + rb - tol)
    # both (nearly) polygons: erode one by the remaining tolerance (exact for convex shapes)
    shrink = tol - ra - rb
    if shrink > 0:
        ca = ca.buffer(-shrink, join_style="mitre")
        if ca.is_empty:
            return False
    inter = shapely.intersection(ca, cb)
    return bool(inter.area > 0.0)


def footprints_overlap(a: SceneObject, pa: Sequence[float], b: SceneObject, pb: Sequence[float]) -> bool:
    """Whether the footprints overlap, touching not counted: disks closer than their radii less 1e-12 m,
    polygons sharing more than 1e-14 m^2 (so that rounding at a designed contact is not an overlap)."""
    (ca, ra), (cb, rb) = shapely_core(a, pa), shapely_core(b, pb)
    if ra + rb > 0:
        return bool(ca.distance(cb) < ra + rb - 1e-12)
    return bool(shapely.intersection(ca, cb).area > 1e-14)


def fcl_object(obj: SceneObject, pose: Sequence[float]):
    """The footprint as a tall fcl prism (or cylinder) at ``pose``."""
    import fcl

    core, r = footprint_core(obj)
    h = PRISM_HEIGHT
    if len(core) == 1:
        geom = fcl.Cylinder(r, h)
    else:
        k = len(core)
        verts = np.concatenate([np.c_[core, np.full(k, -h / 2)], np.c_[core, np.full(k, h / 2)]])
        faces = [k, *range(k - 1, -1, -1), k, *range(k, 2 * k)]
        for i in range(k):
            j = (i + 1) % k
            faces += [4, i, j, k + j, k + i]
        geom = fcl.Convex(verts, k + 2, np.array(faces))
    x, y, t = pose
    q = np.array([math.cos(t / 2), 0.0, 0.0, math.sin(t / 2)])
    return fcl.CollisionObject(geom, fcl.Transform(q, np.array([x, y, 0.0])))


def fcl_signed_distance(a: SceneObject, pa: Sequence[float], b: SceneObject, pb: Sequence[float]) -> float:
    """fcl's signed distance of two footprints (negative: minus the penetration depth), via tall prisms.

    Measured here: fcl's signed *distance* query agrees with the exact value on overlapping pairs, while
    the contact ``penetration_depth`` of ``collide`` is approximate (libccd) or sometimes 0 (GST_INDEP).
    """
    import fcl

    req = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
    res = fcl.DistanceResult()
    return float(fcl.distance(fcl_object(a, pa), fcl_object(b, pb), req, res))
