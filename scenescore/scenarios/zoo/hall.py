"""zoo-hall: vases and a stool by a fixed console table."""

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
    free_slot,
    in_frame,
    jitter,
    make_object,
    placed_of,
    random_heading,
)

__all__ = ["HallScenario"]


@dataclass
class HallScenario(ZooScenario):
    """A fixed 2 m console table anywhere in a 4.4 m hall, at any angle; a vase on the floor in front of
    each of its ends and a stool in front of its middle, farther out. Small objects by one big fixed one
    in large bounds, every relation rigid to the console (nothing depends on the walls).
    """

    _stream: ClassVar[int] = 211
    name: str = "zoo-hall"
    half: tuple[float, float] = (2.2, 2.2)
    console: tuple[float, float] = (2.0, 0.4)
    vase: float = 0.12
    stool: float = 0.34
    vase_at: tuple[float, float] = (0.7, 0.22)  # from the console's centre: along it, in front of its front
    stool_out: float = 0.45  # stool centre in front of the console's front
    pos_noise: float = 0.015
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("vase", "stool")
    symmetric: tuple[str, ...] = ("vase", "stool")

    @property
    def counts(self) -> tuple[int, int]:
        return (4, 4)

    def _slot(self, console: Pose, cat: str, k: int) -> Pose:
        front = self.console[1] / 2
        if cat == "stool":
            return in_frame(console, 0.0, front + self.stool_out)
        u, v = self.vase_at
        return in_frame(console, (-u, u)[k], front + v)

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        H = self.half[0]
        console = (
            float(rng.uniform(-H, H)),
            float(rng.uniform(-H, H)),
            float(rng.uniform(-math.pi, math.pi)),
        )
        objs = [make_object("console", 0, self.console, console, (110, 80, 55), fixed=True)]
        for k in range(2):
            x, y, _ = jitter(rng, self._slot(console, "vase", k), self.pos_noise, 0.0)
            objs.append(
                make_object(
                    "vase",
                    k,
                    (self.vase, self.vase),
                    (x, y, random_heading(rng)),
                    (70, 130, 160),
                    shape="disk",
                )
            )
        x, y, t = jitter(rng, self._slot(console, "stool", 0), self.pos_noise, self.angle_noise)
        turn = int(rng.integers(4)) * math.pi / 2  # a square stool: a quarter turn looks the same
        objs.append(
            make_object(
                "stool", 0, (self.stool, self.stool), (x, y, float(wrap_angle(t + turn))), (150, 120, 90)
            )
        )
        return objs, {}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Stool: in front of the console's middle; vase: in front of the end the other vase leaves free."""
        obj = checked_target(scene, name, self.missing, self.name)
        console = anchor_of(scene, "console", name).pose
        assert console is not None
        if obj.category == "stool":
            return self._slot(console, "stool", 0)
        slots = [self._slot(console, "vase", k) for k in range(2)]
        return free_slot(slots, placed_of(scene, "vase", but=name))
