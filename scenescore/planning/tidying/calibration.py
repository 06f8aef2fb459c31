"""Calibration: what a move must gain to be worth making, measured on scenes taken as right (how much
re-placing one object lowers the learned energy by the model's own noise) and stored in the model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...models import ScoreModel, TidyCalibration
from ...runtime.threads import torch_threads
from ...scene.scene import Scene
from .problem import tidy_problem, whole_cost
from .selection import best_replacements
from .types import GAIN_QUANTILE, TidyError, TidyOptions

__all__ = ["object_gains", "move_gains", "calibrate"]


def object_gains(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> list[tuple[int, str, float]]:
    """Per movable object of each scene taken as right: ``(scene index, name, gain)``, how much re-placing
    that object alone lowers the learned energy (with non-overlap and bounds; negative where the search
    finds no pose as good as the one it has); the noise of the model's own judgement that a move must
    beat. Every object's search runs in one batched chain per object count, on one torch thread."""
    scenes = list(scenes)
    o = TidyOptions(count=0.0)
    problems = [tidy_problem(model, s, 0.0, options=o) for s in scenes]
    items = [(k, n) for k, p in enumerate(problems) for n in p.movable]
    now = [float(whole_cost(p, s.poses()[None])[0]) for p, s in zip(problems, scenes)]
    # one job per object: the scene repeated, so that each object's best re-placement is kept
    with torch_threads(1):  # small tensors; the energy's large batches go in pieces side by side
        found = best_replacements(
            model,
            [scenes[k] for k, _ in items],
            [problems[k] for k, _ in items],
            {j: [[n]] for j, (_, n) in enumerate(items)},
            o,
            seed,
        )
    return [(k, n, now[k] - found[j][0] if j in found else 0.0) for j, (k, n) in enumerate(items)]


def _best_per_scene(gains: list[tuple[int, str, float]], scenes: int) -> np.ndarray:
    """Per scene of :func:`object_gains`' ``gains``: its best single object's gain, at least 0."""
    best = np.zeros(scenes)
    for k, _, g in gains:
        best[k] = max(best[k], g)
    return best


def move_gains(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> np.ndarray:
    """Per scene taken as right: how much re-placing its best single object lowers the learned energy
    (with non-overlap and bounds), at least 0."""
    return _best_per_scene(object_gains(model, scenes, seed), len(scenes))


def calibrate(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> float:
    """Measure what a move must gain on ``scenes`` taken as right (held-out ones are best) and store it in
    ``model.info.tidy`` (and so in the checkpoint): ``gains``, every object's single-move gain
    (:func:`object_gains`, at least 0, sorted), from which :func:`count_weight` sets the cost of a move
    in a scene of any size; and ``move_gain``, the :data:`GAIN_QUANTILE` quantile of each scene's best
    single move (:func:`move_gains`), returned."""
    posed = [s for s in scenes if not s.unknown]
    if not posed:
        raise TidyError("calibrate: no scene with every pose known to measure the move gain on")
    gains = object_gains(model, posed, seed)
    gain = float(np.quantile(_best_per_scene(gains, len(posed)), GAIN_QUANTILE))
    model.info.tidy = TidyCalibration(
        move_gain=gain,
        gains=sorted(max(0.0, g) for _, _, g in gains),
        scenes=len(posed),
        quantile=GAIN_QUANTILE,
    )
    return gain
