"""A zoo of seeded arrangement processes for robustness testing, each with an oracle.

Every scenario here is a dataclass with ``name``, ``n_train``, ``n_test``, a ``bounds`` property,
``generate(n, seed)``, ``split(seed)``, ``missing`` (the categories an experiment removes and asks a
method to place back: never fixed, always present in a scene), ``symmetric`` (categories whose
orientation means nothing: disks and squares), ``counts`` (the fewest and most objects in a scene) and
``oracle(scene, name)``: the process's best guess for ``name`` from every *other* object's pose (it
never reads the named object's pose, only its size), so that its error is the process noise.

Together they span object sizes from 1 cm (a resistor) to 3 m (a banquet table), bounds from 0.3 m
across (a circuit board) to 10 m (a banquet hall), 2 to 25 objects a scene, fixed furniture,
multi-modal relations (which side, which end, which hand), chains of dependence, rows and grids of a
variable count, symmetric footprints and relations that depend on the objects' sizes:

========================  ====================================================================
``zoo-pcb``               resistors in a row (2-8) beside a fixed chip, on one of its 4 sides
``zoo-jars``              a grid of 2x2 .. 4x5 jars on a shelf; the pitch grows with the jar
``zoo-bedroom``           fixed bed; nightstand(s) either side of its head; a lamp beside each
``zoo-banquet``           fixed 3 m table in a 10 m hall; 4-12 chairs around it; a fixed sideboard
``zoo-workstation``       fixed monitor -> keyboard -> mouse on the right or left, mug opposite
``zoo-garden``            pots in a row from a fixed bench, largest first, gaps scale with the pots
``zoo-cascade``           crate -> case -> tin -> matchbox, each beside the last, turning one way
``zoo-books``             4-24 books sorted by depth from a fixed bookend, backs flush to the wall
``zoo-lounge``            fixed 2 m sofa in a 4.4 m room; coffee table, side table at one end
``zoo-hall``              fixed 2 m console anywhere in a 4.4 m hall; vases at its ends, a stool
========================  ====================================================================

Poses carry clipped Gaussian noise (about 1-3 % of the relation's length scale). Scenes are drawn
again (from the same stream, so still reproducible) until every object lies inside the bounds and no
two footprints overlap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np

from ..scene import Scene, SceneError, SceneObject, wrap_angle

__all__ = [
    "ZOO",
    "PcbScenario",
    "JarGridScenario",
    "BedroomScenario",
    "BanquetScenario",
    "WorkstationScenario",
    "GardenScenario",
    "CascadeScenario",
    "BookshelfScenario",
    "LoungeScenario",
    "HallScenario",
    "footprint_extent",
    "footprints_overlap",
]

Pose = tuple[float, float, float]
Colour = tuple[int, int, int]
_TRIES = 500  # draws per scene before giving up
_CLIP = 2.5  # noise is clipped at this many standard deviations


# -- helpers ------------------------------------------------------------------------------------------
def _compose(pose: Sequence[float], u: float, v: float, dtheta: float = 0.0) -> Pose:
    """The pose at ``(u, v)`` in the frame ``pose``, turned by ``dtheta`` from it."""
    x, y, t = pose
    c, s = math.cos(t), math.sin(t)
    return (float(x + c * u - s * v), float(y + s * u + c * v), float(wrap_angle(t + dtheta)))


def _local(pose: Sequence[float], x: float, y: float) -> tuple[float, float]:
    """``(x, y)`` in the frame ``pose``."""
    px, py, t = pose
    c, s = math.cos(t), math.sin(t)
    dx, dy = x - px, y - py
    return (c * dx + s * dy, -s * dx + c * dy)


def _noise(rng: np.random.Generator, sigma: float, n: int | None = None):
    """Gaussian noise clipped at ``_CLIP`` standard deviations (so that designed gaps stay open)."""
    return np.clip(rng.normal(0.0, sigma, n), -_CLIP * sigma, _CLIP * sigma)


def _jitter(rng: np.random.Generator, pose: Pose, sigma: float, angle_sigma: float) -> Pose:
    dx, dy = _noise(rng, sigma, 2)
    dt = float(_noise(rng, angle_sigma)) if angle_sigma > 0 else 0.0
    return (float(pose[0] + dx), float(pose[1] + dy), float(wrap_angle(pose[2] + dt)))


def _spin(rng: np.random.Generator) -> float:
    """An arbitrary angle for a disk, whose orientation nothing shows."""
    return float(rng.uniform(-math.pi, math.pi))


def _obj(
    cat: str,
    k: int | str,
    size: tuple[float, float],
    pose: Pose,
    color: Colour,
    shape: str = "box",
    fixed: bool = False,
) -> SceneObject:
    return SceneObject(
        f"{cat}_{k}",
        cat,
        (float(size[0]), float(size[1])),
        pose,
        color=tuple(int(c) for c in color),  # type: ignore[arg-type]
        fixed=fixed,
        shape=shape,
    )


def footprint_extent(
    o: SceneObject, pose: Sequence[float] | None = None
) -> tuple[float, float, float, float]:
    """``(xmin, ymin, xmax, ymax)`` of the footprint (exact for round disks and polygons)."""
    pose = o.pose if pose is None else pose
    if pose is None:
        raise SceneError(f"object {o.name!r}: has no pose")
    if o.round:
        r = o.size[0] / 2
        return (pose[0] - r, pose[1] - r, pose[0] + r, pose[1] + r)
    pts = o.world_polygon(pose)
    return (float(pts[:, 0].min()), float(pts[:, 1].min()), float(pts[:, 0].max()), float(pts[:, 1].max()))


def _geom(o: SceneObject):
    from shapely.geometry import Point, Polygon

    if o.round:
        pose = cast(Pose, o.pose)
        return Point(pose[0], pose[1]), o.size[0] / 2
    return Polygon(o.world_polygon()), 0.0


def footprints_overlap(a: SceneObject, b: SceneObject) -> bool:
    """Whether two placed footprints overlap (touching is not overlapping); shapely, exact for circles."""
    ga, ra = _geom(a)
    gb, rb = _geom(b)
    if ra + rb > 0:
        return bool(ga.distance(gb) < ra + rb - 1e-12)
    return bool(ga.intersection(gb).area > 1e-14)


def _inside(objs: list[SceneObject], bounds, margin: float = 0.0) -> bool:
    (x0, y0), (x1, y1) = bounds
    for o in objs:
        a, b, c, d = footprint_extent(o)
        if a < x0 + margin or b < y0 + margin or c > x1 - margin or d > y1 - margin:
            return False
    return True


def _overlap_free(objs: list[SceneObject]) -> bool:
    ext = [footprint_extent(o) for o in objs]
    for i in range(len(objs)):
        for j in range(i + 1, len(objs)):
            a, b = ext[i], ext[j]
            if a[2] < b[0] or b[2] < a[0] or a[3] < b[1] or b[3] < a[1]:
                continue  # bounding boxes apart
            if footprints_overlap(objs[i], objs[j]):
                return False
    return True


def _shift_into(rng: np.random.Generator, objs: list[SceneObject], bounds, margin: float) -> bool:
    """Translate the whole group uniformly at random to somewhere it fits; ``False`` if it cannot."""
    ext = np.array([footprint_extent(o) for o in objs])
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


def _pose(scene: Scene, name: str, target: str) -> Pose:
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


def _of(scene: Scene, category: str, but: str | None = None) -> list[SceneObject]:
    """The objects of ``category`` with a pose, other than ``but``."""
    return [o for o in scene.objects if o.category == category and o.name != but and o.pose is not None]


def _one_of(scene: Scene, category: str, target: str) -> SceneObject:
    objs = [o for o in scene.objects if o.category == category]
    if not objs or objs[0].pose is None:
        raise SceneError(f"oracle: {target!r} needs the scene's {category} (with a pose)")
    return objs[0]


def _target(scene: Scene, name: str, allowed: Sequence[str], scenario: str) -> SceneObject:
    obj = scene[name]
    if obj.category not in allowed:
        raise SceneError(f"oracle: {scenario} places {', '.join(allowed)}, not {name!r} (a {obj.category})")
    return obj


def _free_slot(slots: list[Pose], others: list[SceneObject]) -> Pose:
    """The slot farthest from every other object of the row (the one the masked object left)."""
    if not others:
        return slots[len(slots) // 2]
    pts = np.array([o.pose[:2] for o in others])  # type: ignore[index]
    gaps = [float(np.min(np.hypot(*(pts - np.array(s[:2])).T))) for s in slots]
    return slots[int(np.argmax(gaps))]


class _Zoo:
    """Shared machinery: bounds from ``half``, seeded generation with redraws, the split."""

    _stream: ClassVar[int] = 0
    name: str
    half: tuple[float, float]
    n_train: int
    n_test: int
    margin: ClassVar[float] = 0.0  # objects keep this far inside the bounds

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        hx, hy = self.half
        return ((-hx, -hy), (hx, hy))

    def generate(self, n: int, seed: int) -> list[Scene]:
        """``n`` scenes from the process, reproducible from ``seed``."""
        rng = np.random.default_rng(seed)
        return [self._draw(rng) for _ in range(n)]

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        """The experiment's training and test scenes (disjoint random streams)."""
        s = self._stream
        return self.generate(self.n_train, seed * 2 + s), self.generate(self.n_test, seed * 2 + s + 1)

    def _draw(self, rng: np.random.Generator) -> Scene:
        for _ in range(_TRIES):
            drawn = self._one(rng)
            if drawn is None:
                continue
            objs, meta = drawn
            if _inside(objs, self.bounds, self.margin) and _overlap_free(objs):
                return Scene(objs, self.bounds, meta={"scenario": self.name, **meta})
        raise SceneError(f"{self.name}: no valid scene in {_TRIES} draws; are the bounds too small?")

    def _one(self, rng: np.random.Generator) -> tuple[list[SceneObject], dict] | None:
        raise NotImplementedError


# -- 1. a circuit board ----------------------------------------------------------------------------
@dataclass
class PcbScenario(_Zoo):
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
        return [_compose(frame, d, (i - (n - 1) / 2) * self.pitch) for i in range(n)]

    def _cap(self, chip: Pose, side: int) -> Pose:
        frame = (chip[0], chip[1], chip[2] + side * math.pi / 2)
        return _compose(frame, -(self.chip / 2 + self.gap + self.capacitor / 2), 0.0)

    def _one(self, rng):
        chip = (0.0, 0.0, float(rng.uniform(-math.pi / 4, math.pi / 4)))
        side = int(rng.integers(4))
        n = int(rng.integers(self.row[0], self.row[1] + 1))
        objs = [_obj("chip", 0, (self.chip, self.chip), chip, (28, 28, 32), fixed=True)]
        body = [(214, 190, 150), (96, 150, 205)][int(rng.integers(2))]  # carbon film beige, metal film blue
        for i, slot in enumerate(self._slots(chip, side, n)):
            pose = _jitter(rng, slot, self.pos_noise, self.angle_noise)
            objs.append(_obj("resistor", i, self.resistor, pose, body))
        cap = self._cap(chip, side)
        cap = _jitter(rng, (cap[0], cap[1], _spin(rng)), self.pos_noise, 0.0)
        objs.append(_obj("capacitor", 0, (self.capacitor, self.capacitor), cap, (30, 45, 110), "disk"))
        if not _shift_into(rng, objs, self.bounds, 0.01):
            return None
        return objs, {"side": side, "resistors": n}

    def _side(self, scene: Scene, chip: Pose, target: str) -> int:
        """The side (0-3) the row is on: resistors vote for it, the capacitor against it."""
        votes = [(o, 1.0) for o in _of(scene, "resistor", but=target)]
        votes += [(o, -1.0) for o in _of(scene, "capacitor", but=target)]
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
        obj = _target(scene, name, self.missing, self.name)
        chip = _one_of(scene, "chip", name).pose
        assert chip is not None
        side = self._side(scene, chip, name)
        if obj.category == "capacitor":
            return self._cap(chip, side)
        n = sum(o.category == "resistor" for o in scene.objects)
        return _free_slot(self._slots(chip, side, n), _of(scene, "resistor", but=name))


# -- 2. jars in a grid on a shelf ------------------------------------------------------------------------
JAR_COLOURS: tuple[Colour, ...] = (
    (214, 150, 40),  # honey
    (150, 30, 50),  # jam
    (120, 140, 60),  # pickles
    (235, 225, 200),  # flour
    (90, 60, 40),  # coffee
    (200, 80, 30),  # paprika
)


@dataclass
class JarGridScenario(_Zoo):
    """A grid of 2x2 to 4x5 round jars on a 1 m x 0.4 m shelf; the pitch grows with the jars' size.

    All jars of a scene share a diameter (drawn per scene); the grid's pitch is ``(1 + spacing)`` times
    it. The oracle counts the grid's rows and columns from the other jars, fits the grid and returns the
    empty cell.
    """

    _stream: ClassVar[int] = 111
    margin: ClassVar[float] = 0.003
    name: str = "zoo-jars"
    half: tuple[float, float] = (0.5, 0.2)
    diameter: tuple[float, float] = (0.05, 0.075)
    spacing: float = 0.3  # gap between jars as a fraction of the diameter
    rows: tuple[int, int] = (2, 4)
    cols: tuple[int, int] = (2, 5)
    pos_noise: float = 0.0012
    angle_noise: float = 0.0
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("jar",)
    symmetric: tuple[str, ...] = ("jar",)

    @property
    def counts(self) -> tuple[int, int]:
        return (self.rows[0] * self.cols[0], self.rows[1] * self.cols[1])

    def _one(self, rng):
        r = int(rng.integers(self.rows[0], self.rows[1] + 1))
        c = int(rng.integers(self.cols[0], self.cols[1] + 1))
        d = float(rng.uniform(*self.diameter))
        p = d * (1 + self.spacing)
        objs = []
        for i in range(r):
            for j in range(c):
                x, y = (j - (c - 1) / 2) * p, (i - (r - 1) / 2) * p
                pose = _jitter(rng, (x, y, _spin(rng)), self.pos_noise, 0.0)
                colour = JAR_COLOURS[int(rng.integers(len(JAR_COLOURS)))]
                objs.append(_obj("jar", i * c + j, (d, d), pose, colour, "disk"))
        if not _shift_into(rng, objs, self.bounds, 0.005):
            return None
        return objs, {"rows": r, "cols": c, "diameter": d}

    @staticmethod
    def _clusters(values: np.ndarray, tol: float) -> np.ndarray:
        v = np.sort(values)
        groups, cur = [], [v[0]]
        for a in v[1:]:
            if a - cur[-1] > tol:
                groups.append(np.mean(cur))
                cur = []
            cur.append(a)
        groups.append(np.mean(cur))
        return np.array(groups)

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The grid's empty cell, the grid fitted to the other jars."""
        obj = _target(scene, name, self.missing, self.name)
        others = _of(scene, "jar", but=name)
        n = sum(o.category == "jar" for o in scene.objects)
        if len(others) < 3:
            raise SceneError(f"oracle: {name!r} needs at least three other jars to find the grid")
        p = obj.size[0] * (1 + self.spacing)
        pts = np.array([cast(Pose, o.pose)[:2] for o in others])
        cx, cy = self._clusters(pts[:, 0], p / 2), self._clusters(pts[:, 1], p / 2)
        if len(cx) * len(cy) != n:
            raise SceneError(f"oracle: {name!r}: the other jars do not form a grid of {n} cells")
        ci = np.argmin(np.abs(pts[:, 0, None] - cx[None]), axis=1)
        ri = np.argmin(np.abs(pts[:, 1, None] - cy[None]), axis=1)
        ox = float(np.mean(pts[:, 0] - ci * p))
        oy = float(np.mean(pts[:, 1] - ri * p))
        cells = [(ox + j * p, oy + i * p, 0.0) for i in range(len(cy)) for j in range(len(cx))]
        return _free_slot(cells, others)


# -- 3. a bedroom -----------------------------------------------------------------------------------------
BEDS: tuple[tuple[float, float], ...] = ((2.0, 0.95), (2.0, 1.45), (2.05, 1.85))  # single, double, king


def _wall_frame(half: float, wall: int, t: float, depth: float) -> Pose:
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


@dataclass
class BedroomScenario(_Zoo):
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
        return _compose(bed.pose, u, side * (w / 2 + self.bed_gap + width / 2))

    def _lamp(self, stand: Pose, side: float, width: float, diameter: float) -> Pose:
        return _compose(stand, 0.0, side * (width / 2 + self.lamp_gap + diameter / 2))

    def _bench(self, bed: SceneObject, depth: float) -> Pose:
        assert bed.pose is not None
        return _compose(bed.pose, bed.size[0] / 2 + self.bench_gap + depth / 2, 0.0)

    def _one(self, rng):
        H = self.half[0]
        bl, bw = BEDS[int(rng.integers(len(BEDS)))]
        width = float(rng.uniform(*self.nightstand_width))
        reach = bw / 2 + self.bed_gap + width + self.lamp_gap + self.lamp + 0.05
        wall = int(rng.integers(4))
        t = float(rng.uniform(-(H - reach), H - reach))
        bed = _obj("bed", 0, (bl, bw), _wall_frame(H, wall, t, 0.05 + bl / 2), (205, 200, 220), fixed=True)
        objs = [bed]
        sides = [1.0, -1.0] if rng.uniform() < self.p_two else [float(rng.choice([-1.0, 1.0]))]
        sides = [sides[i] for i in rng.permutation(len(sides))]
        wood = [(150, 105, 60), (235, 230, 220), (70, 50, 35)][int(rng.integers(3))]
        for k, side in enumerate(sides):
            stand = _jitter(rng, self._nightstand(bed, side, width), self.pos_noise, self.angle_noise)
            objs.append(_obj("nightstand", k, (self.nightstand_depth, width), stand, wood))
            lamp = self._lamp(stand, side, width, self.lamp)
            lamp = _jitter(rng, (lamp[0], lamp[1], _spin(rng)), self.pos_noise, 0.0)
            objs.append(_obj("lamp", k, (self.lamp, self.lamp), lamp, (240, 225, 170), "disk"))
        if rng.uniform() < self.p_bench:
            size = (self.bench_depth, min(1.4, bw - 0.1))
            bench = _jitter(rng, self._bench(bed, size[0]), self.pos_noise, self.angle_noise)
            objs.append(_obj("bench", 0, size, bench, (120, 80, 110)))
        wwall = int((wall + rng.integers(1, 4)) % 4)
        d, w = self.wardrobe
        tw = float(rng.uniform(-(H - w / 2 - 0.05), H - w / 2 - 0.05))
        objs.append(
            _obj("wardrobe", 0, (d, w), _wall_frame(H, wwall, tw, 0.02 + d / 2), (110, 75, 45), fixed=True)
        )
        return objs, {"wall": wall, "sides": sides}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Nightstand: beside the bed's head, on its lamp's side; lamp: beside its nightstand, outwards;
        bench: at the bed's foot."""
        obj = _target(scene, name, self.missing, self.name)
        bed = _one_of(scene, "bed", name)
        assert bed.pose is not None
        k = name.rpartition("_")[2]
        if obj.category == "bench":
            return self._bench(bed, obj.size[0])
        if obj.category == "nightstand":
            lamp = _pose(scene, f"lamp_{k}", name)
            side = math.copysign(1.0, _local(bed.pose, lamp[0], lamp[1])[1])
            return self._nightstand(bed, side, obj.size[1])
        stand = _pose(scene, f"nightstand_{k}", name)
        side = math.copysign(1.0, _local(bed.pose, stand[0], stand[1])[1])
        return self._lamp(stand, side, scene[f"nightstand_{k}"].size[1], obj.size[0])


# -- 4. a banquet hall ---------------------------------------------------------------------------------
@dataclass
class BanquetScenario(_Zoo):
    """A 10 m hall: a fixed 3 m table anywhere at any angle, 2-5 chairs evenly along each long side
    and sometimes one at each end (4-12 chairs), all facing it; a fixed sideboard against a wall.

    The oracle counts the chairs, sees from the others whether the ends are laid, and returns the
    empty seat facing the table.
    """

    _stream: ClassVar[int] = 131
    name: str = "zoo-banquet"
    half: tuple[float, float] = (5.0, 5.0)
    table: tuple[float, float] = (3.0, 1.0)
    chair: tuple[float, float] = (0.50, 0.46)  # depth (along its heading), width
    clearance: float = 0.10  # table edge to chair
    per_side: tuple[int, int] = (2, 5)
    p_ends: float = 0.5
    sideboard: tuple[float, float] = (0.5, 2.0)
    pos_noise: float = 0.015
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("chair",)
    symmetric: tuple[str, ...] = ()

    @property
    def counts(self) -> tuple[int, int]:
        return (2 * self.per_side[0] + 2, 2 * self.per_side[1] + 4)  # chairs, table, sideboard

    def _slots(self, table: Pose, m: int, ends: bool) -> list[Pose]:
        L, W = self.table
        v = W / 2 + self.clearance + self.chair[0] / 2
        out = []
        for side in (1.0, -1.0):
            for j in range(m):
                out.append(_compose(table, -L / 2 + (j + 0.5) * L / m, side * v, -side * math.pi / 2))
        if ends:
            u = L / 2 + self.clearance + self.chair[0] / 2
            out += [_compose(table, u, 0.0, math.pi), _compose(table, -u, 0.0, 0.0)]
        return out

    def _one(self, rng):
        H = self.half[0]
        m = int(rng.integers(self.per_side[0], self.per_side[1] + 1))
        ends = bool(rng.uniform() < self.p_ends)
        table = (0.0, 0.0, float(rng.uniform(-math.pi, math.pi)))
        objs = [_obj("table", 0, self.table, table, (110, 70, 40), fixed=True)]
        colour = [(160, 30, 40), (200, 190, 160), (60, 60, 70)][int(rng.integers(3))]
        for k, slot in enumerate(self._slots(table, m, ends)):
            objs.append(
                _obj("chair", k, self.chair, _jitter(rng, slot, self.pos_noise, self.angle_noise), colour)
            )
        if not _shift_into(rng, objs, self.bounds, 0.3):
            return None
        d, w = self.sideboard
        t = float(rng.uniform(-(H - w / 2 - 0.1), H - w / 2 - 0.1))
        board = _wall_frame(H, int(rng.integers(4)), t, 0.03 + d / 2)
        objs.append(_obj("sideboard", 0, self.sideboard, board, (80, 50, 30), fixed=True))
        return objs, {"per_side": m, "ends": ends}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The table's empty seat."""
        _target(scene, name, self.missing, self.name)
        table = _one_of(scene, "table", name).pose
        assert table is not None
        others = _of(scene, "chair", but=name)
        n = sum(o.category == "chair" for o in scene.objects)
        L = self.table[0]
        ends = any(
            abs(_local(table, cast(Pose, o.pose)[0], cast(Pose, o.pose)[1])[0]) > L / 2 + self.clearance
            for o in others
        )
        m2 = n - 2 * ends
        if m2 < 2 or m2 % 2:
            raise SceneError(f"oracle: {name!r}: {n} chairs do not fit the table's seating")
        return _free_slot(self._slots(table, m2 // 2, ends), others)


# -- 5. a workstation ---------------------------------------------------------------------------------
@dataclass
class WorkstationScenario(_Zoo):
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

    def _one(self, rng):
        hx, hy = self.half
        mon = (
            float(rng.uniform(-hx + 0.45, hx - 0.45)),
            hy - 0.15,
            float(rng.uniform(-self.max_turn, self.max_turn)),
        )
        d = float(rng.uniform(*self.distance))
        hand = -1.0 if rng.uniform() < self.p_left else 1.0
        kb = _jitter(rng, _compose(mon, 0.0, -d), self.pos_noise, self.angle_noise)
        mouse = _jitter(
            rng, _compose(kb, hand * self.mouse_offset, 0.0, math.pi / 2), self.pos_noise, self.angle_noise
        )
        mug = _compose(kb, -hand * self.mug_offset[0], self.mug_offset[1])
        mug = _jitter(rng, (mug[0], mug[1], _spin(rng)), self.pos_noise, 0.0)
        keys = [(40, 40, 45), (235, 235, 230)][int(rng.integers(2))]
        objs = [
            _obj("monitor", 0, self.monitor, mon, (20, 20, 25), fixed=True),
            _obj("keyboard", 0, self.keyboard, kb, keys),
            _obj("mouse", 0, self.mouse, mouse, keys),
            _obj("mug", 0, (self.mug, self.mug), mug, (180, 40, 40), "disk"),
        ]
        return objs, {"distance": d, "hand": hand}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Keyboard: in front of the monitor at the depth the mouse and mug show; mouse and mug: beside
        the keyboard, each on the side the other is not."""
        obj = _target(scene, name, self.missing, self.name)
        if obj.category == "keyboard":
            mon = _one_of(scene, "monitor", name).pose
            assert mon is not None
            depths = []
            for cat, back in (("mouse", 0.0), ("mug", self.mug_offset[1])):
                for o in _of(scene, cat, but=name):
                    depths.append(_local(mon, cast(Pose, o.pose)[0], cast(Pose, o.pose)[1])[1] - back)
            if not depths:
                raise SceneError(f"oracle: {name!r} needs the mouse or the mug to find its depth")
            return _compose(mon, 0.0, float(np.mean(depths)))
        kb = _pose(scene, "keyboard_0", name)
        partner = _of(scene, "mug" if obj.category == "mouse" else "mouse", but=name)
        if not partner:
            raise SceneError(f"oracle: {name!r} needs the {'mug' if obj.category == 'mouse' else 'mouse'}")
        u = _local(kb, cast(Pose, partner[0].pose)[0], cast(Pose, partner[0].pose)[1])[0]
        if obj.category == "mouse":
            hand = -math.copysign(1.0, u)
            return _compose(kb, hand * self.mouse_offset, 0.0, math.pi / 2)
        hand = math.copysign(1.0, u)
        x, y, _ = _compose(kb, -hand * self.mug_offset[0], self.mug_offset[1])
        return (x, y, 0.0)


# -- 6. a garden -----------------------------------------------------------------------------------------
POT_COLOURS: tuple[Colour, ...] = (
    (190, 95, 60),
    (50, 90, 150),
    (150, 150, 145),
    (70, 110, 70),
    (225, 215, 195),
)


@dataclass
class GardenScenario(_Zoo):
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

    def _one(self, rng):
        n = int(rng.integers(self.pots[0], self.pots[1] + 1))
        ds = rng.uniform(*self.diameter, n)
        k = float(rng.uniform(*self.gap_ratio))
        bench = (0.0, 0.0, float(rng.uniform(-self.max_turn, self.max_turn)))
        objs = [_obj("bench", 0, self.bench, bench, (120, 90, 60), fixed=True)]
        names = rng.permutation(n)  # names carry no order; the order is by size
        s = self.bench[0] / 2
        prev = None
        for i, d in enumerate(sorted(ds, reverse=True)):
            # the first pot: k of its diameter from the bench; then k of the two pots' mean diameter
            s += k * d + d / 2 if prev is None else (1 + k) * (prev + d) / 2
            pose = _compose(bench, s, 0.0)
            pose = _jitter(rng, (pose[0], pose[1], _spin(rng)), self.pos_noise, 0.0)
            colour = POT_COLOURS[int(rng.integers(len(POT_COLOURS)))]
            objs.append(_obj("pot", int(names[i]), (d, d), pose, colour, "disk"))
            prev = d
        if not _shift_into(rng, objs, self.bounds, 0.05):
            return None
        return objs, {"gap_ratio": k}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """From the masked pot's neighbours in size order, with the gap ratio the other gaps show."""
        _target(scene, name, self.missing, self.name)
        bench = _one_of(scene, "bench", name).pose
        assert bench is not None
        row = self._order([o for o in scene.objects if o.category == "pot"])
        i = [o.name for o in row].index(name)
        d = [o.size[0] for o in row]
        known = [
            None if o.name == name or o.pose is None else _local(bench, o.pose[0], o.pose[1])[0] for o in row
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
        x, y, _ = _compose(bench, float(np.mean(est)), 0.0)
        return (x, y, 0.0)


# -- 7. a cascade of boxes -------------------------------------------------------------------------------
CASCADE: tuple[tuple[str, tuple[float, float], Colour], ...] = (
    ("crate", (0.50, 0.34), (170, 130, 80)),
    ("case", (0.34, 0.22), (60, 80, 120)),
    ("tin", (0.20, 0.13), (190, 190, 200)),
    ("matchbox", (0.11, 0.07), (200, 60, 40)),
)


@dataclass
class CascadeScenario(_Zoo):
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

    def _one(self, rng):
        sc = float(rng.uniform(*self.scale))
        hand = float(rng.choice([-1.0, 1.0]))
        pose = (0.0, 0.0, float(rng.uniform(-math.pi, math.pi)))
        objs, prev = [], None
        for cat, size, colour in CASCADE:
            size = (size[0] * sc, size[1] * sc)
            if prev is not None:
                u, v = self._offset(prev.size, size, hand)
                pose = _jitter(
                    rng, _compose(prev.pose, u, v, hand * math.pi / 2), self.pos_noise, self.angle_noise
                )
            prev = _obj(cat, 0, size, pose, colour)
            objs.append(prev)
        if not _shift_into(rng, objs, self.bounds, 0.02):
            return None
        return objs, {"hand": hand, "scale": sc}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """From the parent (or, for the root, the child), with the hand read off another link."""
        obj = _target(scene, name, self.missing, self.name)
        chain = [scene[f"{cat}_0"] for cat, _, _ in CASCADE]
        i = [o.name for o in chain].index(name)
        hand = None
        for j in range(len(chain) - 1):
            a, b = chain[j], chain[j + 1]
            if name not in (a.name, b.name) and a.pose is not None and b.pose is not None:
                hand = math.copysign(1.0, _local(a.pose, b.pose[0], b.pose[1])[1])
                break
        if hand is None:
            raise SceneError(f"oracle: {name!r} needs a link between two other boxes to see the chain's hand")
        if i > 0:
            parent = chain[i - 1]
            u, v = self._offset(parent.size, obj.size, hand)
            return _compose(_pose(scene, parent.name, name), u, v, hand * math.pi / 2)
        child = chain[1]
        cp = _pose(scene, child.name, name)
        theta = wrap_angle(cp[2] - hand * math.pi / 2)
        u, v = self._offset(obj.size, child.size, hand)
        x, y, _ = _compose((cp[0], cp[1], theta), -u, -v)
        return (x, y, float(theta))


# -- 8. books on a shelf ---------------------------------------------------------------------------------
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
class BookshelfScenario(_Zoo):
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

    def _one(self, rng):
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
        objs = [_obj("bookend", 0, self.bookend, end, (90, 90, 95), fixed=True)]
        books = []
        for k in rng.permutation(n):
            size = (float(rng.uniform(*self.depth)), float(th[len(books)]))
            books.append(_obj("book", int(k), size, end, BOOK_COLOURS[int(rng.integers(len(BOOK_COLOURS)))]))
        books.sort(key=lambda o: int(o.name.rpartition("_")[2]))
        places = self._places(end, direction, books)
        for o in books:
            o.pose = _jitter(rng, places[o.name], self.pos_noise, self.angle_noise)
        return objs + books, {"direction": direction}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """The masked book's place in the depth order, counted from the bookend."""
        _target(scene, name, self.missing, self.name)
        end = _one_of(scene, "bookend", name).pose
        assert end is not None
        others = _of(scene, "book", but=name)
        if not others:
            raise SceneError(f"oracle: {name!r} needs another book to see which way the row runs")
        direction = math.copysign(1.0, float(np.mean([cast(Pose, o.pose)[0] for o in others])) - end[0])
        return self._places(end, direction, [o for o in scene.objects if o.category == "book"])[name]


# -- 9. a lounge ---------------------------------------------------------------------------------------
@dataclass
class LoungeScenario(_Zoo):
    """A 4.4 m room with a fixed 2 m sofa against one wall, off the wall's centre; a coffee table in
    front of it; sometimes a square side table at the sofa's end nearer the room's corner (the end away
    from the wall's centre). Two small objects beside one big fixed one, in large bounds.
    """

    _stream: ClassVar[int] = 181
    name: str = "zoo-lounge"
    half: tuple[float, float] = (2.2, 2.2)
    sofa: tuple[float, float] = (2.0, 0.9)
    coffee_table: tuple[float, float] = (0.9, 0.5)
    side_table: float = 0.45
    clearance: float = 0.40  # sofa front to coffee table
    end_gap: float = 0.06
    offset: tuple[float, float] = (0.25, 0.6)  # sofa centre from the wall's centre
    p_side: float = 0.6
    pos_noise: float = 0.025
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("coffee_table", "side_table")
    symmetric: tuple[str, ...] = ("side_table",)

    @property
    def counts(self) -> tuple[int, int]:
        return (2, 3)

    def _coffee(self, sofa: Pose) -> Pose:
        return _compose(sofa, 0.0, self.sofa[1] / 2 + self.clearance + self.coffee_table[1] / 2)

    def _side(self, sofa: Pose) -> Pose:
        end = math.copysign(1.0, math.cos(sofa[2]) * sofa[0] + math.sin(sofa[2]) * sofa[1])
        return _compose(sofa, end * (self.sofa[0] / 2 + self.end_gap + self.side_table / 2), -0.2)

    def _one(self, rng):
        H = self.half[0]
        t = float(rng.choice([-1.0, 1.0]) * rng.uniform(*self.offset))
        back = _wall_frame(H, int(rng.integers(4)), t, 0.05 + self.sofa[1] / 2)
        sofa = (
            back[0],
            back[1],
            float(wrap_angle(back[2] - math.pi / 2)),
        )  # +x along the wall, +y into the room
        fabric = [(90, 110, 130), (150, 60, 50), (190, 180, 160)][int(rng.integers(3))]
        objs = [_obj("sofa", 0, self.sofa, sofa, fabric, fixed=True)]
        coffee = _jitter(rng, self._coffee(sofa), self.pos_noise, self.angle_noise)
        objs.append(_obj("coffee_table", 0, self.coffee_table, coffee, (100, 70, 45)))
        if rng.uniform() < self.p_side:
            x, y, th = self._side(sofa)
            pose = _jitter(
                rng, (x, y, th + int(rng.integers(4)) * math.pi / 2), self.pos_noise, self.angle_noise
            )
            objs.append(_obj("side_table", 0, (self.side_table, self.side_table), pose, (60, 60, 60)))
        return objs, {"offset": t}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Coffee table: in front of the sofa; side table: at the sofa's end away from the wall's centre."""
        obj = _target(scene, name, self.missing, self.name)
        sofa = _one_of(scene, "sofa", name).pose
        assert sofa is not None
        return self._coffee(sofa) if obj.category == "coffee_table" else self._side(sofa)


# -- 10. a hall ----------------------------------------------------------------------------------------
@dataclass
class HallScenario(_Zoo):
    """A fixed 2 m console table anywhere in a 4.4 m hall, at any angle; a vase on the floor in front of
    each of its ends and a stool in front of its middle, farther out. Small objects by one big fixed one
    in large bounds, every relation rigid to the console (nothing depends on the walls).
    """

    _stream: ClassVar[int] = 211
    name: str = "zoo-hall"
    half: tuple[float, float] = (2.2, 2.2)
    console: tuple[float, float] = (2.0, 0.4)
    vase: float = 0.12
    stool: float = 0.34
    vase_at: tuple[float, float] = (0.7, 0.22)  # from the console's centre: along it, in front of its front
    stool_out: float = 0.45  # stool centre in front of the console's front
    pos_noise: float = 0.015
    angle_noise: float = math.radians(3.0)
    n_train: int = 48
    n_test: int = 16
    missing: tuple[str, ...] = ("vase", "stool")
    symmetric: tuple[str, ...] = ("vase", "stool")

    @property
    def counts(self) -> tuple[int, int]:
        return (4, 4)

    def _slot(self, console: Pose, cat: str, k: int) -> Pose:
        front = self.console[1] / 2
        if cat == "stool":
            return _compose(console, 0.0, front + self.stool_out)
        u, v = self.vase_at
        return _compose(console, (-u, u)[k], front + v)

    def _one(self, rng):
        H = self.half[0]
        console = (
            float(rng.uniform(-H, H)),
            float(rng.uniform(-H, H)),
            float(rng.uniform(-math.pi, math.pi)),
        )
        objs = [_obj("console", 0, self.console, console, (110, 80, 55), fixed=True)]
        for k in range(2):
            x, y, _ = _jitter(rng, self._slot(console, "vase", k), self.pos_noise, 0.0)
            objs.append(
                _obj("vase", k, (self.vase, self.vase), (x, y, _spin(rng)), (70, 130, 160), shape="disk")
            )
        x, y, t = _jitter(rng, self._slot(console, "stool", 0), self.pos_noise, self.angle_noise)
        turn = int(rng.integers(4)) * math.pi / 2  # a square stool: a quarter turn looks the same
        objs.append(
            _obj("stool", 0, (self.stool, self.stool), (x, y, float(wrap_angle(t + turn))), (150, 120, 90))
        )
        return objs, {}

    def oracle(self, scene: Scene, name: str) -> Pose:
        """Stool: in front of the console's middle; vase: in front of the end the other vase leaves free."""
        obj = _target(scene, name, self.missing, self.name)
        console = _one_of(scene, "console", name).pose
        assert console is not None
        if obj.category == "stool":
            return self._slot(console, "stool", 0)
        slots = [self._slot(console, "vase", k) for k in range(2)]
        return _free_slot(slots, _of(scene, "vase", but=name))


ZOO: tuple[str, ...] = (
    "zoo-pcb",
    "zoo-jars",
    "zoo-bedroom",
    "zoo-banquet",
    "zoo-workstation",
    "zoo-garden",
    "zoo-cascade",
    "zoo-books",
    "zoo-lounge",
    "zoo-hall",
)
