"""zoo-cafe: 8-16 fixed tables in a 16 x 12 m room, a chair at each side of each table."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...scene.scene import Scene
from .common import FreeSlotScenario, Layout, Pose, in_frame, jitter, make_object

__all__ = ["CafeScenario"]


@dataclass
class CafeScenario(FreeSlotScenario):
    """A 16 x 12 m cafe: 8-16 fixed 1.0 x 0.8 m tables in cells of a 5 x 4 grid drawn at random, each
    jittered and turned by a multiple of 90 degrees (plus a few degrees), and four chairs at each table,
    one at the middle of each side, 0.15 m out from its edge, facing the table's centre. A room-scale
    scene of 40-80 objects whose slots depend on which way each table is turned; the experiment removes
    three chairs at once.

    The oracle puts a masked chair in the slot at a table that no present chair occupies.
    """

    _stream: ClassVar[int] = 231
    missing_count: ClassVar[int] = 3
    name: str = "zoo-cafe"
    half: tuple[float, float] = (8.0, 6.0)
    table: tuple[float, float] = (1.0, 0.8)
    chair: tuple[float, float] = (0.42, 0.42)
    tables: tuple[int, int] = (8, 16)
    grid: tuple[int, int] = (5, 4)  # columns (x), rows (y)
    pitch: tuple[float, float] = (3.2, 2.9)
    table_noise: float = 0.1  # the table's position in its cell (clipped: 25 cm)
    table_angle_noise: float = math.radians(3.0)
    gap: float = 0.15  # the table's edge to the chair's
    pos_noise: float = 0.015
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("chair",)
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (5 * self.tables[0], 5 * self.tables[1])  # a table and its four chairs

    def _seats(self, table: Pose) -> list[Pose]:
        """The noise-free poses of ``table``'s four chairs, each facing the table's centre."""
        u = self.table[0] / 2 + self.gap + self.chair[0] / 2
        v = self.table[1] / 2 + self.gap + self.chair[0] / 2
        return [
            in_frame(table, u, 0.0, math.pi),
            in_frame(table, -u, 0.0, 0.0),
            in_frame(table, 0.0, v, -math.pi / 2),
            in_frame(table, 0.0, -v, math.pi / 2),
        ]

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        n = int(rng.integers(self.tables[0], self.tables[1] + 1))
        cols, rows = self.grid
        px, py = self.pitch
        cells = sorted(int(i) for i in rng.choice(cols * rows, size=n, replace=False))
        objs, chairs = [], []
        for k, cell in enumerate(cells):
            r, c = divmod(cell, cols)
            turn = int(rng.integers(4)) * math.pi / 2
            centre = ((c - (cols - 1) / 2) * px, (r - (rows - 1) / 2) * py, turn)
            table = jitter(rng, centre, self.table_noise, self.table_angle_noise)
            objs.append(make_object("table", k, self.table, table, (120, 85, 50), fixed=True))
            for j, seat in enumerate(self._seats(table)):
                pose = jitter(rng, seat, self.pos_noise, self.angle_noise)
                chairs.append(make_object("chair", 4 * k + j, self.chair, pose, (170, 60, 50)))
        return objs + chairs, {"tables": n}

    def _slots(self, scene: Scene) -> list[Pose]:
        return [
            seat
            for o in scene.objects
            if o.category == "table" and o.pose is not None
            for seat in self._seats(o.pose)
        ]
