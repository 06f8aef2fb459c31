"""zoo-jars: a grid of round jars on a shelf, the pitch growing with the jars."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np

from ...scene.scene import Scene, SceneError
from .common import (
    Colour,
    Layout,
    Pose,
    ZooScenario,
    checked_target,
    free_slot,
    jitter,
    make_object,
    placed_of,
    random_heading,
    shift_into_bounds,
)

__all__ = ["JarGridScenario"]

JAR_COLOURS: tuple[Colour, ...] = (
    (214, 150, 40),  # honey
    (150, 30, 50),  # jam
    (120, 140, 60),  # pickles
    (235, 225, 200),  # flour
    (90, 60, 40),  # coffee
    (200, 80, 30),  # paprika
)


@dataclass
class JarGridScenario(ZooScenario):
    """A grid of 2x2 to 4x5 round jars on a 1 m x 0.4 m shelf; the pitch grows with the jars' size.

    All jars of a scene share a diameter (drawn per scene); the grid's pitch is ``(1 + spacing)`` times
    it. The oracle counts the grid's rows and columns from the other jars, fits the grid and returns the
    empty cell.
    """

    _stream: ClassVar[int] = 111
    margin: ClassVar[float] = 0.003
    name: str = "zoo-jars"
    half: tuple[float, float] = (0.5, 0.2)
    diameter: tuple[float, float] = (0.05, 0.075)
    spacing: float = 0.3  # gap between jars as a fraction of the diameter
    rows: tuple[int, int] = (2, 4)
    cols: tuple[int, int] = (2, 5)
    pos_noise: float = 0.0012
    angle_noise: float = 0.0
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("jar",)
    symmetric: tuple[str, ...] = ("jar",)

    @property
    def counts(self) -> tuple[int, int]:
        return (self.rows[0] * self.cols[0], self.rows[1] * self.cols[1])

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        r = int(rng.integers(self.rows[0], self.rows[1] + 1))
        c = int(rng.integers(self.cols[0], self.cols[1] + 1))
        d = float(rng.uniform(*self.diameter))
        p = d * (1 + self.spacing)
        objs = []
        for i in range(r):
            for j in range(c):
                x, y = (j - (c - 1) / 2) * p, (i - (r - 1) / 2) * p
                pose = jitter(rng, (x, y, random_heading(rng)), self.pos_noise, 0.0)
                colour = JAR_COLOURS[int(rng.integers(len(JAR_COLOURS)))]
                objs.append(make_object("jar", i * c + j, (d, d), pose, colour, "disk"))
        if not shift_into_bounds(rng, objs, self.bounds, 0.005):
            return None
        return objs, {"rows": r, "cols": c, "diameter": d}

    @staticmethod
    def _clusters(values: np.ndarray, tol: float) -> np.ndarray:
        v = np.sort(values)
        groups, cur = [], [v[0]]
        for a in v[1:]:
            if a - cur[-1] > tol:
                groups.append(np.mean(cur))
                cur = []
            cur.append(a)
        groups.append(np.mean(cur))
        return np.array(groups)

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The grid's empty cell, the grid fitted to the other jars."""
        obj = checked_target(scene, name, self.missing, self.name)
        others = placed_of(scene, "jar", but=name)
        n = sum(o.category == "jar" for o in scene.objects)
        if len(others) < 3:
            raise SceneError(f"oracle: {name!r} needs at least three other jars to find the grid")
        p = obj.size[0] * (1 + self.spacing)
        pts = np.array([cast(Pose, o.pose)[:2] for o in others])
        cx, cy = self._clusters(pts[:, 0], p / 2), self._clusters(pts[:, 1], p / 2)
        if len(cx) * len(cy) != n:
            raise SceneError(f"oracle: {name!r}: the other jars do not form a grid of {n} cells")
        ci = np.argmin(np.abs(pts[:, 0, None] - cx[None]), axis=1)
        ri = np.argmin(np.abs(pts[:, 1, None] - cy[None]), axis=1)
        ox = float(np.mean(pts[:, 0] - ci * p))
        oy = float(np.mean(pts[:, 1] - ri * p))
        cells = [(ox + j * p, oy + i * p, 0.0) for i in range(len(cy)) for j in range(len(cx))]
        return free_slot(cells, others)
