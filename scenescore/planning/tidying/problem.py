"""The problem tidying solves: the learned energy plus the effort of moving objects from where they
are, each object's effort weight, the energy one move costs (from the model's calibration), and the
two measures every stage uses: each object's displacement and the whole cost of a batch of poses."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import numpy as np
import torch

from ...costs import Bounds, Cost, Displacement, LearnedEnergy, MoveCount, ReachLimit
from ...models import ScoreModel
from ...problem.problem import Problem
from ...scene.scene import Scene
from ..placement import OVERLAP_WEIGHT, non_overlap
from .types import COUNT, EFFORT, GAIN_QUANTILE, Reach, TidyError, TidyOptions

__all__ = ["tidy_problem", "effort_weights", "count_weight", "displacements", "whole_cost"]


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


def _valid_gain(value: Any) -> float | None:
    """A stored gain when it is a finite number >= 0, else None."""
    ok = (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value >= 0
    )
    return float(value) if ok else None


def _valid_gains(value: Any) -> list[float] | None:
    """Stored gains when they are a non-empty list of finite numbers >= 0, else None."""
    if not isinstance(value, list) or not value:
        return None
    out = [_valid_gain(v) for v in value]
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
    stored = model.info.tidy
    if stored is None:
        return COUNT
    gains = _valid_gains(stored.gains)
    if scene is not None and gains is not None:
        movable = max(1, sum(not ob.fixed for ob in scene.objects))
        return float(np.quantile(gains, GAIN_QUANTILE ** (1.0 / movable)))
    g = _valid_gain(stored.move_gain)
    return COUNT if g is None else g


def displacements(scene: Scene, x: np.ndarray) -> np.ndarray:
    """``d_i`` per object (centre and tip, metres) from its pose in ``scene`` to ``x``."""
    d = Displacement(objects=scene.names).bind(scene)
    return cast(Displacement, d).moves(x)


def whole_cost(problem: Problem, x: np.ndarray | torch.Tensor) -> np.ndarray:
    """The whole cost of ``problem`` at each row of ``x`` ``(B, N, 3)``."""
    with torch.no_grad():
        return problem.evaluate(problem.full(x)).cpu().numpy()
