"""Tidying from start to end: the problem, the selection, the pruning, the placement candidates and
the finish, for one scene (:func:`tidy`) or several at once (:func:`tidy_many`); for one scene on a
machine with a core to spare, the placement of the set chosen so far starts on that core while the
selection goes on."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import numpy as np

from ...models import ScoreModel
from ...problem.problem import Problem
from ...runtime.ahead import Ahead
from ...runtime.threads import POOL_ROWS, torch_threads
from ...scene.scene import Scene
from ...solvers import Status, make_result
from ..placement import PLACE
from .calibration import ensure_calibrated
from .problem import tidy_problem
from .pruning import blanked_scenes, place_again, prune_moves, refine_and_plan
from .selection import PAIR_CANDIDATES, SWAP_CANDIDATES, select_moves
from .types import EFFORT, Reach, Request, TidyError, TidyOptions, TidyResult

__all__ = ["tidy", "tidy_many"]


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
    if o.count is None:  # a move's cost is the model's calibrated gain: measured now if deferred
        ensure_calibrated(model, say=_note)
    for scene in scenes:
        if scene.unknown:
            raise TidyError(
                f"tidy: {scene.label()}: object {scene.unknown[0]!r} has pose null; tidy moves objects from "
                "where they are (fill unknown poses first with `scenescore place`)"
            )
    problems = [tidy_problem(model, s, effort, stay, weights, reach, o) for s in scenes]
    ask = Request(effort, stay, weights, reach)
    tol = o.move_tol * model.config.length_scale  # metres
    # small tensors: one torch thread (restored after; the placement chains choose their own)
    with torch_threads(1), _placing_ahead(model, scenes, problems, o, seed, tol) as ahead:
        states = select_moves(model, scenes, problems, o, seed, None if ahead is None else ahead[1])
        pruned, moved = [], []
        for p, x in zip(problems, states):
            x, names = prune_moves(p, x, tol)
            pruned.append(x)
            moved.append(names)
        if not o.place:
            placed: list[list[np.ndarray]] = [[] for _ in scenes]
        elif ahead is not None:  # one scene
            placed = [ahead[0].result(tuple(moved[0]), lambda: place_again(model, scenes, moved, seed)[0])]
        else:
            placed = place_again(model, scenes, moved, seed)
        out = []
        for s, p, x, m, alt in zip(scenes, problems, pruned, moved, placed):
            r0 = make_result(p, "tidy", x, Status.SAMPLED, 0, 0.0, 0.0)
            out.append(refine_and_plan(model, s, p, r0, m, alt, seed, ask, o))
    return out


def _note(line: str) -> None:
    print(line, file=sys.stderr)


@contextmanager
def _placing_ahead(
    model: ScoreModel, scenes: list[Scene], problems: list[Problem], o: TidyOptions, seed: int, tol: float
) -> Iterator[tuple[Ahead, Callable[[int, np.ndarray], None]] | None]:
    """For a single scene on a machine with a core to spare (:meth:`~scenescore.runtime.ahead.Ahead.worth`):
    an :class:`~scenescore.runtime.ahead.Ahead` and the selection's callback that starts :func:`place_again` of
    the set its poses so far move, on the second core while the selection goes on (its last rounds
    usually confirm that set). The answers are the same to the bit as without it, which needs every
    chain on one torch thread (fewer than :data:`~scenescore.runtime.threads.POOL_ROWS` particles): the
    selection's batches (at most one set per movable object and :data:`SWAP_CANDIDATES` swaps, or the
    pairs round) and each placement's. None otherwise (several scenes have their placements batched
    together)."""

    pairs = PAIR_CANDIDATES * (PAIR_CANDIDATES - 1) // 2
    if (
        len(scenes) != 1
        or not o.place
        or o.propose.particles * max(len(problems[0].movable) + SWAP_CANDIDATES, pairs) >= POOL_ROWS
        or not Ahead.worth()
    ):
        yield None
        return

    def submit(k: int, x: np.ndarray) -> None:
        names = prune_moves(problems[k], x, tol)[1]
        if names and PLACE.particles * len(blanked_scenes(scenes[k], names)) < POOL_ROWS:
            ahead.submit(tuple(names), lambda: place_again(model, scenes, [names], seed)[0])

    with Ahead() as ahead:
        yield ahead, submit
