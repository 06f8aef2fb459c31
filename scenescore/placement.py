"""Placing objects whose pose is unknown: batched Langevin on the learned energy, best particle wins."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import torch

from .encoders import Encoder
from .models import SceneTensors, ScoreModel
from .scene import Scene, SceneError
from .solvers.langevin import LangevinConfig, best_of, langevin, screen, uniform_init
from .training import TrainConfig, train

__all__ = ["PlaceConfig", "place", "place_many", "Placer", "SceneScorePlacer"]


@dataclass
class PlaceConfig:
    """Particles and the Langevin schedule used by :func:`place`."""

    particles: int = 64
    candidates: int = 2048  # uniform draws screened by energy (forward only); the best seed the particles
    langevin: LangevinConfig = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.langevin is None:
            self.langevin = LangevinConfig(
                steps=60, step_init=0.05, step_final=5e-4, noise=1.0, final_descent=20
            )


def place(model: ScoreModel, scene: Scene, config: PlaceConfig | None = None, seed: int = 0) -> Scene:
    """Fill every ``null`` pose of ``scene``; the others stay fixed. Returns a new scene."""
    return place_many(model, [scene], config, seed)[0]


def place_many(
    model: ScoreModel, scenes: list[Scene], config: PlaceConfig | None = None, seed: int = 0
) -> list[Scene]:
    """:func:`place` for several scenes with the same number of objects, in one batch."""
    cfg = config or PlaceConfig()
    if not scenes:
        return []
    n = len(scenes[0])
    for s in scenes:
        if len(s) != n:
            raise SceneError(
                "place_many: scenes must have the same number of objects; call place() per scene"
            )
    todo = [s for s in scenes if s.unknown]
    if not todo:
        return [s.copy() for s in scenes]
    gen = torch.Generator().manual_seed(seed)
    st = model.tensors(todo)
    p = cfg.particles
    g = len(todo)
    init = _screened_init(model, st, max(cfg.candidates, p), p, gen)  # (G * P, N, 3)
    rep = st.repeat(p)  # (G * P, ...)
    movable = ~rep.known
    with torch.no_grad():
        nodes = model.net.node_embedding(rep.feats, rep.sizes)  # pose-independent, computed once

    def energy(x: torch.Tensor) -> torch.Tensor:
        return model.net(x, None, None, rep.mask, nodes=nodes)  # type: ignore[arg-type]

    poses, e = langevin(energy, init, movable, rep.lo, rep.hi, cfg.langevin, gen)
    best, _ = best_of(poses, e, g)
    out, j = [], 0
    for s in scenes:
        if not s.unknown:
            out.append(s.copy())
            continue
        names = s.unknown
        idx = [s.index(nm) for nm in names]
        out.append(s.with_poses(best[j, idx].numpy(), names))
        j += 1
    return out


def _screened_init(model: ScoreModel, st: SceneTensors, m: int, p: int, gen: torch.Generator) -> torch.Tensor:
    """Draw ``m`` uniform poses for the unknown objects of each scene, keep the ``p`` of lowest energy.

    Returns ``(G * P, N, 3)``, scenes in contiguous groups of ``p``.
    """
    g, n = st.mask.shape
    keep = []
    for k in range(g):
        one = st.index([k])
        draws = uniform_init((m, n), one.lo[0], one.hi[0], gen, dtype=one.poses.dtype)
        draws = torch.where(one.known[0][None, :, None], one.poses[0][None], draws)
        with torch.no_grad():
            fn = model.energy_fn_for(one)
        keep.append(screen(fn, draws, p))
    return torch.cat(keep)


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
    place_config: PlaceConfig = field(default_factory=PlaceConfig)
    encoder: Encoder | None = None
    progress: bool = False
    model: ScoreModel | None = None

    def fit(self, scenes: list[Scene], seed: int = 0) -> SceneScorePlacer:
        self.model = train(scenes, self.train_config, encoder=self.encoder, seed=seed, progress=self.progress)
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        if self.model is None:
            raise RuntimeError(f"{self.name}: call fit() before predict()")
        groups: dict[int, list[int]] = {}
        for i, s in enumerate(scenes):
            groups.setdefault(len(s), []).append(i)
        out: list[Scene | None] = [None] * len(scenes)
        for idx in groups.values():
            for chunk in range(0, len(idx), 8):
                part = idx[chunk : chunk + 8]
                placed = place_many(self.model, [scenes[i] for i in part], self.place_config, seed + chunk)
                for i, s in zip(part, placed):
                    out[i] = s
        return out  # type: ignore[return-value]
