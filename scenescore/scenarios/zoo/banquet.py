"""zoo-banquet: chairs around a fixed 3 m table in a 10 m hall."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np

from ...scene.scene import Scene, SceneError
from .common import (
    Layout,
    Pose,
    ZooScenario,
    anchor_of,
    checked_target,
    free_slot,
    in_frame,
    jitter,
    make_object,
    placed_of,
    shift_into_bounds,
    to_frame,
    wall_frame,
)

__all__ = ["BanquetScenario"]


@dataclass
class BanquetScenario(ZooScenario):
    """A 10 m hall: a fixed 3 m table anywhere at any angle, 2-5 chairs evenly along each long side
    and sometimes one at each end (4-12 chairs), all facing it; a fixed sideboard against a wall.

    The oracle counts the chairs, sees from the others whether the ends are laid, and returns the
    empty seat facing the table.
    """

    _stream: ClassVar[int] = 131
    name: str = "zoo-banquet"
    half: tuple[float, float] = (5.0, 5.0)
    table: tuple[float, float] = (3.0, 1.0)
    chair: tuple[float, float] = (0.50, 0.46)  # depth (along its heading), width
    clearance: float = 0.10  # table edge to chair
    per_side: tuple[int, int] = (2, 5)
    p_ends: float = 0.5
    sideboard: tuple[float, float] = (0.5, 2.0)
    pos_noise: float = 0.015
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("chair",)
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (2 * self.per_side[0] + 2, 2 * self.per_side[1] + 4)  # chairs, table, sideboard

    def _slots(self, table: Pose, m: int, ends: bool) -> list[Pose]:
        L, W = self.table
        v = W / 2 + self.clearance + self.chair[0] / 2
        out = []
        for side in (1.0, -1.0):
            for j in range(m):
                out.append(in_frame(table, -L / 2 + (j + 0.5) * L / m, side * v, -side * math.pi / 2))
        if ends:
            u = L / 2 + self.clearance + self.chair[0] / 2
            out += [in_frame(table, u, 0.0, math.pi), in_frame(table, -u, 0.0, 0.0)]
        return out

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        H = self.half[0]
        m = int(rng.integers(self.per_side[0], self.per_side[1] + 1))
        ends = bool(rng.uniform() < self.p_ends)
        table = (0.0, 0.0, float(rng.uniform(-math.pi, math.pi)))
        objs = [make_object("table", 0, self.table, table, (110, 70, 40), fixed=True)]
        colour = [(160, 30, 40), (200, 190, 160), (60, 60, 70)][int(rng.integers(3))]
        for k, slot in enumerate(self._slots(table, m, ends)):
            objs.append(
                make_object(
                    "chair", k, self.chair, jitter(rng, slot, self.pos_noise, self.angle_noise), colour
                )
            )
        if not shift_into_bounds(rng, objs, self.bounds, 0.3):
            return None
        d, w = self.sideboard
        t = float(rng.uniform(-(H - w / 2 - 0.1), H - w / 2 - 0.1))
        board = wall_frame(H, int(rng.integers(4)), t, 0.03 + d / 2)
        objs.append(make_object("sideboard", 0, self.sideboard, board, (80, 50, 30), fixed=True))
        return objs, {"per_side": m, "ends": ends}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The table's empty seat."""
        checked_target(scene, name, self.missing, self.name)
        table = anchor_of(scene, "table", name).pose
        assert table is not None
        others = placed_of(scene, "chair", but=name)
        n = sum(o.category == "chair" for o in scene.objects)
        L = self.table[0]
        ends = any(
            abs(to_frame(table, cast(Pose, o.pose)[0], cast(Pose, o.pose)[1])[0]) > L / 2 + self.clearance
            for o in others
        )
        m2 = n - 2 * ends
        if m2 < 2 or m2 % 2:
            raise SceneError(f"oracle: {name!r}: {n} chairs do not fit the table's seating")
        return free_slot(self._slots(table, m2 // 2, ends), others)
