"""The missing-object protocol: cases with poses removed, errors against the truth, the oracle.

Position error ``t`` in the data's lengths times 100 (cm for metres), orientation error ``R`` in degrees
(none for rotationally symmetric categories: in the experiments the scenario names them, in
:func:`~scenescore.evaluation.report.evaluate` they are the round disks).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..scene.scene import Scene, SceneError, SceneObject

__all__ = [
    "MissingCase",
    "make_cases",
    "leave_one_out",
    "score_cases",
    "angle_error_deg",
    "case_errors",
    "assignment",
    "OraclePlacer",
]


@dataclass
class MissingCase:
    """One test case: a scene with ``name``'s pose removed, and the true pose; ``others``: further
    objects whose poses the same scene lacks, each ``(name, category, truth)`` (none in the one-object
    protocol)."""

    scene: Scene
    name: str
    category: str
    truth: tuple[float, float, float]
    others: tuple[tuple[str, str, tuple[float, float, float]], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The case as JSON (a sweep's record keeps it): the scene, the removed objects, their truths."""
        return {
            "scene": self.scene.to_dict(),
            "name": self.name,
            "category": self.category,
            "truth": [float(v) for v in self.truth],
            "others": [[n, c, [float(v) for v in t]] for n, c, t in self.others],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MissingCase:
        """The case :meth:`to_dict` wrote (its scene read and checked as a scene file is)."""

        def pose(v: Any) -> tuple[float, float, float]:
            x, y, t = (float(a) for a in v)
            return x, y, t

        others = tuple((str(n), str(c), pose(t)) for n, c, t in d["others"])
        return cls(Scene.from_dict(d["scene"]), str(d["name"]), str(d["category"]), pose(d["truth"]), others)

    @property
    def names(self) -> list[str]:
        """Every removed object's name, ``name`` first."""
        return [self.name] + [n for n, _, _ in self.others]

    def singles(self) -> list[MissingCase]:
        """One one-object case per removed object, all on this case's scene (this case itself when it
        removes one object)."""
        if not self.others:
            return [self]
        first = MissingCase(self.scene, self.name, self.category, self.truth)
        return [first] + [MissingCase(self.scene, n, c, t) for n, c, t in self.others]


def make_cases(test: list[Scene], categories: tuple[str, ...]) -> list[MissingCase]:
    """Every (scene, object of a listed category) pair, that object's pose removed."""
    cases = []
    for s in test:
        for o in s.objects:
            if o.category in categories and o.pose is not None:
                cases.append(MissingCase(s.without(o.name), o.name, o.category, o.pose))
    return cases


def angle_error_deg(a: float, b: float) -> float:
    d = (a - b + math.pi) % (2 * math.pi) - math.pi
    return abs(math.degrees(d))


def score_cases(
    cases: list[MissingCase], predicted: list[Scene], symmetric: tuple[str, ...]
) -> dict[str, float]:
    """Per-category and mean errors: ``<cat>_t_cm``, ``<cat>_R_deg``, ``mean_t_cm``, ``mean_R_deg``."""
    t: dict[str, list[float]] = {}
    r: dict[str, list[float]] = {}
    for case, pred in zip(cases, predicted):
        pose = pred[case.name].pose
        if pose is None:
            raise RuntimeError(f"method left {case.name!r} without a pose")
        t.setdefault(case.category, []).append(
            100 * math.hypot(pose[0] - case.truth[0], pose[1] - case.truth[1])
        )
        if case.category not in symmetric:
            r.setdefault(case.category, []).append(angle_error_deg(pose[2], case.truth[2]))
    out: dict[str, float] = {}
    for cat in t:
        out[f"{cat}_t_cm"] = float(np.mean(t[cat]))
        if cat in r:
            out[f"{cat}_R_deg"] = float(np.mean(r[cat]))
    out["mean_t_cm"] = float(np.mean([out[f"{c}_t_cm"] for c in t]))
    out["mean_R_deg"] = float(np.mean([out[f"{c}_R_deg"] for c in r])) if r else float("nan")
    return out


@dataclass
class OraclePlacer:
    """The process's own best guess for a missing object: the floor no method can beat."""

    scenario: Any  # a scenario with ``oracle(scene, name)``
    name: str = "Oracle"

    def fit(self, scenes: list[Scene], seed: int = 0) -> OraclePlacer:
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        out = []
        for s in scenes:
            names = s.unknown
            out.append(s.with_poses([self.scenario.oracle(s, n) for n in names], names))
        return out


def leave_one_out(
    scenes: Sequence[Scene], objects: Sequence[str] | None = None, per_category: int | None = None
) -> list[MissingCase]:
    """Every object that may move (or only those called ``objects``), masked in turn: one case each, in
    scene order. ``per_category``: at most that many of each category, spread over the scenes (each
    scene's first object of the category, scene by scene, then each one's second, ...), so that a room of
    a hundred chairs is judged on a few of them and a table's few forks on every one."""
    picked: list[tuple[int, int, int, Scene, SceneObject]] = []  # (rank, scene, order, ...)
    for k, s in enumerate(scenes):
        seen: dict[str, int] = {}
        for o in s.objects:
            if o.pose is None or o.fixed or (objects is not None and o.name not in objects):
                continue
            rank = seen[o.category] = seen.get(o.category, -1) + 1
            picked.append((rank, k, len(picked), s, o))
    if per_category is not None:
        taken: dict[str, int] = {}
        kept = []
        for item in sorted(picked, key=lambda t: (t[0], t[1])):
            cat = item[4].category
            if taken.get(cat, 0) < per_category:
                taken[cat] = taken.get(cat, 0) + 1
                kept.append(item)
        picked = sorted(kept, key=lambda t: t[2])
    return [MissingCase(s.without(o.name), o.name, o.category, _known(o)) for _, _, _, s, o in picked]


def _known(o: SceneObject) -> tuple[float, float, float]:
    assert o.pose is not None  # leave_one_out picks only objects with a pose
    return o.pose


def case_errors(case: MissingCase, pose: Sequence[float], symmetric: bool) -> tuple[float, float | None]:
    """A placement's position error (cm) and orientation error (deg; ``None`` when ``symmetric``)."""
    t = 100 * math.hypot(pose[0] - case.truth[0], pose[1] - case.truth[1])
    return t, None if symmetric else angle_error_deg(pose[2], case.truth[2])


def assignment(
    poses: Sequence[Sequence[float]],
    truths: Sequence[Sequence[float]],
    categories: Sequence[str] | None = None,
) -> list[int]:
    """For each truth, the index of the pose matched to it: the one-to-one matching of interchangeable
    objects that minimises the summed position error (``scipy.optimize.linear_sum_assignment``). With
    ``categories`` (one per truth, and per pose in the same order) only objects of one category match."""
    if len(poses) != len(truths):
        raise SceneError(f"assignment: {len(poses)} poses for {len(truths)} truths")
    if categories is not None and len(categories) != len(truths):
        raise SceneError(f"assignment: {len(categories)} categories for {len(truths)} truths")
    if not truths:
        return []
    p = np.asarray(poses, dtype=float)[:, :2]
    t = np.asarray(truths, dtype=float)[:, :2]
    cost = np.hypot(*(t[:, None, :] - p[None, :, :]).transpose(2, 0, 1))  # (truth, pose)
    if categories is not None:
        cats = np.asarray(categories)
        cost = np.where(cats[:, None] == cats[None, :], cost, cost.max() * len(truths) + 1e6)
    rows, cols = linear_sum_assignment(cost)
    out = [0] * len(truths)
    for r, c in zip(rows, cols):
        out[int(r)] = int(c)
    return out
