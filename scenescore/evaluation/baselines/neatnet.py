"""NeatNet: a graph VAE over whole arrangements, trained with masking (the paper's baseline).

Each object is a node with its category (one-hot over the training categories), its size, its slot
(its index in the scene) and its pose as ``(x, y, cos, sin)`` (the paper's extension of NeatNet to
orientation), positions scaled by the scene's bounds. The encoder pools the full arrangement into a
latent ``z``; the decoder predicts every node's pose from ``z``, the node's own features and a pooled
context of the objects that are *not* masked. Training masks a random subset of the poses (the
decoder must rebuild them from the rest) and adds the KL term of the VAE.

- ``predict``: fill the ``null`` poses of a scene from the known ones (``z`` at the prior mean).
- ``sample``: whole arrangements from the prior, every pose masked (the Fig. 4 baseline, which then
  rejects the samples that break the constraints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor, nn

from ...scene.scene import Scene, SceneError, wrap_angle

__all__ = ["NeatNet", "NeatNetConfig"]


@dataclass
class NeatNetConfig:
    """Sizes and the training schedule of :class:`NeatNet`."""

    hidden: int = 64
    latent: int = 4
    max_objects: int = 16
    iterations: int = 1500
    batch: int = 32
    lr: float = 3e-3
    beta: float = 0.05  # weight of the KL term
    mask_prob: float = 0.5


def _mlp(i: int, h: int, o: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(i, h), nn.ReLU(), nn.Linear(h, h), nn.ReLU(), nn.Linear(h, o))


class _VAE(nn.Module):
    def __init__(self, feat: int, cfg: NeatNetConfig):
        super().__init__()
        h, z = cfg.hidden, cfg.latent
        self.latent = z
        self.enc_node = _mlp(feat + 4, h, h)
        self.enc_out = nn.Linear(h, 2 * z)
        self.ctx_node = _mlp(feat + 4, h, h)
        self.dec = _mlp(feat + z + h, h, 4)

    def encode(self, f: Tensor, p: Tensor, valid: Tensor) -> tuple[Tensor, Tensor]:
        w = valid.float().unsqueeze(-1)
        pooled = (self.enc_node(torch.cat([f, p], -1)) * w).sum(1) / w.sum(1).clamp(min=1)
        mu, logvar = self.enc_out(pooled).chunk(2, -1)
        return mu, logvar.clamp(-8, 8)

    def decode(self, f: Tensor, p: Tensor, known: Tensor, z: Tensor) -> Tensor:
        w = known.float().unsqueeze(-1)
        ctx = (self.ctx_node(torch.cat([f, p * w], -1)) * w).sum(1) / w.sum(1).clamp(min=1)
        n = f.shape[1]
        x = torch.cat([f, z.unsqueeze(1).expand(-1, n, -1), ctx.unsqueeze(1).expand(-1, n, -1)], -1)
        return self.dec(x)


@dataclass
class NeatNet:
    """The NeatNet baseline as a :class:`~scenescore.planning.placement.Placer`, with ``sample`` for Fig. 4."""

    name: str = "NeatNet"
    config: NeatNetConfig = field(default_factory=NeatNetConfig)
    categories: list[str] = field(default_factory=list)
    net: _VAE | None = None

    # -- tensors ------------------------------------------------------------------------------------
    @property
    def _feat(self) -> int:
        return len(self.categories) + 2 + self.config.max_objects

    def _tensors(self, scenes: list[Scene]) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        """Features (B, M, F), normalised poses (B, M, 4), valid (B, M), known (B, M)."""
        m = self.config.max_objects
        b = len(scenes)
        f = torch.zeros(b, m, self._feat)
        p = torch.zeros(b, m, 4)
        valid = torch.zeros(b, m, dtype=torch.bool)
        known = torch.zeros(b, m, dtype=torch.bool)
        nc = len(self.categories)
        for i, s in enumerate(scenes):
            if len(s) > m:
                raise SceneError(f"NeatNet: {len(s)} objects, more than max_objects={m}")
            (x0, y0), (x1, y1) = s.bounds
            cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
            for j, o in enumerate(s.objects):
                if o.category in self.categories:
                    f[i, j, self.categories.index(o.category)] = 1.0
                f[i, j, nc : nc + 2] = torch.tensor(o.size[:2], dtype=torch.float32) * 5
                f[i, j, nc + 2 + j] = 1.0
                valid[i, j] = True
                if o.pose is not None:
                    x, y, th = o.pose
                    p[i, j] = torch.tensor([(x - cx) / hx, (y - cy) / hy, math.cos(th), math.sin(th)])
                    known[i, j] = True
        return f, p, valid, known

    @staticmethod
    def _poses(scene: Scene, out: np.ndarray) -> np.ndarray:
        (x0, y0), (x1, y1) = scene.bounds
        cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
        x = cx + out[..., 0] * hx
        y = cy + out[..., 1] * hy
        th = wrap_angle(np.arctan2(out[..., 3], out[..., 2]))
        return np.stack([x, y, th], -1)

    # -- Placer -------------------------------------------------------------------------------------
    def fit(self, scenes: list[Scene], seed: int = 0) -> NeatNet:
        """Train the masked VAE on complete arrangements."""
        if not scenes:
            raise SceneError("NeatNet.fit: no training scenes")
        cfg = self.config
        self.categories = sorted({o.category for s in scenes for o in s.objects})
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        f, p, valid, known = self._tensors(scenes)
        if not bool((known == valid).all()):
            raise SceneError("NeatNet.fit: training scenes must have every pose")
        self.net = _VAE(self._feat, cfg)
        opt = torch.optim.Adam(self.net.parameters(), lr=cfg.lr)
        for _ in range(cfg.iterations):
            idx = torch.randint(len(scenes), (cfg.batch,), generator=gen)
            fb, pb, vb = f[idx], p[idx], valid[idx]
            keep = (torch.rand(vb.shape, generator=gen) > cfg.mask_prob) & vb
            # half the batch sees nothing: the decoder must also build whole arrangements from z
            keep[: cfg.batch // 2] = False
            mu, logvar = self.net.encode(fb, pb, vb)
            z = mu + torch.randn(mu.shape, generator=gen) * (0.5 * logvar).exp()
            out = self.net.decode(fb, pb, keep, z)
            w = vb.float().unsqueeze(-1)
            rec = (((out - pb) ** 2) * w).sum() / w.sum()
            kl = -0.5 * (1 + logvar - mu**2 - logvar.exp()).sum(-1).mean()
            loss = rec + cfg.beta * kl
            opt.zero_grad()
            loss.backward()
            opt.step()
        return self

    def _check(self) -> _VAE:
        if self.net is None:
            raise SceneError("NeatNet: call fit() first")
        return self.net

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        """Fill every ``null`` pose from the known ones (latent at the prior mean)."""
        net = self._check()
        if not scenes:
            return []
        f, p, _, known = self._tensors(scenes)
        with torch.no_grad():
            out = net.decode(f, p, known, torch.zeros(len(scenes), net.latent)).numpy()
        res = []
        for i, s in enumerate(scenes):
            names = s.unknown
            if not names:
                res.append(s.copy())
                continue
            idx = [s.index(n) for n in names]
            res.append(s.with_poses(self._poses(s, out[i, idx]), names))
        return res

    def sample(self, scene: Scene, n: int, seed: int = 0) -> np.ndarray:
        """``n`` arrangements of ``scene``'s objects with a ``null`` pose, drawn from the prior:
        ``(n, N, 3)`` full pose arrays (known poses copied, the rest sampled)."""
        net = self._check()
        gen = torch.Generator().manual_seed(seed)
        f, p, _, known = self._tensors([scene])
        # the VAE models the arrangement alone: objects it never saw (clutter) stay out of its context
        seen = torch.tensor(
            [o.category in self.categories for o in scene.objects]
            + [False] * (self.config.max_objects - len(scene))
        )
        known = known & seen
        with torch.no_grad():
            z = torch.randn(n, net.latent, generator=gen)
            out = net.decode(f.expand(n, -1, -1), p.expand(n, -1, -1), known.expand(n, -1), z).numpy()
        poses = np.repeat(scene.poses()[None], n, 0)
        unk = [scene.index(nm) for nm in scene.unknown]
        poses[:, unk] = self._poses(scene, out[:, unk])
        return poses
