"""The dining table of the paper's first experiment (missing objects, Table 1).

A round table with two place settings at any angle around it. Each setting is a plate facing the
table's centre, a fork and a knife an equal, varying distance either side of it (which side the fork
is on varies: the data are multi-modal), and a bowl further in. Poses carry a little noise.
Object names end in the setting's index: ``plate_0, fork_0, knife_0, bowl_0, plate_1, ...``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..scene.scene import Scene, SceneError, SceneObject, wrap_angle

__all__ = ["DiningScenario", "CATALOGUE"]

# category -> (size [l, w] m, colour, shape)
CATALOGUE: dict[str, tuple[tuple[float, float], tuple[int, int, int], str]] = {
    "plate": ((0.24, 0.24), (240, 240, 232), "disk"),
    "bowl": ((0.14, 0.14), (70, 120, 200), "disk"),
    "fork": ((0.19, 0.03), (165, 165, 180), "box"),
    "knife": ((0.22, 0.022), (205, 205, 212), "box"),
}


@dataclass
class DiningScenario:
    """Seeded generator of dining scenes, with an oracle that knows the process."""

    name: str = "dining"
    table_radius: float = 0.6
    plate_radius: float = 0.42  # plate centres lie on this circle
    side_min: float = 0.15  # fork/knife distance either side of the plate (m)
    side_max: float = 0.21
    bowl_offset: float = 0.19  # bowl, towards the table's centre from the plate (m)
    pos_noise: float = 0.005  # std of position noise on fork, knife, bowl (m)
    angle_noise: float = math.radians(3.0)  # std of orientation noise on fork and knife
    settings: int = 2
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("bowl", "fork", "knife")  # the categories the experiment removes
    symmetric: tuple[str, ...] = ("plate", "bowl")  # orientation error is not counted for these

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        r = self.table_radius
        return ((-r, -r), (r, r))

    def generate(self, n: int, seed: int) -> list[Scene]:
        """``n`` scenes from the process, reproducible from ``seed``."""
        return list(self.iter_scenes(n, seed))

    def iter_scenes(self, n: int, seed: int) -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream (none held)."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            yield self._one(rng)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        """The experiment's training and test scenes (disjoint random streams)."""
        return self.generate(self.n_train, seed * 2 + 11), self.generate(self.n_test, seed * 2 + 12)

    def _obj(self, cat: str, k: int, pose: tuple[float, float, float]) -> SceneObject:
        size, color, shape = CATALOGUE[cat]
        return SceneObject(name=f"{cat}_{k}", category=cat, size=size, pose=pose, color=color, shape=shape)

    def _one(self, rng: np.random.Generator) -> Scene:
        phi0 = rng.uniform(-math.pi, math.pi)
        phis = [
            phi0 + k * 2 * math.pi / self.settings + rng.uniform(-math.pi / 3, math.pi / 3) * (k > 0)
            for k in range(self.settings)
        ]
        objects, settings_meta = [], []
        for k, phi in enumerate(phis):
            side = float(rng.choice([-1.0, 1.0]))
            d = rng.uniform(self.side_min, self.side_max)
            inward = phi + math.pi
            px, py = self.plate_radius * math.cos(phi), self.plate_radius * math.sin(phi)
            frame = _Frame(px, py, inward)
            # a disk has no visible orientation: its angle is arbitrary, as an image would give it
            objects.append(self._obj("plate", k, (px, py, rng.uniform(-math.pi, math.pi))))

            objects.append(self._obj("fork", k, self._noisy(rng, frame, 0.0, side * d, True)))
            objects.append(self._obj("knife", k, self._noisy(rng, frame, 0.0, -side * d, True)))
            bowl = self._noisy(rng, frame, self.bowl_offset, 0.0, False)
            objects.append(self._obj("bowl", k, bowl))
            settings_meta.append({"phi": phi, "fork_side": side, "distance": d})
        return Scene(objects, self.bounds, meta={"scenario": self.name, "settings": settings_meta})

    def _noisy(
        self, rng: np.random.Generator, frame: _Frame, u: float, v: float, directed: bool
    ) -> tuple[float, float, float]:
        """The pose at ``(u, v)`` in the setting's frame, with noise; heading inward (random if not ``directed``)."""
        du, dv = rng.normal(0, self.pos_noise, 2)
        dt = rng.normal(0, self.angle_noise) if directed else rng.uniform(-math.pi, math.pi)
        x, y = frame.to_world(u + du, v + dv)
        return (float(x), float(y), float(wrap_angle(frame.theta + dt)))

    # -- the oracle ---------------------------------------------------------------------------------
    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]:
        """The process's best guess for ``name``'s pose given the rest of its setting."""
        cat, _, k = name.rpartition("_")
        plate = scene[f"plate_{k}"].pose
        if plate is None:
            raise SceneError(f"oracle: plate_{k} has no pose; the oracle needs the plate of {name!r}")
        inward = math.atan2(plate[1], plate[0]) + math.pi  # the table's centre is the origin
        frame = _Frame(plate[0], plate[1], inward)
        if cat == "bowl":
            x, y = frame.to_world(self.bowl_offset, 0.0)
            return (x, y, 0.0)
        if cat in ("fork", "knife"):
            other = scene[f"{'knife' if cat == 'fork' else 'fork'}_{k}"].pose
            if other is None:
                raise SceneError(f"oracle: {name!r} needs its setting's other piece of cutlery")
            u, v = frame.to_local(other[0], other[1])
            x, y = frame.to_world(0.0, -v)
            return (x, y, float(wrap_angle(inward)))
        if cat == "plate":
            bowl = scene[f"bowl_{k}"].pose
            if bowl is None:
                raise SceneError(f"oracle: {name!r} needs its setting's bowl")
            phi = math.atan2(bowl[1], bowl[0])
            r = self.plate_radius
            return (r * math.cos(phi), r * math.sin(phi), 0.0)
        raise SceneError(f"oracle: no object {name!r} in the dining process")


@dataclass
class _Frame:
    """A 2-D frame at ``(x, y)`` with heading ``theta``."""

    x: float
    y: float
    theta: float

    def to_world(self, u: float, v: float) -> tuple[float, float]:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (self.x + c * u - s * v, self.y + s * u + c * v)

    def to_local(self, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(self.theta), math.sin(self.theta)
        dx, dy = x - self.x, y - self.y
        return (c * dx + s * dy, -s * dx + c * dy)
