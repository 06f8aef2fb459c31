"""A pose target: a quadratic pull of one object toward a position (and a heading, when given)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import casadi as ca
import torch
from pydantic import Field
from torch import Tensor

from ..scene.fields import MAX_LENGTH
from .base import Cost
from .spec import Coordinate, CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, register_casadi_form
from .terms import CostError, check_scene_names

__all__ = ["PoseTarget", "TargetSpec"]


class PoseTarget(Cost):
    """A quadratic pull of one object toward a target: ``|p - xy|^2 + w_theta * (1 - cos(theta - theta*))``."""

    needs_scene = True

    def __init__(
        self,
        obj: str,
        xy: Sequence[float],
        theta: float | None = None,
        theta_weight: float = 0.01,
        name: str | None = None,
    ):
        if len(xy) != 2 or not all(
            isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= MAX_LENGTH for v in xy
        ):
            raise CostError(
                f"PoseTarget: xy: expected [x, y] in metres, finite and within +-{MAX_LENGTH:g}, got {xy!r}"
            )
        for key, v in (("theta", theta), ("theta_weight", theta_weight)):
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise CostError(f"PoseTarget: {key}: expected a finite number, got {v!r}")
        self.obj = obj
        self.xy = (float(xy[0]), float(xy[1]))
        self.theta = None if theta is None else float(theta)
        self.theta_weight = float(theta_weight)
        self.name = name or f"target_{obj}"

    def _on_bind(self) -> None:
        (self._i,) = check_scene_names(self.binding.scene, [self.obj], f"PoseTarget {self.name!r}: object")

    def evaluate(self, poses: Tensor) -> Tensor:
        p = poses[:, self._i]
        d = p[:, :2] - torch.tensor(self.xy, dtype=poses.dtype, device=poses.device)
        out = (d * d).sum(-1)
        if self.theta is None:  # no target heading: the heading is free
            return out
        return out + self.theta_weight * (1 - torch.cos(p[:, 2] - self.theta))

    @property
    def index(self) -> int:
        """The bound scene's index of the object this term pulls."""
        self.binding  # noqa: B018 - raises a clear error when unbound
        return self._i


def _target_casadi(term: PoseTarget, weight: float, nlp: SymbolicProblem) -> None:
    p = nlp.poses[term.index, :]
    f = ca.sumsqr(p[:2] - ca.DM(term.xy).T)
    if term.theta is not None:
        f = f + term.theta_weight * (1 - ca.cos(p[2] - term.theta))
    nlp.add_objective(weight * f)


class TargetSpec(CostSpec):
    """``{type: target, weight, object, xy: [x, y], theta (optional), name}``."""

    type: Literal["target"]
    object: str
    xy: tuple[Coordinate, Coordinate]
    theta: float | None = Field(None, allow_inf_nan=False)

    def build(self, ctx: SpecContext) -> Cost:
        return PoseTarget(ctx.object(self.object, ("object",)), self.xy, self.theta, **self.named())


register_casadi_form(PoseTarget, _target_casadi)
register_cost_type("target", TargetSpec)
