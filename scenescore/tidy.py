"""Tidying a messy scene: a desirable arrangement reached with little robot effort, and the order of moves.

Every known pose is the current state. :func:`tidy` minimises the learned energy plus the effort of
moving objects from where they are (:class:`~scenescore.costs.Displacement` and
:class:`~scenescore.costs.MoveCount`), with non-overlap, bounds and, when given, reach:

1. *Selection*: a forward selection of the objects to move, with a backward check. Each step re-places
   the objects chosen so far together with one more movable object (placed by the learned energy with
   the others where they are; as many draws as placement screens for the bounds, half of them proposed
   beside the objects that stay as the data has them; half keep the chosen objects where the last step
   put them, an eighth start near where the set's objects are, a quarter put two of the set in each
   other's places; every candidate set of every scene in one batched chain per size; the exact
   exchanges of two of the set are candidates too) and keeps the set whose best placement lowers the
   whole cost most; then each chosen object is tried back where it is, the rest re-placed. Each step
   also tries the pairs of objects of different kinds whose exchange lowers the cost most (a swap,
   where a false single move may pay first). When no single object pays, pairs of the best single
   candidates are tried together (two objects each where the other belongs). It stops when nothing
   lowers the cost. Moving an object costs, at effort 1, what re-placing an object of a
   right scene gains by the model's noise (:func:`calibrate`, :func:`count_weight`), times the object's
   effort weight: larger objects than the scene's median cost more (:func:`effort_weights`), so where
   moving either end of a relation fixes it, the smaller one moves.
2. *Pruning*: objects that moved less than ``move_tol`` go back to where they are; each remaining move
   is undone when that lowers the cost; the moved objects are also placed again by the missing-object
   placement, and so is each set of them one smaller (the left-out object where it is); the candidate
   with the lowest whole cost is kept, and a last refinement (``osqp``) runs over its moved objects
   alone, so every other object is exactly where it was. For one scene on a machine with a core to
   spare, that placement of the set chosen so far starts on the second core while the selection goes
   on (:func:`_placing_ahead`; the same answer to the bit).

:func:`plan_moves` then orders the moves so that each target is free of every object still in place
when the object is put down (the exact check), parking an object at a buffer pose where the moves
depend on each other in a cycle (two objects swapping places); :func:`validate_plan` replays a plan.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np
import torch
from torch import Tensor

from .costs import Bounds, Cost, Displacement, HingeCollision, LearnedEnergy, MoveCount, ReachLimit
from .devices import draw, generator
from .errors import ConfigError, check_number
from .models import ScoreModel
from .placement import OVERLAP_WEIGHT, non_overlap
from .problem import FEASIBILITY_TOL, Problem, ProblemError
from .sampling import PLACEMENT, screen
from .scene import Scene, atomic_write_text, wrap_angle
from .solvers import Result, Status, make_result, solve
from .solvers.base import torch_threads
from .solvers.langevin import LangevinOptions, LangevinSolver
from .threads import POOL_ROWS, Ahead

__all__ = [
    "EFFORT",
    "TidyError",
    "TidyOptions",
    "TidyResult",
    "Step",
    "PlanCheck",
    "Reach",
    "tidy",
    "tidy_many",
    "tidy_problem",
    "COUNT",
    "calibrate",
    "count_weight",
    "effort_weights",
    "object_gains",
    "move_gains",
    "plan_moves",
    "validate_plan",
    "blocking",
]

#: the default effort weight: multiplies the count and displacement weights of :class:`TidyOptions`
EFFORT = 1.0
#: energy per moved object when the model has no calibrated move gain (:func:`calibrate`)
COUNT = 0.3
#: the chance that noise alone moves none of a right scene's objects (:func:`calibrate`, :func:`count_weight`)
GAIN_QUANTILE = 0.75
#: the selection tries pairs of objects among this many best single moves when no single move pays
PAIR_CANDIDATES = 5
#: each step of the selection also tries this many pairs whose exchange (each object at the other's
#: position) lowers the whole cost the most
SWAP_CANDIDATES = 3
#: the spread (length scales; radians for the heading) of the re-placement draws started near an
#: object's current pose (:func:`_near_draws`; 0: none)
NEAR = 1.0

Reach = tuple[tuple[float, float], float]  # ((x, y) of the robot's base, radius in metres)


class TidyError(ProblemError):
    """A scene that cannot be tidied or a plan that cannot be made; one line naming the object."""


@dataclass(frozen=True)
class TidyOptions:
    """Settings of :func:`tidy` (the effort weight is an argument of its own)."""

    # at effort 1: energy per moved object (the smooth count's weight); None: the model's calibrated
    # move gain (:func:`calibrate`, stored in the checkpoint), else COUNT
    count: float | None = None
    distance: float = 0.1  # at effort 1: energy per length scale of displacement
    delta: float = 0.1  # length scales: the displacement is quadratic within this, then linear
    sigma: float = 0.05  # length scales: a move this long counts as half a moved object
    move_tol: float = 0.1  # length scales: an object that moved less than this stays where it is
    max_moves: int | None = None  # objects the forward selection may add (None: every movable one)
    gain_tol: float = 1e-6  # a step of the selection must lower the whole cost by more than this
    propose: LangevinOptions = LangevinOptions(
        particles=16, candidates=256, proposals=0.5, chain=replace(PLACEMENT, steps=40, final_descent=10)
    )
    refine: str | None = "osqp"  # the refinement of the moved objects after pruning (None: none)
    # the moved objects (and each set of them one smaller) also placed again by the missing-object
    # placement; the candidate with the lowest whole cost is kept
    place: bool = True
    refine_options: dict[str, Any] = field(default_factory=lambda: {"max_iter": 40})
    # objects larger than the scene's median one cost more to move (:func:`effort_weights`): where moving
    # either end of a relation fixes it, the smaller object is the one moved
    by_size: bool = True

    def __post_init__(self) -> None:
        own = "TidyOptions"
        if self.count is not None:
            check_number(own, "count", self.count, 0.0, math.inf)
        check_number(own, "distance", self.distance, 0.0, math.inf)
        for k in ("delta", "sigma", "move_tol"):
            check_number(own, k, getattr(self, k), 0.0, math.inf, open_lo=True)
        if self.max_moves is not None:
            check_number(own, "max_moves", self.max_moves, 0, 1_000_000, integer=True)
        check_number(own, "gain_tol", self.gain_tol, 0.0, math.inf)
        for k in ("place", "by_size"):
            if not isinstance(getattr(self, k), bool):
                raise ConfigError(f"TidyOptions: {k}: expected true or false, got {getattr(self, k)!r}")


@dataclass
class Step:
    """One pick-and-place: ``name`` from ``start`` (``None``: brought in) to ``goal``; ``buffer``: a parking move."""

    name: str
    start: tuple[float, float, float] | None
    goal: tuple[float, float, float]
    buffer: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "object": self.name,
            "from": None if self.start is None else [float(v) for v in self.start],
            "to": [float(v) for v in self.goal],
            "kind": "buffer" if self.buffer else "target",
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Step:
        start = d.get("from")
        return cls(
            str(d["object"]),
            None if start is None else cast(tuple[float, float, float], tuple(float(v) for v in start)),
            cast(tuple[float, float, float], tuple(float(v) for v in d["to"])),
            d.get("kind") == "buffer",
        )


@dataclass
class PlanCheck:
    """A replayed plan: valid when every step was legal and every object ended at its target."""

    valid: bool
    problems: list[str] = field(default_factory=list)

    def describe(self) -> str:
        return "valid" if self.valid else "; ".join(self.problems)


@dataclass
class TidyResult:
    """What :func:`tidy` found: the current and the tidy scene, who moves, how far, and in what order."""

    before: Scene
    after: Scene
    moved: list[str]
    distance: dict[str, float]  # metres each object's centre travels (moved objects)
    turn: dict[str, float]  # radians each moved object turns (0 for round objects)
    displacement: dict[str, float]  # the effort's d_i: centre and tip together, metres
    steps: list[Step]
    check: PlanCheck
    result: Result
    effort: float
    seed: int
    warnings: list[str] = field(default_factory=list)
    count: float = 0.0  # energy one moved object costs (the count weight times the effort)

    @property
    def total_displacement(self) -> float:
        """Sum of the moved objects' displacements ``d_i`` (metres)."""
        return float(sum(self.displacement.values()))

    @property
    def total_distance(self) -> float:
        """Sum of the distances the moved objects' centres travel (metres)."""
        return float(sum(self.distance.values()))

    @property
    def plan_made(self) -> bool:
        """Whether a plan could be made (False: a target admits none; the reason is in ``check``)."""
        return self.check.valid or bool(self.steps)

    @property
    def buffers(self) -> int:
        return sum(s.buffer for s in self.steps)

    def to_dict(self) -> dict[str, Any]:
        objects = {}
        for o, a in zip(self.before.objects, self.after.objects):
            objects[o.name] = {
                "moves": o.name in self.moved,
                "from": None if o.pose is None else [float(v) for v in o.pose],
                "to": None if a.pose is None else [float(v) for v in a.pose],
                "distance": self.distance.get(o.name, 0.0),
                "turn": self.turn.get(o.name, 0.0),
                "displacement": self.displacement.get(o.name, 0.0),
            }
        r = self.result
        return {
            "effort": self.effort,
            "move_cost": self.count,
            "seed": self.seed,
            "moved": list(self.moved),
            "total_displacement": self.total_displacement,
            "total_distance": self.total_distance,
            "objects": objects,
            "plan": {
                "steps": [s.to_dict() for s in self.steps],
                "buffers": self.buffers,
                "valid": self.check.valid,
                "problems": self.check.problems,
            },
            "solve": {
                "solver": r.solver,
                "status": r.status.value,
                "feasible": r.feasible,
                "objective": r.objective,
                "terms": {k: t["weighted"] for k, t in r.terms.items()},
            },
            "warnings": list(self.warnings),
            "scene": self.after.to_dict(),
        }

    def to_json(self, path: str | os.PathLike | None = None) -> str:
        """The result as JSON; written atomically to ``path`` when given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            atomic_write_text(path, text + "\n")
        return text


# -- the problem ----------------------------------------------------------------------------------------


def tidy_problem(
    model: ScoreModel,
    scene: Scene,
    effort: float = EFFORT,
    stay: Sequence[str] = (),
    weights: dict[str, float] | None = None,
    reach: Reach | None = None,
    options: TidyOptions | None = None,
    movable: Sequence[str] | None = None,
) -> Problem:
    """The problem :func:`tidy` solves: the learned energy plus ``effort`` times the effort (the smooth
    count of moved objects, :func:`count_weight` each, and the displacement, ``options.distance`` per
    length scale), non-overlap (as ``place`` keeps it), bounds and reach, with every object movable
    that is not fixed and not in ``stay`` (or only ``movable``)."""
    o = options or TidyOptions()
    if isinstance(effort, bool) or not isinstance(effort, (int, float)) or not (0 <= effort < math.inf):
        raise TidyError(f"tidy: effort: expected a finite weight >= 0, got {effort!r}")
    for n in stay:
        if n not in scene.names:
            raise TidyError(f"tidy: stay: no object named {n!r}; objects are {scene.names}")
    if movable is None:
        names = [ob.name for ob in scene.objects if not ob.fixed and ob.name not in stay]
    else:
        names = list(movable) + [n for n in scene.unknown if n not in movable]
    if not names:
        raise TidyError("tidy: no object may move (every object is fixed or told to stay)")
    length = model.config.length_scale
    weights = effort_weights(scene, weights, o)
    cost: Cost = LearnedEnergy(model)
    if effort * o.distance > 0:
        cost = cost + (effort * o.distance / length) * Displacement(delta=o.delta * length, weights=weights)
    count = count_weight(model, o, scene)
    if effort * count > 0:
        cost = cost + effort * count * MoveCount(sigma=o.sigma * length, weights=weights)
    hinge = non_overlap(model, scene, names)
    if hinge is not None:
        cost = cost + (OVERLAP_WEIGHT / length) * hinge
    cost = cost + (OVERLAP_WEIGHT / length) * Bounds()
    if reach is not None:
        (bx, by), radius = reach
        cost = cost + (OVERLAP_WEIGHT / length) * ReachLimit(base=(bx, by), radius=radius)
    return Problem(scene, cost, movable=names, name="tidy")


def effort_weights(
    scene: Scene, weights: dict[str, float] | None = None, options: TidyOptions | None = None
) -> dict[str, float] | None:
    """Each object's effort weight: the user's ``weights`` (default 1) times, with ``options.by_size``,
    ``sqrt(area / median area)`` of the scene's objects that are not fixed, at least 1 (a plate costs
    more to move than the knife beside it; no object costs less than 1)."""
    o = options or TidyOptions()
    if not o.by_size:
        return weights
    free = [ob for ob in scene.objects if not ob.fixed]
    if not free:
        return weights
    median = float(np.median([ob.size[0] * ob.size[1] for ob in free]))
    user = weights or {}
    return {
        ob.name: user.get(ob.name, 1.0) * max(1.0, math.sqrt(ob.size[0] * ob.size[1] / median))
        for ob in scene.objects
    }


# -- solving --------------------------------------------------------------------------------------------


def _moves(scene: Scene, x: np.ndarray) -> np.ndarray:
    """``d_i`` per object (centre and tip, metres) from its pose in ``scene`` to ``x``."""
    d = Displacement(objects=scene.names).bind(scene)
    return cast(Displacement, d).moves(x)


def tidy(
    model: ScoreModel,
    scene: Scene,
    effort: float = EFFORT,
    seed: int = 0,
    stay: Sequence[str] = (),
    weights: dict[str, float] | None = None,
    reach: Reach | None = None,
    options: TidyOptions | None = None,
) -> TidyResult:
    """Tidy ``scene``: which objects to move where, with ``effort`` weighing the robot's work against
    the learned energy (0: re-arrange freely), and the order to move them in. ``stay``: objects that
    must not move; ``weights``: ``{name: weight}`` of each object's effort (heavy or fragile: more);
    ``reach``: ``((x, y), radius)`` of the robot. Deterministic in ``seed``."""
    return tidy_many(model, [scene], effort, seed, stay, weights, reach, options)[0]


def tidy_many(
    model: ScoreModel,
    scenes: Sequence[Scene],
    effort: float = EFFORT,
    seed: int = 0,
    stay: Sequence[str] = (),
    weights: dict[str, float] | None = None,
    reach: Reach | None = None,
    options: TidyOptions | None = None,
) -> list[TidyResult]:
    """:func:`tidy` for several scenes, their placements batched (one chain per number of objects)."""
    o = options or TidyOptions()
    scenes = list(scenes)
    for scene in scenes:
        if scene.unknown:
            raise TidyError(
                f"tidy: {scene.label()}: object {scene.unknown[0]!r} has pose null; tidy moves objects from "
                "where they are (fill unknown poses first with `scenescore place`)"
            )
    problems = [tidy_problem(model, s, effort, stay, weights, reach, o) for s in scenes]
    tol = o.move_tol * model.config.length_scale  # metres
    # small tensors: one torch thread (restored after; the placement chains choose their own)
    with torch_threads(1), _placing_ahead(model, scenes, problems, o, seed, tol) as ahead:
        states = _select(model, scenes, problems, o, seed, None if ahead is None else ahead[1])
        pruned, moved = [], []
        for p, x in zip(problems, states):
            x, names = _pruned(p, x, tol)
            pruned.append(x)
            moved.append(names)
        if not o.place:
            placed: list[list[np.ndarray]] = [[] for _ in scenes]
        elif ahead is not None:  # one scene
            placed = [ahead[0].result(tuple(moved[0]), lambda: _placed(model, scenes, moved, seed)[0])]
        else:
            placed = _placed(model, scenes, moved, seed)
        out = []
        for s, p, x, m, alt in zip(scenes, problems, pruned, moved, placed):
            r0 = make_result(p, "tidy", x, Status.SAMPLED, 0, 0.0, 0.0)
            out.append(_finish(model, s, p, r0, m, alt, effort, seed, stay, weights, reach, o))
    return out


def _pruned(problem: Problem, x: np.ndarray, tol: float) -> tuple[np.ndarray, list[str]]:
    """The selection's poses ``x (N, 3)`` pruned (:func:`_prune`) and the objects that move in them."""
    scene = problem.scene
    x = _prune(problem, x, scene.poses(), tol)
    return x, [n for n, d in zip(scene.names, _moves(scene, x)) if d > tol]


def _blanks(scene: Scene, names: list[str]) -> list[Scene]:
    """The scenes :func:`_placed` fills for the moved objects ``names``: ``scene`` with their poses
    unknown, and, where two or more moved, with those of each set one smaller."""
    sets = [names] if names else []
    if len(names) > 1:
        sets += [[m for m in names if m != n] for n in names]
    out = []
    for subset in sets:
        b = scene.copy()
        for n in subset:
            b.objects[b.index(n)].pose = None
        out.append(b)
    return out


@contextmanager
def _placing_ahead(
    model: ScoreModel, scenes: list[Scene], problems: list[Problem], o: TidyOptions, seed: int, tol: float
) -> Iterator[tuple[Ahead, Callable[[int, np.ndarray], None]] | None]:
    """For a single scene on a machine with a core to spare (:meth:`~scenescore.threads.Ahead.worth`):
    an :class:`~scenescore.threads.Ahead` and the selection's callback that starts :func:`_placed` of
    the set its poses so far move, on the second core while the selection goes on (its last rounds
    usually confirm that set). The answers are the same to the bit as without it, which needs every
    chain on one torch thread (fewer than :data:`~scenescore.threads.POOL_ROWS` particles): the
    selection's batches (at most one set per movable object and :data:`SWAP_CANDIDATES` swaps, or the
    pairs round) and each placement's. None otherwise (several scenes have their placements batched
    together)."""
    from .placement import PLACE

    pairs = PAIR_CANDIDATES * (PAIR_CANDIDATES - 1) // 2
    if (
        len(scenes) != 1
        or not o.place
        or o.propose.threads not in (None, 1)
        or o.propose.particles * max(len(problems[0].movable) + SWAP_CANDIDATES, pairs) >= POOL_ROWS
        or not Ahead.worth()
    ):
        yield None
        return

    def submit(k: int, x: np.ndarray) -> None:
        names = _pruned(problems[k], x, tol)[1]
        if names and PLACE.particles * len(_blanks(scenes[k], names)) < POOL_ROWS:
            ahead.submit(tuple(names), lambda: _placed(model, scenes, [names], seed)[0])

    with Ahead() as ahead:
        yield ahead, submit


def _placed(
    model: ScoreModel, scenes: list[Scene], moved: list[list[str]], seed: int
) -> list[list[np.ndarray]]:
    """Per scene, candidate poses from the missing-object placement
    (:func:`~scenescore.placement.place_many`: its longer chain and trust ranking, the other objects
    where they are): the objects of ``moved`` placed again, and, where two or more moved, the set with
    each one of them left where it is (an object the selection moved only to fit a short-chained
    placement of another); empty where nothing moves."""
    from .placement import place_many

    blanks, idx = [], []
    for k, (s, names) in enumerate(zip(scenes, moved)):
        for b in _blanks(s, names):
            blanks.append(b)
            idx.append(k)
    out: list[list[np.ndarray]] = [[] for _ in scenes]
    for k, filled in zip(idx, place_many(model, blanks, seed=seed)):
        out[k].append(filled.poses())
    return out


def _select(
    model: ScoreModel,
    scenes: list[Scene],
    problems: list[Problem],
    o: TidyOptions,
    seed: int,
    on_change: Callable[[int, np.ndarray], None] | None = None,
) -> list[np.ndarray]:
    """Which objects to move, per scene, by forward selection with a backward check: each step re-places
    the chosen set with one more movable object (the others where they are) and keeps the set whose
    best placement lowers the whole cost (energy, effort, overlap, bounds, reach) the most; then each
    chosen object is tried back where it is, the rest re-placed, and dropped when that lowers the cost
    (a first pick that only made room for the right one). When no such step lowers the cost, pairs of
    the :data:`PAIR_CANDIDATES` best single additions are tried together (two objects that are each
    where the other belongs: neither move pays alone); it stops when that fails too. Each step also
    tries the chosen set with the :data:`SWAP_CANDIDATES` pairs whose exchange lowers the cost most
    (:func:`_swaps`), so that two objects in each other's places are found even where a false single
    move pays first. ``on_change(k, poses)`` is called whenever scene ``k``'s poses change.
    Returns each scene's poses ``(N, 3)``."""
    states = [s.poses() for s in scenes]
    chosen: list[list[str]] = [[] for _ in scenes]
    best = [float(_cost(p, x[None])[0]) for p, x in zip(problems, states)]
    limit = [len(p.movable) if o.max_moves is None else min(o.max_moves, len(p.movable)) for p in problems]
    active = [k for k in range(len(scenes)) if limit[k] > 0]
    step = 0
    while active and step < 4 * max(limit):
        step += 1
        grow = {
            k: [[*chosen[k], n] for n in problems[k].movable if n not in chosen[k]]
            + (_swaps(problems[k], states[k], best[k], chosen[k]) if len(chosen[k]) + 2 <= limit[k] else [])
            for k in active
        }
        shrink = {
            k: [[m for m in chosen[k] if m != n] for n in chosen[k]] for k in active if len(chosen[k]) > 1
        }
        jobs = {k: (grow[k] if len(chosen[k]) < limit[k] else []) + shrink.get(k, []) for k in active}
        every: dict[int, list[tuple[float, list[str]]]] = {}
        found = _replacements(model, scenes, problems, jobs, o, seed + 7919 * step, states, every)
        still, stuck = [], []
        for k in active:
            if k in found and found[k][0] < best[k] - o.gain_tol:
                best[k], states[k], chosen[k] = found[k]
                still.append(k)
            elif len(chosen[k]) + 2 <= limit[k]:
                stuck.append(k)
        if stuck:
            pairs = {k: _pairs(chosen[k], every.get(k, [])) for k in stuck}
            found = _replacements(model, scenes, problems, pairs, o, seed + 7919 * step + 1, states)
            for k in stuck:
                if k in found and found[k][0] < best[k] - o.gain_tol:
                    best[k], states[k], chosen[k] = found[k]
                    still.append(k)
        active = sorted(still)
        if on_change is not None:
            for k in active:
                on_change(k, states[k])
    return states


def _swaps(problem: Problem, x: np.ndarray, best: float, chosen: list[str]) -> list[list[str]]:
    """The chosen set with each of the :data:`SWAP_CANDIDATES` pairs of movable objects not in it, of
    different kinds (:attr:`~scenescore.scene.SceneObject.kind`: category or size), whose exchange at
    the poses ``x (N, 3)`` (each at the other's position, with its own heading or the other's, the
    better) lowers the whole cost below ``best`` the most; one batched cost evaluation."""
    scene = problem.scene
    free = [n for n in problem.movable if n not in chosen]
    pairs = [(a, b) for i, a in enumerate(free) for b in free[i + 1 :] if scene[a].kind != scene[b].kind]
    if not pairs or SWAP_CANDIDATES <= 0:
        return []
    xs = _exchanges(x, [(scene.index(a), scene.index(b)) for a, b in pairs])  # (2P, N, 3)
    costs = _cost(problem, xs).reshape(2, len(pairs)).min(0)  # (P,): the better of the two exchanges
    order = [j for j in np.argsort(costs, kind="stable") if costs[j] < best][:SWAP_CANDIDATES]
    return [[*chosen, *pairs[j]] for j in order]


def _pairs(chosen: list[str], tried: list[tuple[float, list[str]]]) -> list[list[str]]:
    """The chosen set with two more objects, every pair among the :data:`PAIR_CANDIDATES` single additions
    to it that cost least (``tried``: each tried set's lowest cost)."""
    singles = sorted((c, names[-1]) for c, names in tried if len(names) == len(chosen) + 1)
    top = [n for _, n in singles[:PAIR_CANDIDATES]]
    return [[*chosen, a, b] for i, a in enumerate(top) for b in top[i + 1 :]]


def _replacements(
    model: ScoreModel,
    scenes: list[Scene],
    problems: list[Problem],
    jobs: dict[int, list[list[str]]],
    o: TidyOptions,
    seed: int,
    warm: list[np.ndarray] | None = None,
    every: dict[int, list[tuple[float, list[str]]]] | None = None,
) -> dict[int, tuple[float, np.ndarray, list[str]]]:
    """Per scene ``k`` of ``jobs``: the lowest cost of ``problems[k]`` found by re-placing one of its
    sets of objects (the others where they are; every set of every scene placed in one batched chain
    per size), its poses ``(N, 3)`` and that set. ``warm``: each scene's poses so far; half the draws
    keep the objects of the set that those poses moved where they put them. ``every``, when given, is
    filled with each scene's ``(lowest cost, set)`` of every set."""
    from .placement import covering, placement_problem

    flat = [(k, names) for k, sets in jobs.items() for names in sets if names]
    blanks, starts = [], []
    gen = generator(seed, model.device)
    keep = o.propose.particles
    for k, names in flat:
        blank = scenes[k].copy()
        for m in names:
            blank.objects[blank.index(m)].pose = None
        # the fused network alone; the whole cost judges overlap below
        p = placement_problem(model, blank, energy_only=True)
        # as many draws as placement screens for these bounds (small objects in large bounds need more);
        # a share of them proposed beside the objects that stay, as the data has them, the rest uniform
        draws = max(covering(o.propose, model, [scenes[k]]).candidates, keep)
        x = p.initial(draws, gen, proposals=o.propose.proposals)  # (draws, N, 3): the others where they are
        rows = [scenes[k].index(m) for m in names]
        if warm is not None:
            now = scenes[k].poses()
            moved = [i for i in rows if not np.array_equal(warm[k][i], now[i])]
            if moved:
                x[: draws // 2, moved] = torch.as_tensor(warm[k][moved], dtype=x.dtype, device=x.device)
        _near_draws(x, scenes[k], rows, model.config.length_scale, gen)
        _swap_draws(x, scenes[k], names)
        blanks.append(p)
        starts.append(screen(p.cost, x, keep))
    found: dict[int, tuple[float, np.ndarray, list[str]]] = {}
    solver = LangevinSolver(o.propose)
    for idx in _by_size(blanks):
        results = solver.solve_many([blanks[j] for j in idx], seed=seed, init=[starts[j] for j in idx])
        for j, res in zip(idx, results):
            k, names = flat[j]
            assert res.samples is not None
            # the chain's samples and the set's exact exchanges (a chain may leave a swap it was started on)
            pairs = _set_pairs(scenes[k], names)
            got = np.asarray(res.samples, dtype=float)
            if pairs:
                got = np.concatenate([got, _exchanges(scenes[k].poses(), pairs)])
            costs = _cost(problems[k], got)
            i = int(np.argmin(costs))
            if every is not None:
                every.setdefault(k, []).append((float(costs[i]), list(names)))
            if k not in found or costs[i] < found[k][0]:
                found[k] = (float(costs[i]), got[i], list(names))
    return found


def object_gains(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> list[tuple[int, str, float]]:
    """Per movable object of each scene taken as right: ``(scene index, name, gain)``, how much re-placing
    that object alone lowers the learned energy (with non-overlap and bounds; negative where the search
    finds no pose as good as the one it has); the noise of the model's own judgement that a move must beat."""
    scenes = list(scenes)
    o = TidyOptions(count=0.0)
    problems = [tidy_problem(model, s, 0.0, options=o) for s in scenes]
    items = [(k, n) for k, p in enumerate(problems) for n in p.movable]
    now = [float(_cost(p, s.poses()[None])[0]) for p, s in zip(problems, scenes)]
    # one job per object: the scene repeated, so that each object's best re-placement is kept
    found = _replacements(
        model,
        [scenes[k] for k, _ in items],
        [problems[k] for k, _ in items],
        {j: [[n]] for j, (_, n) in enumerate(items)},
        o,
        seed,
    )
    return [(k, n, now[k] - found[j][0] if j in found else 0.0) for j, (k, n) in enumerate(items)]


def _near_draws(x: Tensor, scene: Scene, rows: list[int], length: float, gen: torch.Generator) -> None:
    """In the eighth of the draws ``x (D, N, 3)`` before their last quarter, the objects ``rows`` near
    where they are now: their poses in ``scene`` plus Gaussian noise of :data:`NEAR` length scales
    ``length`` (and radians): an object nudged a little is found by a short chain, not left to uniform
    draws over the whole bounds."""
    if NEAR <= 0 or not rows:
        return
    d = x.shape[0]
    a, z = d - d // 4 - d // 8, d - d // 4
    if z <= a:
        return
    now = torch.as_tensor(scene.poses()[rows], dtype=x.dtype, device=x.device)  # (R, 3)
    noise = draw("randn", (z - a, len(rows), 3), gen, x.device, x.dtype)
    noise[..., :2] *= NEAR * length
    noise[..., 2] *= NEAR
    x[a:z, rows] = now + noise


def _exchanges(x: np.ndarray, pairs: Sequence[tuple[int, int]]) -> np.ndarray:
    """The poses ``x (N, 3)`` with each pair of rows ``pairs`` exchanged, two ways: ``(2P, N, 3)``, first
    each object at the other's pose, then (rows ``P..2P``) at the other's position with its own heading."""
    x = np.asarray(x, dtype=float)
    out = np.repeat(x[None], 2 * len(pairs), axis=0)
    for j, (a, b) in enumerate(pairs):
        out[j, a], out[j, b] = x[b], x[a]
        out[len(pairs) + j, a, :2], out[len(pairs) + j, b, :2] = x[b, :2], x[a, :2]
    return out


def _set_pairs(scene: Scene, names: Sequence[str]) -> list[tuple[int, int]]:
    """Rows of every pair of the objects ``names`` of ``scene``."""
    rows = [scene.index(m) for m in names]
    return [(a, b) for i, a in enumerate(rows) for b in rows[i + 1 :]]


def _swap_draws(x: Tensor, scene: Scene, names: list[str]) -> None:
    """In the last quarter of the draws ``x (D, N, 3)``, each pair of the set ``names`` in turn trades
    places (:func:`_exchanges`: with the other's heading, and in every other round with its own), the
    set's other objects as drawn: two objects in each other's places are found at once, not left to
    uniform draws."""
    pairs = _set_pairs(scene, names)
    if not pairs:
        return
    swapped = torch.as_tensor(_exchanges(scene.poses(), pairs), dtype=x.dtype, device=x.device)  # (2P, N, 3)
    p, start = len(pairs), x.shape[0] - x.shape[0] // 4
    k = torch.arange(x.shape[0] - start, device=x.device)  # the last quarter's draws: k // p is the round
    # each draw's row of ``swapped``: its pair, in every other round with its own heading
    src = k % p + p * ((k // p) % 2)
    for i, (a, b) in enumerate(pairs):
        mine = k[k % p == i]  # (M,)
        rows = torch.tensor([a, b], device=x.device)
        x[start + mine[:, None], rows] = swapped[src[mine]][:, rows]


def _scene_best(gains: list[tuple[int, str, float]], scenes: int) -> np.ndarray:
    """Per scene of :func:`object_gains`' ``gains``: its best single object's gain, at least 0."""
    best = np.zeros(scenes)
    for k, _, g in gains:
        best[k] = max(best[k], g)
    return best


def move_gains(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> np.ndarray:
    """Per scene taken as right: how much re-placing its best single object lowers the learned energy
    (with non-overlap and bounds), at least 0."""
    return _scene_best(object_gains(model, scenes, seed), len(scenes))


def calibrate(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> float:
    """Measure what a move must gain on ``scenes`` taken as right (held-out ones are best) and store it in
    ``model.info["tidy"]`` (and so in the checkpoint): ``gains``, every object's single-move gain
    (:func:`object_gains`, at least 0, sorted), from which :func:`count_weight` sets the cost of a move
    in a scene of any size; and ``move_gain``, the :data:`GAIN_QUANTILE` quantile of each scene's best
    single move (:func:`move_gains`), returned."""
    posed = [s for s in scenes if not s.unknown]
    if not posed:
        raise TidyError("calibrate: no scene with every pose known to measure the move gain on")
    gains = object_gains(model, posed, seed)
    gain = float(np.quantile(_scene_best(gains, len(posed)), GAIN_QUANTILE))
    model.info["tidy"] = {
        "move_gain": gain,
        "gains": sorted(max(0.0, g) for _, _, g in gains),
        "scenes": len(posed),
        "quantile": GAIN_QUANTILE,
    }
    return gain


def _gain(value: Any) -> float | None:
    """A stored gain when it is a finite number >= 0, else None."""
    ok = (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value >= 0
    )
    return float(value) if ok else None


def _gains(value: Any) -> list[float] | None:
    """Stored gains when they are a non-empty list of finite numbers >= 0, else None."""
    if not isinstance(value, list) or not value:
        return None
    out = [_gain(v) for v in value]
    return None if any(v is None for v in out) else cast(list[float], out)


def count_weight(model: ScoreModel, options: TidyOptions | None = None, scene: Scene | None = None) -> float:
    """Energy per moved object at effort 1: ``options.count``; else, for ``scene`` and a model that
    :func:`calibrate` stored gains per object in, the ``GAIN_QUANTILE ** (1 / M)`` quantile of those
    gains, ``M`` the scene's objects that are not fixed (so that noise alone moves none of ``M`` right
    objects with probability about :data:`GAIN_QUANTILE`, whatever the scene's size); else the model's
    ``move_gain`` (checkpoints calibrated before gains per object); else :data:`COUNT`."""
    o = options or TidyOptions()
    if o.count is not None:
        return float(o.count)
    stored = model.info.get("tidy") if isinstance(model.info, dict) else None
    if not isinstance(stored, dict):
        return COUNT
    gains = _gains(stored.get("gains"))
    if scene is not None and gains is not None:
        movable = max(1, sum(not ob.fixed for ob in scene.objects))
        return float(np.quantile(gains, GAIN_QUANTILE ** (1.0 / movable)))
    g = _gain(stored.get("move_gain"))
    return COUNT if g is None else g


def _by_size(problems: Sequence[Problem]) -> list[list[int]]:
    """Indices of ``problems`` grouped by their number of objects (one batched chain each)."""
    groups: dict[int, list[int]] = {}
    for j, p in enumerate(problems):
        groups.setdefault(p.n, []).append(j)
    return list(groups.values())


def _cost(problem: Problem, x: np.ndarray | torch.Tensor) -> np.ndarray:
    """The whole cost of ``problem`` at each row of ``x`` ``(B, N, 3)``."""
    with torch.no_grad():
        return problem.evaluate(problem.full(x)).cpu().numpy()


def _finish(
    model: ScoreModel,
    scene: Scene,
    problem: Problem,
    r: Result,
    moved: list[str],
    placed: list[np.ndarray],
    effort: float,
    seed: int,
    stay: Sequence[str],
    weights: dict[str, float] | None,
    reach: Reach | None,
    o: TidyOptions,
) -> TidyResult:
    """Choose among the selection's pruned poses ``r.poses`` and the ``placed`` candidates (the
    missing-object placement of the moved objects, and of each subset one smaller) the one that violates
    the constraints least at the lowest whole cost; refine its moved objects alone; plan the moves."""
    current = scene.poses()
    x = r.poses
    tol = o.move_tol * model.config.length_scale  # metres
    final = tidy_problem(model, scene, effort, stay, weights, reach, o, movable=moved or problem.movable)

    def worse(a: np.ndarray, b: np.ndarray) -> bool:
        """Whether ``a`` violates the constraints more than ``b``, or as much at a higher whole cost."""
        va, vb = (float(final.violation(torch.as_tensor(v))[0]) for v in (a, b))
        if va > vb + 1e-12:
            return True
        return va >= vb - 1e-12 and float(_cost(final, a[None])[0]) > float(_cost(final, b[None])[0])

    for alt in placed:
        if not worse(alt, x):
            x = alt
    if moved:
        far = _moves(scene, x) > tol  # (N,)
        moved = [n for n, f in zip(scene.names, far) if f]
        x = np.where(far[:, None], x, current)
        final = tidy_problem(model, scene, effort, stay, weights, reach, o, movable=moved or problem.movable)
    if moved and o.refine:
        # the moved objects alone, every other one exactly where it is; by the energy and the constraints
        # without the effort: the selection chose which objects move and to which spot, and a pull back
        # toward where they were would leave them short of it
        put = tidy_problem(model, scene, 0.0, stay, weights, reach, o, movable=moved)
        r2 = solve(put, o.refine, init=x, seed=seed, options={o.refine: o.refine_options})
        if (
            float(final.violation(torch.as_tensor(r2.poses))[0])
            <= float(final.violation(torch.as_tensor(x))[0]) + 1e-12
        ):
            x, r = r2.poses, r2
    r = make_result(final, r.solver, x, r.status, r.iterations, r.time_setup, r.time_solve, message=r.message)
    after = scene.with_poses(x)
    d = _moves(scene, x)
    dist = {n: float(np.hypot(*(x[i, :2] - current[i, :2]))) for i, n in enumerate(scene.names) if n in moved}
    turn = {
        n: 0.0 if scene[n].round else float(abs(wrap_angle(x[i, 2] - current[i, 2])))
        for i, n in enumerate(scene.names)
        if n in moved
    }
    disp = {n: float(d[i]) for i, n in enumerate(scene.names) if n in moved}
    warnings = [v.describe() for v in final.check(x).violations]
    try:
        steps = plan_moves(scene, after, model=model, reach=reach, seed=seed)
        check = validate_plan(scene, after, steps, model=model, reach=reach)
    except TidyError as e:
        steps, check = [], PlanCheck(False, [str(e)])
        warnings.append(str(e))
    count = float(effort) * count_weight(model, o, scene)
    return TidyResult(
        scene, after, moved, dist, turn, disp, steps, check, r, float(effort), seed, warnings, count
    )


def _prune(problem: Problem, x: np.ndarray, current: np.ndarray, tol: float) -> np.ndarray:
    """Objects moved less than ``tol`` (metres) back where they are; then each move undone while that
    lowers the whole cost (smallest moves first)."""
    x = np.array(x, dtype=float)
    before = problem.scene
    d = _moves(before, x)
    x[d <= tol] = current[d <= tol]

    def cost(p: np.ndarray) -> float:
        return float(_cost(problem, p[None])[0])

    best = cost(x)
    changed = True
    while changed:
        changed = False
        d = _moves(before, x)
        for i in np.argsort(d):
            if d[i] <= tol:
                continue
            y = x.copy()
            y[i] = current[i]
            c = cost(y)
            if c <= best:
                x, best, changed = y, c, True
                break
    return x


# -- the pick-and-place plan ----------------------------------------------------------------------------


def blocking(scene: Scene, name: str, model: ScoreModel | None = None) -> list[str]:
    """The objects whose footprint ``name``'s overlaps in ``scene`` (the exact check of non-overlap, at
    the feasibility tolerance; with ``model``, category pairs that overlap in its training data are
    allowed, as in :func:`~scenescore.placement.non_overlap`)."""
    placed = scene.copy()
    for ob in placed.objects:  # objects not on the table (pose null) block nothing
        if ob.pose is None:
            ob.pose = (1e6 + 10 * placed.index(ob.name), 1e6, 0.0)
    if model is not None:
        hinge = non_overlap(model, placed, [name])
    else:
        pairs = [[name, n] for n in placed.names if n != name]
        hinge = HingeCollision(pairs=pairs, name="overlap") if pairs else None
    if hinge is None:
        return []
    term = cast(HingeCollision, hinge.bind(placed, [name]))
    names = placed.names
    by_label = {lab: names[j] for lab, (_, j) in zip(term.labels(), term.support())}
    return [by_label[v.label] for v in term.check(placed.poses(), FEASIBILITY_TOL)]


def _legal(scene: Scene, name: str, reach: Reach | None) -> list[str]:
    """What is wrong with ``name``'s pose in ``scene`` by the exact bounds and reach checks."""
    terms: list[Cost] = [Bounds(objects=[name])]
    if reach is not None:
        terms.append(ReachLimit(base=reach[0], radius=reach[1], objects=[name]))
    out = []
    for t in terms:
        b = t.bind(scene, [name])
        out += [v.describe() for v in b.check(scene.poses(), FEASIBILITY_TOL)]
    return out


def _state(before: Scene, poses: dict[str, tuple[float, float, float] | None]) -> Scene:
    out = before.copy()
    for ob in out.objects:
        ob.pose = poses[ob.name]
    return out


def plan_moves(
    before: Scene,
    after: Scene,
    model: ScoreModel | None = None,
    reach: Reach | None = None,
    seed: int = 0,
    tol: float = 1e-9,
    buffer_draws: int = 4000,
) -> list[Step]:
    """The order of pick-and-place moves from ``before`` to ``after``: each object is put down only
    where no object still in place lies (exact check); where every remaining move waits on another
    (a cycle, such as a swap), one object is parked at a buffer pose, free of every object and every
    remaining target, inside the bounds and the reach. Raises :class:`TidyError` when a target is
    blocked by an object that does not move, or no buffer pose is found."""
    if before.names != after.names:
        raise TidyError("plan: the two scenes have different objects")
    state: dict[str, tuple[float, float, float] | None] = {o.name: o.pose for o in before.objects}
    goal = {o.name: o.pose for o in after.objects}
    todo = []
    for n in before.names:
        g = goal[n]
        if g is None:
            raise TidyError(f"plan: object {n!r} has no target pose")
        s = state[n]
        if s is None or not _same(s, g, tol):
            todo.append(n)
    final = _state(before, {n: goal[n] for n in before.names})
    for n in todo:
        wrong = _legal(final, n, reach)
        if wrong:
            raise TidyError(f"plan: {n!r}'s target is not allowed: {wrong[0]}")
    steps: list[Step] = []
    gen = np.random.default_rng(seed)
    parked: set[str] = set()
    for _ in range(3 * len(todo) + 3):
        if not todo:
            return steps
        blocked: dict[str, list[str]] = {}
        for n in todo:
            trial = _state(before, {**state, n: goal[n]})
            blocked[n] = blocking(trial, n, model)
        free = [n for n in todo if not blocked[n]]
        if free:
            n = free[0]
            steps.append(Step(n, state[n], cast(tuple[float, float, float], goal[n])))
            state[n] = goal[n]
            todo.remove(n)
            continue
        for n in todo:
            stuck = [b for b in blocked[n] if b not in todo]
            if stuck:
                raise TidyError(f"plan: {n!r}'s target overlaps {stuck[0]!r}, which does not move")
        # a cycle: park the object that blocks the most others (ties: the first), at the buffer pose
        # closest to its way from where it is to its target
        count = {n: sum(n in blocked[m] for m in todo) for n in todo}
        order = sorted((n for n in todo if n not in parked), key=lambda n: -count[n]) or todo
        for n in order:
            pose = _buffer(before, state, goal, todo, n, model, reach, gen, buffer_draws)
            if pose is not None:
                steps.append(Step(n, state[n], pose, buffer=True))
                state[n] = pose
                parked.add(n)
                break
        else:
            raise TidyError(f"plan: no buffer pose free of the other objects for any of {todo}")
    raise TidyError(f"plan: the moves of {todo} could not be ordered")


def _buffer(
    before: Scene,
    state: dict[str, tuple[float, float, float] | None],
    goal: dict[str, tuple[float, float, float] | None],
    todo: list[str],
    name: str,
    model: ScoreModel | None,
    reach: Reach | None,
    gen: np.random.Generator,
    draws: int,
) -> tuple[float, float, float] | None:
    """A parking pose for ``name``: free of every object where it is now and of every remaining
    target, inside the bounds (footprint) and the reach; the one with the shortest detour."""
    (x0, y0), (x1, y1) = before.bounds
    src = state[name]
    dst = goal[name]
    assert dst is not None
    heading = (src or dst)[2]
    pts = np.c_[gen.uniform(x0, x1, draws), gen.uniform(y0, y1, draws)]
    a = np.array((src or dst)[:2])
    b = np.array(dst[:2])
    detour = np.hypot(*(pts - a).T) + np.hypot(*(pts - b).T)
    if reach is not None:
        ok = np.hypot(*(pts - np.array(reach[0])).T) <= reach[1]
        pts, detour = pts[ok], detour[ok]
    # what must stay clear: every object where it is now, and the targets still to be reached
    targets = [(m, goal[m]) for m in todo if m != name]
    # try first the draws whose bounding circle clears every other object's (no exact check rejects them)
    others = [(before[m].size, p) for m, p in state.items() if m != name and p is not None]
    others += [(before[m].size, p) for m, p in targets if p is not None]
    r = 0.5 * math.hypot(*before[name].size)
    clear = np.ones(len(pts), dtype=bool)
    for size, p in others:
        clear &= np.hypot(*(pts - np.array(p[:2])).T) > r + 0.5 * math.hypot(*size)
    for k in sorted(range(len(pts)), key=lambda k: (not clear[k], detour[k])):
        pose = (float(pts[k, 0]), float(pts[k, 1]), float(heading))
        trial = _state(before, {**state, name: pose})
        if _legal(trial, name, reach) or blocking(trial, name, model):
            continue
        if any(g is not None and _overlap_at(before, name, pose, m, g, model) for m, g in targets):
            continue
        return pose
    return None


def _overlap_at(
    before: Scene,
    name: str,
    pose: tuple[float, float, float],
    other: str,
    other_pose: tuple[float, float, float],
    model: ScoreModel | None,
) -> bool:
    """Whether ``name`` at ``pose`` overlaps ``other`` at ``other_pose`` (the two alone)."""
    pair = Scene([before[name], before[other]], before.bounds).with_poses([pose, other_pose])
    return bool(blocking(pair, name, model))


def validate_plan(
    before: Scene,
    after: Scene,
    steps: Sequence[Step | dict[str, Any]],
    model: ScoreModel | None = None,
    reach: Reach | None = None,
    tol: float = 1e-6,
) -> PlanCheck:
    """Replay ``steps`` from ``before``: each step picks its object where it is and puts it down
    inside the bounds and the reach, overlapping no object in place (the exact check); at the end
    every object is at its pose in ``after``."""
    state: dict[str, tuple[float, float, float] | None] = {o.name: o.pose for o in before.objects}
    problems: list[str] = []
    for k, raw in enumerate(steps, start=1):
        s = Step.from_dict(raw) if isinstance(raw, dict) else raw
        if s.name not in state:
            problems.append(f"step {k}: no object named {s.name!r}")
            continue
        now = state[s.name]
        if (now is None) != (s.start is None) or (
            now is not None and s.start is not None and not _same(now, s.start, tol)
        ):
            problems.append(f"step {k}: {s.name!r} is not where the step picks it up")
        state[s.name] = s.goal
        trial = _state(before, state)
        problems += [f"step {k}: {p}" for p in _legal(trial, s.name, reach)]
        problems += [f"step {k}: {s.name!r} put down on {b!r}" for b in blocking(trial, s.name, model)]
    for o in after.objects:
        now = state[o.name]
        if o.pose is not None and (now is None or not _same(now, o.pose, tol)):
            problems.append(f"{o.name!r} does not end at its target")
    return PlanCheck(not problems, problems)


def _same(a: Sequence[float], b: Sequence[float], tol: float) -> bool:
    return abs(a[0] - b[0]) <= tol and abs(a[1] - b[1]) <= tol and abs(wrap_angle(a[2] - b[2])) <= tol
