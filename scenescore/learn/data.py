"""The example scenes training reads: the checks that refuse data which cannot teach, its scale, whether
it stands against its bounds, and the held-out split."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..models.layout import touching_bound
from ..scene.scene import Scene, SceneError

__all__ = [
    "VALIDATION_FRACTION",
    "VALIDATION_PER_CATEGORY",
    "check_training_data",
    "data_scale",
    "local_radius",
    "split_validation",
    "stands_against_walls",
]

#: the fraction of the scenes ``scenescore train`` holds out for validation by default (``--val``)
VALIDATION_FRACTION = 0.15
# held-out placements judged per category: every one of a table's few forks, a sample of a hall's chairs
VALIDATION_PER_CATEGORY = 32


def data_scale(scenes: Sequence[Scene], movable: bool = False) -> tuple[float, float]:
    """The data's length scale and largest offset: ``(L, R)``.

    ``L`` (metres) is the median over every object (``movable``: every object not fixed, where there
    are any) of half its footprint's longer side; ``R`` is the largest distance between two objects'
    centres in any scene, in units of ``L``. Both scale with the data, exactly for powers of two:
    scaling every length by ``k`` scales ``L`` by ``k`` and keeps ``R``.
    """
    objects = [o for s in scenes for o in s.objects]
    if movable and any(not o.fixed for o in objects):
        objects = [o for o in objects if not o.fixed]
    halves = sorted(max(o.size) / 2 for o in objects)
    n = len(halves)
    length = halves[n // 2] if n % 2 else (halves[n // 2 - 1] + halves[n // 2]) / 2
    far = 0.0
    for s in scenes:
        p = s.poses()[:, :2]
        if len(p) > 1:
            far = max(far, float(np.sqrt(((p[:, None] - p[None]) ** 2).sum(-1)).max()))
    return float(length), max(far / length, 1.0)


def local_radius(scenes: Sequence[Scene], length: float, neighbours: int) -> float:
    """The gap (length scales ``length``) at which a local graph's edges fade out, so that objects read
    about ``neighbours`` others: the lower quartile over the data's objects of the gap to their
    ``neighbours``-th nearest (by the gap between the circles of half their longer sides), so that few
    lists cut off an edge of weight, but at least the 95th percentile of the gap to the nearest (nearly
    every object reads its nearest) and one length scale."""
    kth: list[float] = []
    first: list[float] = []
    for s in scenes:
        p = s.poses()[:, :2]
        if len(p) < 2:
            continue
        reach = np.array([max(o.size) / 2 for o in s.objects])
        gap = np.sqrt(((p[:, None] - p[None]) ** 2).sum(-1)) - reach[:, None] - reach[None]
        gap = np.maximum(gap, 0.0) / length
        np.fill_diagonal(gap, np.inf)
        gap.sort(axis=1)
        first += gap[:, 0].tolist()
        if len(p) > neighbours:
            kth += gap[:, neighbours - 1].tolist()
    lower = float(np.quantile(kth, 0.25)) if kth else 0.0
    near = float(np.quantile(first, 0.95)) if first else 0.0
    return max(lower, near, 1.0)


def stands_against_walls(scenes: Sequence[Scene], gap: float = 0.02, share: float = 0.9) -> bool:
    """Whether the data places objects against its bounds: in at least ``share`` of the scenes some
    footprint lies within ``gap`` of the bounds' larger side from a bound (a sofa against the wall, a
    bookend at the shelf's end). Relations to the room then need the walls in the graph."""
    near = 0
    for s in scenes:
        (x0, y0), (x1, y1) = s.bounds
        tol = gap * max(x1 - x0, y1 - y0)
        if any(o.pose is not None and touching_bound(o, o.pose, s.bounds, tol) for o in s.objects):
            near += 1
    return near >= share * len(scenes)


def check_training_data(scenes: Sequence[Scene]) -> None:
    """Refuse, naming the scene (``file:line`` where it was read from) and the object, example scenes
    that cannot teach an energy: fewer than two scenes, a scene without objects or with unknown poses,
    an object whose centre lies far outside the bounds, or data in which no scene has a movable object
    beside another object (nothing relational to learn)."""
    if len(scenes) < 2:
        raise SceneError(f"train: need at least 2 example scenes, got {len(scenes)}")
    teaches = False
    for i, s in enumerate(scenes):
        where = s.label(i)
        if not s.objects:
            raise SceneError(f"train: {where}: the scene has no objects")
        if s.unknown:
            raise SceneError(f"train: {where}: objects without a pose: {s.unknown}; every pose must be known")
        (x0, y0), (x1, y1) = s.bounds
        span = max(x1 - x0, y1 - y0)
        for o in s.objects:
            x, y, _ = o.pose  # type: ignore[misc]
            if not (x0 - span <= x <= x1 + span and y0 - span <= y <= y1 + span):
                raise SceneError(
                    f"train: {where}: object {o.name!r} at ({x:g}, {y:g}) lies far outside the bounds "
                    f"{list(s.bounds[0])} .. {list(s.bounds[1])}; check the units and the bounds"
                )
        teaches = teaches or (len(s) >= 2 and any(not o.fixed for o in s.objects))
    if not teaches:
        raise SceneError(
            "train: no example scene has a movable object beside another object, so there is no relation to "
            "learn (every scene has one object, or every object is fixed)"
        )


def split_validation(
    scenes: Sequence[Scene], fraction: float = VALIDATION_FRACTION, minimum: int = 4, seed: int = 0
) -> tuple[list[Scene], list[Scene]]:
    """Hold out about ``fraction`` of the scenes (at least ``minimum``, and at least 2 left to train on),
    chosen by ``seed``: ``(train, held_out)``; ``fraction == 0`` holds out none."""
    if not 0 <= fraction < 1:
        raise SceneError(f"validation fraction: expected a number in [0, 1), got {fraction!r}")
    if fraction == 0:
        return list(scenes), []
    n = len(scenes)
    k = max(minimum, round(fraction * n))
    if n - k < 2:
        raise SceneError(
            f"validation: {n} scenes are too few to hold out {k} (at least {minimum}) and train on 2 or more; "
            "pass --val 0 to train on all of them"
        )
    order = np.random.default_rng(seed).permutation(n)
    held = set(order[:k].tolist())
    return [s for i, s in enumerate(scenes) if i not in held], [s for i, s in enumerate(scenes) if i in held]
