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

import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from tqdm.auto import tqdm

from .devices import draw, generator, resolve_device
from .encoders import Encoder, FootprintEncoder
from .errors import ConfigError, check_number
from .geometry import compose_poses, relative_poses
from .models import SceneTensors, ScoreModel
from .models.trust import reference, touching_bound
from .sampling import TRAINING, LangevinConfig, langevin, uniform_init
from .scene import Scene, SceneError
from .threads import threads_for, torch_threads

__all__ = [
    "TrainConfig",
    "RAW_EDGES",
    "train",
    "infonce_loss",
    "perturbed_negatives",
    "data_scale",
    "heldout_loss",
    "split_validation",
    "stands_against_walls",
    "check_training_data",
    "require_tensorboard",
    "summary_writer",
    "log_validation",
    "model_cache",
    "MODEL_CACHE_ENV",
]


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
    perturb_pos: tuple[float, float] = (
        0.05,
        2.0,
    )  # log-uniform range of the position noise's std (length scales)
    perturb_angle: tuple[float, float] = (0.03, 1.5)  # log-uniform range of the angle noise's std (rad)
    # extra counter-examples: one movable object put at the pose relative to another object (not its
    # nearest) that it has to its nearest neighbour: a relation of the data on the wrong anchor (a book at
    # the row's far end instead of its place in the row)
    reanchored: int = 8
    # fraction of restarted chains that start from such a pose (one object on the wrong anchor, it alone
    # moving) halfway through their schedule, instead of from uniform: the chain relaxes it into the
    # nearest hard counter-example (flush to the wall, at the row's far end)
    reanchor_restart: float = 0.5
    # noise on every node input, fresh per object and iteration, so that the energy leans on geometry more
    # than on exact features, which carries it to objects it never saw (Table 2): Gaussian noise of std
    # feature_noise on the encoder's vector, and of std size_noise length scales on the scale descriptor
    # (the footprint's size as the network reads it; without it the network with its edge encoder ordered
    # Table 2's unseen spoons by their width, 15 cm off on seed 0)
    feature_noise: float = 0.6
    size_noise: float = 0.3
    full_fraction: float = 0.3  # chains moving every object
    single_fraction: float = 0.5  # chains moving one object (the rest: a random subset)
    lr: float = 2e-3
    lr_final: float = 2e-4  # cosine decay to this
    weight_decay: float = 0.0  # AdamW's decoupled weight decay
    energy_reg: float = 1e-3  # small L2 on energies, keeps them bounded
    grad_penalty: float = 0.0  # optional penalty on the energy's gradient norm at counter-examples
    grad_margin: float = 10.0
    model: dict[str, Any] = field(default_factory=dict)  # EnergyConfig fields (hidden, layers, ...)
    # lengths in the data's own unit, stored in the checkpoint: None derives them (see data_scale);
    # a number (metres; for edge_range, length scales) sets them by hand
    length_scale: float | None = None
    edge_range: float | None = None
    # derive edge_range from the data (False: linear edge positions). Off by default: with it on, one
    # seed of Table 2's Unseen-Class placed spoons 37 cm off (0.89 cm with it off, same data and seed)
    saturate_edges: bool = False
    # the bounds' sides as fixed objects in every graph; None: when the data stands against them
    walls: bool | None = None
    # with walls: walls as lines (see EnergyConfig.wall_lines): no edge reads where along a wall an
    # object stands. As boxes, the four walls added up to ramps across the room that pulled zoo-bedroom's
    # benches 28 to 33 cm off (benchmarks/wall_pull.py); False reads them as boxes
    wall_lines: bool = True
    # with walls: length scales beyond which the offsets on an edge touching a wall saturate, each axis
    # on its own (EnergyConfig.wall_range); None: linear. At 2 zoo-bedroom had no catastrophic placement
    # but zoo-books had two; at 1 zoo-lounge's sofa lost its wall
    wall_range: float | None = None
    # round disks' headings ignored by the energy (their headings in the data are arbitrary, and a network
    # that sees them learns noise: on zoo-jars, all round, placements were 15 cm off with them seen)
    round_invariant: bool = True
    # width of the network's edge encoder (see EnergyConfig.edge_encoder); None: the raw edge features,
    # which leave the energy flat around the truth in larger rooms (zoo-bedroom, zoo-banquet)
    edge_encoder: int | None = 32
    # evaluate each batch in groups of similar object counts, each cropped to its own largest (the same
    # energies; fewer padded edges where 4 and 24 objects share a batch); False: one padded pass
    group_sizes: bool = True
    # the trained model is the exponential moving average of the weights with this decay, taken over the
    # second half of training (0: the last iterate, whose noise left Fig. 4's seed-0 energy preferring
    # speakers 4 cm from symmetric); a short run's decay is lowered to 1 - 3 / (its averaged iterations),
    # so that the weights of the average's first iteration weigh at most e^-3 (0.99 from 600 iterations)
    average: float = 0.99

    def __post_init__(self) -> None:
        if isinstance(self.chain, dict):
            self.chain = LangevinConfig(**self.chain)
        own = "TrainConfig"
        check_number(own, "iterations", self.iterations, 1, 10_000_000, integer=True)
        for name in ("batch_scenes", "negatives", "chain_steps"):
            check_number(own, name, getattr(self, name), 1, 100_000, integer=True)
        check_number(own, "perturbed", self.perturbed, 0, 100_000, integer=True)
        check_number(own, "reanchored", self.reanchored, 0, 100_000, integer=True)
        if self.edge_encoder is not None:
            check_number(own, "edge_encoder", self.edge_encoder, 1, 8192, integer=True)
        for name in ("restart", "full_fraction", "single_fraction", "reanchor_restart", "average"):
            check_number(own, name, getattr(self, name), 0, 1)
        if self.average == 1:
            raise ConfigError(f"{own}: average: expected a decay below 1 (0: no averaging), got 1")
        if self.full_fraction + self.single_fraction > 1:
            raise ConfigError(
                f"{own}: full_fraction + single_fraction: expected at most 1, got "
                f"{self.full_fraction} + {self.single_fraction}"
            )
        check_number(own, "lr", self.lr, 0, open_lo=True)
        for name in (
            "lr_final",
            "weight_decay",
            "energy_reg",
            "grad_penalty",
            "grad_margin",
            "feature_noise",
            "size_noise",
        ):
            check_number(own, name, getattr(self, name), 0)
        for name in ("length_scale", "edge_range", "wall_range"):
            if getattr(self, name) is not None:
                check_number(own, name, getattr(self, name), 0, open_lo=True)
        if not isinstance(self.chain, LangevinConfig):
            raise ConfigError(f"{own}: chain: expected a LangevinConfig or a dict of its fields")
        for name in ("saturate_edges", "round_invariant", "group_sizes", "wall_lines"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{own}: {name}: expected true or false, got {getattr(self, name)!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


#: the network without its edge encoder, trained as the default was before the encoder (its feature
#: noise, no re-anchored counter-examples): ``TrainConfig(**RAW_EDGES)``
RAW_EDGES: Mapping[str, Any] = MappingProxyType(
    {"edge_encoder": None, "feature_noise": 0.3, "size_noise": 0.0, "reanchored": 0, "reanchor_restart": 0.0}
)


_ABSENT = 1e4  # the energy given to a counter-example that is not there: its softmax weight is 0


def infonce_loss(e_pos: torch.Tensor, e_neg: torch.Tensor) -> torch.Tensor:
    """The paper's equation 2: ``-log softmax`` of the true scene among its counter-examples.

    ``e_pos``: ``(B,)``; ``e_neg``: ``(B, K)``.
    """
    logits = -torch.cat([e_pos[:, None], e_neg], dim=1)  # (B, 1 + K)
    target = torch.zeros(e_pos.shape[0], dtype=torch.long, device=e_pos.device)
    return F.cross_entropy(logits, target)


def _log_uniform(n: int, lo: float, hi: float, gen: torch.Generator, device: torch.device) -> torch.Tensor:
    return torch.exp(math.log(lo) + draw("rand", (n,), gen, device) * (math.log(hi) - math.log(lo)))


def data_scale(scenes: Sequence[Scene]) -> tuple[float, float]:
    """The data's length scale and largest offset: ``(L, R)``.

    ``L`` (metres) is the median over every object of half its footprint's longer side; ``R`` is the
    largest distance between two objects' centres in any scene, in units of ``L``. Both scale with the
    data, exactly for powers of two: scaling every length by ``k`` scales ``L`` by ``k`` and keeps ``R``.
    """
    halves = sorted(max(o.size) / 2 for s in scenes for o in s.objects)
    n = len(halves)
    length = halves[n // 2] if n % 2 else (halves[n // 2 - 1] + halves[n // 2]) / 2
    far = 0.0
    for s in scenes:
        p = s.poses()[:, :2]
        if len(p) > 1:
            far = max(far, float(np.sqrt(((p[:, None] - p[None]) ** 2).sum(-1)).max()))
    return float(length), max(far / length, 1.0)


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


def perturbed_negatives(
    batch: SceneTensors, k: int, cfg: TrainConfig, gen: torch.Generator, length_scale: float
) -> torch.Tensor:
    """``k`` copies of each true scene with one movable object displaced: ``(B * k, N, 3)``."""
    rep = batch.repeat(k)
    m, n = rep.mask.shape
    dev = rep.poses.device
    real = rep.mask & ~rep.fixed
    pick = draw("rand", (m, n), gen, dev).masked_fill(~real, 2.0).argmin(dim=1)  # (M,)
    sp = _log_uniform(m, *cfg.perturb_pos, gen, dev) * length_scale
    sa = _log_uniform(m, *cfg.perturb_angle, gen, dev)
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


class _BySize:
    """A batch's pose sets evaluated in groups of similar object counts, each group cropped to its own
    largest count: the energies of one padded pass to float rounding (padding adds only zeros), with fewer
    ``(N, N)`` edges when scenes of 4 and 24 objects share a batch (``zoo-books``).

    ``counts (S,)``: real objects (walls included) of each scene of the batch, whose pose sets come in
    ``k`` consecutive rows each. Scenes are sorted by count and cut into at most :attr:`MAX_GROUPS`
    contiguous groups where that saves at least a fifth of the edges, else one group.
    """

    MAX_GROUPS = 4

    def __init__(self, counts: torch.Tensor, enabled: bool = True):
        c = counts.tolist()
        order = sorted(range(len(c)), key=lambda i: c[i])
        cuts = _best_cuts([c[i] for i in order], self.MAX_GROUPS)
        one = len(c) * max(c) ** 2
        cost = sum((b - a) * c[order[b - 1]] ** 2 for a, b in zip([0, *cuts[:-1]], cuts))
        if cost > 0.8 * one or not enabled:
            cuts = [len(c)]
        self.groups: list[tuple[list[int], int]] = []  # (scene positions, count)
        for a, b in zip([0, *cuts[:-1]], cuts):
            self.groups.append((order[a:b], c[order[b - 1]]))

    def bound(
        self, model: ScoreModel, st: SceneTensors, k: int = 1
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        """``poses (S * k, N, 3) -> model.energy(poses, st)`` for ``k`` rows per scene, each group's rows and
        cropped tensors made once (the chain calls it at every step)."""
        if len(self.groups) == 1:
            return lambda poses: model.energy(poses, st)
        parts = []
        for scenes, n in self.groups:
            r = torch.tensor([i * k + j for i in scenes for j in range(k)], device=st.poses.device)
            parts.append((r, n, _cropped(st.index(r), n)))
        order = torch.cat([r for r, _, _ in parts])
        inverse = torch.empty_like(order)
        inverse[order] = torch.arange(len(order), device=order.device)

        def energy(poses: torch.Tensor) -> torch.Tensor:
            return torch.cat([model.energy(poses[r, :n], sub) for r, n, sub in parts])[inverse]

        return energy


def _cropped(st: SceneTensors, n: int) -> SceneTensors:
    """``st`` with its object axis cut to the first ``n`` (the rest padding)."""
    per_object = ("poses", "feats", "sizes", "mask", "known", "fixed", "round")
    return SceneTensors(
        *(getattr(st, f)[:, :n] if f in per_object else getattr(st, f) for f in st.__dataclass_fields__)
    )


def _best_cuts(sorted_counts: list[int], most: int) -> list[int]:
    """Ends of at most ``most`` contiguous groups of ``sorted_counts`` (ascending) that minimise the
    padded edges ``sum(len(group) * max(group) ** 2)`` (dynamic programming over the cut points)."""
    m = len(sorted_counts)
    inf = float("inf")
    best = [[inf] * (m + 1) for _ in range(most + 1)]  # best[g][b]: first b scenes in g groups
    back = [[0] * (m + 1) for _ in range(most + 1)]
    best[0][0] = 0.0
    for g in range(1, most + 1):
        for b in range(1, m + 1):
            for a in range(g - 1, b):
                v = best[g - 1][a] + (b - a) * sorted_counts[b - 1] ** 2
                if v < best[g][b]:
                    best[g][b], back[g][b] = v, a
    g = min(range(1, most + 1), key=lambda j: best[j][m])
    cuts, b = [], m
    while g > 0:
        cuts.append(b)
        b, g = back[g][b], g - 1
    return cuts[::-1]


class _ChainBuffer:
    """Persistent counter-example chains: ``(S, K, N, 3)`` poses and ``(S, K, N)`` movable masks."""

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


TENSORBOARD_EXTRA = "TensorBoard logging needs the 'tensorboard' extra: pip install -e '.[tensorboard]'"


def require_tensorboard() -> Any:
    """``torch.utils.tensorboard.SummaryWriter``, or :class:`ConfigError` naming the extra when the
    tensorboard package is missing."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError as e:
        raise ConfigError(f"{TENSORBOARD_EXTRA} ({e})") from None
    return SummaryWriter


def summary_writer(log_dir: str | os.PathLike) -> Any:
    """A TensorBoard ``SummaryWriter`` on ``log_dir`` (see :func:`require_tensorboard`)."""
    return require_tensorboard()(log_dir=str(log_dir), flush_secs=10)


def log_validation(log_dir: str | os.PathLike, report: Mapping[str, Any], step: int) -> None:
    """Add an evaluation's figures (``EvalReport.to_dict()``: the held-out loss, the mean and per-category
    errors) to the TensorBoard log in ``log_dir`` at ``step`` (the training's last iteration)."""
    figures: dict[str, Any] = {
        "validation/heldout_loss": report.get("heldout_loss"),
        "validation/chance_loss": report.get("chance_loss"),
        "validation/mean_t_cm": report.get("mean_t_cm"),
        "validation/mean_R_deg": report.get("mean_R_deg"),
    }
    for c in report.get("categories", []):
        for key in ("t_cm", "R_deg", "baseline_t_cm", "baseline_R_deg"):
            figures[f"validation/{key}/{c['category']}"] = c.get(key)
    writer = summary_writer(log_dir)
    try:
        for tag, v in figures.items():
            if isinstance(v, (int, float)) and math.isfinite(v):
                writer.add_scalar(tag, float(v), step)
    finally:
        writer.close()


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


def train(
    scenes: Sequence[Scene],
    config: TrainConfig | None = None,
    encoder: Encoder | None = None,
    seed: int = 0,
    progress: bool = True,
    validation: Sequence[Scene] = (),
    log_dir: str | os.PathLike | None = None,
    device: str | torch.device | None = None,
) -> ScoreModel:
    """Train a :class:`ScoreModel` on example arrangements (every pose must be known).

    ``validation``: held-out scenes (not trained on) whose energies become the trust reference that
    placements are judged against; without them the training scenes' energies are used.
    ``log_dir``: write a TensorBoard log there, every iteration's loss (``train/loss``, the InfoNCE loss
    with its regularisers; ``train/infonce`` alone) and learning rate (``train/lr``);
    :func:`log_validation` adds an evaluation's figures to it.
    ``device`` (default the CPU): where the model trains and stays; its weights start the same on every
    device (drawn on the CPU), its counter-examples' random numbers come from a generator there.
    """
    cfg = config or TrainConfig()
    dev = resolve_device(device)
    check_training_data(scenes)
    cached = _cached_path(scenes, cfg, encoder, seed, validation, dev) if log_dir is None else None
    if cached is not None and cached.exists():
        from .models.model import load

        return load(cached, device=dev)
    writer = summary_writer(log_dir) if log_dir is not None else None
    try:
        with torch_threads(1):  # tiny tensors; the training loop chooses threads for its batch
            model = _train(scenes, cfg, encoder, seed, progress, validation, writer, dev)
    finally:
        if writer is not None:
            writer.close()
    if cached is not None:
        model.save(cached)  # atomic: a worker training the same model at once writes the same file
    return model


#: the environment variable that :func:`model_cache` sets (worker processes inherit it)
MODEL_CACHE_ENV = "SCENESCORE_MODEL_CACHE"


@contextmanager
def model_cache(folder: str | os.PathLike) -> Iterator[Path]:
    """Within the block (and in the worker processes started in it), :func:`train` keeps each model it
    trains in ``folder`` and loads it instead of training it again when asked for the same one: the same
    scenes, validation scenes, settings, seed, device and torch thread count, with the default encoder (a
    model trained with another encoder, or with a TensorBoard log, is not kept). ``scenescore experiment
    all`` trains each of its experiments' shared models once this way. The folder is only read within the
    block: models from another version of the code are never mixed in."""
    path = Path(folder)
    path.mkdir(parents=True, exist_ok=True)
    before = os.environ.get(MODEL_CACHE_ENV)
    os.environ[MODEL_CACHE_ENV] = str(path)
    try:
        yield path
    finally:
        if before is None:
            os.environ.pop(MODEL_CACHE_ENV, None)
        else:
            os.environ[MODEL_CACHE_ENV] = before


def _cached_path(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    encoder: Encoder | None,
    seed: int,
    validation: Sequence[Scene],
    device: torch.device,
) -> Path | None:
    """Where :func:`model_cache` keeps the model of this training, None outside one or with an encoder."""
    folder = os.environ.get(MODEL_CACHE_ENV)
    if not folder or encoder is not None:
        return None
    what = {
        "scenes": [s.to_dict() for s in scenes],
        "validation": [s.to_dict() for s in validation],
        "config": cfg.to_dict(),
        "seed": int(seed),
        "device": str(device),
        # the thread count changes the trained weights (float rounding): a model trained in the main
        # process's threads is not the one a one-thread worker would train
        "threads": torch.get_num_threads(),
    }
    key = hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:24]
    return Path(folder) / f"{key}.ckpt"


def _train(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    encoder: Encoder | None,
    seed: int,
    progress: bool,
    validation: Sequence[Scene],
    writer: Any,
    device: torch.device,
) -> ScoreModel:
    torch.manual_seed(seed)
    gen = generator(seed, device)
    length, far = data_scale(scenes)
    length = cfg.length_scale or cfg.model.get("length_scale") or length
    reach = cfg.edge_range or cfg.model.get("edge_range") or (far if cfg.saturate_edges else None)
    encoder = encoder or FootprintEncoder()
    if isinstance(encoder, FootprintEncoder):
        encoder = encoder.scaled(length)  # sizes in the data's unit
    walls = cfg.walls if cfg.walls is not None else cfg.model.get("walls", stands_against_walls(scenes))
    model = ScoreModel.create(
        encoder,
        **{
            "round_invariant": cfg.round_invariant,
            "edge_encoder": cfg.edge_encoder,
            **cfg.model,
            "length_scale": length,
            "edge_range": reach,
            "walls": bool(walls),
            "wall_range": cfg.model.get("wall_range", cfg.wall_range) if walls else None,
            "wall_lines": bool(cfg.model.get("wall_lines", cfg.wall_lines)) and bool(walls),
        },
    ).to(device)
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
    shadow: list[torch.Tensor] | None = None  # the weights' moving average (TrainConfig.average)
    averaged_from = cfg.iterations // 2  # the first iteration in the average
    decay = max(min(cfg.average, 1 - 3 / max(cfg.iterations - averaged_from, 1)), 0.0)
    t0 = time.perf_counter()
    bar = tqdm(range(cfg.iterations), desc="train", disable=not progress, unit="it", dynamic_ncols=True)
    for it in bar:
        # the chains and the loss run on bs * k pose sets: threads chosen for that batch (re-chosen every
        # iteration, so a machine that gets busy mid-run is met with fewer), restored after
        with torch_threads(threads_for(bs * k)):
            rows = torch.randperm(s_count, generator=gen, device=gen.device).to(device)[:bs]
            buf.restart(
                (draw("rand", (s_count, k), gen, device) < cfg.restart)
                & torch.isin(torch.arange(s_count, device=device), rows)[:, None]
            )
            batch = data.index(rows)
            if cfg.feature_noise:
                noise = draw("randn", tuple(batch.feats.shape), gen, device, batch.feats.dtype)
                noise = noise * cfg.feature_noise
                batch = replace(batch, feats=batch.feats + noise)
            if cfg.size_noise:
                noise = draw("randn", tuple(batch.sizes.shape), gen, device, batch.sizes.dtype)
                batch = replace(
                    batch, sizes=batch.sizes + noise * (cfg.size_noise * model.config.length_scale)
                )
            rep = batch.repeat(k)  # (bs * k, ...)
            sizes = _BySize(batch.mask.sum(dim=1), cfg.group_sizes)
            model.net.eval()
            init = buf.poses[rows].reshape(bs * k, *buf.poses.shape[2:])
            movable = buf.movable[rows].reshape(bs * k, -1)

            energy = sizes.bound(model, rep, k)
            age = buf.age[rows].reshape(-1)
            neg, _ = langevin(
                energy, init, movable, rep.lo, rep.hi, chain_cfg, gen, age=age, run_steps=cfg.chain_steps
            )
            buf.poses[rows] = neg.reshape(bs, k, *neg.shape[1:])
            buf.age[rows] += cfg.chain_steps
            model.net.train()
            e_pos = sizes.bound(model, batch)(batch.poses)
            e_neg = energy(neg).reshape(bs, k)
            if cfg.perturbed:
                pert = perturbed_negatives(batch, cfg.perturbed, cfg, gen, model.config.length_scale)
                e_pert = sizes.bound(model, batch.repeat(cfg.perturbed), cfg.perturbed)(pert)
                e_pert = e_pert.reshape(bs, cfg.perturbed)
                e_neg = torch.cat([e_neg, e_pert], dim=1)
            e_real = e_neg.flatten()  # the counter-examples that are there, for the energies' L2
            if cfg.reanchored:
                poses, moved = reanchored_negatives(batch, cfg.reanchored, gen)
                e_move = sizes.bound(model, batch.repeat(cfg.reanchored), cfg.reanchored)(poses)
                e_move, valid = (
                    e_move.reshape(bs, cfg.reanchored),
                    moved.any(dim=1).reshape(bs, cfg.reanchored),
                )
                e_neg = torch.cat([e_neg, e_move.masked_fill(~valid, _ABSENT)], dim=1)
                e_real = torch.cat([e_real, e_move[valid]])
            loss = infonce = infonce_loss(e_pos, e_neg)
            if cfg.energy_reg:
                loss = loss + cfg.energy_reg * (e_pos.pow(2).mean() + e_real.pow(2).mean())
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
            if writer is not None:
                writer.add_scalar("train/loss", loss.item(), it)
                writer.add_scalar("train/infonce", infonce.item(), it)
                writer.add_scalar("train/lr", opt.param_groups[0]["lr"], it)
            sched.step()
            if decay and it >= averaged_from:
                shadow = _average(shadow, list(model.net.parameters()), decay)
            history.append(loss.item())
            if it % 20 == 0:
                bar.set_postfix(loss=f"{sum(history[-20:]) / len(history[-20:]):.3f}")
    model.net.eval()
    if shadow is not None:
        with torch.no_grad():
            for p, a in zip(model.net.parameters(), shadow, strict=True):
                p.copy_(a)
    model.info = {
        "train_config": cfg.to_dict(),
        "seed": seed,
        "scenes": s_count,
        "final_loss": float(sum(history[-50:]) / max(len(history[-50:]), 1)),
        "chance_loss": math.log(k + cfg.perturbed + cfg.reanchored + 1),
        "seconds": round(time.perf_counter() - t0, 2),
        # the learning curve: the mean loss over each block of 10 iterations
        "history": [
            round(sum(history[i : i + 10]) / len(history[i : i + 10]), 4) for i in range(0, len(history), 10)
        ],
    }
    model.info["trust"] = reference(model, scenes, validation, cfg.feature_noise).to_dict()
    return model


@torch.no_grad()
def _average(
    shadow: list[torch.Tensor] | None, params: list[torch.Tensor], decay: float
) -> list[torch.Tensor]:
    """One step of the weights' exponential moving average (started from the weights themselves)."""
    if shadow is None:
        return [p.detach().clone() for p in params]
    for a, p in zip(shadow, params, strict=True):
        a.mul_(decay).add_(p.detach(), alpha=1 - decay)
    return shadow


def heldout_loss(
    model: ScoreModel, scenes: Sequence[Scene], negatives: int = 16, seed: int = 0
) -> tuple[float, float]:
    """InfoNCE on ``scenes`` against fresh counter-examples (Langevin chains moving every movable object
    from uniform starts, the training schedule run to its end): ``(loss, chance)``; on the model's device."""
    gen = generator(seed, model.device)
    st = model.tensors(scenes)
    rep = st.repeat(negatives)
    movable = rep.mask & ~rep.fixed
    init = torch.where(
        movable[..., None],
        uniform_init((rep.mask.shape[0], rep.mask.shape[1]), rep.lo, rep.hi, gen, rep.poses.dtype),
        rep.poses,
    )

    def energy(x: torch.Tensor) -> torch.Tensor:
        return model.energy(x, rep)

    with torch_threads(threads_for(rep.mask.shape[0])):
        neg, _ = langevin(energy, init, movable, rep.lo, rep.hi, replace(TRAINING, final_descent=0), gen)
        with torch.no_grad():
            loss = infonce_loss(
                model.energy(st.poses, st), model.energy(neg, rep).reshape(len(scenes), negatives)
            )
    return float(loss), math.log(negatives + 1)


#: the fraction of the scenes ``scenescore train`` holds out for validation by default (``--val``)
VALIDATION_FRACTION = 0.15


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
