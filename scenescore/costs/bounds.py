"""Bounds: moving objects inside a rectangle (torch, projection, exact check, CasADi, YAML)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import torch
from torch import Tensor

from ..geometry.exact import footprint_extent
from ..geometry.footprints import support_extent
from .base import ConstraintCost, Cost
from .spec import CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, register_casadi_form
from .terms import CostError, Violation, check_scene_names

__all__ = ["Bounds", "BoundsSpec"]


class Bounds(ConstraintCost):
    """Keep moving objects inside ``[lo, hi]`` (default: the scene's bounds, the table or the room).

    ``footprint=True``: the whole footprint must be inside; ``False``: only the centre.
    Four rows per object (``x - lo``, ``y - lo``, ``hi - x``, ``hi - y`` of its extent), metres.
    """

    def __init__(
        self,
        lo: Sequence[float] | None = None,
        hi: Sequence[float] | None = None,
        footprint: bool = True,
        objects: Sequence[str] | None = None,
        power: float = 1.0,
        name: str = "bounds",
    ):
        for key, v in (("lo", lo), ("hi", hi)):
            if v is not None and (len(v) != 2 or not all(isinstance(x, (int, float)) for x in v)):
                raise CostError(f"Bounds: {key}: expected [x, y] in metres, got {v!r}")
        self.lo, self.hi = lo, hi
        self.footprint = bool(footprint)
        self.objects = objects
        self.power = float(power)
        self.name = name

    def _on_bind(self) -> None:
        b = self.binding
        lo = b.scene.bounds[0] if self.lo is None else self.lo
        hi = b.scene.bounds[1] if self.hi is None else self.hi
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            raise CostError(f"Bounds {self.name!r}: expected lo < hi on both axes, got lo={lo}, hi={hi}")
        self._lo = torch.tensor(lo, dtype=torch.float64, device=b.device)
        self._hi = torch.tensor(hi, dtype=torch.float64, device=b.device)
        if self.objects is None:
            self._idx = [int(i) for i in np.flatnonzero(b.movable)]
        else:
            self._idx = check_scene_names(b.scene, list(self.objects), f"Bounds {self.name!r}: objects")
        self._idx_t = torch.tensor(self._idx, dtype=torch.long, device=b.device)

    def _extent(self, poses: Tensor) -> tuple[Tensor, Tensor]:
        if self.footprint:
            mn, mx = support_extent(poses, self.binding.footprints)
            return mn[:, self._idx_t], mx[:, self._idx_t]
        p = poses[:, self._idx_t, :2]
        return p, p

    def constraints(self, poses: Tensor) -> Tensor:
        mn, mx = self._extent(poses)  # (B, M, 2)
        lo, hi = self._lo.to(poses.dtype), self._hi.to(poses.dtype)
        return torch.cat([mn - lo, hi - mx], dim=-1).flatten(1)  # (B, 4M): per object x-lo, y-lo, hi-x, hi-y

    def labels(self) -> list[str]:
        names = self.binding.scene.names
        lo, hi = self._lo.tolist(), self._hi.tolist()
        out = []
        for i in self._idx:
            out += [
                f"{names[i]}: x >= {lo[0]:g}",
                f"{names[i]}: y >= {lo[1]:g}",
                f"{names[i]}: x <= {hi[0]:g}",
                f"{names[i]}: y <= {hi[1]:g}",
            ]
        return out

    def support(self) -> list[tuple[int, ...]]:
        return [(i,) for i in self._idx for _ in range(4)]

    @property
    def limits(self) -> tuple[list[float], list[float]]:
        """The bound scene's ``([x_lo, y_lo], [x_hi, y_hi])`` this term holds objects in."""
        return self._lo.tolist(), self._hi.tolist()

    @property
    def objects_index(self) -> list[int]:
        """Indices of the objects this term holds inside."""
        return list(self._idx)

    def check(self, poses: np.ndarray, tol: float) -> list[Violation]:
        """Exact (shapely): each object's extent (footprint or centre) against the limits."""
        objs = self.binding.scene.objects
        lo, hi = (np.asarray(v) for v in self.limits)
        out = []
        for i in self._idx:
            if self.footprint:
                x0, y0, x1, y1 = footprint_extent(objs[i], poses[i])
                mn, mx = np.array([x0, y0]), np.array([x1, y1])
            else:
                mn = mx = np.asarray(poses[i][:2], dtype=float)
            v = float(max(np.max(lo - mn), np.max(mx - hi), 0.0))
            if v > tol:
                name = objs[i].name
                out.append(Violation(self.name, name, v, f"{name} out of bounds by {v * 1000:.2f} mm"))
        return out

    def project(self, poses: Tensor, movable: Tensor) -> Tensor:
        """Shift each moving object's centre so its extent (at its current angle) lies inside the bounds."""
        if not self._idx:
            return poses
        mn, mx = self._extent(poses)
        lo, hi = self._lo.to(poses.dtype), self._hi.to(poses.dtype)
        shift = torch.relu(lo - mn) - torch.relu(
            mx - hi
        )  # (B, M, 2); objects larger than the bounds: centred
        too_big = (mx - mn) > (hi - lo)
        centre = (lo + hi) / 2 - (mn + mx) / 2
        shift = torch.where(too_big, centre, shift)
        out = poses.clone()
        sel = movable.reshape(-1, poses.shape[1]).expand(poses.shape[0], -1)[:, self._idx_t, None]
        out[:, self._idx_t, :2] = torch.where(
            sel, poses[:, self._idx_t, :2] + shift, poses[:, self._idx_t, :2]
        )
        return out


def _bounds_casadi(term: Bounds, weight: float, nlp: SymbolicProblem) -> None:
    """Every footprint vertex (grown by the radius) inside the limits, or the centre (``footprint: false``)."""
    lo, hi = term.limits
    for i in term.objects_index:
        if term.footprint:
            verts, r = nlp.footprint_vertices(i)
        else:
            verts, r = [(nlp.poses[i, 0], nlp.poses[i, 1])], 0.0
        for px, py in verts:
            nlp.add_rows([px, py], [lo[0] + r, lo[1] + r], [hi[0] - r, hi[1] - r])


class BoundsSpec(CostSpec):
    """``{type: bounds, weight, lo: [x, y], hi: [x, y], footprint, objects, name}`` (default: the scene's)."""

    type: Literal["bounds"]
    lo: tuple[float, float] | None = None
    hi: tuple[float, float] | None = None
    footprint: bool = True
    objects: list[str] | None = None

    def build(self, ctx: SpecContext) -> Cost:
        objs = ctx.objects(self.objects, ("objects",))
        return Bounds(lo=self.lo, hi=self.hi, footprint=self.footprint, objects=objs, **self.named())


register_casadi_form(Bounds, _bounds_casadi)
register_cost_type("bounds", BoundsSpec)
