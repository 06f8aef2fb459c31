"""The desk of the paper's real-world demo: book, pen, mug.

The book lies anywhere on the desk, turned by up to ``max_turn``; the pen lies to the book's right
(along the book's +x axis) at a varying distance ``d``; the mug stands to the book's left at
``mug_base + mug_gain * d``: the farther the pen from the book, the farther the mug. A pencil (a
class never trained on, long and thin like the pen) can stand in for the pen at test time.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..scene.scene import Scene, SceneError, SceneObject, wrap_angle

__all__ = ["DeskScenario", "DESK_CATALOGUE"]

DESK_CATALOGUE: dict[str, tuple[tuple[float, float], tuple[int, int, int], str]] = {
    "book": ((0.15, 0.22), (150, 40, 40), "box"),
    "pen": ((0.14, 0.012), (30, 40, 160), "box"),
    "pencil": ((0.17, 0.009), (230, 190, 40), "box"),
    "mug": ((0.09, 0.09), (230, 230, 225), "disk"),
}


@dataclass
class DeskScenario:
    """Seeded book-pen-mug arrangements, with an oracle for the mug."""

    name: str = "desk"
    half: tuple[float, float] = (0.6, 0.4)  # the desk is [-hx, hx] x [-hy, hy] (m)
    pen_min: float = 0.12  # book centre to pen centre (m)
    pen_max: float = 0.30
    mug_base: float = 0.05  # book centre to mug centre: mug_base + mug_gain * pen distance (m)
    mug_gain: float = 1.0
    max_turn: float = math.radians(30.0)
    pos_noise: float = 0.004
    n_train: int = 48
    n_test: int = 16

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        hx, hy = self.half
        return ((-hx, -hy), (hx, hy))

    def mug_distance(self, pen_distance: float) -> float:
        """The true relation: book centre to mug centre, given the pen's distance from the book."""
        return self.mug_base + self.mug_gain * pen_distance

    def _obj(self, cat: str, pose, fixed: bool = False) -> SceneObject:
        size, color, shape = DESK_CATALOGUE[cat]
        return SceneObject(cat, cat, size, pose, color=color, fixed=fixed, shape=shape)

    def arrange(
        self, book: tuple[float, float, float], pen_distance: float, pen: str = "pen", mug: bool = True
    ) -> Scene:
        """The noise-free arrangement: book at ``book``, the pen (or ``pen="pencil"``) at ``pen_distance``,
        the mug where the relation puts it (or ``mug=False``: its pose ``null``)."""
        if pen not in ("pen", "pencil"):
            raise SceneError(f"desk: the writing tool is 'pen' or 'pencil', not {pen!r}")
        x, y, th = book
        c, s = math.cos(th), math.sin(th)
        pen_pose = (x + pen_distance * c, y + pen_distance * s, wrap_angle(th + math.pi / 2))
        m = self.mug_distance(pen_distance)
        mug_pose = (x - m * c, y - m * s, 0.0) if mug else None
        objs = [self._obj("book", book), self._obj(pen, pen_pose), self._obj("mug", mug_pose)]
        return Scene(objs, self.bounds, meta={"scenario": self.name, "pen_distance": float(pen_distance)})

    def generate(self, n: int, seed: int, pen: str = "pen") -> list[Scene]:
        return list(self.iter_scenes(n, seed, pen))

    def iter_scenes(self, n: int, seed: int, pen: str = "pen") -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream (none held)."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            d = rng.uniform(self.pen_min, self.pen_max)
            reach = max(d, self.mug_distance(d)) + 0.08
            th = rng.uniform(-self.max_turn, self.max_turn)
            x = rng.uniform(-self.half[0] + reach, self.half[0] - reach)
            y = rng.uniform(-self.half[1] + 0.15, self.half[1] - 0.15)
            s = self.arrange((float(x), float(y), float(th)), float(d), pen=pen)
            noisy = s.poses()
            noisy[1:, :2] += rng.normal(0, self.pos_noise, (2, 2))
            noisy[2, 2] = rng.uniform(-math.pi, math.pi)  # a mug (disk) has no visible heading
            yield s.with_poses(noisy)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        return self.generate(self.n_train, seed * 2 + 71), self.generate(self.n_test, seed * 2 + 72)

    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]:
        if name != "mug":
            raise SceneError(f"oracle: the desk process predicts the mug only, not {name!r}")
        book = scene["book"].pose
        tool = next((o for o in scene.objects if o.category in ("pen", "pencil")), None)
        if book is None or tool is None or tool.pose is None:
            raise SceneError("oracle: the mug needs the book and the pen (or pencil)")
        d = math.hypot(tool.pose[0] - book[0], tool.pose[1] - book[1])
        m = self.mug_distance(d)
        return (book[0] - m * math.cos(book[2]), book[1] - m * math.sin(book[2]), 0.0)
