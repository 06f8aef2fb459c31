"""Messy scenes to tidy, and the check that judges a tidied one.

A messy case displaces ``k`` objects of a true scene (shifted by a fraction of the bounds' half-extent in
a random direction and turned, or two objects of different kinds swapped) and is kept only when it is
collision-free, inside the bounds and *rejected* by the scenario's check; :func:`accepts` is that check
(each object back within a tolerance of where the truth has it, or where the scenario's own check allows,
and the scene feasible). The tidying experiment (:mod:`scenescore.experiments.tidy`) runs the methods on
these cases.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from ..costs import Bounds, Displacement, HingeCollision
from ..problem.problem import Problem
from ..scene.scene import Scene, SceneError, wrap_angle

__all__ = ["SIZES", "CHECK_TOL", "CHECK_DEG", "MessyCase", "displaceable", "accepts", "messy_cases"]

SIZES: tuple[float, ...] = (0.15, 0.4)  # displacement, as a fraction of the bounds' smaller half-extent
CHECK_TOL = 0.08  # the check's position tolerance, as a fraction of the same half-extent
CHECK_DEG = 20.0  # and its heading tolerance (boxes modulo a half turn)

# objects a scenario's check can judge, where the scenario does not name them (``missing``)
_DISPLACEABLE: dict[str, tuple[str, ...]] = {"desk": ("mug", "pen"), "tv": ("speaker",)}


def displaceable(scenario: Any) -> tuple[str, ...]:
    """The categories whose objects are displaced (those the scenario's check judges)."""
    return _DISPLACEABLE.get(scenario.name, tuple(getattr(scenario, "missing", ())))


def _half(scene: Scene) -> float:
    (x0, y0), (x1, y1) = scene.bounds
    return min(x1 - x0, y1 - y0) / 2


def _feasible(scene: Scene, truth: Scene) -> bool:
    """No overlap but those the true scene has (a lamp on its nightstand), every object inside."""
    full = HingeCollision(pairs=[[a, b] for k, a in enumerate(scene.names) for b in scene.names[k + 1 :]])
    allowed = {v.label for v in full.bind(truth, truth.names).check(truth.poses(), 1e-4)}
    prob = Problem(scene, full + Bounds(), movable=[o.name for o in scene.objects if not o.fixed])
    return all(v.label in allowed for v in prob.check(scene.poses()).violations)


def _heading_ok(obj: Any, got: float, want: float) -> bool:
    turn = abs(wrap_angle(got - want))
    if obj.shape_kind == "box":
        turn = min(turn, math.pi - turn)
    return math.degrees(turn) <= CHECK_DEG


def accepts(scenario: Any, scene: Scene, truth: Scene) -> bool:
    """The scenario's check: collision-free (as the truth is) and inside the bounds, and every object it
    judges where the process would put it given the rest (the television's own ``correct``; the desk's
    pen at its distance to the right of the book)."""
    if not _feasible(scene, truth):
        return False
    if scenario.name == "tv":
        return bool(scenario.aligned(scene))
    tol = CHECK_TOL * _half(scene)
    cats = displaceable(scenario)
    symmetric = tuple(getattr(scenario, "symmetric", ()))
    for o in scene.objects:
        if o.category not in cats or o.pose is None:
            continue
        if scenario.name == "desk" and o.category == "pen":
            if not _pen_ok(scenario, scene, tol):
                return False
            continue
        try:
            want = scenario.oracle(scene, o.name)
        except SceneError:  # the rest is too disordered for the process to say where it goes (a broken grid)
            return False
        if math.hypot(o.pose[0] - want[0], o.pose[1] - want[1]) > tol:
            return False
        if o.category not in symmetric and not o.round and not _heading_ok(o, o.pose[2], want[2]):
            return False
    return True


def _pen_ok(scenario: Any, scene: Scene, tol: float) -> bool:
    book, pen = scene["book"].pose, scene["pen"].pose
    assert book is not None and pen is not None
    c, s = math.cos(book[2]), math.sin(book[2])
    dx, dy = pen[0] - book[0], pen[1] - book[1]
    u, v = c * dx + s * dy, -s * dx + c * dy
    inside = scenario.pen_min - tol <= u <= scenario.pen_max + tol and abs(v) <= tol
    return inside and _heading_ok(scene["pen"], pen[2], book[2] + math.pi / 2)


@dataclass
class MessyCase:
    """A test scene with objects displaced: the truth, the messy scene, which and how."""

    scenario: str
    truth: Scene
    messy: Scene
    displaced: list[str]
    kind: str  # "shift" or "swap"
    size: float  # the shift as a fraction of the half-extent (0 for swaps)
    seed: int = 0  # the seed of the scenario's split, the model's training and the displacement

    def to_dict(self) -> dict[str, Any]:
        """The case as JSON (a sweep's record keeps it)."""
        scenes = {"truth": self.truth.to_dict(), "messy": self.messy.to_dict()}
        return {"scenario": self.scenario, **scenes, "displaced": self.displaced, "kind": self.kind,
                "size": self.size, "seed": self.seed}  # fmt: skip

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MessyCase:
        truth, messy = Scene.from_dict(d["truth"]), Scene.from_dict(d["messy"])
        displaced = [str(n) for n in d["displaced"]]
        return cls(
            str(d["scenario"]), truth, messy, displaced, str(d["kind"]), float(d["size"]), int(d["seed"])
        )

    @property
    def putback(self) -> float:
        """The displacement of moving the displaced objects back where they were (metres)."""
        d = Displacement(objects=self.displaced).bind(self.messy)
        return float(cast(Displacement, d).moves(self.truth.poses()).sum())


def messy_cases(
    scenario: Any,
    scenes: list[Scene],
    seed: int,
    ks: tuple[int, ...] = (1, 2),
    sizes: tuple[float, ...] = SIZES,
    swaps: bool = True,
    tries: int = 200,
) -> list[MessyCase]:
    """Per test scene: ``k`` objects shifted by each size (and turned by up to 60 degrees), and one
    swap of two objects of different kinds; only messy scenes the check rejects that are feasible."""
    rng = np.random.default_rng(20_000 + seed)
    cats = displaceable(scenario)
    out = []
    for truth in scenes:
        names = [o.name for o in truth.objects if o.category in cats and not o.fixed and o.pose is not None]
        half = _half(truth)
        plans: list[tuple[str, int, float]] = [("shift", k, f) for k in ks if k <= len(names) for f in sizes]
        pairs = [
            (a, b) for i, a in enumerate(names) for b in names[i + 1 :] if truth[a].kind != truth[b].kind
        ]
        if swaps and pairs:
            plans.append(("swap", 2, 0.0))
        for kind, k, frac in plans:
            for _ in range(tries):
                x = truth.poses()
                if kind == "swap":
                    a, b = pairs[int(rng.integers(len(pairs)))]
                    chosen = [a, b]
                    ia, ib = truth.index(a), truth.index(b)
                    x[[ia, ib], :2] = x[[ib, ia], :2]
                else:
                    chosen = [str(n) for n in rng.choice(names, size=k, replace=False)]
                    for n in chosen:
                        i = truth.index(n)
                        phi = rng.uniform(-math.pi, math.pi)
                        x[i, :2] += frac * half * np.array([math.cos(phi), math.sin(phi)])
                        x[i, 2] += rng.uniform(-math.pi / 3, math.pi / 3)
                messy = truth.with_poses(x)
                if _feasible(messy, truth) and not accepts(scenario, messy, truth):
                    out.append(MessyCase(scenario.name, truth, messy, sorted(chosen), kind, frac, seed))
                    break
    return out
