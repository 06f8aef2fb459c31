"""Hinge collision: footprints at least ``margin`` apart (torch, exact shapely check, CasADi, YAML)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import casadi as ca
import numpy as np
import torch
from pydantic import Field
from torch import Tensor

from ..geometry.exact import overlap_depth_exceeds, shapely_core
from ..geometry.footprints import signed_distance_placed
from ..runtime import chunk_rows, return_freed_memory
from .base import ConstraintCost, Cost
from .spec import CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, register_casadi_form
from .terms import CostError, Violation, check_scene_names

__all__ = ["HingeCollision", "CollisionSpec"]

# bytes one pair of one pose set takes while its signed distance is computed (float64, with the
# footprints' vertices and the intermediates), with room to spare
PAIR_BYTES = 4096
# metres added to the bounding-circle test on top of the rounding allowance: a pair is skipped only
# when its circles are this far beyond the margin, so its computed signed distance is certainly above it
CULL_CUSHION = 1e-6
# fewer pair rows than this (pose sets x pairs) are computed in full: the screening's own few dozen
# operations would cost more than the kernel it saves
SCREEN_ROWS = 256


class HingeCollision(ConstraintCost):
    """Zero when footprints are more than ``margin`` apart, growing with penetration: ``relu(margin - sd) ** power``.

    ``pairs``: ``"all"`` (every pair in which at least one object moves) or a list of ``[name, name]``.
    Rows ``g = sd - margin`` per pair, in metres; see :mod:`scenescore.costs.geometry` for ``sd``.

    The hinge (``evaluate``) and ``violation`` compute the signed distance only for the pairs whose
    bounding circles (about each object's origin) come within ``margin`` of each other; the others'
    rows are certainly positive, so their hinge and its gradient are exactly 0. With a gradient to
    take, the pairs that may touch are screened without one and only those that overlap are evaluated
    again with it. The numbers are those of the full computation, bit for bit (small batches, below
    :data:`SCREEN_ROWS` pair rows, are computed in full). ``constraints`` and ``jacobian`` give every
    row exactly.
    """

    # how the hinge is computed (tests and benchmarks compare them): "fast" (the screened pairs) or
    # "full" (every pair, the same kernel)
    _path: Literal["fast", "full"] = "fast"

    def __init__(
        self,
        margin: float = 0.0,
        pairs: str | Sequence[Sequence[str]] = "all",
        power: float = 1.0,
        name: str = "collision",
    ):
        if not isinstance(margin, (int, float)) or margin < 0 or not math.isfinite(margin):
            raise CostError(f"HingeCollision: margin: expected a distance >= 0 in metres, got {margin!r}")
        if power not in (1, 2, 1.0, 2.0):
            raise CostError(f"HingeCollision: power: expected 1 or 2, got {power!r}")
        if not (pairs == "all" or (isinstance(pairs, (list, tuple)) and all(len(p) == 2 for p in pairs))):
            raise CostError(f"HingeCollision: pairs: expected 'all' or a list of [name, name], got {pairs!r}")
        self.margin = float(margin)
        self.pairs = pairs
        self.power = float(power)
        self.name = name

    def _on_bind(self) -> None:
        b = self.binding
        n = len(b.scene)
        if self.pairs == "all":
            pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if b.movable[i] or b.movable[j]]
        else:
            pairs = []
            for p in self.pairs:
                i, j = check_scene_names(b.scene, list(p), f"HingeCollision {self.name!r}: pairs")
                if i == j:
                    raise CostError(f"HingeCollision {self.name!r}: pairs: {p!r} pairs an object with itself")
                pairs.append((i, j))
        self._pairs = pairs
        self._pi = torch.tensor([p[0] for p in pairs], dtype=torch.long, device=b.device)
        self._pj = torch.tensor([p[1] for p in pairs], dtype=torch.long, device=b.device)
        fp = b.footprints
        circle = fp.verts.norm(dim=-1).amax(-1) + fp.radius  # (N,) bounding circle about the origin
        self._reach = circle[self._pi] + circle[self._pj] + self.margin + CULL_CUSHION  # (P,)
        self._reach_max = float(self._reach.max()) if pairs else 0.0
        # the exact check's copies, on the CPU: pair indices and squared reach
        self._pi_np, self._pj_np = self._pi.cpu().numpy(), self._pj.cpu().numpy()
        self._reach2_np = (self._reach * self._reach).cpu().numpy()

    def _kernel(self, pose_a: Tensor, pose_b: Tensor, pi: Tensor, pj: Tensor) -> Tensor:
        return signed_distance_placed(pose_a, pose_b, self.binding.footprints, pi, pj)

    def _circles(self, poses: Tensor) -> tuple[Tensor, Tensor]:
        """Squared centre distance ``(B, P)`` and the reach ``(P,)`` beyond which a pair's row is certainly
        positive: the bounding circles' radii, the margin, and an allowance for the rounding of the
        signed distance computed from these coordinates (float32 included)."""
        xy = poses[..., :2].detach()
        d = xy[:, self._pi] - xy[:, self._pj]  # (B, P, 2)
        scale = xy.abs().amax() if xy.numel() else xy.new_zeros(())  # kept on the device: not read
        eps = torch.finfo(poses.dtype).eps
        reach = self._reach.to(poses.device, poses.dtype) + 64 * eps * (scale + self._reach_max)
        return d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], reach

    def _near(self, poses: Tensor) -> Tensor:
        """``(B, P)``: the pairs whose bounding circles come within the margin (NaN poses count as near,
        so that they reach the cost); the others' rows are certainly positive."""
        d2, reach = self._circles(poses)
        return ~(d2 > reach * reach)

    def _rows_at(self, poses: Tensor, flat: Tensor) -> Tensor:
        """Rows ``g`` of the pairs ``flat`` (indices into the flattened ``(B, P)``) -> ``(M,)``, in chunks."""
        p = len(self._pairs)
        rows = chunk_rows(PAIR_BYTES, f"collision {self.name!r}: one pair", "the number of objects or pairs")
        pi_all, pj_all = self._pi.to(flat.device), self._pj.to(flat.device)
        parts = []
        for a in range(0, len(flat), rows):
            f = flat[a : a + rows]
            bi, k = f // p, f % p
            pi, pj = pi_all[k], pj_all[k]
            parts.append(self._kernel(poses[bi, pi][None], poses[bi, pj][None], pi, pj)[0] - self.margin)
        if len(parts) > 1:
            return_freed_memory()
        return parts[0] if len(parts) == 1 else torch.cat(parts)

    def _hinge_rows(self, poses: Tensor) -> Tensor:
        """``relu(-g) (B, P)``, computed only where the pair may touch (0 elsewhere, exactly as computed)."""
        b, p = poses.shape[0], len(self._pairs)
        flat = self._near(poses).flatten().nonzero().squeeze(1)  # b-major, as the full computation
        out = poses.new_zeros(b * p)
        grad = torch.is_grad_enabled() and poses.requires_grad
        if len(flat) and grad:
            with torch.no_grad():
                g = self._rows_at(poses, flat)
            flat = flat[~(g >= 0)]  # only overlapping rows carry a gradient (NaN ones go on to the cost)
        if len(flat):
            out = out.index_put((flat,), torch.relu(-self._rows_at(poses, flat)))
        elif grad:  # nothing overlaps: still a function of the poses (its gradient 0), as the full one is
            out = out.index_put((flat,), poses.reshape(-1)[:0])
        return out.view(b, p)

    def _screens(self, poses: Tensor) -> bool:
        """Whether to screen the pairs of ``poses`` by their bounding circles (else: compute them all, the
        same numbers). Not on a GPU: which pairs pass is read back from the device, a wait at every step
        of a chain, where computing every pair keeps the device busy instead."""
        return (
            self._path == "fast"
            and bool(self._pairs)
            and poses.shape[0] * len(self._pairs) >= SCREEN_ROWS
            and poses.device.type == "cpu"
        )

    def evaluate(self, poses: Tensor) -> Tensor:
        if not self._screens(poses):
            return super().evaluate(poses)
        return (self._hinge_rows(poses) ** self.power).sum(-1)

    def violation(self, poses: Tensor) -> Tensor:
        poses = self._check(poses)
        if not self._screens(poses):
            return super().violation(poses)
        return self._hinge_rows(poses).max(-1).values

    def signed_distance(self, poses: Tensor) -> Tensor:
        """Signed distance per pair ``(B, P)``; many pose sets (candidates being screened) go in chunks of
        rows, with the same numbers."""
        poses = self._check(poses)
        if not self._pairs:
            return poses.new_zeros(poses.shape[0], 0)
        b = poses.shape[0]
        rows = chunk_rows(
            PAIR_BYTES * len(self._pairs),
            f"collision {self.name!r}: one pose set of {len(self._pairs)} pairs",
            "the number of objects or pairs",
        )
        if b <= rows:
            return self._kernel(poses[:, self._pi], poses[:, self._pj], self._pi, self._pj)
        return_freed_memory()
        return torch.cat(
            [
                self._kernel(poses[a : a + rows, self._pi], poses[a : a + rows, self._pj], self._pi, self._pj)
                for a in range(0, b, rows)
            ]
        )

    def constraints(self, poses: Tensor) -> Tensor:
        return self.signed_distance(poses) - self.margin

    def constraints_below(self, poses: Tensor, floor: Tensor) -> Tensor:
        """Rows exact where the bounding circles allow them to reach ``floor (B, P)``; elsewhere the
        circles' lower bound (above ``floor``, not differentiated)."""
        poses = self._check(poses)
        b, p = poses.shape[0], len(self._pairs)
        if not self._screens(poses):
            return self.constraints(poses)
        d2, reach = self._circles(poses)
        bound = torch.sqrt(d2) - reach  # <= the row: sd >= centre distance - both radii
        flat = (~(bound > floor)).flatten().nonzero().squeeze(1)  # NaN: computed
        if not len(flat):
            return bound
        return bound.flatten().index_put((flat,), self._rows_at(poses, flat)).view(b, p)

    def jacobian(self, poses: Tensor) -> tuple[Tensor, Tensor]:
        """Per-pair rows and Jacobian ``(B, P)``, ``(B, P, N, 3)``: each pair gets its own copy of its two poses."""
        poses = self._check(poses).detach()
        b, n, _ = poses.shape
        p = len(self._pairs)
        jac = poses.new_zeros(b, p, n, 3)
        if p == 0:
            return poses.new_zeros(b, 0), jac
        with torch.enable_grad():
            pa = poses[:, self._pi].clone().requires_grad_(True)
            pb = poses[:, self._pj].clone().requires_grad_(True)
            g = self._kernel(pa, pb, self._pi, self._pj) - self.margin
            ga, gb = torch.autograd.grad(g.sum(), (pa, pb))
        rows = torch.arange(p, device=poses.device)
        jac[:, rows, self._pi] = ga
        jac[:, rows, self._pj] = gb
        return g.detach(), jac

    def labels(self) -> list[str]:
        names = self.binding.scene.names
        return [f"{names[i]} / {names[j]}" for i, j in self._pairs]

    def support(self) -> list[tuple[int, ...]]:
        return list(self._pairs)

    def check(self, poses: np.ndarray, tol: float) -> list[Violation]:
        """Exact (shapely): pairs overlapping by more than ``tol``, or closer than ``margin - tol``; a pair
        whose bounding circles stay beyond the margin is clear without a shapely call."""
        objs = self.binding.scene.objects
        xy = np.asarray(poses, dtype=float)[:, :2]
        d2 = ((xy[self._pi_np] - xy[self._pj_np]) ** 2).sum(-1)  # (P,) squared centre distances
        geo: dict[int, tuple] = {}  # shapely cores, made for the objects of pairs that may touch
        sd: list[float] | None = None
        out = []
        for k, (i, j) in enumerate(self._pairs):
            if d2[k] >= self._reach2_np[k]:  # bounding circles beyond the margin: certainly clear
                continue
            for m in (i, j):
                if m not in geo:
                    geo[m] = shapely_core(objs[m], poses[m])
            (ca_, ra), (cb, rb) = geo[i], geo[j]
            a, b = objs[i].name, objs[j].name
            if overlap_depth_exceeds((ca_, ra), (cb, rb), tol):
                if sd is None:  # every pair's depth, computed once for the pose set
                    x = torch.as_tensor(np.asarray(poses, dtype=np.float64), device=self.binding.device)[None]
                    sd = self.signed_distance(x)[0].tolist()
                d = sd[k]
                out.append(Violation(self.name, f"{a} / {b}", -d, f"{a} overlaps {b} ({-d * 1000:.2f} mm)"))
            elif self.margin > tol:
                d = ca_.distance(cb) - ra - rb
                if d < self.margin - tol:
                    text = f"{a} within margin of {b} ({d * 1000:.2f} mm apart)"
                    out.append(Violation(self.name, f"{a} / {b}", self.margin - d, text))
        return out


def _collision_casadi(term: HingeCollision, weight: float, nlp: SymbolicProblem) -> None:
    """Exact non-overlap for convex footprints: one separating line per pair (angle ``phi``, offset ``b``
    as extra variables), every core vertex of one object on its side, grown by its radius and half the
    margin."""
    for i, j in term.support():
        phi, b = ca.MX.sym(f"phi_{i}_{j}"), ca.MX.sym(f"b_{i}_{j}")
        nx, ny = ca.cos(phi), ca.sin(phi)
        va, ra = nlp.footprint_vertices(i)
        vb, rb = nlp.footprint_vertices(j)
        rows = [nx * px + ny * py + ra + term.margin / 2 - b for px, py in va]  # i on the negative side
        rows += [b - (nx * px + ny * py) + rb + term.margin / 2 for px, py in vb]  # j on the positive side
        nlp.add_rows(rows, -ca.inf, 0.0)

        def start(x0: np.ndarray, i: int = i, j: int = j) -> np.ndarray:
            return _line_between(x0, i, j)

        nlp.add_variables(ca.vertcat(phi, b), start)


def _line_between(x0: np.ndarray, i: int, j: int) -> np.ndarray:
    """A start for a pair's separating line: through the midpoint, normal along the centre-to-centre line."""
    d = x0[j, :2] - x0[i, :2]
    phi = math.atan2(d[1], d[0]) if np.hypot(*d) > 1e-9 else 0.0
    mid = (x0[i, :2] + x0[j, :2]) / 2
    return np.array([phi, math.cos(phi) * mid[0] + math.sin(phi) * mid[1]])


class CollisionSpec(CostSpec):
    """``{type: collision, weight, margin, pairs: all | [[a, b], ...], power: 1 | 2, name}``."""

    type: Literal["collision"]
    margin: float = Field(0.0, ge=0, allow_inf_nan=False)
    pairs: Literal["all"] | list[tuple[str, str]] = "all"
    power: Literal[1, 2] = 1

    def build(self, ctx: SpecContext) -> Cost:
        pairs: str | list[list[str]] = (
            self.pairs
            if self.pairs == "all"
            else [
                [ctx.object(a, ("pairs", k)), ctx.object(b, ("pairs", k))]
                for k, (a, b) in enumerate(self.pairs)
            ]
        )
        return HingeCollision(margin=self.margin, pairs=pairs, power=self.power, **self.named())


register_casadi_form(HingeCollision, _collision_casadi)
register_cost_type("collision", CollisionSpec)
