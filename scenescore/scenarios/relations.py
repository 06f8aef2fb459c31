"""A library of spatial relations on 2-D footprints: an exact checker and an example generator for each.

Each relation holds between named objects in roles: ``left_of(scene, ("cup", "plate"))`` says whether
the cup stands left of the plate. Its scenario (``relation-left_of``, ...) draws small example scenes
(2 objects, 3 for ``between``) on a 1.2 x 0.8 m table, the objects named ``a``, ``b`` (``c``) in the
colours of their roles (:data:`~scenescore.costs.relation.ROLE_COLOURS`) with random boxes and disks of
5 to 20 cm, each scene one its own checker accepts with no slack; a model trained on them binds to the
objects of any scene through :class:`~scenescore.costs.Relation`.

Frame: x to the right, y away from the viewer, who stands at low y; an object's heading is its own +x
axis. Every checker takes ``tol`` (metres, default :data:`TOL`): the slack each inequality is allowed;
the thresholds below are part of the definitions, documented with each relation:

=============  =========================================================================================
``left_of``    a's footprint wholly left of b's: ``xmax(a) <= xmin(b) + tol``
``right_of``   a's footprint wholly right of b's: ``xmin(a) >= xmax(b) - tol``
``in_front_of`` a's footprint wholly nearer the viewer than b's: ``ymax(a) <= ymin(b) + tol``
``behind``     a's footprint wholly farther from the viewer than b's: ``ymin(a) >= ymax(b) - tol``
``aligned_x``  centres on one line along the x axis: ``|ya - yb| <= ALIGNED + tol``; no overlap
``aligned_y``  centres on one line along the y axis: ``|xa - xb| <= ALIGNED + tol``; no overlap
``centred_on`` a's centre within ``CENTRED + tol`` of b's (a stands on b: they may overlap)
``near``       no overlap, and the gap between the footprints at most ``NEAR + tol``
``far_from``   the gap between the footprints at least ``FAR - tol``
``facing``     no overlap, and a's heading points at b's centre within ``FACING`` radians
``between``    a's centre projects inside the segment from b's centre to c's, at most ``BETWEEN + tol``
               off it; a overlaps neither
=============  =========================================================================================
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..costs.relation import ROLE_COLOURS, compass
from ..geometry.exact import footprint_extent, footprints_overlap, shapely_core
from ..scene.scene import Scene, SceneError, SceneObject
from .zoo.common import inside_bounds

__all__ = [
    "RELATIONS",
    "SCENARIOS",
    "RelationKind",
    "RelationScenario",
    "TOL",
    "ALIGNED",
    "CENTRED",
    "NEAR",
    "FAR",
    "FACING",
    "BETWEEN",
]

TOL = 1e-3  # metres: the default slack of every checker's inequalities
ALIGNED = 0.01  # metres: how far off a common line two aligned centres may be
CENTRED = 0.01  # metres: how far apart the centres of an object and the one it is centred on may be
NEAR = 0.10  # metres: the largest gap between two footprints that are near
FAR = 0.40  # metres: the smallest gap between two footprints that are far apart
FACING = math.radians(10.0)  # radians: how far a's heading may turn from the direction to b's centre
BETWEEN = 0.02  # metres: how far a's centre may lie off the segment between the other two centres
ROLES = ("a", "b", "c")  # the objects' names (and categories) in the example scenes
HALF = (0.6, 0.4)  # the example table is [-0.6, 0.6] x [-0.4, 0.4] (m)
SIDES = (0.05, 0.20)  # metres: the range of an example object's sides
MAX_TRIES = 1000  # draws of one example before the generator gives up (none needs more than a few)

Objects = Sequence[str]


def _pose(scene: Scene, name: str) -> tuple[float, float, float]:
    pose = scene[name].pose
    if pose is None:
        raise SceneError(f"relation check: object {name!r} has no pose")
    return (float(pose[0]), float(pose[1]), float(pose[2]))


def _extent(scene: Scene, name: str) -> tuple[float, float, float, float]:
    return footprint_extent(scene[name], _pose(scene, name))


def _overlap(scene: Scene, a: str, b: str) -> bool:
    return footprints_overlap(scene[a], _pose(scene, a), scene[b], _pose(scene, b))


def _gap(scene: Scene, a: str, b: str) -> float:
    """The distance between the two footprints (0 where they touch or overlap), exact (shapely)."""
    (ga, ra), (gb, rb) = shapely_core(scene[a], _pose(scene, a)), shapely_core(scene[b], _pose(scene, b))
    return max(float(ga.distance(gb)) - ra - rb, 0.0)


def _pair(objects: Objects, arity: int = 2) -> tuple[str, ...]:
    if isinstance(objects, str) or len(objects) != arity:
        raise SceneError(f"relation check: expected {arity} object names, got {objects!r}")
    return tuple(objects)


def left_of(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's footprint wholly left of b's: ``xmax(a) <= xmin(b) + tol``."""
    a, b = _pair(objects)
    return _extent(scene, a)[2] <= _extent(scene, b)[0] + tol


def right_of(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's footprint wholly right of b's: ``xmin(a) >= xmax(b) - tol``."""
    a, b = _pair(objects)
    return _extent(scene, a)[0] >= _extent(scene, b)[2] - tol


def in_front_of(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's footprint wholly nearer the viewer (lower y) than b's: ``ymax(a) <= ymin(b) + tol``."""
    a, b = _pair(objects)
    return _extent(scene, a)[3] <= _extent(scene, b)[1] + tol


def behind(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's footprint wholly farther from the viewer (higher y) than b's: ``ymin(a) >= ymax(b) - tol``."""
    a, b = _pair(objects)
    return _extent(scene, a)[1] >= _extent(scene, b)[3] - tol


def aligned_x(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """Centres on one line along the x axis (``|ya - yb| <= ALIGNED + tol``), footprints apart."""
    a, b = _pair(objects)
    return abs(_pose(scene, a)[1] - _pose(scene, b)[1]) <= ALIGNED + tol and not _overlap(scene, a, b)


def aligned_y(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """Centres on one line along the y axis (``|xa - xb| <= ALIGNED + tol``), footprints apart."""
    a, b = _pair(objects)
    return abs(_pose(scene, a)[0] - _pose(scene, b)[0]) <= ALIGNED + tol and not _overlap(scene, a, b)


def centred_on(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's centre within ``CENTRED + tol`` of b's (a stands on b; the footprints may overlap)."""
    a, b = _pair(objects)
    pa, pb = _pose(scene, a), _pose(scene, b)
    return math.hypot(pa[0] - pb[0], pa[1] - pb[1]) <= CENTRED + tol


def near(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """Footprints apart, the gap between them at most ``NEAR + tol``."""
    a, b = _pair(objects)
    return not _overlap(scene, a, b) and _gap(scene, a, b) <= NEAR + tol


def far_from(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """The gap between the footprints at least ``FAR - tol``."""
    a, b = _pair(objects)
    return _gap(scene, a, b) >= FAR - tol


def facing(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """Footprints apart, a's heading (its +x axis) within ``FACING`` radians of the direction to b's
    centre (``tol`` is not an angle and does not widen it)."""
    a, b = _pair(objects)
    pa, pb = _pose(scene, a), _pose(scene, b)
    turn = math.atan2(pb[1] - pa[1], pb[0] - pa[0]) - pa[2]
    off = abs(math.atan2(math.sin(turn), math.cos(turn)))
    return off <= FACING and not _overlap(scene, a, b)


def between(scene: Scene, objects: Objects, tol: float = TOL) -> bool:
    """a's centre projects strictly inside the segment from b's centre to c's, at most ``BETWEEN + tol``
    off it; a's footprint overlaps neither."""
    a, b, c = _pair(objects, 3)
    pa, pb, pc = (np.array(_pose(scene, n)[:2]) for n in (a, b, c))
    d = pc - pb
    length2 = float(d @ d)
    if length2 == 0.0:
        return False
    t = float((pa - pb) @ d) / length2
    off = abs(float(d[0] * (pa - pb)[1] - d[1] * (pa - pb)[0])) / math.sqrt(length2)
    return 0.0 < t < 1.0 and off <= BETWEEN + tol and not _overlap(scene, a, b) and not _overlap(scene, a, c)


# -- example generators: each draws poses for objects of given sizes; the scenario keeps a draw only
# -- when its checker accepts it with no slack, every footprint lies inside the table and none overlap


def _uniform(rng: np.random.Generator, k: int) -> np.ndarray:
    """``k`` poses drawn uniformly on the table, headings uniform."""
    xy = rng.uniform((-HALF[0], -HALF[1]), HALF, (k, 2))
    return np.concatenate([xy, rng.uniform(-math.pi, math.pi, (k, 1))], axis=1)


def _beside(rng: np.random.Generator, sizes: np.ndarray, gap: tuple[float, float]) -> np.ndarray:
    """b uniform; a in a uniform direction from b, its centre the sizes' half diagonals plus a gap apart."""
    p = _uniform(rng, 2)
    reach = float(np.hypot(*sizes[0]) + np.hypot(*sizes[1])) / 2 * rng.uniform(0.6, 1.0)
    ang = rng.uniform(-math.pi, math.pi)
    r = reach + rng.uniform(*gap)
    p[0, :2] = p[1, :2] + r * np.array([math.cos(ang), math.sin(ang)])
    return p


def _draw_aligned(axis: int) -> Callable[[np.random.Generator, np.ndarray], np.ndarray]:
    def draw(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
        p = _uniform(rng, 2)
        p[0, 1 - axis] = p[1, 1 - axis] + rng.uniform(-ALIGNED, ALIGNED) * 0.9
        return p

    return draw


def _draw_centred(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
    p = _uniform(rng, 2)
    r, ang = rng.uniform(0, CENTRED) * 0.9, rng.uniform(-math.pi, math.pi)
    p[0, :2] = p[1, :2] + r * np.array([math.cos(ang), math.sin(ang)])
    return p


def _draw_facing(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
    p = _uniform(rng, 2)
    d = p[1, :2] - p[0, :2]
    p[0, 2] = math.atan2(d[1], d[0]) + rng.uniform(-FACING, FACING) * 0.9
    return p


def _draw_between(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
    p = _uniform(rng, 3)
    d = p[2, :2] - p[1, :2]
    normal = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9)
    p[0, :2] = p[1, :2] + rng.uniform(0.3, 0.7) * d + rng.uniform(-BETWEEN, BETWEEN) * 0.9 * normal
    return p


def _draw_uniform(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
    return _uniform(rng, len(sizes))


@dataclass(frozen=True)
class RelationKind:
    """One relation: its name, how many objects it relates, its checker, how examples are drawn, and
    whether its objects may overlap (``centred_on``)."""

    name: str
    arity: int
    check: Callable[..., bool]
    draw: Callable[[np.random.Generator, np.ndarray], np.ndarray]
    overlaps: bool = False
    small_on_large: bool = False  # a drawn smaller than b (an object centred on another)
    frame: bool = False  # it depends on the world's axes: the examples hold the axes marker (a compass)
    reads_heading: bool = False  # it depends on the subject's heading, a round subject's too (facing)


RELATIONS: dict[str, RelationKind] = {
    k.name: k
    for k in (
        RelationKind("left_of", 2, left_of, _draw_uniform, frame=True),
        RelationKind("right_of", 2, right_of, _draw_uniform, frame=True),
        RelationKind("in_front_of", 2, in_front_of, _draw_uniform, frame=True),
        RelationKind("behind", 2, behind, _draw_uniform, frame=True),
        RelationKind("aligned_x", 2, aligned_x, _draw_aligned(0), frame=True),
        RelationKind("aligned_y", 2, aligned_y, _draw_aligned(1), frame=True),
        RelationKind("centred_on", 2, centred_on, _draw_centred, overlaps=True, small_on_large=True),
        RelationKind("near", 2, near, lambda rng, s: _beside(rng, s, (0.0, NEAR))),
        RelationKind("far_from", 2, far_from, _draw_uniform),
        RelationKind("facing", 2, facing, _draw_facing, reads_heading=True),
        RelationKind("between", 3, between, _draw_between),
    )
}


@dataclass
class RelationScenario:
    """Small example scenes of one spatial relation between objects named a, b (and c), in role colours.

    ``relation``: a name of :data:`RELATIONS`. Every scene is accepted by the relation's checker with
    no slack, its footprints inside the table and (but for ``centred_on``) apart.
    """

    relation: str = "left_of"
    n_train: int = 48
    n_test: int = 16

    def __post_init__(self) -> None:
        if self.relation not in RELATIONS:
            raise SceneError(
                f"relation scenario: unknown relation {self.relation!r}; known: {', '.join(RELATIONS)}"
            )
        self.kind = RELATIONS[self.relation]
        self.name = f"relation-{self.relation}"

    @property
    def roles(self) -> tuple[str, ...]:
        """The objects' names in their roles (the subject first)."""
        return ROLES[: self.kind.arity]

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return ((-HALF[0], -HALF[1]), HALF)

    def check(self, scene: Scene, objects: Objects | None = None, tol: float = TOL) -> bool:
        """The relation's checker on ``objects`` (default: the example scene's roles)."""
        return bool(self.kind.check(scene, self.roles if objects is None else objects, tol=tol))

    def _sizes(self, rng: np.random.Generator) -> tuple[np.ndarray, list[str]]:
        """Each object's (length, width) and shape: a disk or a box of sides in :data:`SIDES`."""
        shapes = ["disk" if rng.uniform() < 0.5 else "box" for _ in self.roles]
        sizes = rng.uniform(*SIDES, (len(self.roles), 2))
        if self.kind.small_on_large:  # the object on top no larger than 60 % of the one below
            sizes[0] = np.minimum(sizes[0], 0.6 * sizes[1].min())
        for k, s in enumerate(shapes):
            if s == "disk":
                sizes[k, 1] = sizes[k, 0]
        return sizes, shapes

    def _valid(self, scene: Scene) -> bool:
        if not inside_bounds(scene.objects, scene.bounds):  # every footprint inside, at its pose
            return False
        names = self.roles
        if not self.kind.overlaps:
            pairs = [(names[i], names[j]) for i in range(len(names)) for j in range(i + 1, len(names))]
            if any(_overlap(scene, a, b) for a, b in pairs):
                return False
        return self.check(scene, tol=0.0)

    def _example(self, rng: np.random.Generator) -> Scene:
        for _ in range(MAX_TRIES):
            sizes, shapes = self._sizes(rng)
            poses = self.kind.draw(rng, sizes)
            objs = [
                SceneObject(n, n, (float(s[0]), float(s[1])), tuple(float(v) for v in p), color=c, shape=sh)  # type: ignore[arg-type]
                for n, s, p, c, sh in zip(self.roles, sizes, poses, ROLE_COLOURS, shapes)
            ]
            objs += [compass()] if self.kind.frame else []
            scene = Scene(objs, self.bounds, meta={"scenario": self.name, "relation": self.relation})
            if self._valid(scene):
                return scene
        raise SceneError(f"{self.name}: no valid example in {MAX_TRIES} draws")  # pragma: no cover

    def generate(self, n: int, seed: int) -> list[Scene]:
        return list(self.iter_scenes(n, seed))

    def iter_scenes(self, n: int, seed: int) -> Iterator[Scene]:
        """:meth:`generate`'s scenes one at a time, from the same random stream."""
        rng = np.random.default_rng(seed)
        for _ in range(n):
            yield self._example(rng)

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]:
        return self.generate(self.n_train, seed * 2 + 91), self.generate(self.n_test, seed * 2 + 92)

    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]:
        raise SceneError(
            f"{self.name}: a relation holds for many poses and has no single oracle pose for {name!r}; "
            "judge a placement with its checker (scenario.check(scene))"
        )


def _factory(relation: str) -> Callable[..., RelationScenario]:
    """The registry's constructor of one relation's scenario, its docstring what ``--list`` shows."""

    def make(**options: object) -> RelationScenario:
        return RelationScenario(relation=relation, **options)  # type: ignore[arg-type]

    check = RELATIONS[relation].check
    first = (check.__doc__ or "").split("\n\n")[0].strip()
    make.__doc__ = f"Example scenes of the relation {relation}: {first[0].lower()}{first[1:]}"
    return make


#: every relation's scenario by its registry name (``relation-left_of``, ...)
SCENARIOS: dict[str, Callable[..., RelationScenario]] = {f"relation-{k}": _factory(k) for k in RELATIONS}
