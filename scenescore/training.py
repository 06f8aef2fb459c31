"""Training the energy with InfoNCE against Langevin counter-examples.

Each training scene is scored against ``negatives`` counter-examples with the same objects. The
counter-examples are Langevin chains on the current model, started uniformly inside the bounds. To
keep training cheap on a laptop CPU the chains are persistent: every scene keeps its ``negatives``
chains between iterations, each iteration advances them a few steps, and a fraction restarts from
uniform every iteration (so new chains always explore). A chain moves either all objects, one
object, or a random subset, the rest staying at their true poses: partial chains teach the
conditional distributions that placing a missing object needs. No gradient flows through a chain.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import torch
import torch.nn.functional as F
from tqdm.auto import tqdm

from .encoders import Encoder, FootprintEncoder
from .models import SceneTensors, ScoreModel
from .sampling import TRAINING, LangevinConfig, langevin, uniform_init
from .scene import Scene, SceneError

__all__ = ["TrainConfig", "train", "infonce_loss", "perturbed_negatives"]


@dataclass
class TrainConfig:
    """Training settings; the defaults work for about 50 scenes of up to a dozen objects."""

    iterations: int = 600
    batch_scenes: int = 16
    negatives: int = 16  # counter-examples per scene
    chain_steps: int = 6  # Langevin steps each persistent chain advances per iteration
    restart: float = 0.1  # fraction of chains restarted from uniform each iteration
    # each chain follows this schedule from its (re)start: coarse moves first, then fine ones
    chain: LangevinConfig = TRAINING
    perturbed: int = 0  # extra counter-examples: one object's true pose moved by noise of a random scale
    perturb_pos: tuple[float, float] = (0.005, 0.2)  # log-uniform range of the position noise's std (m)
    perturb_angle: tuple[float, float] = (0.03, 1.5)  # log-uniform range of the angle noise's std (rad)
    # std of Gaussian noise added to the object features, per object and iteration: the energy leans
    # on geometry more than on exact features, which carries it to unseen objects (Table 2)
    feature_noise: float = 0.3
    full_fraction: float = 0.3  # chains moving every object
    single_fraction: float = 0.5  # chains moving one object (the rest: a random subset)
    lr: float = 2e-3
    lr_final: float = 2e-4  # cosine decay to this
    weight_decay: float = 0.0  # AdamW's decoupled weight decay
    energy_reg: float = 1e-3  # small L2 on energies, keeps them bounded
    grad_penalty: float = 0.0  # optional penalty on the energy's gradient norm at counter-examples
    grad_margin: float = 10.0
    model: dict[str, Any] = field(default_factory=dict)  # EnergyConfig fields (hidden, layers, ...)

    def __post_init__(self) -> None:
        if isinstance(self.chain, dict):
            self.chain = LangevinConfig(**self.chain)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def infonce_loss(e_pos: torch.Tensor, e_neg: torch.Tensor) -> torch.Tensor:
    """The paper's equation 2: ``-log softmax`` of the true scene among its counter-examples.

    ``e_pos``: ``(B,)``; ``e_neg``: ``(B, K)``.
    """
    logits = -torch.cat([e_pos[:, None], e_neg], dim=1)  # (B, 1 + K)
    target = torch.zeros(e_pos.shape[0], dtype=torch.long, device=e_pos.device)
    return F.cross_entropy(logits, target)


def _log_uniform(n: int, lo: float, hi: float, gen: torch.Generator) -> torch.Tensor:
    return torch.exp(math.log(lo) + torch.rand(n, generator=gen) * (math.log(hi) - math.log(lo)))


def perturbed_negatives(batch: SceneTensors, k: int, cfg: TrainConfig, gen: torch.Generator) -> torch.Tensor:
    """``k`` copies of each true scene with one movable object displaced: ``(B * k, N, 3)``."""
    rep = batch.repeat(k)
    m, n = rep.mask.shape
    real = rep.mask & ~rep.fixed
    pick = torch.rand(m, n, generator=gen).masked_fill(~real, 2.0).argmin(dim=1)  # (M,)
    sp = _log_uniform(m, *cfg.perturb_pos, gen)
    sa = _log_uniform(m, *cfg.perturb_angle, gen)
    noise = torch.randn(m, 3, generator=gen) * torch.stack([sp, sp, sa], dim=1)
    x = rep.poses.clone()
    rows = torch.arange(m)
    x[rows, pick] = x[rows, pick] + noise.to(x.dtype)
    x[..., :2] = torch.minimum(torch.maximum(x[..., :2], rep.lo[:, None]), rep.hi[:, None])
    return x


class _ChainBuffer:
    """Persistent counter-example chains: ``(S, K, N, 3)`` poses and ``(S, K, N)`` movable masks."""

    def __init__(self, data: SceneTensors, k: int, cfg: TrainConfig, gen: torch.Generator):
        self.data, self.k, self.cfg, self.gen = data, k, cfg, gen
        s, n = data.mask.shape
        self.poses = data.poses[:, None].repeat(1, k, 1, 1)
        self.movable = torch.zeros(s, k, n, dtype=torch.bool)
        self.age = torch.zeros(s, k, dtype=torch.long)
        self.restart(torch.ones(s, k, dtype=torch.bool))

    def _masks(self, rows: torch.Tensor) -> torch.Tensor:
        """New movable masks for the scenes ``rows`` (one per chain), among real, non-fixed objects."""
        real = self.data.mask[rows] & ~self.data.fixed[rows]  # (M, N)
        m, n = real.shape
        u = torch.rand(m, generator=self.gen)
        scores = torch.rand(m, n, generator=self.gen).masked_fill(~real, 2.0)
        single = torch.zeros(m, n, dtype=torch.bool)
        single[torch.arange(m), scores.argmin(dim=1)] = True
        subset = (torch.rand(m, n, generator=self.gen) < 0.5) & real
        subset = subset | single  # never empty
        full = real
        cf, cs = self.cfg.full_fraction, self.cfg.full_fraction + self.cfg.single_fraction
        out = torch.where((u < cf)[:, None], full, torch.where((u < cs)[:, None], single, subset))
        return out & real

    def restart(self, which: torch.Tensor) -> None:
        """Restart the chains flagged in ``which (S, K)`` from uniform poses with fresh masks."""
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
        self.poses[rows, cols] = torch.where(masks[..., None], init, true)
        self.movable[rows, cols] = masks
        self.age[rows, cols] = 0


def train(
    scenes: Sequence[Scene],
    config: TrainConfig | None = None,
    encoder: Encoder | None = None,
    seed: int = 0,
    progress: bool = True,
) -> ScoreModel:
    """Train a :class:`ScoreModel` on example arrangements (every pose must be known)."""
    cfg = config or TrainConfig()
    encoder = encoder or FootprintEncoder()
    if len(scenes) < 2:
        raise SceneError(f"train: need at least 2 example scenes, got {len(scenes)}")
    for i, s in enumerate(scenes):
        if s.unknown:
            raise SceneError(
                f"train: scene {i} has objects without a pose: {s.unknown}; every pose must be known"
            )
    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    model = ScoreModel.create(encoder, **cfg.model)
    data = model.tensors(scenes)
    s_count = len(scenes)
    buf = _ChainBuffer(data, cfg.negatives, cfg, gen)
    chain_cfg = LangevinConfig(**{**asdict(cfg.chain), "final_descent": 0})
    opt = torch.optim.AdamW(model.net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(
        opt, T_max=max(cfg.iterations, 1), eta_min=cfg.lr_final
    )
    bs = min(cfg.batch_scenes, s_count)
    k = cfg.negatives
    history: list[float] = []
    t0 = time.perf_counter()
    bar = tqdm(range(cfg.iterations), desc="train", disable=not progress, unit="it", dynamic_ncols=True)
    for it in bar:
        rows = torch.randperm(s_count, generator=gen)[:bs]
        buf.restart(
            (torch.rand(s_count, k, generator=gen) < cfg.restart)
            & torch.isin(torch.arange(s_count), rows)[:, None]
        )
        batch = data.index(rows)
        if cfg.feature_noise:
            noise = torch.randn(batch.feats.shape, generator=gen, dtype=batch.feats.dtype) * cfg.feature_noise
            batch = replace(batch, feats=batch.feats + noise)
        rep = batch.repeat(k)  # (bs * k, ...)
        model.net.eval()
        init = buf.poses[rows].reshape(bs * k, *buf.poses.shape[2:])
        movable = buf.movable[rows].reshape(bs * k, -1)

        def energy(x: torch.Tensor, rep: SceneTensors = rep) -> torch.Tensor:
            return model.energy(x, rep)

        age = buf.age[rows].reshape(-1)
        neg, _ = langevin(
            energy, init, movable, rep.lo, rep.hi, chain_cfg, gen, age=age, run_steps=cfg.chain_steps
        )
        buf.poses[rows] = neg.reshape(bs, k, *neg.shape[1:])
        buf.age[rows] += cfg.chain_steps
        model.net.train()
        e_pos = model.energy(batch.poses, batch)
        e_neg = model.energy(neg, rep).reshape(bs, k)
        if cfg.perturbed:
            pert = perturbed_negatives(batch, cfg.perturbed, cfg, gen)
            e_pert = model.energy(pert, batch.repeat(cfg.perturbed)).reshape(bs, cfg.perturbed)
            e_neg = torch.cat([e_neg, e_pert], dim=1)
        loss = infonce_loss(e_pos, e_neg)
        if cfg.energy_reg:
            loss = loss + cfg.energy_reg * (e_pos.pow(2).mean() + e_neg.pow(2).mean())
        if cfg.grad_penalty:
            x = neg.detach().requires_grad_(True)
            (g,) = torch.autograd.grad(model.energy(x, rep).sum(), x, create_graph=True)
            gmax = g.abs().amax(dim=(1, 2))
            loss = loss + cfg.grad_penalty * F.relu(gmax - cfg.grad_margin).pow(2).mean()
        if not torch.isfinite(loss):
            raise FloatingPointError(
                f"train: loss became {loss.item()} at iteration {it}; lower TrainConfig.lr"
            )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.net.parameters(), 10.0)
        opt.step()
        sched.step()
        history.append(loss.item())
        if it % 20 == 0:
            bar.set_postfix(loss=f"{sum(history[-20:]) / len(history[-20:]):.3f}")
    model.net.eval()
    model.info = {
        "train_config": cfg.to_dict(),
        "seed": seed,
        "scenes": s_count,
        "final_loss": float(sum(history[-50:]) / max(len(history[-50:]), 1)),
        "chance_loss": math.log(k + cfg.perturbed + 1),
        "seconds": round(time.perf_counter() - t0, 2),
    }
    return model
