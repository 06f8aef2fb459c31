"""Counter-examples: the arrangements each true scene is told apart from.

Three kinds, each with the true scene's objects: the persistent Langevin chains of :class:`ChainBuffer`
(every scene keeps ``negatives`` chains between iterations; each iteration advances them a few steps and
restarts a fraction, so new chains always explore; a chain moves all objects, one object, or a random
subset, the rest staying at their true poses, which teaches the conditional distributions that placing a
missing object needs), one object displaced by noise (:func:`perturbed_negatives`), and one object put
on the wrong anchor (:func:`reanchored_negatives`). No gradient flows through any of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from ..geometry.poses import compose_poses, relative_poses, uniform_init
from ..models import SceneTensors
from ..runtime.devices import draw
from ..solvers.kernel import LangevinConfig, Limits, chain
from .config import TrainConfig

__all__ = ["ChainBuffer", "perturbed_negatives", "reanchored_negatives", "log_uniform"]


def log_uniform(n: int, lo: float, hi: float, gen: torch.Generator, device: torch.device) -> torch.Tensor:
    """``n`` numbers log-uniform in ``[lo, hi]``."""
    return torch.exp(math.log(lo) + draw("rand", (n,), gen, device) * (math.log(hi) - math.log(lo)))


def perturbed_negatives(
    batch: SceneTensors, k: int, cfg: TrainConfig, gen: torch.Generator, length_scale: float
) -> torch.Tensor:
    """``k`` copies of each true scene with one movable object displaced: ``(B * k, N, 3)``."""
    rep = batch.repeat(k)
    m, n = rep.mask.shape
    dev = rep.poses.device
    real = rep.mask & ~rep.fixed
    pick = draw("rand", (m, n), gen, dev).masked_fill(~real, 2.0).argmin(dim=1)  # (M,)
    sp = log_uniform(m, *cfg.perturb_pos, gen, dev) * length_scale
    sa = log_uniform(m, *cfg.perturb_angle, gen, dev)
    noise = draw("randn", (m, 3), gen, dev) * torch.stack([sp, sp, sa], dim=1)
    x = rep.poses.clone()
    rows = torch.arange(m, device=dev)
    x[rows, pick] = x[rows, pick] + noise.to(x.dtype)
    x[..., :2] = torch.minimum(torch.maximum(x[..., :2], rep.lo[:, None]), rep.hi[:, None])
    return x


def reanchored_negatives(
    batch: SceneTensors, k: int, gen: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """``k`` copies of each true scene with one movable object ``i`` moved to the pose relative to another
    object ``j`` that it has to its nearest neighbour: ``(poses (B * k, N, 3), moved (B * k, N))``, where
    ``moved`` marks ``i``; a copy of a scene with fewer than three objects (or none movable) is the scene
    itself, with no object marked."""
    rep = batch.repeat(k)
    m, n = rep.mask.shape
    dev = rep.poses.device
    rows = torch.arange(m, device=dev)
    x = rep.poses.clone()
    real = rep.mask & ~rep.fixed
    i = draw("rand", (m, n), gen, dev).masked_fill(~real, 2.0).argmin(dim=1)  # (M,)
    d = (x[..., :2] - x[rows, i, None, :2]).norm(dim=-1)  # (M, N): from i
    d = d.masked_fill(~rep.mask, math.inf)
    d[rows, i] = math.inf
    near = d.argmin(dim=1)  # (M,)
    other = rep.mask.clone()
    other[rows, i] = False
    other[rows, near] = False
    j = draw("rand", (m, n), gen, dev).masked_fill(~other, 2.0).argmin(dim=1)
    valid = real.any(dim=1) & other.any(dim=1)
    pose = compose_poses(x[rows, j], relative_poses(x[rows, near], x[rows, i]))
    pose[:, :2] = torch.minimum(torch.maximum(pose[:, :2], rep.lo), rep.hi)
    x[rows, i] = torch.where(valid[:, None], pose, x[rows, i])
    moved = torch.zeros(m, n, dtype=torch.bool, device=dev)
    moved[rows, i] = valid
    return x, moved


class ChainBuffer:
    """Persistent counter-example chains: ``(S, K, N, 3)`` poses, ``(S, K, N)`` movable masks and
    ``(S, K)`` ages (the steps each chain has taken since its restart, its place in the schedule)."""

    def __init__(self, data: SceneTensors, k: int, cfg: TrainConfig, gen: torch.Generator):
        self.data, self.k, self.cfg, self.gen = data, k, cfg, gen
        s, n = data.mask.shape
        self.device = dev = data.poses.device
        self.poses = data.poses[:, None].repeat(1, k, 1, 1)
        self.movable = torch.zeros(s, k, n, dtype=torch.bool, device=dev)
        self.age = torch.zeros(s, k, dtype=torch.long, device=dev)
        self.restart(torch.ones(s, k, dtype=torch.bool, device=dev))

    def _masks(self, rows: torch.Tensor) -> torch.Tensor:
        """New movable masks for the scenes ``rows`` (one per chain), among real, non-fixed objects."""
        real = self.data.mask[rows] & ~self.data.fixed[rows]  # (M, N)
        m, n = real.shape
        dev = self.device
        u = draw("rand", (m,), self.gen, dev)
        scores = draw("rand", (m, n), self.gen, dev).masked_fill(~real, 2.0)
        single = torch.zeros(m, n, dtype=torch.bool, device=dev)
        single[torch.arange(m, device=dev), scores.argmin(dim=1)] = True
        subset = (draw("rand", (m, n), self.gen, dev) < 0.5) & real
        subset = subset | single  # never empty
        full = real
        cf, cs = self.cfg.full_fraction, self.cfg.full_fraction + self.cfg.single_fraction
        out = torch.where((u < cf)[:, None], full, torch.where((u < cs)[:, None], single, subset))
        return out & real

    def restart(self, which: torch.Tensor) -> None:
        """Restart the chains flagged in ``which (S, K)`` from uniform poses with fresh masks (a share of
        them, ``reanchor_restart``, from one object on the wrong anchor, halfway through the schedule)."""
        idx = which.nonzero()
        if idx.numel() == 0:
            return
        rows, cols = idx[:, 0], idx[:, 1]
        masks = self._masks(rows)
        init = uniform_init(
            (len(rows), self.poses.shape[2]),
            self.data.lo[rows],
            self.data.hi[rows],
            self.gen,
            dtype=self.poses.dtype,
        )
        true = self.data.poses[rows]
        init = torch.where(masks[..., None], init, true)
        age = torch.zeros(len(rows), dtype=torch.long, device=self.device)
        if self.cfg.reanchor_restart:
            poses, moved = reanchored_negatives(self.data.index(rows), 1, self.gen)
            u = draw("rand", (len(rows),), self.gen, self.device)
            take = moved.any(dim=1) & (u < self.cfg.reanchor_restart)
            init = torch.where(take[:, None, None], poses, init)
            masks = torch.where(take[:, None], moved, masks)
            age = age.masked_fill(take, self.cfg.chain.steps // 2)
        self.poses[rows, cols] = init
        self.movable[rows, cols] = masks
        self.age[rows, cols] = age

    def advance(
        self,
        rows: torch.Tensor,
        energy: Callable[[torch.Tensor], torch.Tensor],
        rep: SceneTensors,
        schedule: LangevinConfig,
        steps: int,
    ) -> torch.Tensor:
        """Advance the chains of the scenes ``rows`` ``steps`` Langevin steps on ``energy`` (of ``rep``, the
        scenes repeated ``k`` times), each from its own place in ``schedule``: their new poses
        ``(len(rows) * k, N, 3)``, also kept."""
        b, k = len(rows), self.k
        init = self.poses[rows].reshape(b * k, *self.poses.shape[2:])
        movable = self.movable[rows].reshape(b * k, -1)
        age = self.age[rows].reshape(-1)
        limits = Limits(movable, rep.lo, rep.hi)
        neg = chain(energy, init, limits, schedule, self.gen, age=age, run_steps=steps)
        self.poses[rows] = neg.reshape(b, k, *neg.shape[1:])
        self.age[rows] += steps
        return neg
