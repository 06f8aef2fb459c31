"""Calibration: what a move must gain to be worth making, measured on scenes taken as right (how much
re-placing one object lowers the learned energy by the model's own noise) and stored in the model:
now (:func:`calibrate`), or when the model first tidies (:func:`defer`, :func:`ensure_calibrated`)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence

import numpy as np

from ...models import ScoreModel, TidyCalibration
from ...runtime.cache import cache_folder
from ...runtime.provenance import code_version
from ...runtime.threads import torch_threads
from ...scene.outputs import atomic_write_text
from ...scene.scene import Scene
from .problem import tidy_problem, whole_cost
from .selection import best_replacements
from .types import GAIN_QUANTILE, TidyError, TidyOptions

__all__ = ["object_gains", "move_gains", "calibrate", "defer", "ensure_calibrated"]


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


def defer(model: ScoreModel, scenes: Sequence[Scene], seed: int = 0) -> None:
    """Keep ``scenes`` (taken as right) in ``model.info.tidy`` to calibrate on when the model first
    tidies (:func:`ensure_calibrated`), instead of measuring now: training then does no tidying work."""
    posed = [s for s in scenes if not s.unknown]
    if not posed:
        raise TidyError("calibrate: no scene with every pose known to measure the move gain on")
    model.info.tidy = TidyCalibration(scenes=len(posed), pending=[s.to_dict() for s in posed], seed=seed)


def ensure_calibrated(model: ScoreModel, say: Callable[[str], None] | None = None) -> None:
    """Measure a deferred calibration (:func:`defer`) now, once per model on this machine: the gains of a
    model's scenes are kept in the user's cache folder (``tidy/``, keyed by the model's weights, its
    scenes and the code), so a later tidy with the same checkpoint reads them. ``say``: told when it measures."""
    stored = model.info.tidy
    if stored is None or stored.pending is None:
        return
    key = _key(model, stored)
    path = cache_folder("tidy") / f"{key}.json"
    if path.exists():
        try:
            model.info.tidy = TidyCalibration.from_dict(json.loads(path.read_text(encoding="utf-8")))
            return
        except (OSError, ValueError, TypeError):
            pass  # damaged: measured again and written anew
    scenes = [Scene.from_dict(d) for d in stored.pending]
    if say is not None:
        say(f"tidy: calibrating on {len(scenes)} scenes (once for this model; kept in {path.parent})")
    calibrate(model, scenes, seed=stored.seed or 0)
    assert model.info.tidy is not None
    atomic_write_text(path, json.dumps(model.info.tidy.to_dict()) + "\n")


def _key(model: ScoreModel, stored: TidyCalibration) -> str:
    """A digest of what a calibration depends on: the networks' weights, the scenes, the seed and the
    code (:func:`~scenescore.runtime.provenance.code_version`), so that an upgrade measures again."""
    h = hashlib.sha256(code_version().encode())
    for name, tensor in sorted(model.net.state_dict().items()):
        h.update(name.encode() + b"\0" + tensor.detach().cpu().contiguous().numpy().tobytes())
    h.update(json.dumps([stored.pending, stored.seed], sort_keys=True).encode())
    return h.hexdigest()[:32]
