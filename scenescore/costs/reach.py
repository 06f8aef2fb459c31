"""Reach: object centres within a radius of the robot's base (torch, projection, check, CasADi, YAML)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import torch
from pydantic import Field
from torch import Tensor

from .base import ConstraintCost, Cost
from .spec import Coordinate, CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, register_casadi_form
from .terms import CostError, Violation, check_scene_names

__all__ = ["ReachLimit", "ReachSpec"]


class ReachLimit(ConstraintCost):
    """Object centres within ``radius`` of the robot's ``base`` (x, y): rows ``radius - |p - base|``, metres."""

    def __init__(
        self,
        base: Sequence[float] = (0.0, 0.0),
        radius: float = 1.0,
        objects: Sequence[str] | None = None,
        power: float = 1.0,
        name: str = "reach",
    ):
        if len(base) != 2 or not all(isinstance(x, (int, float)) for x in base):
            raise CostError(f"ReachLimit: base: expected [x, y] in metres, got {base!r}")
        if not isinstance(radius, (int, float)) or radius <= 0:
            raise CostError(f"ReachLimit: radius: expected a distance > 0 in metres, got {radius!r}")
        self.base = (float(base[0]), float(base[1]))
        self.radius = float(radius)
        self.objects = objects
        self.power = float(power)
        self.name = name

    def _on_bind(self) -> None:
        b = self.binding
        if self.objects is None:
            self._idx = [int(i) for i in np.flatnonzero(b.movable)]
        else:
            self._idx = check_scene_names(b.scene, list(self.objects), f"ReachLimit {self.name!r}: objects")
        self._idx_t = torch.tensor(self._idx, dtype=torch.long, device=b.device)

    def constraints(self, poses: Tensor) -> Tensor:
        d = poses[:, self._idx_t, :2] - torch.tensor(self.base, dtype=poses.dtype, device=poses.device)
        return self.radius - torch.sqrt((d * d).sum(-1) + 1e-20)

    def labels(self) -> list[str]:
        names = self.binding.scene.names
        return [f"{names[i]}: within {self.radius:g} m of {list(self.base)}" for i in self._idx]

    def support(self) -> list[tuple[int, ...]]:
        return [(i,) for i in self._idx]

    @property
    def objects_index(self) -> list[int]:
        """Indices of the objects that must be within reach."""
        return list(self._idx)

    def check(self, poses: np.ndarray, tol: float) -> list[Violation]:
        """Exact: each centre's distance from the base against the radius."""
        names = self.binding.scene.names
        out = []
        for i in self._idx:
            v = float(np.hypot(*(np.asarray(poses[i][:2], dtype=float) - np.array(self.base))) - self.radius)
            if v > tol:
                out.append(Violation(self.name, names[i], v, f"{names[i]} out of reach by {v * 1000:.2f} mm"))
        return out

    def project(self, poses: Tensor, movable: Tensor) -> Tensor:
        """Pull centres that are out of reach radially back onto the reach circle."""
        if not self._idx:
            return poses
        base = torch.tensor(self.base, dtype=poses.dtype, device=poses.device)
        p = poses[:, self._idx_t, :2]
        d = p - base
        r = torch.sqrt((d * d).sum(-1, keepdim=True) + 1e-20)
        q = torch.where(r > self.radius, base + d * (self.radius / r), p)
        out = poses.clone()
        sel = movable.reshape(-1, poses.shape[1]).expand(poses.shape[0], -1)[:, self._idx_t, None]
        out[:, self._idx_t, :2] = torch.where(sel, q, p)
        return out


def _reach_casadi(term: ReachLimit, weight: float, nlp: SymbolicProblem) -> None:
    """``|p - base|^2 <= radius^2`` per object."""
    bx, by = term.base
    rows = [(nlp.poses[i, 0] - bx) ** 2 + (nlp.poses[i, 1] - by) ** 2 for i in term.objects_index]
    if rows:
        nlp.add_rows(rows, -np.inf, term.radius**2)


class ReachSpec(CostSpec):
    """``{type: reach, weight, base: [x, y], radius, objects, name}``."""

    type: Literal["reach"]
    base: tuple[Coordinate, Coordinate]
    radius: float = Field(gt=0, allow_inf_nan=False)
    objects: list[str] | None = None

    def build(self, ctx: SpecContext) -> Cost:
        objs = ctx.objects(self.objects, ("objects",))
        return ReachLimit(base=self.base, radius=self.radius, objects=objs, **self.named())


register_casadi_form(ReachLimit, _reach_casadi)
register_cost_type("reach", ReachSpec)
