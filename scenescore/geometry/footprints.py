"""Footprint geometry in batched torch: signed distances between convex footprints.

Every footprint is a *sphere-swept convex polygon*: a convex core (a polygon, or a single point)
grown by a radius. A box is its rectangle with radius 0; a round disk (``shape == "disk"`` with
``l == w``) is a point with radius ``l / 2``, so disks are exact circles; an elliptical disk
(``l != w``) is the 24-gon of :meth:`SceneObject.polygon` (inscribed, at most ``0.9 %`` of a radius
inside the ellipse); a polygon footprint is its convex hull (a non-convex outline is treated as its hull).

The signed distance of two footprints is the exact distance between them when they are apart, and
minus the exact penetration depth (the shortest translation that separates them) when they overlap:
a separating-axis test over the cores' edge normals, with the overlap along an axis measured as
``min(maxA - minB, maxB - minA)`` so that containment is measured in full; apart, the smallest
vertex-to-segment distance of the cores. The radii are then subtracted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from ..scene.scene import Scene, SceneObject

__all__ = [
    "Footprints",
    "footprint_core",
    "signed_distance",
    "signed_distance_placed",
    "support_extent",
]

_BIG = 1e9


def footprint_core(obj: SceneObject) -> tuple[np.ndarray, float]:
    """The convex core ``(K, 2)`` (counter-clockwise, in the object's frame) and the radius of ``obj``."""
    length, width = obj.size
    if obj.shape_kind == "disk" and math.isclose(length, width, rel_tol=1e-9):
        return np.zeros((1, 2)), length / 2
    pts = obj.polygon()
    if obj.shape_kind == "polygon":
        from scipy.spatial import ConvexHull

        hull = ConvexHull(pts)
        pts = pts[hull.vertices]  # counter-clockwise for 2-D hulls
    area2 = float(np.dot(pts[:, 0], np.roll(pts[:, 1], -1)) - np.dot(pts[:, 1], np.roll(pts[:, 0], -1)))
    if area2 < 0:
        pts = pts[::-1]
    return np.ascontiguousarray(pts, dtype=float), 0.0


@dataclass
class Footprints:
    """The footprints of a scene's objects as padded tensors.

    ``verts (N, K, 2)``: core vertices, padded by repeating vertex 0; ``edge_valid (N, K)``: which edges
    ``v_k -> v_{k+1}`` are real; ``radius (N,)``.
    """

    verts: Tensor
    edge_valid: Tensor
    radius: Tensor
    names: list[str]

    @classmethod
    def from_scene(
        cls, scene: Scene, dtype: torch.dtype = torch.float64, device: torch.device | None = None
    ) -> Footprints:
        """The footprints of ``scene``'s objects, on ``device`` (default the CPU)."""
        cores = [footprint_core(o) for o in scene.objects]
        k = max(len(c) for c, _ in cores)
        verts = np.zeros((len(cores), k, 2))
        valid = np.zeros((len(cores), k), dtype=bool)
        for i, (c, _) in enumerate(cores):
            m = len(c)
            verts[i, :m] = c
            verts[i, m:] = c[0]
            if m >= 2:
                valid[i, :m] = True
        radius = np.array([r for _, r in cores])
        return cls(
            torch.as_tensor(verts, dtype=dtype, device=device),
            torch.as_tensor(valid, device=device),
            torch.as_tensor(radius, dtype=dtype, device=device),
            [o.name for o in scene.objects],
        )

    def world(self, poses: Tensor, idx: Tensor | None = None) -> Tensor:
        """Core vertices placed at ``poses (B, N, 3)`` -> ``(B, N, K, 2)`` (``idx``: the objects ``poses`` hold)."""
        v = (self.verts if idx is None else self.verts[idx]).to(poses.dtype)
        c, s = torch.cos(poses[..., 2])[..., None], torch.sin(poses[..., 2])[..., None]  # (B, N, 1)
        x = c * v[None, ..., 0] - s * v[None, ..., 1] + poses[..., 0:1]
        y = s * v[None, ..., 0] + c * v[None, ..., 1] + poses[..., 1:2]
        return torch.stack([x, y], dim=-1)

    def world_xy(self, poses: Tensor, idx: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """As :meth:`world`, the coordinates apart: ``x, y (B, N, K)``."""
        v = (self.verts if idx is None else self.verts[idx]).to(poses.dtype)
        c, s = torch.cos(poses[..., 2])[..., None], torch.sin(poses[..., 2])[..., None]  # (B, N, 1)
        x = c * v[None, ..., 0] - s * v[None, ..., 1] + poses[..., 0:1]
        y = s * v[None, ..., 0] + c * v[None, ..., 1] + poses[..., 1:2]
        return x, y


def _edges_xy(x: Tensor, y: Tensor, valid: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Edge vectors ``v_k -> v_{k+1}`` and unit outward normals of cores given by their coordinates
    ``x, y (B, P, K)``: ``ex, ey, nx, ny``; invalid edges have normal 0."""
    ex, ey = torch.roll(x, -1, dims=-1) - x, torch.roll(y, -1, dims=-1) - y
    norm = torch.sqrt(torch.where(valid[None], ey * ey + ex * ex, torch.ones_like(ex)))
    zero = torch.zeros_like(ex)
    return ex, ey, torch.where(valid[None], ey / norm, zero), torch.where(valid[None], -ex / norm, zero)


def _vertex_segment_d2_xy(px: Tensor, py: Tensor, qx: Tensor, qy: Tensor, ex: Tensor, ey: Tensor) -> Tensor:
    """Smallest squared distance from the vertices ``px, py (B, P, K)`` to the edges of the core ``qx, qy``
    (edge vectors ``ex, ey``) -> ``(B, P)``."""
    sx, sy, ex, ey = qx[..., None, :], qy[..., None, :], ex[..., None, :], ey[..., None, :]
    dx, dy = px[..., :, None] - sx, py[..., :, None] - sy  # (B, P, K, K)
    ee = ex * ex + ey * ey
    t = ((dx * ex + dy * ey) / torch.where(ee > 0, ee, torch.ones_like(ee))).clamp(0.0, 1.0)
    rx, ry = dx - t * ex, dy - t * ey
    return (rx * rx + ry * ry).flatten(-2).min(-1).values


def _project(nx: Tensor, ny: Tensor, x: Tensor, y: Tensor) -> Tensor:
    """Projections of the vertices ``x, y (B, P, K)`` on the axes ``nx, ny (B, P, A)`` -> ``(B, P, A, K)``."""
    return nx[..., :, None] * x[..., None, :] + ny[..., :, None] * y[..., None, :]


def signed_distance(poses: Tensor, fp: Footprints, pi: Tensor, pj: Tensor) -> Tensor:
    """Signed distance of footprint pairs ``(pi[p], pj[p])`` at ``poses (B, N, 3)`` -> ``(B, P)``, metres.

    Positive: the gap between them; negative: minus the penetration depth.
    """
    return signed_distance_placed(poses[:, pi], poses[:, pj], fp, pi, pj)


def signed_distance_placed(pose_a: Tensor, pose_b: Tensor, fp: Footprints, pi: Tensor, pj: Tensor) -> Tensor:
    """As :func:`signed_distance`, with each pair's two poses given: ``pose_a, pose_b (B, P, 3)`` -> ``(B, P)``.

    Each row depends only on its own two poses, so one backward pass gives every row's Jacobian. The x
    and y coordinates are kept apart: no products reduced over a dimension of two (``tests/test_geometry.py``
    holds the plain form it equals, operation for operation).
    """
    ax, ay = fp.world_xy(pose_a, pi)  # (B, P, K)
    bx, by = fp.world_xy(pose_b, pj)
    va, vb = fp.edge_valid[pi], fp.edge_valid[pj]  # (P, K)
    eax, eay, nax, nay = _edges_xy(ax, ay, va)
    ebx, eby, nbx, nby = _edges_xy(bx, by, vb)
    nx, ny = torch.cat([nax, nbx], dim=-1), torch.cat([nay, nby], dim=-1)  # (B, P, 2K)
    valid = torch.cat([va, vb], dim=-1)  # (P, 2K)
    pa, pb = _project(nx, ny, ax, ay), _project(nx, ny, bx, by)  # (B, P, 2K, K)
    overlap = torch.minimum(pa.max(-1).values - pb.min(-1).values, pb.max(-1).values - pa.min(-1).values)
    overlap = torch.where(valid[None], overlap, torch.full_like(overlap, _BIG))
    depth = overlap.min(-1).values  # (B, P): penetration depth of the cores if positive
    has_axis = valid.any(-1)[None]  # two point cores have no axis: use the distance
    d2 = torch.minimum(
        _vertex_segment_d2_xy(ax, ay, bx, by, ebx, eby), _vertex_segment_d2_xy(bx, by, ax, ay, eax, eay)
    )
    dist = torch.sqrt(d2 + 1e-20)
    inside = has_axis & (depth > 0)
    core = torch.where(inside, -torch.where(inside, depth, torch.zeros_like(depth)), dist)
    r = fp.radius.to(pose_a.dtype)
    return core - r[pi] - r[pj]


def support_extent(poses: Tensor, fp: Footprints) -> tuple[Tensor, Tensor]:
    """Axis-aligned extent of each footprint: ``(min_xy, max_xy)``, each ``(B, N, 2)``."""
    w = fp.world(poses)  # (B, N, K, 2)
    r = fp.radius.to(poses.dtype)[None, :, None]
    return w.min(dim=-2).values - r, w.max(dim=-2).values + r
