"""Object poses from image moments.

For one instance mask: the centroid and the principal axis come from the first and second moments;
the footprint's extents along the principal axes give the scale descriptor and the box centre (the
pose's position: a sprite's mass centroid is off its footprint's centre, a fork's towards its tines);
the 180-degree ambiguity of the axis is resolved by the mass distribution along it (the half with
more area is ``+x``: a fork's tines, a knife's blade; when the halves balance, the half across the
axis with more area is ``+y``). A near-circular mask is rotationally symmetric: its angle is the
canonical 0 and it is marked symmetric. Symmetry orders: 0 continuous (a disk), 1 none (direction
resolved), 2 two-fold (a plain rectangle: the angle is canonical in [-90, 90) degrees), 4 four-fold (a
square: canonical in [-45, 45) degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..scene.scene import Bounds, SceneError, wrap_angle
from .render import pixel_to_world

__all__ = ["MomentPose", "pose_from_mask", "angle_error"]


@dataclass
class MomentPose:
    """What the moments of one mask say about its object (world metres and radians)."""

    x: float  # footprint centre (box centre in the principal frame)
    y: float
    theta: float  # direction of the object's +x axis; canonical for symmetric objects
    length: float  # extent along +x (the scale descriptor's first entry)
    width: float  # extent along +y
    symmetry: int  # 0 continuous, 1 none, 2 two-fold, 4 four-fold
    centroid: tuple[float, float]  # the mask's centroid (first moments)
    area: float  # m^2
    eig_ratio: float  # minor / major second moment
    imbalance: tuple[float, float]  # (area(+x) - area(-x)) / area, and the same across the axis

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)

    @property
    def size(self) -> tuple[float, float]:
        return (self.length, self.width)

    @property
    def symmetric(self) -> bool:
        """Rotationally symmetric (a disk): its orientation means nothing."""
        return self.symmetry == 0


def _extents(pts: np.ndarray, m: np.ndarray, alpha: float, ppm: float):
    a = np.array([math.cos(alpha), math.sin(alpha)])
    b = np.array([-a[1], a[0]])
    d = pts - m
    u, v = d @ a, d @ b
    # extents are the range of the pixel centres: a pixel belongs to a mask when about half of it is
    # covered, so at any angle but the axis-aligned ones the outermost centres lie on the outline (the
    # extents need no half-pixel margin; tests/vision checks them against rendered sprites)
    half = 0.0
    u0, u1, v0, v1 = u.min() - half, u.max() + half, v.min() - half, v.max() + half
    cu, cv = 0.5 * (u0 + u1), 0.5 * (v0 + v1)
    return u - cu, v - cv, (u1 - u0, v1 - v0), m + cu * a + cv * b


def _circle_fill(d: np.ndarray, ppm: float, area: float) -> float:
    """The share of the circle about the centroid, through the farthest pixel, that the mask covers."""
    r_max = float(np.sqrt((d**2).sum(axis=1)).max()) + 0.5 / ppm
    return area / (math.pi * r_max**2)


def _disk_pose(m: np.ndarray, area: float, ratio: float) -> MomentPose:
    """A disk: the centroid is its centre; the diameter from the area is unbiased."""
    dia = 2 * math.sqrt(area / math.pi)
    return MomentPose(
        float(m[0]),
        float(m[1]),
        0.0,
        dia,
        dia,
        0,
        (float(m[0]), float(m[1])),
        area,
        ratio,
        (0.0, 0.0),
    )


def _square_pose(
    cols: np.ndarray,
    rows: np.ndarray,
    pts: np.ndarray,
    m: np.ndarray,
    ppm: float,
    area: float,
    ratio: float,
) -> MomentPose:
    """Isotropic but not round (a square): the minimum-area rectangle gives the axes (four-fold)."""
    pix = np.stack([cols, rows], axis=1).astype(np.float32)
    (_, _), (_, _), ang = cv2.minAreaRect(pix)
    alpha = wrap_angle(-math.radians(ang))  # image rows point down: angles flip sign
    alpha = (alpha + math.pi / 4) % (math.pi / 2) - math.pi / 4
    u, v, (lx, ly), c = _extents(pts, m, alpha, ppm)
    return MomentPose(
        float(c[0]),
        float(c[1]),
        float(alpha),
        float(lx),
        float(ly),
        4,
        (float(m[0]), float(m[1])),
        area,
        ratio,
        (0.0, 0.0),
    )


def _direction(ix: float, iy: float, direction_tol: float) -> tuple[int, bool]:
    """``(symmetry, flip)`` from the area imbalances along and across the axis.

    The half with more area along the axis is ``+x``; when those balance, the half with more area
    across it is ``+y``; when both balance the object is two-fold symmetric.
    """
    if abs(ix) >= direction_tol:
        return 1, ix < 0
    if abs(iy) >= direction_tol:
        return 1, iy < 0
    return 2, False


def _directed_pose(
    pts: np.ndarray,
    m: np.ndarray,
    n: int,
    alpha: float,
    ppm: float,
    area: float,
    ratio: float,
    direction_tol: float,
) -> MomentPose:
    """An elongated mask: the principal axis, its direction resolved by the mass along it."""
    u, v, (lx, ly), c = _extents(pts, m, alpha, ppm)
    ix = float((np.count_nonzero(u > 0) - np.count_nonzero(u < 0)) / n)
    iy = float((np.count_nonzero(v > 0) - np.count_nonzero(v < 0)) / n)
    sym, flip = _direction(ix, iy, direction_tol)
    if flip:
        alpha += math.pi
        ix, iy = -ix, -iy
    alpha = float(wrap_angle(alpha))
    if sym == 2:
        alpha = (alpha + math.pi / 2) % math.pi - math.pi / 2
    return MomentPose(
        float(c[0]),
        float(c[1]),
        alpha,
        float(lx),
        float(ly),
        sym,
        (float(m[0]), float(m[1])),
        area,
        ratio,
        (ix, iy),
    )


def pose_from_mask(
    mask: np.ndarray,
    ppm: float,
    bounds: Bounds,
    circular_ratio: float = 0.88,
    circular_fill: float = 0.86,
    direction_tol: float = 0.04,
) -> MomentPose:
    """The pose, extents and symmetry of the object whose pixels are ``mask`` (``HxW`` bool).

    ``circular_ratio``: minor/major second moment above which a mask is isotropic; an isotropic mask
    that fills at least ``circular_fill`` of its circumscribed circle is a disk (symmetric), otherwise a
    square (four-fold). ``direction_tol``: the least area imbalance between halves that sets a
    direction; below it on both axes the object is two-fold symmetric.
    """
    rows, cols = np.nonzero(mask)
    n = rows.size
    if n < 3:
        raise SceneError(f"pose_from_mask: a mask needs at least 3 pixels, got {n}")
    xs, ys = pixel_to_world(cols, rows, bounds, ppm)
    pts = np.stack([xs, ys], axis=1)
    m = pts.mean(axis=0)
    d = pts - m
    cov = d.T @ d / n
    evals, evecs = np.linalg.eigh(cov)  # ascending
    major = evecs[:, 1]
    ratio = float(evals[0] / max(evals[1], 1e-18))
    area = n / ppm**2
    alpha = math.atan2(major[1], major[0])
    if ratio >= circular_ratio:
        if _circle_fill(d, ppm, area) >= circular_fill:
            return _disk_pose(m, area, ratio)
        return _square_pose(cols, rows, pts, m, ppm, area, ratio)
    return _directed_pose(pts, m, n, alpha, ppm, area, ratio, direction_tol)


def angle_error(estimate: float, truth: float, symmetry: int = 1) -> float:
    """Absolute angle difference in radians, modulo the symmetry (0: always 0; 2: modulo pi; 4: pi/2)."""
    if symmetry == 0:
        return 0.0
    period = 2 * math.pi / max(symmetry, 1)
    d = (estimate - truth) % period
    return float(min(d, period - d))
