"""Effort: what it costs a robot to move objects from where they are now (torch, CasADi, YAML).

Every term measures each object's move from its *reference* pose, by default the pose it has in the
bound scene (the current state). One object's move is a length in metres::

    d_i^2 = |p_i - p0_i|^2 + rho_i^2 * 2 (1 - cos(theta_i - theta0_i))

where ``rho_i`` is half the object's longest side, so that the heading part is the chord its tip
travels (none for round objects, whose heading means nothing). Each object has a weight (heavy or
fragile objects cost more; default 1).

- :class:`Displacement`: robust and sparse, ``sum_i w_i * delta * (sqrt(1 + d_i^2 / delta^2) - 1)``
  (pseudo-Huber): quadratic within ``delta`` of the reference, then linear, so a few long moves cost
  what their length is and objects already in a good place are not dragged along.
- :class:`MoveCount`: a smooth count of moved objects, ``sum_i w_i * d_i^2 / (d_i^2 + sigma^2)``.
- :class:`Anchor`: objects the user says must stay, pulled quadratically to their reference
  (``|p - p0|^2 + theta_weight * (1 - cos(theta - theta0))``, as :class:`~.target.PoseTarget`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Literal

import casadi as ca
import numpy as np
import torch
from pydantic import Field
from torch import Tensor

from .base import Cost
from .spec import CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, objective_by_torch, register_casadi_form
from .terms import CostError, check_scene_names

__all__ = [
    "EffortTerm",
    "Displacement",
    "MoveCount",
    "Anchor",
    "DisplacementSpec",
    "MoveCountSpec",
    "AnchorSpec",
    "tip_radius",
]


def tip_radius(obj: Any) -> float:
    """Half the longest side of ``obj``'s footprint (how far its tip travels per radian), 0 when round."""
    return 0.0 if obj.round else 0.5 * max(obj.size)


class EffortTerm(Cost):
    """Base of the effort terms: which objects count, their reference poses and weights, and ``d_i^2``.

    ``objects``: the names that count (default: every moving object with a known pose); ``weights``:
    ``{name: weight >= 0}`` (default 1); ``reference``: ``{name: [x, y, theta]}`` (default: each
    object's pose in the bound scene).
    """

    needs_scene = True
    kind = "effort"

    def __init__(
        self,
        objects: Sequence[str] | None = None,
        weights: Mapping[str, float] | None = None,
        reference: Mapping[str, Sequence[float]] | None = None,
        name: str = "effort",
    ):
        label = f"{type(self).__name__} {name!r}"
        if objects is not None and (isinstance(objects, str) or not all(isinstance(o, str) for o in objects)):
            raise CostError(f"{label}: objects: expected a list of object names, got {objects!r}")
        for k, w in (weights or {}).items():
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w < 0:
                raise CostError(f"{label}: weights: {k!r}: expected a finite number >= 0, got {w!r}")
        for k, p in (reference or {}).items():
            if len(p) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in p):
                raise CostError(f"{label}: reference: {k!r}: expected [x, y, theta], got {p!r}")
        self.objects = None if objects is None else list(objects)
        self.weights = {k: float(v) for k, v in (weights or {}).items()}
        self.reference = {k: tuple(float(v) for v in p) for k, p in (reference or {}).items()}
        self.name = name

    def _on_bind(self) -> None:
        b = self.binding
        scene = b.scene
        label = f"{type(self).__name__} {self.name!r}"
        check_scene_names(scene, list(self.weights), f"{label}: weights")
        check_scene_names(scene, list(self.reference), f"{label}: reference")
        if self.objects is None:
            idx = [
                int(i)
                for i in np.flatnonzero(b.movable)
                if scene.objects[i].pose is not None or scene.objects[i].name in self.reference
            ]
        else:
            idx = check_scene_names(scene, self.objects, f"{label}: objects")
        ref: list[tuple[float, ...]] = []
        for i in idx:
            o = scene.objects[i]
            pose = self.reference.get(o.name, o.pose)
            if pose is None:
                raise CostError(f"{label}: object {o.name!r} has no pose to measure its move from")
            ref.append(pose)
        self._idx = [int(i) for i in idx]
        dev = b.device
        self._idx_t = torch.tensor(self._idx, dtype=torch.long, device=dev)
        self._ref = torch.tensor(ref, dtype=torch.float64, device=dev).reshape(-1, 3)
        self._rho = torch.tensor(
            [tip_radius(scene.objects[i]) for i in self._idx], dtype=torch.float64, device=dev
        )
        self._w = torch.tensor(
            [self.weights.get(scene.objects[i].name, 1.0) for i in self._idx], dtype=torch.float64, device=dev
        )

    @property
    def objects_index(self) -> list[int]:
        """Indices of the objects this term counts."""
        self.binding  # noqa: B018 - raises a clear error when unbound
        return list(self._idx)

    def reference_poses(self) -> np.ndarray:
        """The reference poses ``(M, 3)`` of :attr:`objects_index`."""
        self.binding  # noqa: B018
        return self._ref.cpu().numpy().copy()

    def object_weights(self) -> np.ndarray:
        """Each counted object's weight ``(M,)``."""
        self.binding  # noqa: B018
        return self._w.cpu().numpy().copy()

    def tip_radii(self) -> np.ndarray:
        """Each counted object's ``rho`` ``(M,)`` (0 for round objects)."""
        self.binding  # noqa: B018
        return self._rho.cpu().numpy().copy()

    def squared_moves(self, poses: Tensor) -> Tensor:
        """``d_i^2`` per counted object ``(B, M)``, metres squared."""
        p = poses[:, self._idx_t]
        ref = self._ref.to(poses.dtype)
        dxy = p[..., :2] - ref[:, :2]
        turn = 2.0 * (1.0 - torch.cos(p[..., 2] - ref[:, 2]))
        return (dxy * dxy).sum(-1) + self._rho.to(poses.dtype) ** 2 * turn

    def moves(self, poses: np.ndarray) -> np.ndarray:
        """``d_i`` per counted object at one pose set ``(N, 3)``: ``(M,)`` metres."""
        x = torch.as_tensor(np.asarray(poses, dtype=np.float64), device=self.binding.device).reshape(1, -1, 3)
        with torch.no_grad():
            return torch.sqrt(self.squared_moves(x)[0]).cpu().numpy()

    def penalty(self, d2: Tensor) -> Tensor:  # pragma: no cover - abstract
        """Each object's cost from its ``d_i^2`` (same shape)."""
        raise NotImplementedError

    def evaluate(self, poses: Tensor) -> Tensor:
        if not self._idx:
            return poses.new_zeros(poses.shape[0])
        return (self._w.to(poses.dtype) * self.penalty(self.squared_moves(poses))).sum(-1)

    def symbolic_moves(self, nlp: SymbolicProblem) -> list[Any]:
        """``d_i^2`` of every counted object as CasADi expressions."""
        out = []
        for k, i in enumerate(self._idx):
            x0, y0, t0 = (float(v) for v in self._ref[k])
            p = nlp.poses[i, :]
            rho = float(self._rho[k])
            out.append((p[0] - x0) ** 2 + (p[1] - y0) ** 2 + rho**2 * 2 * (1 - ca.cos(p[2] - t0)))
        return out


class Displacement(EffortTerm):
    """Robust displacement from the current poses: ``sum_i w_i * delta * (sqrt(1 + d_i^2 / delta^2) - 1)``.

    About ``w_i * d_i`` (metres) for moves longer than ``delta``, quadratic below it (smooth at rest).
    """

    def __init__(
        self,
        delta: float = 0.01,
        objects: Sequence[str] | None = None,
        weights: Mapping[str, float] | None = None,
        reference: Mapping[str, Sequence[float]] | None = None,
        name: str = "displacement",
    ):
        if isinstance(delta, bool) or not isinstance(delta, (int, float)) or not (0 < delta < math.inf):
            raise CostError(f"Displacement: delta: expected a length > 0 in metres, got {delta!r}")
        super().__init__(objects, weights, reference, name)
        self.delta = float(delta)

    def penalty(self, d2: Tensor) -> Tensor:
        return self.delta * (torch.sqrt(1.0 + d2 / self.delta**2) - 1.0)


class MoveCount(EffortTerm):
    """A smooth count of moved objects: ``sum_i w_i * d_i^2 / (d_i^2 + sigma^2)`` (each term 0 at rest, to 1)."""

    def __init__(
        self,
        sigma: float = 0.02,
        objects: Sequence[str] | None = None,
        weights: Mapping[str, float] | None = None,
        reference: Mapping[str, Sequence[float]] | None = None,
        name: str = "moves",
    ):
        if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not (0 < sigma < math.inf):
            raise CostError(f"MoveCount: sigma: expected a length > 0 in metres, got {sigma!r}")
        super().__init__(objects, weights, reference, name)
        self.sigma = float(sigma)

    def penalty(self, d2: Tensor) -> Tensor:
        return d2 / (d2 + self.sigma**2)


class Anchor(Cost):
    """Objects that must stay, pulled to their reference pose (default: where they are now):
    ``sum |p - p0|^2 + theta_weight * (1 - cos(theta - theta0))``, as :class:`~.target.PoseTarget`."""

    needs_scene = True

    def __init__(
        self,
        objects: Sequence[str],
        theta_weight: float = 0.01,
        reference: Mapping[str, Sequence[float]] | None = None,
        name: str = "anchor",
    ):
        if isinstance(objects, str) or not objects or not all(isinstance(o, str) for o in objects):
            raise CostError(f"Anchor: objects: expected a non-empty list of object names, got {objects!r}")
        if isinstance(theta_weight, bool) or not isinstance(theta_weight, (int, float)) or theta_weight < 0:
            raise CostError(f"Anchor: theta_weight: expected a number >= 0, got {theta_weight!r}")
        self._inner = Displacement(objects=objects, reference=reference, name=name)  # checks the rest
        self.objects = list(objects)
        self.theta_weight = float(theta_weight)
        self.name = name

    def _on_bind(self) -> None:
        b = self.binding
        self._inner = self._inner.bind(b.scene, b.movable, b.device)  # type: ignore[assignment]
        self._idx_t = torch.tensor(self._inner.objects_index, dtype=torch.long, device=b.device)
        self._ref = torch.as_tensor(self._inner.reference_poses(), device=b.device)

    @property
    def objects_index(self) -> list[int]:
        return self._inner.objects_index

    def reference_poses(self) -> np.ndarray:
        return self._inner.reference_poses()

    def evaluate(self, poses: Tensor) -> Tensor:
        p = poses[:, self._idx_t]
        ref = self._ref.to(poses.dtype)
        d = p[..., :2] - ref[:, :2]
        turn = 1.0 - torch.cos(p[..., 2] - ref[:, 2])
        return ((d * d).sum(-1) + self.theta_weight * turn).sum(-1)


def _effort_casadi(term: EffortTerm, weight: float, nlp: SymbolicProblem) -> None:
    d2 = term.symbolic_moves(nlp)
    if not d2:
        return
    w = term.object_weights()
    if isinstance(term, Displacement):
        parts = [term.delta * (ca.sqrt(1 + v / term.delta**2) - 1) for v in d2]
    elif isinstance(term, MoveCount):
        parts = [v / (v + term.sigma**2) for v in d2]
    else:  # a user's subclass: its torch form through a callback
        objective_by_torch(term, weight, nlp)
        return
    nlp.add_objective(weight * sum(float(wk) * pk for wk, pk in zip(w, parts)))


def _anchor_casadi(term: Anchor, weight: float, nlp: SymbolicProblem) -> None:
    f: Any = 0
    for i, (x0, y0, t0) in zip(term.objects_index, term.reference_poses()):
        p = nlp.poses[i, :]
        f = f + (p[0] - x0) ** 2 + (p[1] - y0) ** 2 + term.theta_weight * (1 - ca.cos(p[2] - t0))
    nlp.add_objective(weight * f)


class _EffortSpec(CostSpec):
    objects: list[str] | None = None
    weights: dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]] | None = None

    def _common(self, ctx: SpecContext) -> dict[str, Any]:
        for n in self.weights or {}:
            ctx.object(n, ("weights", n))
        return {"objects": ctx.objects(self.objects, ("objects",)), "weights": self.weights, **self.named()}


class DisplacementSpec(_EffortSpec):
    """``{type: displacement, weight, delta, objects, weights: {name: w}, name}``: moves from the scene's poses."""

    type: Literal["displacement"]
    delta: float = Field(0.01, gt=0, allow_inf_nan=False)

    def build(self, ctx: SpecContext) -> Cost:
        return Displacement(delta=self.delta, **self._common(ctx))


class MoveCountSpec(_EffortSpec):
    """``{type: move_count, weight, sigma, objects, weights: {name: w}, name}``: a smooth count of moved objects."""

    type: Literal["move_count"]
    sigma: float = Field(0.02, gt=0, allow_inf_nan=False)

    def build(self, ctx: SpecContext) -> Cost:
        return MoveCount(sigma=self.sigma, **self._common(ctx))


class AnchorSpec(CostSpec):
    """``{type: anchor, weight, objects: [names that stay], theta_weight, name}``."""

    type: Literal["anchor"]
    objects: list[str] = Field(min_length=1)
    theta_weight: float = Field(0.01, ge=0, allow_inf_nan=False)

    def build(self, ctx: SpecContext) -> Cost:
        objs = ctx.objects(self.objects, ("objects",)) or []
        return Anchor(objs, theta_weight=self.theta_weight, **self.named())


register_casadi_form(EffortTerm, _effort_casadi)
register_casadi_form(Anchor, _anchor_casadi)
register_cost_type("displacement", DisplacementSpec)
register_cost_type("move_count", MoveCountSpec)
register_cost_type("anchor", AnchorSpec)
