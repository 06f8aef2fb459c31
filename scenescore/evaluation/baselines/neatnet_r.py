"""NeatNet-R: regression of each object's pose from the word embedding of its class name.

An MLP maps a class name's embedding to the object's pose ``(x, y, cos, sin)`` relative to the
scene's first fixed object (the anchor; the scene's origin when there is none). It sees nothing but
the class name: a never-seen size or class gets whatever its word's embedding maps to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import nn

from ...scene.scene import Scene
from .word_embed import Embedder, minilm

__all__ = ["NeatNetR"]


def _anchor(scene: Scene) -> tuple[float, float]:
    for o in scene.objects:
        if o.fixed and o.pose is not None:
            return (o.pose[0], o.pose[1])
    return (0.0, 0.0)


@dataclass
class NeatNetR:
    """The regression baseline as a :class:`~scenescore.planning.placement.Placer`."""

    name: str = "NeatNet-R"
    embed: Embedder = minilm
    hidden: int = 64
    epochs: int = 1500
    lr: float = 3e-3
    net: nn.Module | None = None
    _cache: dict[str, np.ndarray] = field(default_factory=dict)

    def _vectors(self, cats: list[str]) -> torch.Tensor:
        new = sorted({c for c in cats if c not in self._cache})
        if new:
            for c, v in zip(new, self.embed(new)):
                self._cache[c] = np.asarray(v, dtype=np.float32)
        return torch.as_tensor(np.stack([self._cache[c] for c in cats]))

    def fit(self, scenes: list[Scene], seed: int = 0) -> NeatNetR:
        cats, targets = [], []
        for s in scenes:
            ax, ay = _anchor(s)
            for o in s.objects:
                if o.fixed or o.pose is None:
                    continue
                cats.append(o.category)
                px, py, t = o.pose
                targets.append([px - ax, py - ay, math.cos(t), math.sin(t)])
        if not cats:
            raise ValueError("NeatNet-R: no movable object with a pose to learn from")
        torch.manual_seed(seed)
        x = self._vectors(cats)
        y = torch.tensor(targets, dtype=torch.float32)
        self.net = nn.Sequential(
            nn.Linear(x.shape[1], self.hidden), nn.ReLU(), nn.Linear(self.hidden, self.hidden), nn.ReLU()
        )
        self.net.append(nn.Linear(self.hidden, 4))
        opt = torch.optim.Adam(self.net.parameters(), lr=self.lr)
        for _ in range(self.epochs):
            opt.zero_grad()
            loss = ((self.net(x) - y) ** 2).mean()
            loss.backward()
            opt.step()
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        if self.net is None:
            raise RuntimeError(f"{self.name}: call fit() before predict()")
        out = []
        for s in scenes:
            names = s.unknown
            if not names:
                out.append(s.copy())
                continue
            ax, ay = _anchor(s)
            with torch.no_grad():
                p = self.net(self._vectors([s[n].category for n in names])).numpy()
            poses = [[ax + q[0], ay + q[1], math.atan2(q[3], q[2])] for q in p]
            out.append(s.with_poses(poses, names))
        return out
