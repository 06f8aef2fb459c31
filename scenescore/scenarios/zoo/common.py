"""What every zoo scenario shares: poses in a frame, clipped noise, objects, the validity checks, the
oracles' look-ups, and :class:`ZooScenario`, the base class that draws, redraws and splits.

The footprint geometry (extents, overlap) is :mod:`scenescore.geometry.exact`'s, the one numpy/shapely form
the costs' exact checks also use.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Any, ClassVar, cast

import numpy as np

from ...geometry.exact import footprint_extent, footprints_overlap
from ...scene.scene import Bounds, Scene, SceneError, SceneObject, wrap_angle

__all__ = [
    "Pose",
    "Colour",
    "Layout",
    "ZooScenario",
    "in_frame",
    "to_frame",
    "clipped_noise",
    "jitter",
    "random_heading",
    "make_object",
    "wall_frame",
    "inside_bounds",
    "overlap_free",
    "shift_into_bounds",
    "pose_of",
    "placed_of",
    "anchor_of",
    "checked_target",
    "free_slot",
    "free_slots",
    "FreeSlotScenario",
]

Pose = tuple[float, float, float]
Colour = tuple[int, int, int]
Layout = tuple[list[SceneObject], dict[str, Any]]  # one draw's objects and the scene's notes (meta)
_TRIES = 500  # draws per scene before giving up
_CLIP = 2.5  # noise is clipped at this many standard deviations


# -- poses and noise ----------------------------------------------------------------------------------
def in_frame(pose: Sequence[float], u: float, v: float, dtheta: float = 0.0) -> Pose:
    """The pose at ``(u, v)`` in the frame ``pose``, turned by ``dtheta`` from it."""
    x, y, t = pose
    c, s = math.cos(t), math.sin(t)
    return (float(x + c * u - s * v), float(y + s * u + c * v), float(wrap_angle(t + dtheta)))


def to_frame(pose: Sequence[float], x: float, y: float) -> tuple[float, float]:
    """``(x, y)`` in the frame ``pose``."""
    px, py, t = pose
    c, s = math.cos(t), math.sin(t)
    dx, dy = x - px, y - py
    return (c * dx + s * dy, -s * dx + c * dy)


def clipped_noise(rng: np.random.Generator, sigma: float, n: int | None = None) -> Any:
    """Gaussian noise clipped at ``_CLIP`` standard deviations (so that designed gaps stay open): a
    float, or an array of ``n``."""
    return np.clip(rng.normal(0.0, sigma, n), -_CLIP * sigma, _CLIP * sigma)


def jitter(rng: np.random.Generator, pose: Pose, sigma: float, angle_sigma: float) -> Pose:
    """``pose`` moved by clipped noise: ``sigma`` metres on each axis, ``angle_sigma`` radians (none if 0)."""
    dx, dy = clipped_noise(rng, sigma, 2)
    dt = float(clipped_noise(rng, angle_sigma)) if angle_sigma > 0 else 0.0
    return (float(pose[0] + dx), float(pose[1] + dy), float(wrap_angle(pose[2] + dt)))


def random_heading(rng: np.random.Generator) -> float:
    """An arbitrary angle for a disk, whose orientation nothing shows."""
    return float(rng.uniform(-math.pi, math.pi))


def make_object(
    cat: str,
    k: int | str,
    size: tuple[float, float],
    pose: Pose,
    color: Colour,
    shape: str = "box",
    fixed: bool = False,
) -> SceneObject:
    """The object ``{cat}_{k}`` of category ``cat``."""
    return SceneObject(
        f"{cat}_{k}",
        cat,
        (float(size[0]), float(size[1])),
        pose,
        color=tuple(int(c) for c in color),  # type: ignore[arg-type]
        fixed=fixed,
        shape=shape,
    )


def wall_frame(half: float, wall: int, t: float, depth: float) -> Pose:
    """The pose of an object whose back is against wall ``wall`` (0: x = -half, then anticlockwise),
    ``t`` along the wall and its centre ``depth`` from it, heading into the room."""
    a = wall * math.pi / 2
    n = (math.cos(a), math.sin(a))
    tau = (-n[1], n[0])
    return (
        float(-half * n[0] + depth * n[0] + t * tau[0]),
        float(-half * n[1] + depth * n[1] + t * tau[1]),
        float(wrap_angle(a)),
    )


# -- a draw's validity --------------------------------------------------------------------------------
def _extent(o: SceneObject) -> tuple[float, float, float, float]:
    """The placed object's footprint extent ``(xmin, ymin, xmax, ymax)``."""
    return footprint_extent(o, cast(Pose, o.pose))


def inside_bounds(objs: list[SceneObject], bounds: Bounds, margin: float = 0.0) -> bool:
    """Whether every footprint lies inside ``bounds``, ``margin`` from its sides."""
    (x0, y0), (x1, y1) = bounds
    for o in objs:
        a, b, c, d = _extent(o)
        if a < x0 + margin or b < y0 + margin or c > x1 - margin or d > y1 - margin:
            return False
    return True


def overlap_free(objs: list[SceneObject]) -> bool:
    """Whether no two footprints overlap (touching is allowed)."""
    ext = [_extent(o) for o in objs]
    for i in range(len(objs)):
        for j in range(i + 1, len(objs)):
            a, b = ext[i], ext[j]
            if a[2] < b[0] or b[2] < a[0] or a[3] < b[1] or b[3] < a[1]:
                continue  # bounding boxes apart
            if footprints_overlap(objs[i], cast(Pose, objs[i].pose), objs[j], cast(Pose, objs[j].pose)):
                return False
    return True


def shift_into_bounds(
    rng: np.random.Generator, objs: list[SceneObject], bounds: Bounds, margin: float
) -> bool:
    """Translate the whole group uniformly at random to somewhere it fits; ``False`` if it cannot."""
    ext = np.array([_extent(o) for o in objs])
    (x0, y0), (x1, y1) = bounds
    lo_x, hi_x = x0 + margin - ext[:, 0].min(), x1 - margin - ext[:, 2].max()
    lo_y, hi_y = y0 + margin - ext[:, 1].min(), y1 - margin - ext[:, 3].max()
    if lo_x > hi_x or lo_y > hi_y:
        return False
    dx, dy = rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)
    for o in objs:
        x, y, t = o.pose  # type: ignore[misc]
        o.pose = (float(x + dx), float(y + dy), float(t))
    return True


# -- the oracles' look-ups ----------------------------------------------------------------------------
def pose_of(scene: Scene, name: str, target: str) -> Pose:
    """``name``'s pose; an error names ``target`` (the object the oracle is placing) if there is none."""
    try:
        p = scene[name].pose
    except SceneError:
        raise SceneError(
            f"oracle: {target!r} needs an object called {name!r}, which the scene lacks"
        ) from None
    if p is None:
        raise SceneError(f"oracle: {target!r} needs {name!r}'s pose, which is null")
    return p


def placed_of(scene: Scene, category: str, but: str | None = None) -> list[SceneObject]:
    """The objects of ``category`` with a pose, other than ``but``."""
    return [o for o in scene.objects if o.category == category and o.name != but and o.pose is not None]


def anchor_of(scene: Scene, category: str, target: str) -> SceneObject:
    """The scene's first object of ``category`` (its fixed anchor: the chip, the bed, the table ...),
    which must have a pose; an error names ``target``."""
    objs = [o for o in scene.objects if o.category == category]
    if not objs or objs[0].pose is None:
        raise SceneError(f"oracle: {target!r} needs the scene's {category} (with a pose)")
    return objs[0]


def checked_target(scene: Scene, name: str, allowed: Sequence[str], scenario: str) -> SceneObject:
    """The object ``name``, which must be of a category the oracle of ``scenario`` places."""
    obj = scene[name]
    if obj.category not in allowed:
        raise SceneError(f"oracle: {scenario} places {', '.join(allowed)}, not {name!r} (a {obj.category})")
    return obj


def free_slot(slots: list[Pose], others: list[SceneObject]) -> Pose:
    """The slot farthest from every other object of the row (the one the masked object left)."""
    if not others:
        return slots[len(slots) // 2]
    pts = np.array([o.pose[:2] for o in others])  # type: ignore[index]
    gaps = [float(np.min(np.hypot(*(pts - np.array(s[:2])).T))) for s in slots]
    return slots[int(np.argmax(gaps))]


def free_slots(slots: list[Pose], others: list[SceneObject], k: int) -> list[Pose]:
    """The ``k`` slots farthest from every other object (the ones the ``k`` masked objects left), each
    slot once, farthest first; without others, the first ``k``."""
    if k > len(slots):
        raise SceneError(f"oracle: {k} objects to place but only {len(slots)} slots")
    if not others:
        return slots[:k]
    pts = np.array([o.pose[:2] for o in others])  # type: ignore[index]
    gaps = [float(np.min(np.hypot(*(pts - np.array(s[:2])).T))) for s in slots]
    order = np.argsort(-np.array(gaps), kind="stable")
    return [slots[int(i)] for i in order[:k]]


# -- the base class -----------------------------------------------------------------------------------
class ZooScenario:
    """Shared machinery: bounds from ``half``, seeded generation with redraws, the split.

    A scenario implements :meth:`_layout`: one draw of the objects from ``rng`` (or None to draw
    again); :meth:`generate` keeps a draw once every footprint is inside the bounds and none overlap.
    """

    _stream: ClassVar[int] = 0  # the split's seeds are ``2 * seed + _stream`` and the next
    name: str
    half: tuple[float, float]
    n_train: int
    n_test: int
    margin: ClassVar[float] = 0.0  # objects keep this far inside the bounds
    missing_count: ClassVar[int] = 1  # objects the zoo experiment removes from each test scene

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        hx, hy = self.half
        return ((-hx, -hy), (hx, hy))

    def generate(self, n: int, seed: int) -> list[Scene]:
        """``n`` scenes from the process, reproducible from ``seed``."""
        return list(self.iter_scenes(n, seed))

    def iter_scenes(self, n: int, seed: int) -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream (none held)."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            yield self._draw_scene(rng)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        """The experiment's training and test scenes (disjoint random streams)."""
        s = self._stream
        return self.generate(self.n_train, seed * 2 + s), self.generate(self.n_test, seed * 2 + s + 1)

    def _draw_scene(self, rng: np.random.Generator) -> Scene:
        """One valid scene: layouts drawn from ``rng`` until one fits the bounds without overlap."""
        for _ in range(_TRIES):
            drawn = self._layout(rng)
            if drawn is None:
                continue
            objs, meta = drawn
            if inside_bounds(objs, self.bounds, self.margin) and overlap_free(objs):
                return Scene(objs, self.bounds, meta={"scenario": self.name, **meta})
        raise SceneError(f"{self.name}: no valid scene in {_TRIES} draws; are the bounds too small?")

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The process's best guess for ``name`` from every other object's pose."""
        raise NotImplementedError

    def oracle_many(self, scene: Scene, names: Sequence[str]) -> list[Pose]:
        """The oracle's poses for the objects ``names``, all masked in ``scene`` at once, in any order (a
        caller matches them to the truths by assignment). Here each by :meth:`oracle`; scenarios whose
        masked objects are interchangeable return the free slots instead."""
        return [self.oracle(scene, n) for n in names]

    def _layout(self, rng: np.random.Generator) -> Layout | None:
        raise NotImplementedError


class FreeSlotScenario(ZooScenario):
    """A scenario whose missing objects are interchangeable and each fill a slot (a chair at a desk):
    the oracle returns the slots no present object of the missing category occupies. A subclass gives
    :meth:`_slots`, every slot of the scene, and one ``missing`` category."""

    missing: tuple[str, ...]

    def _slots(self, scene: Scene) -> list[Pose]:
        raise NotImplementedError

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The slot that no present object of the missing category occupies."""
        checked_target(scene, name, self.missing, self.name)
        return free_slot(self._slots(scene), placed_of(scene, self.missing[0], but=name))

    def oracle_many(self, scene: Scene, names: Sequence[str]) -> list[Pose]:
        """The slots that no present object of the missing category occupies, one each."""
        for n in names:
            checked_target(scene, n, self.missing, self.name)
        present = [o for o in placed_of(scene, self.missing[0]) if o.name not in names]
        return free_slots(self._slots(scene), present, len(names))
