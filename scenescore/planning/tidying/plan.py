"""The pick-and-place plan: the order of the moves from the current scene to the tidy one, each target
free of every object still in place when its object is put down (the exact check), an object parked at
a buffer pose where the moves wait on each other in a cycle (two objects swapping places); and the
replay that checks a plan."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from ...costs import Bounds, Cost, HingeCollision, ReachLimit
from ...geometry.exact import collides
from ...models import ScoreModel
from ...problem.problem import FEASIBILITY_TOL
from ...scene.scene import Scene, wrap_angle
from ..placement import non_overlap
from .types import PlanCheck, Reach, Step, TidyError

__all__ = ["blocking", "plan_moves", "validate_plan"]


def blocking(scene: Scene, name: str, model: ScoreModel | None = None) -> list[str]:
    """The objects whose footprint ``name``'s overlaps in ``scene`` (the exact check of non-overlap, at
    the feasibility tolerance; with ``model``, category pairs that overlap in its training data are
    allowed, as in :func:`~scenescore.planning.placement.non_overlap`)."""
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


def _violations(scene: Scene, name: str, reach: Reach | None) -> list[str]:
    """What is wrong with ``name``'s pose in ``scene`` by the exact bounds and reach checks."""
    terms: list[Cost] = [Bounds(objects=[name])]
    if reach is not None:
        terms.append(ReachLimit(base=reach[0], radius=reach[1], objects=[name]))
    out = []
    for t in terms:
        b = t.bind(scene, [name])
        out += [v.describe() for v in b.check(scene.poses(), FEASIBILITY_TOL)]
    return out


def _scene_at(before: Scene, poses: dict[str, tuple[float, float, float] | None]) -> Scene:
    """``before`` with each object at its pose in ``poses`` (by name; None: not on the table)."""
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
        if s is None or not _same_pose(s, g, tol):
            todo.append(n)
    final = _scene_at(before, {n: goal[n] for n in before.names})
    for n in todo:
        wrong = _violations(final, n, reach)
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
            trial = _scene_at(before, {**state, n: goal[n]})
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
            pose = _buffer_pose(before, state, goal, todo, n, model, reach, gen, buffer_draws)
            if pose is not None:
                steps.append(Step(n, state[n], pose, buffer=True))
                state[n] = pose
                parked.add(n)
                break
        else:
            raise TidyError(f"plan: no buffer pose free of the other objects for any of {todo}")
    raise TidyError(f"plan: the moves of {todo} could not be ordered")


def _buffer_pose(
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
        trial = _scene_at(before, {**state, name: pose})
        if _violations(trial, name, reach) or blocking(trial, name, model):
            continue
        if any(g is not None and _overlaps_at(before, name, pose, m, g, model) for m, g in targets):
            continue
        return pose
    return None


def _overlaps_at(
    before: Scene,
    name: str,
    pose: tuple[float, float, float],
    other: str,
    other_pose: tuple[float, float, float],
    model: ScoreModel | None,
) -> bool:
    """Whether ``name`` at ``pose`` overlaps ``other`` at ``other_pose`` (the two alone): the exact check
    that :func:`blocking` makes, category pairs that overlap in ``model``'s data allowed."""
    a, b = before[name], before[other]
    trust = None if model is None else model.trust
    if trust and trust.may_overlap(a.category, b.category):
        return False
    return collides(a, pose, b, other_pose, FEASIBILITY_TOL)


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
            now is not None and s.start is not None and not _same_pose(now, s.start, tol)
        ):
            problems.append(f"step {k}: {s.name!r} is not where the step picks it up")
        state[s.name] = s.goal
        trial = _scene_at(before, state)
        problems += [f"step {k}: {p}" for p in _violations(trial, s.name, reach)]
        problems += [f"step {k}: {s.name!r} put down on {b!r}" for b in blocking(trial, s.name, model)]
    for o in after.objects:
        now = state[o.name]
        if o.pose is not None and (now is None or not _same_pose(now, o.pose, tol)):
            problems.append(f"{o.name!r} does not end at its target")
    return PlanCheck(not problems, problems)


def _same_pose(a: Sequence[float], b: Sequence[float], tol: float) -> bool:
    """Whether poses ``a`` and ``b`` agree within ``tol`` in x, y and heading (wrapped)."""
    return abs(a[0] - b[0]) <= tol and abs(a[1] - b[1]) <= tol and abs(wrap_angle(a[2] - b[2])) <= tol
