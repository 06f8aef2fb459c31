"""Pruning and finishing: the selection's moves that do not pay undone, the moved objects placed again
by the missing-object placement (and each set of them one smaller), the candidate with the lowest whole
cost refined over its moved objects alone, and the moves planned."""

from __future__ import annotations

import numpy as np
import torch

from ...models import ScoreModel
from ...problem.problem import Problem
from ...scene.scene import Scene, wrap_angle
from ...solvers import Result, make_result, solve
from ..placement import place_many
from .plan import plan_moves, validate_plan
from .problem import count_weight, displacements, tidy_problem, whole_cost
from .types import PlanCheck, Request, TidyError, TidyOptions, TidyResult

__all__ = ["prune_moves", "blanked_scenes", "place_again", "refine_and_plan"]


def prune_moves(problem: Problem, x: np.ndarray, tol: float) -> tuple[np.ndarray, list[str]]:
    """The selection's poses ``x (N, 3)`` with its needless moves undone (:func:`_undo_needless_moves`),
    and the objects that still move in them."""
    scene = problem.scene
    x = _undo_needless_moves(problem, x, scene.poses(), tol)
    return x, [n for n, d in zip(scene.names, displacements(scene, x)) if d > tol]


def _undo_needless_moves(problem: Problem, x: np.ndarray, current: np.ndarray, tol: float) -> np.ndarray:
    """Objects moved less than ``tol`` (metres) back where they are; then each move undone while that
    lowers the whole cost (smallest moves first)."""
    x = np.array(x, dtype=float)
    before = problem.scene
    d = displacements(before, x)
    x[d <= tol] = current[d <= tol]

    def cost(p: np.ndarray) -> float:
        return float(whole_cost(problem, p[None])[0])

    best = cost(x)
    changed = True
    while changed:
        changed = False
        d = displacements(before, x)
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


def blanked_scenes(scene: Scene, names: list[str]) -> list[Scene]:
    """The scenes :func:`place_again` fills for the moved objects ``names``: ``scene`` with their poses
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


def place_again(
    model: ScoreModel, scenes: list[Scene], moved: list[list[str]], seed: int
) -> list[list[np.ndarray]]:
    """Per scene, candidate poses from the missing-object placement
    (:func:`~scenescore.planning.placement.place_many`: its longer chain and trust ranking, the other objects
    where they are): the objects of ``moved`` placed again, and, where two or more moved, the set with
    each one of them left where it is (an object the selection moved only to fit a short-chained
    placement of another); empty where nothing moves."""
    blanks, idx = [], []
    for k, (s, names) in enumerate(zip(scenes, moved)):
        for b in blanked_scenes(s, names):
            blanks.append(b)
            idx.append(k)
    out: list[list[np.ndarray]] = [[] for _ in scenes]
    for k, filled in zip(idx, place_many(model, blanks, seed=seed)):
        out[k].append(filled.poses())
    return out


def refine_and_plan(
    model: ScoreModel,
    scene: Scene,
    problem: Problem,
    r: Result,
    moved: list[str],
    placed: list[np.ndarray],
    seed: int,
    ask: Request,
    o: TidyOptions,
) -> TidyResult:
    """Choose among the selection's pruned poses ``r.poses`` and the ``placed`` candidates (the
    missing-object placement of the moved objects, and of each subset one smaller) the one that violates
    the constraints least at the lowest whole cost; refine its moved objects alone; plan the moves."""
    effort, stay, weights, reach = ask.effort, ask.stay, ask.weights, ask.reach
    current = scene.poses()
    x = r.poses
    tol = o.move_tol * model.config.length_scale  # metres
    final = tidy_problem(model, scene, effort, stay, weights, reach, o, movable=moved or problem.movable)

    def worse(a: np.ndarray, b: np.ndarray) -> bool:
        """Whether ``a`` violates the constraints more than ``b``, or as much at a higher whole cost."""
        va, vb = (float(final.violation(torch.as_tensor(v))[0]) for v in (a, b))
        if va > vb + 1e-12:
            return True
        return va >= vb - 1e-12 and float(whole_cost(final, a[None])[0]) > float(
            whole_cost(final, b[None])[0]
        )

    for alt in placed:
        if not worse(alt, x):
            x = alt
    if moved:
        far = displacements(scene, x) > tol  # (N,)
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
    d = displacements(scene, x)
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
