"""Nearest-Nbr: copy the missing object's pose from the most similar training scene.

The test scene's known objects are matched to each training scene's objects of the same category
(Hungarian assignment on position distance); the training scene with the smallest total distance
wins, and the missing object takes the pose of the object of its category that the matching left
over in that scene.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np
from scipy.optimize import linear_sum_assignment

from ...scene.scene import Scene

_Pose = tuple[float, float, float]

__all__ = ["NearestNeighbour"]


def _match(test: Scene, train: Scene, skip: set[str]) -> tuple[float, dict[str, int]]:
    """Total matched distance and ``test name -> train index`` for the known objects, category by category."""
    cost, assign = 0.0, {}
    cats = {o.category for o in test.objects}
    for cat in cats:
        ti = [i for i, o in enumerate(test.objects) if o.category == cat and o.name not in skip and o.pose]
        tj = [j for j, o in enumerate(train.objects) if o.category == cat]
        if not ti:
            continue
        if len(tj) < len(ti):
            return float("inf"), {}
        a = np.array([cast(_Pose, test.objects[i].pose)[:2] for i in ti])
        b = np.array([cast(_Pose, train.objects[j].pose)[:2] for j in tj])
        d = np.linalg.norm(a[:, None] - b[None], axis=-1)
        r, c = linear_sum_assignment(d)
        cost += float(d[r, c].sum())
        assign.update({test.objects[ti[i]].name: tj[j] for i, j in zip(r, c)})
    return cost, assign


@dataclass
class NearestNeighbour:
    """The paper's Nearest-Nbr baseline as a :class:`~scenescore.planning.placement.Placer`."""

    name: str = "Nearest-Nbr"
    memory: list[Scene] = field(default_factory=list)

    def fit(self, scenes: list[Scene], seed: int = 0) -> NearestNeighbour:
        self.memory = list(scenes)
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        return [self._one(s) for s in scenes]

    def _one(self, scene: Scene) -> Scene:
        missing = set(scene.unknown)
        best: tuple[float, Scene | None, dict[str, int]] = (float("inf"), None, {})
        for candidate in self.memory:
            cost, assign = _match(scene, candidate, missing)
            if cost < best[0]:
                best = (cost, candidate, assign)
        _, train, assign = best
        out = scene.copy()
        if train is None:
            return out
        used = set(assign.values())
        for name in missing:
            cat = scene[name].category
            free = [j for j, o in enumerate(train.objects) if o.category == cat and j not in used]
            if free:
                used.add(free[0])
                out = out.with_poses([cast(_Pose, train.objects[free[0]].pose)], [name])
        return out
