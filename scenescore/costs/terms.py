"""The cost terms: the learned energy, hinge collision, bounds, reach, a pose target, any torch function."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import Tensor

from .base import ConstraintCost, Cost, CostError, check_scene_names
from .geometry import signed_distance, signed_distance_placed, support_extent

__all__ = ["LearnedEnergy", "HingeCollision", "Bounds", "ReachLimit", "PoseTarget", "CostFn"]


class LearnedEnergy(Cost):
    """The trained energy ``E(poses | scene)``, conditioned on the bound scene's objects.

    ``objects``: the names the energy sees (default: all). Objects left out, such as clutter of a
    class the model never saw, are invisible to it and only enter through the other costs.
    """

    needs_scene = True

    def __init__(self, model, name: str = "energy", objects: Sequence[str] | None = None):
        if not hasattr(model, "energy_fn"):
            raise CostError(
                f"LearnedEnergy: expected a ScoreModel (scenescore.models.load), got {type(model).__name__}"
            )
        if objects is not None and (isinstance(objects, str) or len(objects) == 0):
            raise CostError(
                f"LearnedEnergy: objects: expected a non-empty list of object names, got {objects!r}"
            )
        self.model = model
        self.name = name
        self.objects = None if objects is None else list(objects)
        self._fn: Callable[[Tensor], Tensor] | None = None
        self._idx: Tensor | None = None
        self.visible_scene = None

    @property
    def visible(self) -> list[int]:
        """Indices of the bound scene's objects that the energy sees."""
        n = len(self.binding.scene)
        return list(range(n)) if self._idx is None else [int(i) for i in self._idx]

    def _on_bind(self) -> None:
        scene = self.binding.scene
        self._idx = None
        if self.objects is not None:
            idx = check_scene_names(scene, self.objects, f"LearnedEnergy {self.name!r}: objects")
            scene = type(scene)([scene.objects[i] for i in idx], scene.bounds, meta=scene.meta)
            self._idx = torch.tensor(idx, dtype=torch.long)
        self.visible_scene = scene  # the scene the energy is conditioned on
        with torch.no_grad():
            self._fn = self.model.energy_fn(scene)

    def evaluate(self, poses: Tensor) -> Tensor:
        dtype = self.model.dtype
        if self._fn is None:
            self.binding  # noqa: B018 - raises
        if self._idx is not None:
            poses = poses[:, self._idx]
        return self._fn(poses.to(dtype)).to(poses.dtype)  # type: ignore[misc]


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
        self._pi = torch.tensor([p[0] for p in pairs], dtype=torch.long)
        self._pj = torch.tensor([p[1] for p in pairs], dtype=torch.long)

    def signed_distance(self, poses: Tensor) -> Tensor:
        """Signed distance per pair ``(B, P)``."""
        poses = self._check(poses)
        if not self._pairs:
            return poses.new_zeros(poses.shape[0], 0)
        return signed_distance(poses, self.binding.footprints, self._pi, self._pj)

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
        rows = torch.arange(p)
        jac[:, rows, self._pi] = ga
        jac[:, rows, self._pj] = gb
        return g.detach(), jac

    def labels(self) -> list[str]:
        names = self.binding.scene.names
        return [f"{names[i]} / {names[j]}" for i, j in self._pairs]

    def support(self) -> list[tuple[int, ...]]:
        return list(self._pairs)


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
        self._lo = torch.tensor(lo, dtype=torch.float64)
        self._hi = torch.tensor(hi, dtype=torch.float64)
        if self.objects is None:
            self._idx = [int(i) for i in np.flatnonzero(b.movable)]
        else:
            self._idx = check_scene_names(b.scene, list(self.objects), f"Bounds {self.name!r}: objects")
        self._idx_t = torch.tensor(self._idx, dtype=torch.long)

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
        self._idx_t = torch.tensor(self._idx, dtype=torch.long)

    def constraints(self, poses: Tensor) -> Tensor:
        d = poses[:, self._idx_t, :2] - torch.tensor(self.base, dtype=poses.dtype)
        return self.radius - torch.sqrt((d * d).sum(-1) + 1e-20)

    def labels(self) -> list[str]:
        names = self.binding.scene.names
        return [f"{names[i]}: within {self.radius:g} m of {list(self.base)}" for i in self._idx]

    def support(self) -> list[tuple[int, ...]]:
        return [(i,) for i in self._idx]

    def project(self, poses: Tensor, movable: Tensor) -> Tensor:
        """Pull centres that are out of reach radially back onto the reach circle."""
        if not self._idx:
            return poses
        base = torch.tensor(self.base, dtype=poses.dtype)
        p = poses[:, self._idx_t, :2]
        d = p - base
        r = torch.sqrt((d * d).sum(-1, keepdim=True) + 1e-20)
        q = torch.where(r > self.radius, base + d * (self.radius / r), p)
        out = poses.clone()
        sel = movable.reshape(-1, poses.shape[1]).expand(poses.shape[0], -1)[:, self._idx_t, None]
        out[:, self._idx_t, :2] = torch.where(sel, q, p)
        return out


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
        if len(xy) != 2:
            raise CostError(f"PoseTarget: xy: expected [x, y] in metres, got {xy!r}")
        self.obj = obj
        self.xy = (float(xy[0]), float(xy[1]))
        self.theta = None if theta is None else float(theta)
        self.theta_weight = float(theta_weight)
        self.name = name or f"target_{obj}"

    def _on_bind(self) -> None:
        (self._i,) = check_scene_names(self.binding.scene, [self.obj], f"PoseTarget {self.name!r}: object")

    def evaluate(self, poses: Tensor) -> Tensor:
        p = poses[:, self._i]
        d = p[:, :2] - torch.tensor(self.xy, dtype=poses.dtype)
        out = (d * d).sum(-1)
        th = 0.0 if self.theta is None else self.theta
        return out + self.theta_weight * (1 - torch.cos(p[:, 2] - th))


class CostFn(Cost):
    """Any user-written torch function of the poses: ``fn(poses (B, N, 3)) -> (B,)``, differentiable."""

    def __init__(self, fn: Callable[[Tensor], Tensor], name: str | None = None):
        if not callable(fn):
            raise CostError(f"CostFn: expected a callable poses -> (B,), got {type(fn).__name__}")
        self.fn = fn
        self.name = name or getattr(fn, "__name__", "fn")

    def evaluate(self, poses: Tensor) -> Tensor:
        out = self.fn(poses)
        if not isinstance(out, Tensor) or out.shape != (poses.shape[0],):
            got = tuple(out.shape) if isinstance(out, Tensor) else type(out).__name__
            raise CostError(
                f"CostFn {self.name!r}: expected the function to return shape ({poses.shape[0]},), got {got}"
            )
        return out
