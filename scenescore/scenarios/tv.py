"""A television and two speakers (the paper's Fig. 4: composing the energy with constraints).

The television stands anywhere in a room, at any angle; the two speakers stand on its long axis, an
equal, varying distance either side, facing the same way. At test time ``clutter(scene, n, seed)``
adds ``n`` fixed boxes at random on the floor that nothing may collide with, and ``correct`` says
whether an arrangement is aligned and symmetric within the stated thresholds, free of collisions
(the exact shapely check) and inside the room.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..geometry.exact import collides
from ..scene.scene import Scene, SceneError, SceneObject, wrap_angle

__all__ = ["TVScenario", "TV_CATALOGUE"]

TV_CATALOGUE: dict[str, tuple[tuple[float, float], tuple[int, int, int]]] = {
    "television": ((1.0, 0.25), (30, 30, 35)),
    "speaker": ((0.3, 0.3), (90, 60, 40)),
    "clutter": ((0.4, 0.4), (150, 150, 110)),
}


@dataclass
class TVScenario:
    """Seeded television-and-speakers arrangements, the test's clutter and its correctness check."""

    name: str = "tv"
    room: float = 2.0  # the room is [-room, room]^2 (m)
    side_min: float = 0.8  # speaker centre to television centre (m)
    side_max: float = 1.3
    pos_noise: float = 0.005
    angle_noise: float = math.radians(2.0)
    n_train: int = 36
    n_test: int = 16
    # correctness thresholds
    align_tol: float = 0.05  # each speaker's distance from the television's axis (m)
    symmetry_tol: float = 0.05  # difference of the two speakers' distances along the axis (m)
    angle_tol: float = math.radians(10.0)  # speakers' heading against the television's
    gap_min: float = 0.05  # speakers must not touch the television (m)

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        r = self.room
        return ((-r, -r), (r, r))

    def _obj(self, name: str, cat: str, pose, fixed: bool = False) -> SceneObject:
        size, color = TV_CATALOGUE[cat]
        return SceneObject(name, cat, size, pose, color=color, fixed=fixed)

    def generate(self, n: int, seed: int) -> list[Scene]:
        return list(self.iter_scenes(n, seed))

    def iter_scenes(self, n: int, seed: int) -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream (none held)."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            yield self._one(rng)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        return self.generate(self.n_train, seed * 2 + 51), self.generate(self.n_test, seed * 2 + 52)

    def _one(self, rng: np.random.Generator) -> Scene:
        th = rng.uniform(-math.pi, math.pi)
        d = rng.uniform(self.side_min, self.side_max)
        reach = d + 0.25
        x, y = rng.uniform(-self.room + reach, self.room - reach, 2)
        c, s = math.cos(th), math.sin(th)
        objs = [self._obj("television", "television", (float(x), float(y), float(th)))]
        for k, side in enumerate((-1.0, 1.0)):
            dx, dy = rng.normal(0, self.pos_noise, 2)
            pose = (
                float(x + side * d * c + dx),
                float(y + side * d * s + dy),
                float(wrap_angle(th + rng.normal(0, self.angle_noise))),
            )
            objs.append(self._obj(f"speaker_{k}", "speaker", pose))
        return Scene(objs, self.bounds, meta={"scenario": self.name, "distance": float(d)})

    def clutter(self, scene: Scene, n: int, seed: int, keep: bool = False) -> Scene:
        """``scene`` with ``n`` fixed clutter boxes at random, not overlapping each other; the
        television and speakers lose their poses unless ``keep``."""
        rng = np.random.default_rng(seed)
        objs = [o for o in scene.copy().objects if o.category != "clutter"]
        if not keep:
            for o in objs:
                o.pose = None
        placed: list[SceneObject] = []
        tries = 0
        while len(placed) < n:
            tries += 1
            if tries > 10000:
                raise SceneError(f"clutter: could not place {n} boxes without overlap")
            x, y = rng.uniform(-self.room + 0.3, self.room - 0.3, 2)
            th = rng.uniform(-math.pi, math.pi)
            pose = (float(x), float(y), float(th))
            box = self._obj(f"clutter_{len(placed)}", "clutter", pose, True)
            if any(collides(box, pose, p, cast(tuple[float, float, float], p.pose)) for p in placed):
                continue
            placed.append(box)
            objs.append(box)
        return Scene(objs, scene.bounds, meta={**scene.meta, "clutter": n})

    def aligned(self, scene: Scene) -> bool:
        """Speakers on the television's axis, equidistant either side, facing its way."""
        tv = scene["television"].pose
        sp = [scene["speaker_0"].pose, scene["speaker_1"].pose]
        if tv is None or any(p is None for p in sp):
            return False
        return self._aligned(tv, *cast(list[tuple[float, float, float]], sp))

    def _aligned(self, tv: Sequence[float], *speakers: Sequence[float]) -> bool:
        """:meth:`aligned` of the television's and the two speakers' poses."""
        c, s = math.cos(tv[2]), math.sin(tv[2])
        along, across = [], []
        for p in speakers:
            dx, dy = p[0] - tv[0], p[1] - tv[1]
            along.append(c * dx + s * dy)
            across.append(-s * dx + c * dy)
            # a box looks the same turned by pi: compare headings modulo pi
            if abs(wrap_angle(2 * (p[2] - tv[2]))) / 2 > self.angle_tol:
                return False
        if max(abs(a) for a in across) > self.align_tol:
            return False
        if along[0] * along[1] >= 0:  # both on one side
            return False
        if abs(abs(along[0]) - abs(along[1])) > self.symmetry_tol:
            return False
        half = TV_CATALOGUE["television"][0][0] / 2 + TV_CATALOGUE["speaker"][0][0] / 2 + self.gap_min
        return min(abs(a) for a in along) >= half

    def correct(self, scene: Scene) -> bool:
        """Aligned and symmetric, no collision (exact check), inside the room."""
        return bool(self.correct_many(scene, scene.poses()[None])[0])

    def correct_many(self, scene: Scene, poses: np.ndarray) -> np.ndarray:
        """:meth:`correct` for each pose set of ``poses (S, N, 3)`` in ``scene``: ``(S,)`` bool."""
        from ..costs import Bounds, HingeCollision
        from ..problem.problem import Problem

        prob = Problem(scene, HingeCollision(margin=0.0) + Bounds())
        out = np.zeros(len(poses), dtype=bool)
        idx = [scene.index(n) for n in ("television", "speaker_0", "speaker_1")]
        for k, p in enumerate(np.asarray(poses, dtype=float)):
            out[k] = self._aligned(*(p[i].tolist() for i in idx)) and bool(prob.check(p).feasible)
        return out

    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]:
        """A speaker's pose from the television and the other speaker."""
        tv = scene["television"].pose
        if tv is None:
            raise SceneError("oracle: the television has no pose")
        if name not in ("speaker_0", "speaker_1"):
            raise SceneError(f"oracle: the tv process predicts speakers only, not {name!r}")
        other = scene["speaker_1" if name == "speaker_0" else "speaker_0"].pose
        if other is None:
            raise SceneError(f"oracle: {name!r} needs the other speaker")
        return (2 * tv[0] - other[0], 2 * tv[1] - other[1], tv[2])
