"""zoo-cascade: crate -> case -> tin -> matchbox, each beside the last."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np

from ...scene.scene import Scene, SceneError, wrap_angle
from .common import (
    Colour,
    Layout,
    Pose,
    ZooScenario,
    checked_target,
    in_frame,
    jitter,
    make_object,
    pose_of,
    shift_into_bounds,
    to_frame,
)

__all__ = ["CascadeScenario"]

CASCADE: tuple[tuple[str, tuple[float, float], Colour], ...] = (
    ("crate", (0.50, 0.34), (170, 130, 80)),
    ("case", (0.34, 0.22), (60, 80, 120)),
    ("tin", (0.20, 0.13), (190, 190, 200)),
    ("matchbox", (0.11, 0.07), (200, 60, 40)),
)


@dataclass
class CascadeScenario(ZooScenario):
    """A chain A -> B -> C -> D (crate, case, tin, matchbox): each box lies beside the previous one, on
    its left or its right (one hand per scene, so the chain curls one way), turned a quarter towards
    that hand, shifted a quarter of its parent's length forward, with a gap proportional to its own
    width. All four share a scale drawn per scene.

    The oracle reads the hand from a link that does not involve the masked box and places it from its
    parent (the crate: from the case, inverted).
    """

    _stream: ClassVar[int] = 161
    margin: ClassVar[float] = 0.005
    name: str = "zoo-cascade"
    half: tuple[float, float] = (0.75, 0.75)
    scale: tuple[float, float] = (0.75, 1.1)
    gap_ratio: float = 0.3  # gap to the parent, in the child's widths
    shift: float = 0.25  # along the parent, in its lengths
    pos_noise: float = 0.003
    angle_noise: float = math.radians(2.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("crate", "case", "tin", "matchbox")
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (4, 4)

    def _offset(
        self, parent: tuple[float, float], child: tuple[float, float], hand: float
    ) -> tuple[float, float]:
        return (self.shift * parent[0], hand * (parent[1] / 2 + self.gap_ratio * child[1] + child[0] / 2))

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        sc = float(rng.uniform(*self.scale))
        hand = float(rng.choice([-1.0, 1.0]))
        pose = (0.0, 0.0, float(rng.uniform(-math.pi, math.pi)))
        objs, prev = [], None
        for cat, size, colour in CASCADE:
            size = (size[0] * sc, size[1] * sc)
            if prev is not None:
                u, v = self._offset(prev.size, size, hand)
                pose = jitter(
                    rng,
                    in_frame(cast(Pose, prev.pose), u, v, hand * math.pi / 2),
                    self.pos_noise,
                    self.angle_noise,
                )
            prev = make_object(cat, 0, size, pose, colour)
            objs.append(prev)
        if not shift_into_bounds(rng, objs, self.bounds, 0.02):
            return None
        return objs, {"hand": hand, "scale": sc}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """From the parent (or, for the root, the child), with the hand read off another link."""
        obj = checked_target(scene, name, self.missing, self.name)
        chain = [scene[f"{cat}_0"] for cat, _, _ in CASCADE]
        i = [o.name for o in chain].index(name)
        hand = None
        for j in range(len(chain) - 1):
            a, b = chain[j], chain[j + 1]
            if name not in (a.name, b.name) and a.pose is not None and b.pose is not None:
                hand = math.copysign(1.0, to_frame(a.pose, b.pose[0], b.pose[1])[1])
                break
        if hand is None:
            raise SceneError(f"oracle: {name!r} needs a link between two other boxes to see the chain's hand")
        if i > 0:
            parent = chain[i - 1]
            u, v = self._offset(parent.size, obj.size, hand)
            return in_frame(pose_of(scene, parent.name, name), u, v, hand * math.pi / 2)
        child = chain[1]
        cp = pose_of(scene, child.name, name)
        theta = wrap_angle(cp[2] - hand * math.pi / 2)
        u, v = self._offset(obj.size, child.size, hand)
        x, y, _ = in_frame((cp[0], cp[1], theta), -u, -v)
        return (x, y, float(theta))
