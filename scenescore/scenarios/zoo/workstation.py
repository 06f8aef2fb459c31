"""zoo-workstation: monitor -> keyboard -> mouse on one hand, the mug opposite."""

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
    in_frame,
    jitter,
    make_object,
    placed_of,
    pose_of,
    random_heading,
    to_frame,
)

__all__ = ["WorkstationScenario"]


@dataclass
class WorkstationScenario(ZooScenario):
    """A 1.6 m desk: a fixed monitor at the back, the keyboard in front of it at a varying distance,
    the mouse beside the keyboard on the right or the left (the user's hand: two modes), the mug on the
    keyboard's other side, a little further back.

    A chain (monitor -> keyboard -> mouse, mug); the keyboard's distance is seen in the mouse and mug,
    the hand in the mug (for the mouse) and in the mouse (for the mug).
    """

    _stream: ClassVar[int] = 141
    margin: ClassVar[float] = 0.01
    name: str = "zoo-workstation"
    half: tuple[float, float] = (0.8, 0.4)
    monitor: tuple[float, float] = (0.56, 0.18)
    keyboard: tuple[float, float] = (0.44, 0.14)
    mouse: tuple[float, float] = (0.11, 0.065)
    mug: float = 0.09
    distance: tuple[float, float] = (0.22, 0.32)  # monitor centre to keyboard centre
    mouse_offset: float = 0.32  # keyboard centre to mouse, sideways
    mug_offset: tuple[float, float] = (0.36, 0.12)  # keyboard centre to mug: sideways, back
    max_turn: float = 0.15
    p_left: float = 0.3
    pos_noise: float = 0.005
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("keyboard", "mouse", "mug")
    symmetric: tuple[str, ...] = ("mug",)

    @property
    def counts(self) -> tuple[int, int]:
        return (4, 4)

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        hx, hy = self.half
        mon = (
            float(rng.uniform(-hx + 0.45, hx - 0.45)),
            hy - 0.15,
            float(rng.uniform(-self.max_turn, self.max_turn)),
        )
        d = float(rng.uniform(*self.distance))
        hand = -1.0 if rng.uniform() < self.p_left else 1.0
        kb = jitter(rng, in_frame(mon, 0.0, -d), self.pos_noise, self.angle_noise)
        mouse = jitter(
            rng, in_frame(kb, hand * self.mouse_offset, 0.0, math.pi / 2), self.pos_noise, self.angle_noise
        )
        mug = in_frame(kb, -hand * self.mug_offset[0], self.mug_offset[1])
        mug = jitter(rng, (mug[0], mug[1], random_heading(rng)), self.pos_noise, 0.0)
        keys = [(40, 40, 45), (235, 235, 230)][int(rng.integers(2))]
        objs = [
            make_object("monitor", 0, self.monitor, mon, (20, 20, 25), fixed=True),
            make_object("keyboard", 0, self.keyboard, kb, keys),
            make_object("mouse", 0, self.mouse, mouse, keys),
            make_object("mug", 0, (self.mug, self.mug), mug, (180, 40, 40), "disk"),
        ]
        return objs, {"distance": d, "hand": hand}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Keyboard: in front of the monitor at the depth the mouse and mug show; mouse and mug: beside
        the keyboard, each on the side the other is not."""
        obj = checked_target(scene, name, self.missing, self.name)
        if obj.category == "keyboard":
            mon = anchor_of(scene, "monitor", name).pose
            assert mon is not None
            depths = []
            for cat, back in (("mouse", 0.0), ("mug", self.mug_offset[1])):
                for o in placed_of(scene, cat, but=name):
                    depths.append(to_frame(mon, cast(Pose, o.pose)[0], cast(Pose, o.pose)[1])[1] - back)
            if not depths:
                raise SceneError(f"oracle: {name!r} needs the mouse or the mug to find its depth")
            return in_frame(mon, 0.0, float(np.mean(depths)))
        kb = pose_of(scene, "keyboard_0", name)
        partner = placed_of(scene, "mug" if obj.category == "mouse" else "mouse", but=name)
        if not partner:
            raise SceneError(f"oracle: {name!r} needs the {'mug' if obj.category == 'mouse' else 'mouse'}")
        u = to_frame(kb, cast(Pose, partner[0].pose)[0], cast(Pose, partner[0].pose)[1])[0]
        if obj.category == "mouse":
            hand = -math.copysign(1.0, u)
            return in_frame(kb, hand * self.mouse_offset, 0.0, math.pi / 2)
        hand = math.copysign(1.0, u)
        x, y, _ = in_frame(kb, -hand * self.mug_offset[0], self.mug_offset[1])
        return (x, y, 0.0)
