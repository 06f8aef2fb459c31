"""The missing-object protocol: cases with one pose removed, errors against the truth, the oracle.

Shared by ``scenescore demo``, the experiments and (later) validation in training: position error
``t`` in cm, orientation error ``R`` in degrees (none for rotationally symmetric categories).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .scene import Scene

__all__ = ["MissingCase", "make_cases", "score_cases", "angle_error_deg", "OraclePlacer"]


@dataclass
class MissingCase:
    """One test case: a scene with ``name``'s pose removed, and the true pose."""

    scene: Scene
    name: str
    category: str
    truth: tuple[float, float, float]


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
