"""Random consistent problems of spatial relations: N objects, about 1.5 N relations and non-overlap.

A problem is drawn the way Diffusion-CCSP (Yang et al., CoRL 2023) draws its test problems, backwards
from a solution: N objects (boxes and disks of 5 to 20 cm, as in the relations' examples) are first
arranged at random on the examples' 1.2 x 0.8 m table, apart and inside it; then about ``1.5 N``
relations are picked among those the relations' checkers (:mod:`scenescore.scenarios.relations`) accept
in that arrangement with no slack. The arrangement is a known solution, so every problem is
consistent. Relations that rarely hold by chance (aligned, facing, between, near) are planted: an
object is placed relative to one already placed (on its line, turned to it, between two, beside it).
``centred_on`` is left out: it puts one object on another, which non-overlap forbids.

A problem is solved by poses at which every relation's checker (at its default slack,
:data:`~scenescore.scenarios.relations.TOL`), the exact non-overlap check and the bounds hold
(:meth:`RelationProblem.solved`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import permutations

import numpy as np

from ..geometry.exact import footprints_overlap
from ..scene.scene import Scene, SceneError, SceneObject
from .relations import ALIGNED, BETWEEN, FACING, HALF, RELATIONS, SIDES, TOL
from .zoo.common import inside_bounds

__all__ = ["PROBLEM_RELATIONS", "RelationProblem", "relation_problem", "relation_problems"]

#: the relations problems draw from: every relation whose objects stay apart (not ``centred_on``)
PROBLEM_RELATIONS: tuple[str, ...] = tuple(k for k, v in RELATIONS.items() if not v.overlaps)
RELATIONS_PER_OBJECT = 1.5  # a problem of N objects asks about round(1.5 N) relations
PLANT = 0.5  # the chance that an object after the first is placed relative to one already placed
MAX_TRIES = 2000  # draws of one object's pose before the arrangement starts again
MAX_RESTARTS = 100  # arrangements begun before the generator gives up (none needs more than a few)
MAX_OBJECTS = 10  # the largest problem: 10 objects of up to 20 cm fit the table apart with room to move

Instance = tuple[str, tuple[str, ...]]  # a relation's name and its objects in their roles

SYMMETRIC = ("aligned_x", "aligned_y", "near", "far_from")  # r(a, b) says what r(b, a) says
MIRRORS = {"right_of": "left_of", "behind": "in_front_of"}  # right_of(a, b) says left_of(b, a)


@dataclass(frozen=True)
class RelationProblem:
    """Objects to arrange (``scene``: their footprints and a known solution's poses) and the relations
    that must hold between them, each ``(relation, (subject, reference[, third]))``."""

    scene: Scene
    relations: tuple[Instance, ...]

    @property
    def unposed(self) -> Scene:
        """The scene with every pose ``null``: what a solver is given."""
        return Scene(
            [replace(o, pose=None) for o in self.scene.objects], self.scene.bounds, dict(self.scene.meta)
        )

    def by_relation(self) -> dict[str, list[tuple[str, ...]]]:
        """The instances of each relation the problem names, in order: ``{"left_of": [("o0", "o1")]}``."""
        out: dict[str, list[tuple[str, ...]]] = {}
        for rel, objs in self.relations:
            out.setdefault(rel, []).append(objs)
        return out

    def solved(self, poses: np.ndarray | Sequence[Sequence[float]], tol: float = TOL) -> bool:
        """Whether ``poses (N, 3)`` (the scene's order) solve the problem: every relation's checker at
        slack ``tol``, every footprint inside the bounds (``tol`` beyond them allowed) and no two
        footprints overlapping (exact, touching allowed). The cheap checks run first."""
        p = np.asarray(poses, dtype=float)
        if p.shape != (len(self.scene), 3) or not np.isfinite(p).all():
            raise SceneError(
                f"relation problem: expected finite poses of shape ({len(self.scene)}, 3), got {p.shape}"
            )
        objs = [
            replace(o, pose=(float(q[0]), float(q[1]), float(q[2]))) for o, q in zip(self.scene.objects, p)
        ]
        scene = Scene(objs, self.scene.bounds)
        if not all(RELATIONS[rel].check(scene, names, tol=tol) for rel, names in self.relations):
            return False
        if not inside_bounds(objs, self.scene.bounds, margin=-tol):
            return False
        return not any(
            footprints_overlap(objs[i], objs[i].pose, objs[j], objs[j].pose)  # type: ignore[arg-type]
            for i in range(len(objs))
            for j in range(i + 1, len(objs))
        )


def _objects(rng: np.random.Generator, n: int) -> list[SceneObject]:
    """``n`` objects ``o0 .. o{n-1}``: boxes or disks with sides in :data:`SIDES`, no poses yet."""
    out = []
    for k in range(n):
        disk = bool(rng.uniform() < 0.5)
        s = rng.uniform(*SIDES, 2)
        size = (float(s[0]), float(s[0] if disk else s[1]))
        out.append(SceneObject(f"o{k}", f"o{k}", size, None, shape="disk" if disk else "box"))
    return out


def _planted(rng: np.random.Generator, placed: list[tuple[float, float, float]]) -> np.ndarray:
    """A pose drawn relative to the poses already ``placed``: on a line with one of them (along x or
    y), turned to face one, between two, or beside one (a near relation); else uniform."""
    p = np.array([*rng.uniform((-HALF[0], -HALF[1]), HALF), rng.uniform(-math.pi, math.pi)])
    ref = np.asarray(placed[int(rng.integers(len(placed)))])
    how = rng.choice(["aligned_x", "aligned_y", "facing", "between", "near"])
    if how == "aligned_x":
        p[1] = ref[1] + rng.uniform(-ALIGNED, ALIGNED) * 0.9
    elif how == "aligned_y":
        p[0] = ref[0] + rng.uniform(-ALIGNED, ALIGNED) * 0.9
    elif how == "facing":
        p[2] = math.atan2(ref[1] - p[1], ref[0] - p[0]) + rng.uniform(-FACING, FACING) * 0.9
    elif how == "between" and len(placed) >= 2:
        i, j = rng.choice(len(placed), 2, replace=False)
        b, c = np.asarray(placed[i][:2]), np.asarray(placed[j][:2])
        d = c - b
        normal = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9)
        p[:2] = b + rng.uniform(0.3, 0.7) * d + rng.uniform(-BETWEEN, BETWEEN) * 0.9 * normal
    elif how == "near":
        ang, r = rng.uniform(-math.pi, math.pi), rng.uniform(0.08, 0.25)
        p[:2] = ref[:2] + r * np.array([math.cos(ang), math.sin(ang)])
    return p


def _arrange(rng: np.random.Generator, objs: list[SceneObject], bounds: tuple) -> list[SceneObject] | None:
    """The objects placed one by one, apart and inside ``bounds`` (planted with chance :data:`PLANT`);
    ``None`` when one finds no place in :data:`MAX_TRIES` draws."""
    done: list[SceneObject] = []
    for o in objs:
        for _ in range(MAX_TRIES):
            poses = [d.pose for d in done]
            if done and rng.uniform() < PLANT:
                p = _planted(rng, poses)  # type: ignore[arg-type]
            else:
                p = np.array([*rng.uniform((-HALF[0], -HALF[1]), HALF), rng.uniform(-math.pi, math.pi)])
            pose = (float(p[0]), float(p[1]), float(math.atan2(math.sin(p[2]), math.cos(p[2]))))
            placed = replace(o, pose=pose)
            if inside_bounds([placed], bounds) and not any(
                footprints_overlap(o, pose, d, d.pose)  # type: ignore[arg-type]
                for d in done
            ):
                done.append(placed)
                break
        else:
            return None
    return done


def _holding(scene: Scene, relations: Sequence[str]) -> dict[str, list[tuple[str, ...]]]:
    """Every instance of each relation its checker accepts in ``scene`` with no slack, by relation."""
    out: dict[str, list[tuple[str, ...]]] = {}
    for rel in relations:
        kind = RELATIONS[rel]
        hits = [t for t in permutations(scene.names, kind.arity) if kind.check(scene, t, tol=0.0)]
        if hits:
            out[rel] = hits
    return out


def _same(instance: Instance) -> Instance:
    """One name for the instances that say the same: ``right_of(a, b)`` is ``left_of(b, a)``, ``near(b,
    a)`` is ``near(a, b)``, ``between(a, c, b)`` is ``between(a, b, c)``."""
    rel, objs = instance
    if rel in MIRRORS:
        return MIRRORS[rel], (objs[1], objs[0])
    if rel in SYMMETRIC:
        return rel, tuple(sorted(objs))
    if rel == "between":
        return rel, (objs[0], *sorted(objs[1:]))
    return instance


def relation_problem(
    n: int, seed: int, relations: Sequence[str] = PROBLEM_RELATIONS, per_object: float = RELATIONS_PER_OBJECT
) -> RelationProblem:
    """One random consistent problem of ``n`` objects (2 to :data:`MAX_OBJECTS`) and ``round(per_object
    * n)`` relations drawn among ``relations`` (fewer when fewer hold, at least one): a relation first,
    uniformly among those with an instance that holds and says something not yet asked, then one of
    those instances."""
    if not 2 <= n <= MAX_OBJECTS:
        raise SceneError(f"relation problem: n must be 2 to {MAX_OBJECTS} objects, got {n}")
    unknown = [r for r in relations if r not in PROBLEM_RELATIONS]
    if unknown or not relations:
        raise SceneError(
            f"relation problem: unknown relation(s) {unknown or list(relations)}; choose from {', '.join(PROBLEM_RELATIONS)}"
        )
    rng = np.random.default_rng(seed)
    bounds = ((-HALF[0], -HALF[1]), HALF)
    for _ in range(MAX_RESTARTS):  # an arrangement in which one of the relations holds
        placed = _arrange(rng, _objects(rng, n), bounds)
        if placed is None:
            continue
        scene = Scene(placed, bounds, meta={"scenario": "relation-problem", "seed": int(seed)})
        pool = _holding(scene, relations)
        if any(pool.values()):
            break
    else:  # pragma: no cover - ten objects of at most 20 cm always fit, and some relation holds
        raise SceneError(
            f"relation problem: no arrangement of {n} objects in {MAX_RESTARTS} tries in which one of "
            f"{', '.join(relations)} holds"
        )
    chosen: list[Instance] = []
    said: set[Instance] = set()
    for _ in range(int(round(per_object * n))):
        for r in pool:  # drop what the chosen instances already say
            pool[r] = [t for t in pool[r] if _same((r, t)) not in said]
        open_ = [r for r in sorted(pool) if pool[r]]
        if not open_:
            break
        rel = open_[int(rng.integers(len(open_)))]
        objs = pool[rel].pop(int(rng.integers(len(pool[rel]))))
        chosen.append((rel, objs))
        said.add(_same((rel, objs)))
    return RelationProblem(scene, tuple(chosen))


def relation_problems(
    n: int, count: int, seed: int, relations: Sequence[str] = PROBLEM_RELATIONS
) -> list[RelationProblem]:
    """``count`` problems of ``n`` objects, the k-th drawn from seed ``(seed, n, k)``: the problems of one
    size do not depend on how many are drawn or on the other sizes."""
    return [
        relation_problem(n, int(np.random.SeedSequence([seed, n, k]).generate_state(1)[0]), relations)
        for k in range(count)
    ]
