"""Placing objects whose pose is unknown: a problem with the learned energy, solved by ``langevin``.

Placement has no sampler of its own: :func:`place` builds the :class:`~scenescore.problem.Problem` of the
learned energy with the unknown objects movable and solves it with the ``langevin`` solver under the
placement defaults (:data:`PLACE`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

from tqdm.auto import tqdm

from .costs import LearnedEnergy
from .encoders import Encoder
from .models import ScoreModel
from .problem import Problem
from .sampling import PLACEMENT
from .scene import Scene, SceneError
from .solvers import Result, solve
from .solvers.langevin import LangevinOptions, LangevinSolver
from .training import TrainConfig, train

__all__ = ["PLACE", "place", "place_many", "placement_problem", "Placer", "SceneScorePlacer"]


#: placement's default: 64 particles seeded by the best of 2048 uniform draws, the PLACEMENT schedule
PLACE = LangevinOptions(particles=64, candidates=2048, chain=PLACEMENT)


def placement_problem(model: ScoreModel, scene: Scene) -> Problem:
    """The problem :func:`place` solves: the learned energy alone, the unknown poses movable."""
    if not scene.unknown:
        raise SceneError("place: the scene has no object with an unknown pose (pose: null) to place")
    return Problem(scene, LearnedEnergy(model), movable=scene.unknown, name="place")


def place_many(
    model: ScoreModel, scenes: list[Scene], options: LangevinOptions | None = None, seed: int = 0
) -> list[Scene]:
    """:func:`place` for several scenes at once: their problems solved together by
    :meth:`LangevinSolver.solve_many`, one batch per number of objects (the timings need it)."""
    solver = LangevinSolver(options or PLACE)
    out = [s.copy() for s in scenes]
    groups: dict[int, list[int]] = {}
    for i, s in enumerate(scenes):
        if s.unknown:
            groups.setdefault(len(s), []).append(i)
    for idx in groups.values():
        results = solver.solve_many([placement_problem(model, scenes[i]) for i in idx], seed=seed)
        for i, r in zip(idx, results):
            out[i] = _filled(scenes[i], r)
    return out


def _filled(scene: Scene, result: Result) -> Scene:
    """``scene`` with its unknown poses from ``result``, and their confidence in ``meta["placement"]``."""
    names = scene.unknown
    out = scene.with_poses(result.poses[[scene.index(n) for n in names]], names)
    out.meta = {
        **out.meta,
        "placement": {n: result.confidence[n].to_dict() for n in names if n in result.confidence},
    }
    return out


def place(model: ScoreModel, scene: Scene, options: LangevinOptions | None = None, seed: int = 0) -> Scene:
    """Fill every ``null`` pose of ``scene`` (the others stay fixed); returns a new scene.

    This is ``ss.solve(placement_problem(model, scene), LangevinSolver(options or PLACE), seed=seed)``:
    placing and solving give the same answer for the same model, seed and options.
    """
    if not scene.unknown:
        return scene.copy()
    r = solve(placement_problem(model, scene), LangevinSolver(options or PLACE), seed=seed)
    return _filled(scene, r)


class Placer(Protocol):
    """A method for the missing-object experiments: fit on examples, then fill ``null`` poses."""

    name: str

    def fit(self, scenes: list[Scene], seed: int = 0) -> Placer: ...

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]: ...


@dataclass
class SceneScorePlacer:
    """SceneScore as a :class:`Placer`: train the energy, then Langevin placement."""

    name: str = "SceneScore"
    train_config: TrainConfig = field(default_factory=TrainConfig)
    place_options: LangevinOptions = PLACE
    encoder: Encoder | None = None
    progress: bool = False
    model: ScoreModel | None = None

    def fit(self, scenes: list[Scene], seed: int = 0) -> SceneScorePlacer:
        self.model = train(scenes, self.train_config, encoder=self.encoder, seed=seed, progress=self.progress)
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        if self.model is None:
            raise RuntimeError(f"{self.name}: call fit() before predict()")
        model, batch = self.model, 8  # scenes per batched solve
        out: list[Scene] = []
        with tqdm(total=len(scenes), desc="place", unit="scene", disable=not self.progress) as bar:
            for k in range(0, len(scenes), batch):
                out += place_many(model, scenes[k : k + batch], self.place_options, seed + k)
                bar.update(len(scenes[k : k + batch]))
        return out
