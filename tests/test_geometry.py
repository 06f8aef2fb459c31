"""The torch collision geometry against the exact references: shapely (flags, distances) and python-fcl (depth)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from shapely.geometry import MultiPoint, Point
from torch import Tensor

from scenescore.geometry.exact import (
    collides,
    fcl_signed_distance,
    footprint_extent,
    footprint_extents,
    footprints_overlap,
    shapely_core,
)
from scenescore.geometry.footprints import Footprints, footprint_core, signed_distance
from scenescore.geometry.poses import compose_poses, relative_poses
from scenescore.scene.scene import Scene, SceneObject

pytestmark = pytest.mark.float_order


def _random_object(rng: np.random.Generator, name: str) -> SceneObject:
    kind = rng.choice(["box", "disk", "polygon", "ellipse"])
    if kind == "box":
        return SceneObject(name, "box", (rng.uniform(0.02, 0.3), rng.uniform(0.02, 0.3)))
    if kind == "disk":
        d = rng.uniform(0.03, 0.25)
        return SceneObject(name, "disk", (d, d), shape="disk")
    if kind == "ellipse":
        return SceneObject(name, "disk", (rng.uniform(0.05, 0.25), rng.uniform(0.05, 0.25)), shape="disk")
    k = int(rng.integers(3, 8))
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    rad = rng.uniform(0.03, 0.15, k)
    pts = np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    return SceneObject(name, "poly", (0.3, 0.3), shape={"polygon": pts.tolist()})


def _pairs(n: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        a, b = _random_object(rng, "a"), _random_object(rng, "b")
        pa = (0.0, 0.0, rng.uniform(-math.pi, math.pi))
        pb = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
        yield a, pa, b, pb


def _torch_sd(a, pa, b, pb) -> float:
    return float(_batched_sd([(a, pa, b, pb)])[0])


def _batched_sd(pairs) -> np.ndarray:
    """Signed distances of many pairs in one batched call: all objects in one scene, one pair per row."""
    objects, poses = [], []
    for k, (a, pa, b, pb) in enumerate(pairs):
        objects += [
            SceneObject(f"a{k}", a.category, a.size, shape=a.shape),
            SceneObject(f"b{k}", b.category, b.size, shape=b.shape),
        ]
        poses += [pa, pb]
    fp = Footprints.from_scene(Scene(objects))
    idx = torch.arange(len(pairs))
    sd = signed_distance(torch.tensor([poses], dtype=torch.float64), fp, 2 * idx, 2 * idx + 1)
    return sd[0].numpy()


def test_collision_flags_and_distance_match_shapely_on_1200_pairs():
    n_collide = 0
    pairs = list(_pairs(1200, seed=1))
    for (a, pa, b, pb), sd in zip(pairs, _batched_sd(pairs)):
        flag = collides(a, pa, b, pb)
        assert (sd < 0) == flag, (a, pa, b, pb, sd)
        n_collide += flag
        if sd > 0:  # apart: the exact distance
            (ca, ra), (cb, rb) = shapely_core(a, pa), shapely_core(b, pb)
            assert sd == pytest.approx(ca.distance(cb) - ra - rb, abs=1e-9)
    assert 200 < n_collide < 1000  # both outcomes well represented


def test_penetration_depth_matches_fcl_on_tall_prisms():
    n_deep = 0
    pairs = list(_pairs(1200, seed=2))
    for (a, pa, b, pb), sd in zip(pairs, _batched_sd(pairs)):
        if sd > 0 and a.shape == b.shape == "disk":
            continue  # fcl's cylinder-cylinder *distance* is approximate (mm); disks are checked exactly below
        ref = fcl_signed_distance(a, pa, b, pb)
        assert sd == pytest.approx(ref, abs=1e-4, rel=1e-3), (a, pa, b, pb, sd, ref)
        n_deep += sd < -1e-3
    assert n_deep > 200


def test_depth_matches_minkowski_difference():
    """A third, independent reference: depth = distance from the origin to the Minkowski difference's boundary."""
    pairs = list(_pairs(300, seed=3))
    for (a, pa, b, pb), sd in zip(pairs, _batched_sd(pairs)):
        (ca, ra), (cb, rb) = footprint_core(a), footprint_core(b)
        pts_a = np.asarray(
            shapely_core(a, pa)[0].exterior.coords if len(ca) > 1 else shapely_core(a, pa)[0].coords
        )
        pts_b = np.asarray(
            shapely_core(b, pb)[0].exterior.coords if len(cb) > 1 else shapely_core(b, pb)[0].coords
        )
        diff = MultiPoint((pts_a[:, None, :] - pts_b[None, :, :]).reshape(-1, 2)).convex_hull
        origin = Point(0.0, 0.0)
        core = -diff.exterior.distance(origin) if diff.contains(origin) else diff.distance(origin)
        assert sd == pytest.approx(core - ra - rb, abs=1e-9)


def test_containment_is_measured_in_full():
    # a small box inside a big one: the depth is the distance to push it out, not the smaller overlap
    big = SceneObject("big", "box", (0.4, 0.4))
    small = SceneObject("small", "box", (0.1, 0.1))
    sd = _torch_sd(big, (0, 0, 0), small, (0.05, 0, 0))
    # small spans x in [0, 0.1] inside [-0.2, 0.2]: pushing it right by 0.2 separates them; the wrong
    # formula min(max) - max(min) would give min(0.2, 0.1) - max(-0.2, 0.0) = 0.1
    assert sd == pytest.approx(-0.2, abs=1e-12)


def test_disks_are_exact_circles():
    a = SceneObject("a", "disk", (0.2, 0.2), shape="disk")
    b = SceneObject("b", "disk", (0.1, 0.1), shape="disk")
    for d in (0.0, 0.05, 0.149, 0.151, 0.4):
        sd = _torch_sd(a, (0, 0, 0), b, (d * math.cos(1.0), d * math.sin(1.0), 0.3))
        assert sd == pytest.approx(d - 0.15, abs=1e-9)


# the plain form of the signed distance, which the library's split-coordinate kernel must equal
_BIG = 1e9


def _edge_normals(w: Tensor, valid: Tensor) -> Tensor:
    """Unit outward normals of the edges ``v_k -> v_{k+1}`` of ``w (B, P, K, 2)``; invalid edges give 0."""
    e = torch.roll(w, -1, dims=-2) - w
    n = torch.stack([e[..., 1], -e[..., 0]], dim=-1)
    norm2 = (n * n).sum(-1, keepdim=True)
    safe = torch.where(valid[None, ..., None], norm2, torch.ones_like(norm2))
    return torch.where(valid[None, ..., None], n / torch.sqrt(safe), torch.zeros_like(n))


def _vertex_segment_d2(p: Tensor, q: Tensor) -> Tensor:
    """Smallest squared distance from the vertices of ``p (B, P, K, 2)`` to the edges of ``q`` -> ``(B, P)``."""
    s = q[..., None, :, :]  # (B, P, 1, K, 2) segment starts
    e = torch.roll(q, -1, dims=-2)[..., None, :, :] - s  # segment vectors
    d = p[..., :, None, :] - s  # (B, P, K, K, 2)
    ee = (e * e).sum(-1)
    t = ((d * e).sum(-1) / torch.where(ee > 0, ee, torch.ones_like(ee))).clamp(0.0, 1.0)
    r = d - t[..., None] * e
    return (r * r).sum(-1).flatten(-2).min(-1).values


def signed_distance_reference(
    pose_a: Tensor, pose_b: Tensor, fp: Footprints, pi: Tensor, pj: Tensor
) -> Tensor:
    """``signed_distance_placed`` written plainly, points as ``(..., 2)`` vectors: the definition the
    fast kernel is checked against (values and gradients)."""
    a, b = fp.world(pose_a, pi), fp.world(pose_b, pj)  # (B, P, K, 2)
    va, vb = fp.edge_valid[pi], fp.edge_valid[pj]  # (P, K)
    axes = torch.cat([_edge_normals(a, va), _edge_normals(b, vb)], dim=-2)  # (B, P, 2K, 2)
    valid = torch.cat([va, vb], dim=-1)  # (P, 2K)
    pa = (axes[..., :, None, :] * a[..., None, :, :]).sum(-1)  # (B, P, 2K, K)
    pb = (axes[..., :, None, :] * b[..., None, :, :]).sum(-1)
    overlap = torch.minimum(pa.max(-1).values - pb.min(-1).values, pb.max(-1).values - pa.min(-1).values)
    overlap = torch.where(valid[None], overlap, torch.full_like(overlap, _BIG))
    depth = overlap.min(-1).values  # (B, P): penetration depth of the cores if positive
    has_axis = valid.any(-1)[None]  # two point cores have no axis: use the distance
    d2 = torch.minimum(_vertex_segment_d2(a, b), _vertex_segment_d2(b, a))
    dist = torch.sqrt(d2 + 1e-20)
    inside = has_axis & (depth > 0)
    core = torch.where(inside, -torch.where(inside, depth, torch.zeros_like(depth)), dist)
    r = fp.radius.to(pose_a.dtype)
    return core - r[pi] - r[pj]


def test_split_kernel_equals_the_plain_reference():
    """The split-coordinate kernel does the reference's arithmetic operation for operation: the same
    values bit for bit; gradients to rounding (backward sums run in another order on many-vertex cores)."""
    from scenescore.geometry.footprints import signed_distance_placed

    pairs = list(_pairs(400, seed=5))
    objects, poses = [], []
    for k, (a, pa, b, pb) in enumerate(pairs):
        objects += [
            SceneObject(f"a{k}", a.category, a.size, shape=a.shape),
            SceneObject(f"b{k}", b.category, b.size, shape=b.shape),
        ]
        poses += [pa, pb]
    fp = Footprints.from_scene(Scene(objects))
    i = torch.arange(len(pairs))
    for dtype in (torch.float64, torch.float32):
        out = []
        for fn in (signed_distance_placed, signed_distance_reference):
            x = torch.tensor([poses], dtype=dtype).requires_grad_(True)
            sd = fn(x[:, 2 * i], x[:, 2 * i + 1], fp, 2 * i, 2 * i + 1)
            (g,) = torch.autograd.grad((sd * torch.linspace(-1, 1, len(pairs), dtype=dtype)).sum(), x)
            out.append((sd.detach(), g))
        assert torch.equal(out[0][0], out[1][0])
        tol = 1e-12 if dtype == torch.float64 else 1e-5
        assert torch.allclose(out[0][1], out[1][1], rtol=tol, atol=tol)


def test_relative_poses_undo_compose_poses():
    g = torch.Generator().manual_seed(0)
    a = torch.rand(7, 3, generator=g, dtype=torch.float64) * 4 - 2
    b = torch.rand(7, 3, generator=g, dtype=torch.float64) * 4 - 2
    assert torch.allclose(relative_poses(a, compose_poses(a, b)), b, atol=1e-12)
    # a point ahead of a pose turned a quarter: (1, 0) in its frame is (0, 1) in the world's
    q = torch.tensor([0.5, -0.5, math.pi / 2], dtype=torch.float64)
    got = compose_poses(q, torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64))
    assert torch.allclose(got, torch.tensor([0.5, 0.5, math.pi / 2], dtype=torch.float64), atol=1e-12)


def test_extents_at_one_pose_and_many_agree_with_shapely():
    """:func:`footprint_extent` (one pose) and :func:`footprint_extents` (many) are the placed core's
    shapely bounds grown by the radius; :func:`footprints_overlap` is :func:`collides` away from contact."""
    for a, pa, b, pb in _pairs(200, 5):
        geo, r = shapely_core(a, pa)
        x0, y0, x1, y1 = geo.bounds
        assert footprint_extent(a, pa) == pytest.approx((x0 - r, y0 - r, x1 + r, y1 + r), abs=1e-12)
        lo, hi = footprint_extents(a, np.array([pa, pb]))
        assert np.r_[lo[0], hi[0]] == pytest.approx(footprint_extent(a, pa), abs=1e-12)
        assert np.r_[lo[1], hi[1]] == pytest.approx(footprint_extent(a, pb), abs=1e-12)
        if abs(_torch_sd(a, pa, b, pb)) > 1e-9:
            assert footprints_overlap(a, pa, b, pb) == collides(a, pa, b, pb)
