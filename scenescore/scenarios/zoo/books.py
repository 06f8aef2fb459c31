"""zoo-books: books sorted by depth from a fixed bookend, backs to the wall."""

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
    jitter,
    make_object,
    placed_of,
)

__all__ = ["BookshelfScenario"]

BOOK_COLOURS: tuple[Colour, ...] = (
    (140, 30, 35),
    (25, 55, 110),
    (30, 90, 60),
    (220, 200, 150),
    (35, 35, 40),
    (200, 120, 40),
    (110, 70, 120),
    (235, 235, 225),
)


@dataclass
class BookshelfScenario(ZooScenario):
    """4-24 books standing on a 1.2 m x 0.3 m shelf, sorted by depth (deepest first) from a fixed
    bookend at the row's left or right end (two modes), their backs flush a centimetre from the wall,
    a fixed gap between neighbours. Thickness and depth vary per book.

    The oracle sorts every book by depth and sums the thicknesses before the masked one's place.
    """

    _stream: ClassVar[int] = 171
    name: str = "zoo-books"
    half: tuple[float, float] = (0.6, 0.15)
    bookend: tuple[float, float] = (0.14, 0.02)  # depth, thickness
    thickness: tuple[float, float] = (0.015, 0.05)
    depth: tuple[float, float] = (0.12, 0.26)
    books: tuple[int, int] = (4, 24)
    gap: float = 0.008
    back: float = 0.01  # book backs to the wall (the bounds' +y edge)
    pos_noise: float = 0.001
    angle_noise: float = math.radians(0.3)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("book",)
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (self.books[0] + 1, self.books[1] + 1)

    def _order(self, books: list[SceneObject]) -> list[SceneObject]:
        return sorted(books, key=lambda o: (-o.size[0], o.name))

    def _places(self, end: Pose, direction: float, books: list[SceneObject]) -> dict[str, Pose]:
        """Every book's place, from the bookend's."""
        hy = self.half[1]
        s = self.bookend[1] / 2
        out = {}
        for o in self._order(books):
            s += self.gap + o.size[1] / 2
            out[o.name] = (end[0] + direction * s, hy - self.back - o.size[0] / 2, math.pi / 2)
            s += o.size[1] / 2
        return out

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        hx, hy = self.half
        n = int(rng.integers(self.books[0], self.books[1] + 1))
        th = rng.uniform(*self.thickness, n)
        length = self.bookend[1] / 2 + float(np.sum(th + self.gap))
        room = 2 * hx - 0.02 - self.bookend[1] / 2 - length
        if room < 0:
            return None
        direction = float(rng.choice([-1.0, 1.0]))
        x = -direction * (hx - 0.01 - self.bookend[1] / 2) + direction * float(rng.uniform(0, room))
        end = (x, hy - self.back - self.bookend[0] / 2, math.pi / 2)
        objs = [make_object("bookend", 0, self.bookend, end, (90, 90, 95), fixed=True)]
        books: list[SceneObject] = []
        for k in rng.permutation(n):
            size = (float(rng.uniform(*self.depth)), float(th[len(books)]))
            books.append(
                make_object("book", int(k), size, end, BOOK_COLOURS[int(rng.integers(len(BOOK_COLOURS)))])
            )
        books.sort(key=lambda o: int(o.name.rpartition("_")[2]))
        places = self._places(end, direction, books)
        for o in books:
            o.pose = jitter(rng, places[o.name], self.pos_noise, self.angle_noise)
        return objs + books, {"direction": direction}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The masked book's place in the depth order, counted from the bookend."""
        checked_target(scene, name, self.missing, self.name)
        end = anchor_of(scene, "bookend", name).pose
        assert end is not None
        others = placed_of(scene, "book", but=name)
        if not others:
            raise SceneError(f"oracle: {name!r} needs another book to see which way the row runs")
        direction = math.copysign(1.0, float(np.mean([cast(Pose, o.pose)[0] for o in others])) - end[0])
        return self._places(end, direction, [o for o in scene.objects if o.category == "book"])[name]
