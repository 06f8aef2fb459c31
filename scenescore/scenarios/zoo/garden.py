"""zoo-garden: pots in a row from a fixed bench, largest first."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np

from ...scene.scene import Scene, SceneError, SceneObject
from .common import (
    Colour,
    Layout,
    Pose,
    ZooScenario,
    anchor_of,
    checked_target,
    in_frame,
    jitter,
    make_object,
    random_heading,
    shift_into_bounds,
    to_frame,
)

__all__ = ["GardenScenario"]

POT_COLOURS: tuple[Colour, ...] = (
    (190, 95, 60),
    (50, 90, 150),
    (150, 150, 145),
    (70, 110, 70),
    (225, 215, 195),
)


@dataclass
class GardenScenario(ZooScenario):
    """A 6 m x 3 m garden: 3-7 round pots (each its own diameter) in a row from a fixed bench,
    largest first, the gap between two neighbours ``k`` times their mean diameter (``k`` drawn per
    scene, the first gap ``k`` times the first pot's). The oracle sorts the pots by size, estimates
    ``k`` from the other gaps and places the masked pot from its neighbours.
    """

    _stream: ClassVar[int] = 151
    margin: ClassVar[float] = 0.02
    name: str = "zoo-garden"
    half: tuple[float, float] = (3.0, 1.5)
    bench: tuple[float, float] = (0.5, 1.6)  # depth along the row, length across it
    diameter: tuple[float, float] = (0.15, 0.45)
    gap_ratio: tuple[float, float] = (0.25, 0.6)
    pots: tuple[int, int] = (3, 7)
    max_turn: float = 0.25
    pos_noise: float = 0.006
    angle_noise: float = math.radians(2.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("pot",)
    symmetric: tuple[str, ...] = ("pot",)

    @property
    def counts(self) -> tuple[int, int]:
        return (self.pots[0] + 1, self.pots[1] + 1)

    def _order(self, pots: list[SceneObject]) -> list[SceneObject]:
        return sorted(pots, key=lambda o: (-o.size[0], o.name))

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        n = int(rng.integers(self.pots[0], self.pots[1] + 1))
        ds = rng.uniform(*self.diameter, n)
        k = float(rng.uniform(*self.gap_ratio))
        bench = (0.0, 0.0, float(rng.uniform(-self.max_turn, self.max_turn)))
        objs = [make_object("bench", 0, self.bench, bench, (120, 90, 60), fixed=True)]
        names = rng.permutation(n)  # names carry no order; the order is by size
        s = self.bench[0] / 2
        prev = None
        for i, d in enumerate(sorted(ds, reverse=True)):
            # the first pot: k of its diameter from the bench; then k of the two pots' mean diameter
            s += k * d + d / 2 if prev is None else (1 + k) * (prev + d) / 2
            pose = in_frame(bench, s, 0.0)
            pose = jitter(rng, (pose[0], pose[1], random_heading(rng)), self.pos_noise, 0.0)
            colour = POT_COLOURS[int(rng.integers(len(POT_COLOURS)))]
            objs.append(make_object("pot", int(names[i]), (d, d), pose, colour, "disk"))
            prev = d
        if not shift_into_bounds(rng, objs, self.bounds, 0.05):
            return None
        return objs, {"gap_ratio": k}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """From the masked pot's neighbours in size order, with the gap ratio the other gaps show."""
        checked_target(scene, name, self.missing, self.name)
        bench = anchor_of(scene, "bench", name).pose
        assert bench is not None
        row = self._order([o for o in scene.objects if o.category == "pot"])
        i = [o.name for o in row].index(name)
        d = [o.size[0] for o in row]
        known = [
            None if o.name == name or o.pose is None else to_frame(bench, o.pose[0], o.pose[1])[0]
            for o in row
        ]
        start = self.bench[0] / 2
        # least squares for k over every gap between two known neighbours (the bench counts as one)
        num = den = 0.0
        if known[0] is not None:
            num += known[0] - start - d[0] / 2
            den += d[0]
        for j in range(len(row) - 1):
            left, right = known[j], known[j + 1]
            if left is not None and right is not None:
                num += right - left - (d[j] + d[j + 1]) / 2
                den += (d[j] + d[j + 1]) / 2
        if den == 0:
            raise SceneError(f"oracle: {name!r} needs two neighbouring pots to see the gaps")
        k = num / den
        est = []
        if i == 0:
            est.append(start + k * d[0] + d[0] / 2)
        elif known[i - 1] is not None:
            est.append(cast(float, known[i - 1]) + (1 + k) * (d[i - 1] + d[i]) / 2)
        if i + 1 < len(row) and known[i + 1] is not None:
            est.append(cast(float, known[i + 1]) - (1 + k) * (d[i] + d[i + 1]) / 2)
        if not est:
            raise SceneError(f"oracle: {name!r} needs a neighbouring pot")
        x, y, _ = in_frame(bench, float(np.mean(est)), 0.0)
        return (x, y, 0.0)
