"""zoo-lounge: a coffee table and a side table by a fixed sofa."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...scene.scene import Scene, wrap_angle
from .common import (
    Layout,
    Pose,
    ZooScenario,
    anchor_of,
    checked_target,
    in_frame,
    jitter,
    make_object,
    wall_frame,
)

__all__ = ["LoungeScenario"]


@dataclass
class LoungeScenario(ZooScenario):
    """A 4.4 m room with a fixed 2 m sofa against one wall, off the wall's centre; a coffee table in
    front of it; sometimes a square side table at the sofa's end nearer the room's corner (the end away
    from the wall's centre). Two small objects beside one big fixed one, in large bounds.
    """

    _stream: ClassVar[int] = 181
    name: str = "zoo-lounge"
    half: tuple[float, float] = (2.2, 2.2)
    sofa: tuple[float, float] = (2.0, 0.9)
    coffee_table: tuple[float, float] = (0.9, 0.5)
    side_table: float = 0.45
    clearance: float = 0.40  # sofa front to coffee table
    end_gap: float = 0.06
    offset: tuple[float, float] = (0.25, 0.6)  # sofa centre from the wall's centre
    p_side: float = 0.6
    pos_noise: float = 0.025
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("coffee_table", "side_table")
    symmetric: tuple[str, ...] = ("side_table",)

    @property
    def counts(self) -> tuple[int, int]:
        return (2, 3)

    def _coffee(self, sofa: Pose) -> Pose:
        return in_frame(sofa, 0.0, self.sofa[1] / 2 + self.clearance + self.coffee_table[1] / 2)

    def _side(self, sofa: Pose) -> Pose:
        end = math.copysign(1.0, math.cos(sofa[2]) * sofa[0] + math.sin(sofa[2]) * sofa[1])
        return in_frame(sofa, end * (self.sofa[0] / 2 + self.end_gap + self.side_table / 2), -0.2)

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        H = self.half[0]
        t = float(rng.choice([-1.0, 1.0]) * rng.uniform(*self.offset))
        back = wall_frame(H, int(rng.integers(4)), t, 0.05 + self.sofa[1] / 2)
        sofa = (
            back[0],
            back[1],
            float(wrap_angle(back[2] - math.pi / 2)),
        )  # +x along the wall, +y into the room
        fabric = [(90, 110, 130), (150, 60, 50), (190, 180, 160)][int(rng.integers(3))]
        objs = [make_object("sofa", 0, self.sofa, sofa, fabric, fixed=True)]
        coffee = jitter(rng, self._coffee(sofa), self.pos_noise, self.angle_noise)
        objs.append(make_object("coffee_table", 0, self.coffee_table, coffee, (100, 70, 45)))
        if rng.uniform() < self.p_side:
            x, y, th = self._side(sofa)
            pose = jitter(
                rng, (x, y, th + int(rng.integers(4)) * math.pi / 2), self.pos_noise, self.angle_noise
            )
            objs.append(make_object("side_table", 0, (self.side_table, self.side_table), pose, (60, 60, 60)))
        return objs, {"offset": t}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Coffee table: in front of the sofa; side table: at the sofa's end away from the wall's centre."""
        obj = checked_target(scene, name, self.missing, self.name)
        sofa = anchor_of(scene, "sofa", name).pose
        assert sofa is not None
        return self._coffee(sofa) if obj.category == "coffee_table" else self._side(sofa)
