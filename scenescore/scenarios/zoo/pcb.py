"""zoo-pcb: resistors in a row beside a fixed chip, on one of its four sides."""

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
    random_heading,
    shift_into_bounds,
)

__all__ = ["PcbScenario"]


@dataclass
class PcbScenario(ZooScenario):
    """Resistors (1 cm) in a row on a 0.3 m board, beside a fixed chip, on one of its four sides.

    The row lies along one side of the square chip (which side is random: four modes), centred on it,
    at the 0.3-inch pitch; every resistor points away from the chip. A round capacitor stands on the
    opposite side. The oracle finds the side from the other parts and the gap the masked part left.
    """

    _stream: ClassVar[int] = 101
    margin: ClassVar[float] = 0.003
    name: str = "zoo-pcb"
    half: tuple[float, float] = (0.15, 0.15)
    chip: float = 0.032  # side of the square chip (m)
    resistor: tuple[float, float] = (0.010, 0.0035)
    capacitor: float = 0.008  # diameter
    pitch: float = 0.00762
    gap: float = 0.004  # chip edge to the parts (m)
    row: tuple[int, int] = (2, 8)
    pos_noise: float = 0.0002
    angle_noise: float = math.radians(2.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("resistor", "capacitor")
    symmetric: tuple[str, ...] = ("capacitor", "chip")

    @property
    def counts(self) -> tuple[int, int]:
        return (self.row[0] + 2, self.row[1] + 2)

    def _slots(self, chip: Pose, side: int, n: int) -> list[Pose]:
        frame = (chip[0], chip[1], chip[2] + side * math.pi / 2)
        d = self.chip / 2 + self.gap + self.resistor[0] / 2
        return [in_frame(frame, d, (i - (n - 1) / 2) * self.pitch) for i in range(n)]

    def _cap(self, chip: Pose, side: int) -> Pose:
        frame = (chip[0], chip[1], chip[2] + side * math.pi / 2)
        return in_frame(frame, -(self.chip / 2 + self.gap + self.capacitor / 2), 0.0)

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        chip = (0.0, 0.0, float(rng.uniform(-math.pi / 4, math.pi / 4)))
        side = int(rng.integers(4))
        n = int(rng.integers(self.row[0], self.row[1] + 1))
        objs = [make_object("chip", 0, (self.chip, self.chip), chip, (28, 28, 32), fixed=True)]
        body = [(214, 190, 150), (96, 150, 205)][int(rng.integers(2))]  # carbon film beige, metal film blue
        for i, slot in enumerate(self._slots(chip, side, n)):
            pose = jitter(rng, slot, self.pos_noise, self.angle_noise)
            objs.append(make_object("resistor", i, self.resistor, pose, body))
        cap = self._cap(chip, side)
        cap = jitter(rng, (cap[0], cap[1], random_heading(rng)), self.pos_noise, 0.0)
        objs.append(make_object("capacitor", 0, (self.capacitor, self.capacitor), cap, (30, 45, 110), "disk"))
        if not shift_into_bounds(rng, objs, self.bounds, 0.01):
            return None
        return objs, {"side": side, "resistors": n}

    def _side(self, scene: Scene, chip: Pose, target: str) -> int:
        """The side (0-3) the row is on: resistors vote for it, the capacitor against it."""
        votes = [(o, 1.0) for o in placed_of(scene, "resistor", but=target)]
        votes += [(o, -1.0) for o in placed_of(scene, "capacitor", but=target)]
        if not votes:
            raise SceneError(f"oracle: {target!r} needs another resistor or the capacitor to find the side")
        score = []
        for k in range(4):
            a = chip[2] + k * math.pi / 2
            score.append(
                sum(
                    w
                    * (
                        math.cos(a) * (cast(Pose, o.pose)[0] - chip[0])
                        + math.sin(a) * (cast(Pose, o.pose)[1] - chip[1])
                    )
                    for o, w in votes
                )
            )
        return int(np.argmax(score))

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The free slot of the row (resistor) or the spot opposite the row (capacitor)."""
        obj = checked_target(scene, name, self.missing, self.name)
        chip = anchor_of(scene, "chip", name).pose
        assert chip is not None
        side = self._side(scene, chip, name)
        if obj.category == "capacitor":
            return self._cap(chip, side)
        n = sum(o.category == "resistor" for o in scene.objects)
        return free_slot(self._slots(chip, side, n), placed_of(scene, "resistor", but=name))
