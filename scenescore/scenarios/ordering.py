"""Rows of cutlery ordered by a rule (the paper's second experiment, novel objects, Table 2).

A fixed reference object (a ``board``) anchors a row; the cutlery lies side by side to its right,
one slot every ``spacing`` metres, each piece pointing along +y. The rule decides the order:

- ``class_size``: grouped by class (in the order of ``classes``), longest first within a class;
- ``all_size``: longest first, whatever the class;
- ``unseen_class``: trained on forks and knives as ``class_size``; the test rows hold spoons (a
  class never trained on) beside forks.

Lengths come from two disjoint grids: training scenes draw from ``TRAIN_LENGTHS``, test scenes from
``TEST_LENGTHS``, so no test size appears in training. Names: ``board``, ``fork_0``, ``knife_1``, ...
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scene.scene import Scene, SceneError, SceneObject

__all__ = ["OrderingScenario", "RULES", "TRAIN_LENGTHS", "TEST_LENGTHS", "CUTLERY"]

RULES = ("class_size", "all_size", "unseen_class")

# category -> (width m, colour, shape); the length varies per object
CUTLERY: dict[str, tuple[float, tuple[int, int, int]]] = {
    "fork": (0.026, (165, 165, 180)),
    "knife": (0.018, (205, 205, 212)),
    "spoon": (0.038, (185, 175, 160)),
}
TRAIN_LENGTHS = (0.14, 0.16, 0.18, 0.20, 0.22, 0.24)
TEST_LENGTHS = (0.15, 0.17, 0.19, 0.21, 0.23)
BOARD = ((0.30, 0.04), (120, 80, 50))  # (length along its heading, width): a bar along +y like the cutlery


@dataclass
class OrderingScenario:
    """Seeded generator of ordered rows of cutlery, with an oracle that knows the rule."""

    rule: str = "class_size"
    name: str = "ordering"
    per_class: int = 3  # pieces of each class in a row
    spacing: float = 0.05  # distance between slot centres (m)
    first_gap: float = 0.06  # board centre to the first slot (m)
    shift: float = 0.05  # the row is translated by up to this much in x and y (m)
    pos_noise: float = 0.003
    angle_noise: float = math.radians(2.0)
    n_train: int = 16
    n_test: int = 16
    symmetric: tuple[str, ...] = ("fork", "knife", "spoon")  # orientation error is not scored

    def __post_init__(self) -> None:
        if self.rule not in RULES:
            raise SceneError(f"unknown ordering rule {self.rule!r}; choose from {', '.join(RULES)}")

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return ((-0.35, -0.25), (0.35, 0.25))

    @property
    def missing(self) -> tuple[str, ...]:
        """The categories a test removes (every piece of cutlery)."""
        return tuple(CUTLERY)

    def classes(self, test: bool) -> tuple[str, str]:
        if self.rule == "unseen_class" and test:
            return ("fork", "spoon")
        return ("fork", "knife")

    def generate(self, n: int, seed: int, test: bool = False) -> list[Scene]:
        """``n`` rows, reproducible from ``seed``; ``test`` draws the test lengths (and spoons)."""
        return list(self.iter_scenes(n, seed, test))

    def iter_scenes(self, n: int, seed: int, test: bool = False) -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream (none held)."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            yield self._one(rng, test)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        return (
            self.generate(self.n_train, seed * 2 + 31, test=False),
            self.generate(self.n_test, seed * 2 + 32, test=True),
        )

    def origin(self, scene: Scene) -> tuple[float, float]:
        pose = scene["board"].pose
        if pose is None:
            raise SceneError("ordering: the board has no pose")
        return (pose[0], pose[1])

    def order(self, items: list[tuple[str, str, float]]) -> list[str]:
        """Names of ``(name, category, length)`` in the rule's order."""
        classes = sorted({c for _, c, _ in items}, key=lambda c: list(CUTLERY).index(c))
        key: Callable[[tuple[str, str, float]], tuple[Any, ...]]
        if self.rule == "all_size":
            key = lambda it: (-it[2], it[0])  # noqa: E731
        else:
            key = lambda it: (classes.index(it[1]), -it[2], it[0])  # noqa: E731
        return [nm for nm, _, _ in sorted(items, key=key)]

    def slot(self, origin: tuple[float, float], k: int) -> tuple[float, float, float]:
        return (origin[0] + self.first_gap + k * self.spacing, origin[1], math.pi / 2)

    def _one(self, rng: np.random.Generator, test: bool) -> Scene:
        grid = TEST_LENGTHS if test else TRAIN_LENGTHS
        ox = -0.28 + rng.uniform(-self.shift, self.shift)
        oy = rng.uniform(-self.shift, self.shift)
        items = []
        for cat in self.classes(test):
            lengths = rng.choice(grid, size=self.per_class, replace=False)
            for j, length in enumerate(lengths):
                items.append((f"{cat}_{j}", cat, float(length)))
        objects = [SceneObject("board", "board", BOARD[0], (ox, oy, math.pi / 2), color=BOARD[1], fixed=True)]
        length_of = {nm: ln for nm, _, ln in items}
        cats = {nm: c for nm, c, _ in items}
        for k, nm in enumerate(self.order(items)):
            x, y, th = self.slot((ox, oy), k)
            dx, dy = rng.normal(0, self.pos_noise, 2)
            width, color = CUTLERY[cats[nm]]
            pose = (float(x + dx), float(y + dy), float(th + rng.normal(0, self.angle_noise)))
            objects.append(SceneObject(nm, cats[nm], (length_of[nm], width), pose, color=color))
        meta = {"scenario": self.name, "rule": self.rule, "test": test}
        return Scene(objects, self.bounds, meta=meta)

    # -- the oracle ---------------------------------------------------------------------------------
    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]:
        """The slot the rule gives ``name``, from the sizes and classes of the whole row."""
        items = [(o.name, o.category, float(o.size[0])) for o in scene.objects if o.category in CUTLERY]
        if name not in [nm for nm, _, _ in items]:
            raise SceneError(f"oracle: no piece of cutlery {name!r} in the row")
        return self.slot(self.origin(scene), self.order(items).index(name))
