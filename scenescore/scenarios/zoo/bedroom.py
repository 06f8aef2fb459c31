"""zoo-bedroom: a fixed bed, nightstands beside its head, a lamp beside each."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...scene.scene import Scene, SceneObject
from .common import (
    Layout,
    Pose,
    ZooScenario,
    anchor_of,
    checked_target,
    in_frame,
    jitter,
    make_object,
    pose_of,
    random_heading,
    to_frame,
    wall_frame,
)

__all__ = ["BedroomScenario"]

BEDS: tuple[tuple[float, float], ...] = ((2.0, 0.95), (2.0, 1.45), (2.05, 1.85))  # single, double, king


@dataclass
class BedroomScenario(ZooScenario):
    """A 5 m bedroom: a fixed bed with its head against a wall, one or two nightstands beside its
    head (one: either side), a floor lamp beside each nightstand, further out, a bench at the foot
    (sometimes) and a fixed wardrobe against another wall.

    A chain: the nightstand is placed from the bed, its lamp from the nightstand's (noisy) pose, at a
    distance that grows with the nightstand's width (drawn per scene, shared by both nightstands).
    The oracle finds each one's side from its partner.
    """

    _stream: ClassVar[int] = 121
    name: str = "zoo-bedroom"
    half: tuple[float, float] = (2.5, 2.5)
    nightstand_depth: float = 0.40
    nightstand_width: tuple[float, float] = (0.42, 0.58)
    bed_gap: float = 0.05  # bed to nightstand (m)
    lamp_gap: float = 0.06  # nightstand to lamp (m)
    lamp: float = 0.32  # floor lamp's diameter
    bench_gap: float = 0.25
    bench_depth: float = 0.42
    wardrobe: tuple[float, float] = (0.6, 1.2)  # depth, width
    p_two: float = 0.65  # chance of two nightstands
    p_bench: float = 0.6
    pos_noise: float = 0.01
    angle_noise: float = math.radians(2.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("nightstand", "lamp", "bench")
    symmetric: tuple[str, ...] = ("lamp",)

    @property
    def counts(self) -> tuple[int, int]:
        return (4, 7)

    def _nightstand(self, bed: SceneObject, side: float, width: float) -> Pose:
        length, w = bed.size
        u = -length / 2 + self.nightstand_depth / 2
        assert bed.pose is not None
        return in_frame(bed.pose, u, side * (w / 2 + self.bed_gap + width / 2))

    def _lamp(self, stand: Pose, side: float, width: float, diameter: float) -> Pose:
        return in_frame(stand, 0.0, side * (width / 2 + self.lamp_gap + diameter / 2))

    def _bench(self, bed: SceneObject, depth: float) -> Pose:
        assert bed.pose is not None
        return in_frame(bed.pose, bed.size[0] / 2 + self.bench_gap + depth / 2, 0.0)

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        H = self.half[0]
        bl, bw = BEDS[int(rng.integers(len(BEDS)))]
        width = float(rng.uniform(*self.nightstand_width))
        reach = bw / 2 + self.bed_gap + width + self.lamp_gap + self.lamp + 0.05
        wall = int(rng.integers(4))
        t = float(rng.uniform(-(H - reach), H - reach))
        bed = make_object(
            "bed", 0, (bl, bw), wall_frame(H, wall, t, 0.05 + bl / 2), (205, 200, 220), fixed=True
        )
        objs = [bed]
        sides = [1.0, -1.0] if rng.uniform() < self.p_two else [float(rng.choice([-1.0, 1.0]))]
        sides = [sides[i] for i in rng.permutation(len(sides))]
        wood = [(150, 105, 60), (235, 230, 220), (70, 50, 35)][int(rng.integers(3))]
        for k, side in enumerate(sides):
            stand = jitter(rng, self._nightstand(bed, side, width), self.pos_noise, self.angle_noise)
            objs.append(make_object("nightstand", k, (self.nightstand_depth, width), stand, wood))
            lamp = self._lamp(stand, side, width, self.lamp)
            lamp = jitter(rng, (lamp[0], lamp[1], random_heading(rng)), self.pos_noise, 0.0)
            objs.append(make_object("lamp", k, (self.lamp, self.lamp), lamp, (240, 225, 170), "disk"))
        if rng.uniform() < self.p_bench:
            size = (self.bench_depth, min(1.4, bw - 0.1))
            bench = jitter(rng, self._bench(bed, size[0]), self.pos_noise, self.angle_noise)
            objs.append(make_object("bench", 0, size, bench, (120, 80, 110)))
        wwall = int((wall + rng.integers(1, 4)) % 4)
        d, w = self.wardrobe
        tw = float(rng.uniform(-(H - w / 2 - 0.05), H - w / 2 - 0.05))
        objs.append(
            make_object(
                "wardrobe", 0, (d, w), wall_frame(H, wwall, tw, 0.02 + d / 2), (110, 75, 45), fixed=True
            )
        )
        return objs, {"wall": wall, "sides": sides}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Nightstand: beside the bed's head, on its lamp's side; lamp: beside its nightstand, outwards;
        bench: at the bed's foot."""
        obj = checked_target(scene, name, self.missing, self.name)
        bed = anchor_of(scene, "bed", name)
        assert bed.pose is not None
        k = name.rpartition("_")[2]
        if obj.category == "bench":
            return self._bench(bed, obj.size[0])
        if obj.category == "nightstand":
            lamp = pose_of(scene, f"lamp_{k}", name)
            side = math.copysign(1.0, to_frame(bed.pose, lamp[0], lamp[1])[1])
            return self._nightstand(bed, side, obj.size[1])
        stand = pose_of(scene, f"nightstand_{k}", name)
        side = math.copysign(1.0, to_frame(bed.pose, stand[0], stand[1])[1])
        return self._lamp(stand, side, scene[f"nightstand_{k}"].size[1], obj.size[0])
