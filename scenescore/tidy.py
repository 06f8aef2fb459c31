"""Tidying a messy scene: a desirable arrangement reached with little robot effort, and the order of moves.

Every known pose is the current state. :func:`tidy` minimises the learned energy plus the effort of
moving objects from where they are (:class:`~scenescore.costs.Displacement` and
:class:`~scenescore.costs.MoveCount`), with non-overlap, bounds and, when given, reach:

1. *Proposals*: each movable object is placed anew by the learned energy with the others where they
   are (the missing-object placement, every object at once in one batched chain): where it would go.
2. *Sampling*: candidates are the current state with one or two objects moved to a proposal (or
   redrawn uniformly); the best by the whole cost start a short ``langevin`` chain near the current
   state, whose best particle seeds a refinement (``osqp``).
3. *Pruning*: objects that moved less than ``move_tol`` go back to where they are; each remaining move
   is undone when that lowers the cost; a last refinement runs over the moved objects alone, so
   every other object is exactly where it was.

:func:`plan_moves` then orders the moves so that each target is free of every object still in place
when the object is put down (the exact check), parking an object at a buffer pose where the moves
depend on each other in a cycle (two objects swapping places); :func:`validate_plan` replays a plan.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np
import torch

from .costs import Bounds, Cost, Displacement, HingeCollision, LearnedEnergy, MoveCount, ReachLimit
from .models import ScoreModel
from .placement import OVERLAP_WEIGHT, non_overlap
from .problem import FEASIBILITY_TOL, Problem, ProblemError
from .sampling import PLACEMENT, LangevinConfig, screen
from .scene import Scene, atomic_write_text, wrap_angle
from .solvers import Result, make_result, solve
from .solvers.langevin import LangevinOptions, LangevinSolver

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
    "plan_moves",
    "validate_plan",
    "blocking",
]

#: the default effort weight: energy per length scale of displacement (free of units)
EFFORT = 1.0

Reach = tuple[tuple[float, float], float]  # ((x, y) of the robot's base, radius in metres)


class TidyError(ProblemError):
    """A scene that cannot be tidied or a plan that cannot be made; one line naming the object."""


@dataclass(frozen=True)
class TidyOptions:
    """Settings of :func:`tidy` (the effort weight is an argument of its own)."""

    count: float = 1.0  # at effort 1: energy per moved object (the smooth count's weight)
    distance: float = 0.1  # at effort 1: energy per length scale of displacement
    delta: float = 0.01  # metres: the displacement is quadratic within this, then linear
    sigma: float = 0.02  # metres: a move this long counts as half a moved object
    move_tol: float = 0.01  # metres: an object that moved less than this stays where it is
    proposals: int = 8  # proposals kept per object (the best of its placement particles)
    candidates: int = 512  # candidate states screened by cost
    particles: int = 16  # of which the best start the chain
    chain: LangevinConfig = replace(PLACEMENT, steps=20, step_init=0.02, final_descent=10)
    propose: LangevinOptions = LangevinOptions(
        particles=8, candidates=128, chain=replace(PLACEMENT, steps=30, final_descent=10)
    )
    refine: str | None = "osqp"  # the refinement of the moved objects after pruning (None: none)
    refine_options: dict[str, Any] = field(default_factory=lambda: {"max_iter": 40})


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

    @property
    def total_displacement(self) -> float:
        """Sum of the moved objects' displacements ``d_i`` (metres)."""
        return float(sum(self.displacement.values()))

    @property
    def total_distance(self) -> float:
        """Sum of the distances the moved objects' centres travel (metres)."""
        return float(sum(self.distance.values()))

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
    count of moved objects, ``options.count`` each, and the displacement, ``options.distance`` per
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
    cost: Cost = LearnedEnergy(model)
    if effort * o.distance > 0:
        cost = cost + (effort * o.distance / length) * Displacement(delta=o.delta, weights=weights)
    if effort * o.count > 0:
        cost = cost + effort * o.count * MoveCount(sigma=o.sigma, weights=weights)
    hinge = non_overlap(model, scene, names)
    if hinge is not None:
        cost = cost + (OVERLAP_WEIGHT / length) * hinge
    cost = cost + (OVERLAP_WEIGHT / length) * Bounds()
    if reach is not None:
        (bx, by), radius = reach
        cost = cost + (OVERLAP_WEIGHT / length) * ReachLimit(base=(bx, by), radius=radius)
    return Problem(scene, cost, movable=names, name="tidy")


# -- solving --------------------------------------------------------------------------------------------


def _proposals(
    model: ScoreModel, scenes: list[Scene], movable: list[list[str]], o: TidyOptions, seed: int
) -> list[dict[str, np.ndarray]]:
    """Where each movable object would go if it were missing: the best ``o.proposals`` particles of its
    placement by the learned energy alone, the others where they are (one batched chain per size)."""
    from .placement import placement_problem

    jobs = [(k, n) for k, names in enumerate(movable) for n in names]
    problems = [placement_problem(model, scenes[k].without(n), energy_only=True) for k, n in jobs]
    out: list[dict[str, np.ndarray]] = [{} for _ in scenes]
    solver = LangevinSolver(o.propose)
    for idx in _by_size(problems):
        results = solver.solve_many([problems[j] for j in idx], seed=seed)
        for j, r in zip(idx, results):
            k, n = jobs[j]
            assert r.samples is not None and r.sample_costs is not None
            order = np.argsort(r.sample_costs)[: o.proposals]
            out[k][n] = r.samples[order, scenes[k].index(n)]
    return out


def _by_size(problems: Sequence[Problem]) -> list[list[int]]:
    """Indices of ``problems`` grouped by their number of objects (one batched chain each)."""
    groups: dict[int, list[int]] = {}
    for j, p in enumerate(problems):
        groups.setdefault(p.n, []).append(j)
    return list(groups.values())


def _candidates(
    scene: Scene,
    current: np.ndarray,
    proposals: dict[str, np.ndarray],
    o: TidyOptions,
    gen: np.random.Generator,
) -> torch.Tensor:
    """The current state, each object at each proposal, then random pairs of proposals and a few
    uniform redraws, ``o.candidates`` in all."""
    names = list(proposals)
    rows = [current]
    for n, props in proposals.items():
        i = scene.index(n)
        for p in props:
            x = current.copy()
            x[i] = p
            rows.append(x)
    lo, hi = np.asarray(scene.bounds[0]), np.asarray(scene.bounds[1])
    while len(rows) < o.candidates:
        x = current.copy()
        for n in gen.choice(names, size=min(2, len(names)), replace=False):
            i = scene.index(str(n))
            if gen.random() < 0.8:
                x[i] = proposals[str(n)][gen.integers(len(proposals[str(n)]))]
            else:
                x[i, :2] = lo + gen.random(2) * (hi - lo)
                x[i, 2] = gen.uniform(-math.pi, math.pi)
        rows.append(x)
    return torch.as_tensor(np.stack(rows), dtype=torch.float64)


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
    """:func:`tidy` for several scenes, their sampling stages batched (one chain per number of objects)."""
    o = options or TidyOptions()
    scenes = list(scenes)
    for scene in scenes:
        if scene.unknown:
            raise TidyError(
                f"tidy: {scene.label()}: object {scene.unknown[0]!r} has pose null; tidy moves objects from "
                "where they are (fill unknown poses first with `scenescore place`)"
            )
    problems = [tidy_problem(model, s, effort, stay, weights, reach, o) for s in scenes]
    proposals = _proposals(model, scenes, [p.movable for p in problems], o, seed)
    gen = np.random.default_rng(seed)
    starts = []
    for s, p, props in zip(scenes, problems, proposals):
        cands = _candidates(s, s.poses(), props, o, gen)
        starts.append(screen(p.cost, cands, min(o.particles, len(cands))))
    sampled: list[Result | None] = [None] * len(scenes)
    solver = LangevinSolver(LangevinOptions(particles=o.particles, chain=o.chain))
    for idx in _by_size(problems):
        rs = solver.solve_many([problems[j] for j in idx], seed=seed, init=[starts[j] for j in idx])
        for j, r in zip(idx, rs):
            sampled[j] = r
    out = []
    for s, p, r0 in zip(scenes, problems, sampled):
        assert r0 is not None
        out.append(_finish(model, s, p, r0, effort, seed, stay, weights, reach, o))
    return out


def _finish(
    model: ScoreModel,
    scene: Scene,
    problem: Problem,
    r: Result,
    effort: float,
    seed: int,
    stay: Sequence[str],
    weights: dict[str, float] | None,
    reach: Reach | None,
    o: TidyOptions,
) -> TidyResult:
    """Prune the chain's best, refine the moved objects alone, plan the moves."""
    current = scene.poses()
    x = _prune(problem, r.poses, current, o)
    moved = [n for n, d in zip(scene.names, _moves(scene, x)) if d > o.move_tol]
    final = tidy_problem(model, scene, effort, stay, weights, reach, o, movable=moved or problem.movable)
    if moved and o.refine:  # the moved objects alone, every other one exactly where it is
        r2 = solve(final, o.refine, init=x, seed=seed, options={o.refine: o.refine_options})
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
    return TidyResult(scene, after, moved, dist, turn, disp, steps, check, r, float(effort), seed, warnings)


def _prune(problem: Problem, x: np.ndarray, current: np.ndarray, o: TidyOptions) -> np.ndarray:
    """Objects moved less than ``move_tol`` back where they are; then each move undone while that
    lowers the whole cost (smallest moves first)."""
    x = np.array(x, dtype=float)
    before = problem.scene
    d = _moves(before, x)
    x[d <= o.move_tol] = current[d <= o.move_tol]

    def cost(p: np.ndarray) -> float:
        with torch.no_grad():
            return float(problem.evaluate(torch.as_tensor(p)[None])[0])

    best = cost(x)
    changed = True
    while changed:
        changed = False
        d = _moves(before, x)
        for i in np.argsort(d):
            if d[i] <= o.move_tol:
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
