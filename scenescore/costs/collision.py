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

from ..exact import overlap_depth_exceeds, shapely_core
from ..geometry import signed_distance, signed_distance_placed
from ..memory import chunk_rows, return_freed_memory
from .base import (
    ConstraintCost,
    Cost,
    CostError,
    CostSpec,
    SpecContext,
    Violation,
    check_scene_names,
    register_cost_type,
)
from .symbolic import SymbolicProblem, register_casadi_form

__all__ = ["HingeCollision", "CollisionSpec"]

# bytes one pair of one pose set takes while its signed distance is computed (float64, with the
# footprints' vertices and the intermediates; measured about 2 KB)
PAIR_BYTES = 4096


class HingeCollision(ConstraintCost):
    """Zero when footprints are more than ``margin`` apart, growing with penetration: ``relu(margin - sd) ** power``.

    ``pairs``: ``"all"`` (every pair in which at least one object moves) or a list of ``[name, name]``.
    Rows ``g = sd - margin`` per pair, in metres; see :mod:`scenescore.costs.geometry` for ``sd``.
    """

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

    def signed_distance(self, poses: Tensor) -> Tensor:
        """Signed distance per pair ``(B, P)``; many pose sets (candidates being screened) go in chunks of
        rows, with the same numbers."""
        poses = self._check(poses)
        if not self._pairs:
            return poses.new_zeros(poses.shape[0], 0)
        fp, b = self.binding.footprints, poses.shape[0]
        rows = chunk_rows(
            PAIR_BYTES * len(self._pairs),
            f"collision {self.name!r}: one pose set of {len(self._pairs)} pairs",
            "the number of objects or pairs",
        )
        if b <= rows:
            return signed_distance(poses, fp, self._pi, self._pj)
        return_freed_memory()
        return torch.cat(
            [signed_distance(poses[a : a + rows], fp, self._pi, self._pj) for a in range(0, b, rows)]
        )

    def constraints(self, poses: Tensor) -> Tensor:
        return self.signed_distance(poses) - self.margin

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
            g = signed_distance_placed(pa, pb, self.binding.footprints, self._pi, self._pj) - self.margin
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
        """Exact (shapely): pairs overlapping by more than ``tol``, or closer than ``margin - tol``."""
        objs = self.binding.scene.objects
        geo = [shapely_core(o, p) for o, p in zip(objs, poses)]
        out = []
        for k, (i, j) in enumerate(self._pairs):
            (ca_, ra), (cb, rb) = geo[i], geo[j]
            a, b = objs[i].name, objs[j].name
            if overlap_depth_exceeds((ca_, ra), (cb, rb), tol):
                x = torch.as_tensor(np.asarray(poses, dtype=np.float64), device=self.binding.device)[None]
                d = float(self.signed_distance(x)[0, k])
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
