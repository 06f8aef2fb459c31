"""Problems: a scene, a cost bound to it, and which objects move; the exact feasibility check.

``Problem(scene, cost, movable=["mug"])`` binds the cost to the scene. Objects with ``pose: null`` are
always movable (the first solver stage initialises them); fixed objects never are. With ``movable=None``
the unknown objects move if there are any, else every object that is not fixed.

A problem lives on one device (``problem.device``): the device of the learned energy's model by default,
or the ``device`` given; its cost is bound there and its solvers' particles are drawn there.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from ..costs import Cost, Sum, Violation, as_sum, guide
from ..geometry.poses import uniform_init
from ..runtime import resolve_device
from ..scene.scene import Scene, SceneError, fits_bounds, wrap_angle

__all__ = ["Problem", "ProblemError", "Feasibility"]

FEASIBILITY_TOL = 1e-4  # metres: the largest violation that still counts as feasible


class ProblemError(ValueError):
    """A problem that cannot be set up: bad YAML, an unknown object, a missing file; one line for the user."""


@dataclass
class Feasibility:
    """The exact check of a pose set: every violation that each cost term's own check found."""

    feasible: bool
    violations: list[Violation] = field(default_factory=list)

    def describe(self) -> str:
        return "; ".join(v.describe() for v in self.violations) if self.violations else "feasible"

    def by_term(self) -> dict[str, list[Violation]]:
        """Violations grouped by the name of the term that found them."""
        out: dict[str, list[Violation]] = {}
        for v in self.violations:
            out.setdefault(v.term, []).append(v)
        return out


class Problem:
    """A scene, a cost bound to it, and the objects that may move; ``device``: where its tensors live
    (default: the device of the cost's learned energy, else the CPU)."""

    def __init__(
        self,
        scene: Scene,
        cost: Cost,
        movable: Sequence[str] | None = None,
        name: str = "problem",
        device: str | torch.device | None = None,
    ):
        if not isinstance(scene, Scene):
            raise ProblemError(f"Problem: expected a scenescore Scene, got {type(scene).__name__}")
        self.scene = scene
        self.name = name
        unknown = set(scene.unknown)
        if movable is None:
            names = list(scene.unknown) or [o.name for o in scene.objects if not o.fixed]
        else:
            if isinstance(movable, str):
                movable = [movable]
            names = list(movable)
            for n in names:
                try:
                    scene.index(n)
                except SceneError:
                    raise ProblemError(f"movable: no object named {n!r}; objects are {scene.names}") from None
            names += [n for n in scene.unknown if n not in names]
        for n in names:
            if scene[n].fixed:
                raise ProblemError(f'movable: object {n!r} is fixed ("fixed": true) and can never move')
        if not names:
            raise ProblemError(
                "Problem: no object may move (every object is fixed or has a known pose and none is listed)"
            )
        for n in names:
            if not fits_bounds(scene[n], scene.bounds):
                (x0, y0), (x1, y1) = scene.bounds
                raise ProblemError(
                    f"movable: object {n!r} ({scene[n].size[0]:g} x {scene[n].size[1]:g} m) does not fit inside "
                    f"the scene's bounds ({x1 - x0:g} x {y1 - y0:g} m) at any heading; nowhere to place it"
                )
        self.movable_mask = np.array([o.name in names for o in scene.objects])
        self.known = np.array([o.name not in unknown for o in scene.objects])
        own = as_sum(cost).model_device()
        self.device = resolve_device(device) if device is not None else own or torch.device("cpu")
        self.cost: Sum = as_sum(cost).bind(scene, self.movable_mask, device=self.device)

    # -- shapes and bounds -----------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.scene)

    @property
    def movable(self) -> list[str]:
        return [o.name for o, m in zip(self.scene.objects, self.movable_mask) if m]

    @property
    def lo(self) -> Tensor:
        return torch.tensor(self.scene.bounds[0], dtype=torch.float64, device=self.device)

    @property
    def hi(self) -> Tensor:
        return torch.tensor(self.scene.bounds[1], dtype=torch.float64, device=self.device)

    def base_poses(self) -> Tensor:
        """The scene's poses ``(N, 3)`` (unknown ones 0), float64."""
        return torch.tensor(self.scene.poses(), dtype=torch.float64, device=self.device)

    def initial(
        self, particles: int, generator: torch.Generator, keep_known: bool = False, proposals: float = 0.0
    ) -> Tensor:
        """Initial particles ``(B, N, 3)``: moving objects uniform in the bounds (``keep_known``: only unknown
        ones), drawn by ``generator`` (best on :attr:`device`; one elsewhere draws there and is copied).
        ``proposals``: the fraction of the particles (the first ones) whose moving objects the cost's
        guiding terms propose instead where they can (:func:`scenescore.costs.guide.propose`), centres
        kept inside the bounds."""
        x = self.base_poses()[None].repeat(particles, 1, 1)
        u = uniform_init((particles, self.n), self.lo, self.hi, generator, dtype=torch.float64)
        draw = self.movable_mask & (~self.known if keep_known else True)
        mask = torch.as_tensor(draw, device=self.device)[None, :, None]
        x = torch.where(mask, u, x)
        k = round(particles * proposals)
        if k > 0:
            y = guide.propose(self.cost, x[:k], generator)
            if y is not None:
                x = torch.cat([torch.where(mask, self.inside(y), x[:k]), x[k:]])
        return x

    def inside(self, poses: Tensor) -> Tensor:
        """``poses (..., 3)`` with their centres clamped into the bounds and their headings wrapped: where
        a pose proposed beside another object is kept."""
        xy = torch.minimum(torch.maximum(poses[..., :2], self.lo), self.hi)
        return torch.cat([xy, wrap_angle(poses[..., 2:])], dim=-1)

    def full(self, poses: Tensor | np.ndarray) -> Tensor:
        """Poses as ``(B, N, 3)`` float64 on :attr:`device`; a single ``(N, 3)`` pose set is given a batch of 1.
        Checks shapes."""
        x = torch.as_tensor(
            np.asarray(poses) if not isinstance(poses, Tensor) else poses,
            dtype=torch.float64,
            device=self.device,
        )
        if x.dim() == 2:
            x = x[None]
        if x.dim() != 3 or x.shape[1:] != (self.n, 3):
            raise ProblemError(
                f"init: expected poses of shape (N, 3) or (B, N, 3) with N = {self.n}, got {tuple(x.shape)}"
            )
        if not torch.isfinite(x).all():
            raise ProblemError("init: poses contain NaN or inf")
        return x

    # -- evaluation --------------------------------------------------------------------------------
    def evaluate(self, poses: Tensor) -> Tensor:
        """The total cost ``(B,)``."""
        return self.cost(self.full(poses))

    def violation(self, poses: Tensor) -> Tensor:
        """The largest constraint violation per row ``(B,)`` (0 when the cost has no constraint)."""
        v = self.cost.violation(self.full(poses))
        return (
            torch.zeros(self.full(poses).shape[0], dtype=torch.float64, device=self.device)
            if v is None
            else v
        )

    def doubted(self, poses: Tensor) -> Tensor:
        """Rows ``(B,)`` that a guiding term of the cost doubts (:func:`scenescore.costs.guide.doubts`);
        all False when no term has an opinion."""
        x = self.full(poses)
        with torch.no_grad():
            d = guide.doubts(self.cost, x)
        return torch.zeros(x.shape[0], dtype=torch.bool, device=self.device) if d is None else d

    def check(self, poses: np.ndarray | Tensor, tol: float = FEASIBILITY_TOL) -> Feasibility:
        """The exact check of one pose set ``(N, 3)``: each cost term checks itself, within ``tol`` m."""
        p = self.full(poses)[0].detach().cpu().numpy()
        found = [v for _, c in self.cost for v in c.check(p, tol)]
        return Feasibility(not found, found)

    def __repr__(self) -> str:
        return f"Problem({self.name!r}, {self.n} objects, movable={self.movable}, cost={self.cost!r})"
