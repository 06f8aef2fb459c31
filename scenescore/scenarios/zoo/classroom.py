"""zoo-classroom: a chair behind each of 14-22 fixed desks on a grid in a 12 x 10 m room."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...scene.scene import Scene
from .common import FreeSlotScenario, Layout, Pose, clipped_noise, in_frame, jitter, make_object

__all__ = ["ClassroomScenario"]


@dataclass
class ClassroomScenario(FreeSlotScenario):
    """A 12 x 10 m classroom: 14-22 fixed desks on a jittered grid, all facing +y, and behind each a
    chair facing the same way, its centre 0.40 m behind the desk's back edge. The grid has 4-6 columns,
    full rows from the front and the rest in a back row at columns drawn at random. A room-scale scene
    of 28-44 objects; the experiment removes three chairs at once.

    The oracle puts a masked chair in the slot behind the desk that no present chair occupies.
    """

    _stream: ClassVar[int] = 221
    missing_count: ClassVar[int] = 3
    name: str = "zoo-classroom"
    half: tuple[float, float] = (6.0, 5.0)
    desk: tuple[float, float] = (0.6, 1.2)  # depth (along its heading), width
    chair: tuple[float, float] = (0.45, 0.45)
    desks: tuple[int, int] = (14, 22)
    columns: tuple[int, ...] = (4, 5, 6)
    max_rows: int = 5
    pitch: tuple[float, float] = (2.0, 1.8)  # across (x), front to back (y)
    offset: float = 0.25  # the grid's centre moves up to this far from the room's on each axis
    desk_noise: float = 0.03
    desk_angle_noise: float = math.radians(1.5)
    gap: float = 0.40  # the desk's back edge to the chair's centre
    pos_noise: float = 0.02  # the gap's noise (clipped: 35-45 cm)
    side_noise: float = 0.012  # sideways (clipped: 3 cm)
    angle_noise: float = math.radians(2.0)  # the chair's heading from the desk's (clipped: 5 deg)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("chair",)
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (2 * self.desks[0], 2 * self.desks[1])  # a desk and its chair

    def _slot(self, desk: Pose) -> Pose:
        """The noise-free pose of ``desk``'s chair."""
        return in_frame(desk, -(self.desk[0] / 2 + self.gap), 0.0)

    def _grid(self, rng: np.random.Generator) -> list[tuple[int, int]]:
        """The desks' ``(row, column)`` cells: full rows from the front, the rest at random columns."""
        n = int(rng.integers(self.desks[0], self.desks[1] + 1))
        fits = [c for c in self.columns if math.ceil(n / c) <= self.max_rows]
        cols = fits[int(rng.integers(len(fits)))]
        full, rest = divmod(n, cols)
        cells = [(r, c) for r in range(full) for c in range(cols)]
        back = sorted(int(c) for c in rng.choice(cols, size=rest, replace=False)) if rest else []
        return cells + [(full, c) for c in back]

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        cells = self._grid(rng)
        cols = max(c for _, c in cells) + 1
        rows = max(r for r, _ in cells) + 1
        px, py = self.pitch
        cx, cy = rng.uniform(-self.offset, self.offset, 2)
        x0 = cx - (cols - 1) * px / 2
        y0 = cy + (rows - 1) * py / 2 + (self.desk[0] / 2 + self.gap) / 2  # row 0 at the front (+y)
        objs, chairs = [], []
        for k, (r, c) in enumerate(cells):
            grid = (float(x0 + c * px), float(y0 - r * py), math.pi / 2)
            desk = jitter(rng, grid, self.desk_noise, self.desk_angle_noise)
            objs.append(make_object("desk", k, self.desk, desk, (150, 110, 70), fixed=True))
            du = float(clipped_noise(rng, self.pos_noise))
            dv = float(clipped_noise(rng, self.side_noise))
            dt = float(clipped_noise(rng, self.angle_noise))
            seat = in_frame(desk, -(self.desk[0] / 2 + self.gap) + du, dv, dt)
            chairs.append(make_object("chair", k, self.chair, seat, (60, 90, 140)))
        return objs + chairs, {"rows": rows, "cols": cols}

    def _slots(self, scene: Scene) -> list[Pose]:
        return [self._slot(o.pose) for o in scene.objects if o.category == "desk" and o.pose is not None]
