"""Training the energy with InfoNCE against Langevin counter-examples (:func:`fit`).

Each iteration draws a batch of scenes, puts noise on their node inputs, advances their persistent
counter-example chains a few steps (:class:`~scenescore.learn.negatives.ChainBuffer`), scores the true
scenes against those and the other counter-examples, and takes one optimiser step on the loss
(:func:`~scenescore.learn.losses.training_loss`). The trained model is the moving average of the weights
over the second half of training.
"""

from __future__ import annotations

import copy
import math
import os
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import torch
from tqdm.auto import tqdm

from ..encoders import Encoder
from ..models import EnergyNet, ModelInfo, SceneTensors, ScoreModel, load
from ..models.compiled import compiled_of, compiling
from ..models.ensemble import EnsembleNet
from ..models.trust import reference
from ..runtime.devices import draw, generator, resolve_device
from ..runtime.threads import torch_threads
from ..scene.scene import Scene
from .cache import cached_path
from .config import Derived, TrainConfig, averaging, compiles, derive
from .data import check_training_data
from .logs import summary_writer
from .losses import ABSENT, training_loss
from .members import Job, train_members
from .negatives import ChainBuffer, perturbed_negatives, reanchored_negatives
from .run import Run
from .size_groups import SizeGroups
from .training_state import Progress, Trainer, read_state, state_key, write_state
from .warm_start import Start

__all__ = ["fit", "moving_average", "Training"]


def fit(
    scenes: Sequence[Scene],
    config: TrainConfig | None = None,
    *,
    seed: int = 0,
    encoder: Encoder | None = None,
    validation: Sequence[Scene] = (),
    device: str | torch.device | None = None,
    progress: bool = True,
    run: Run | None = None,
) -> ScoreModel:
    """Train a :class:`ScoreModel` on example arrangements (every pose must be known).

    ``validation``: held-out scenes (not trained on) whose energies become the trust reference that
    placements are judged against; without them the training scenes' energies are used.
    ``device`` (default the CPU): where the model trains and stays; its weights start the same on every
    device (drawn on the CPU), its counter-examples' random numbers come from a generator there.
    ``run``: where the run logs, caches and keeps its resumable state, and the worker processes an
    ensemble's members train in, and the model it starts from (:class:`~scenescore.learn.run.Run`;
    default: none of these).

    This is the training alone; :func:`scenescore.train` (:mod:`scenescore.workflow`) also holds scenes
    out, evaluates, calibrates tidying and saves, as ``scenescore train`` does.
    """
    cfg = config or TrainConfig()
    run = run or Run()
    dev = resolve_device(device)
    check_training_data(scenes)
    start = run.start
    if start is not None:  # refused here, before any worker process starts
        d = derive(cfg, scenes, encoder)
        start.check(d.energy, d.encoder)
    if cfg.runs > 1:
        return train_members(fit, scenes, cfg, seed, Job(encoder, progress, validation, device, run))
    cached = None
    digest = start.digest() if start is not None else None
    if run.log_dir is None:
        cached = cached_path(run.cache, scenes, cfg, encoder, seed, validation, dev, digest)
    if cached is not None and cached.exists():
        return load(cached, device=dev)
    from_state = _from_state(run.state, run.resume)
    writer = summary_writer(run.log_dir) if run.log_dir is not None else None
    try:
        with torch_threads(1):  # large batches run in pieces side by side (EnergyNet.forward)
            model = _fit(
                scenes, cfg, encoder, seed, progress, validation, writer, dev, run, from_state, start
            )
    finally:
        if writer is not None:
            writer.close()
    if run.state is not None and not run.keep_state:
        Path(run.state).unlink(missing_ok=True)
    if cached is not None:
        Path(cached).parent.mkdir(parents=True, exist_ok=True)
        model.save(cached)  # atomic: a worker training the same model at once writes the same file
    return model


def _from_state(state: str | os.PathLike | None, resume: bool) -> bool:
    """Whether the run goes on from ``state``: when resuming and the file exists. Either way where it
    differs from what was asked is said: no state to resume from, or an earlier one to be overwritten."""
    if state is None:
        return False
    there = Path(state).exists()
    if resume and not there:
        print(f"note: no training state at {state} yet; training from the start", file=sys.stderr)
    elif there and not resume:
        print(
            f"note: {state} holds the training state of an earlier run; training from the start and "
            "overwriting it (resume to go on from it)",
            file=sys.stderr,
        )
    return resume and there


class Training:
    """One training run from its start: a new model of ``cfg`` for ``scenes`` on ``device``, its
    scenes' tensors, counter-example chains, optimiser, schedule and random streams (seeded by ``seed``),
    and where it stands (:attr:`done`); :meth:`step` runs one iteration, within :meth:`session` (the
    network compiled there when :attr:`compiled`); ``start``: the weights it starts from (None: drawn
    by the seed)."""

    def __init__(
        self,
        scenes: Sequence[Scene],
        cfg: TrainConfig,
        encoder: Encoder | None,
        seed: int,
        device: torch.device,
        start: Start | None = None,
    ):
        torch.manual_seed(seed)
        self.cfg, self.device = cfg, device
        gen = generator(seed, device)
        self.derived = d = derive(cfg, scenes, encoder)
        net = EnergyNet(d.energy)
        if start is not None:
            start.check(d.energy, d.encoder)
            net.load_state_dict(dict(start.weights))
        self.model = model = ScoreModel(net, d.encoder).to(device)
        self.data = model.tensors(scenes)
        buf = ChainBuffer(self.data, cfg.negatives, cfg, gen)
        opt = torch.optim.AdamW(model.net.parameters(), lr=d.lr, weight_decay=cfg.weight_decay)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(
            opt, T_max=max(cfg.iterations, 1), eta_min=cfg.lr_final
        )
        self.trainer = Trainer(model, opt, sched, buf, gen)
        self.done = Progress()
        self.compiled = compiles(cfg, d, device.type)

    @contextmanager
    def session(self) -> Iterator[None]:
        """The block within which :meth:`step` runs: on one torch thread, as :func:`fit` trains (large
        batches go in pieces side by side), the network's passes compiled if they are (a compiled graph
        is kept for one thread count: the pieces' and the caller's must agree)."""
        with torch_threads(1), compiling(self.model.net, self.device.type, self.compiled):
            yield

    def step(self, writer: Any = None) -> None:
        """The next iteration: one optimiser step, the schedule's, the weights' average, the history."""
        _iterate(self.trainer, self.cfg, self.derived, self.data, self.done, writer, self.done.iteration)
        self.done.iteration += 1

    def cycle(self, progress: bool = True) -> tuple[list[torch.Tensor], float]:
        """One snapshot cycle after the run (``ensemble: snapshots``): ``snapshot_cycle x iterations``
        more iterations from the weights where they stand, the learning rate restarted and annealed
        again, averaged over the cycle's second half -> ``(the averaged weights, the cycle's final
        loss)``. The run's own :attr:`done` is left as it is."""
        length = max(round(self.cfg.snapshot_cycle * self.cfg.iterations), 1)
        t = self.trainer
        for group in t.opt.param_groups:
            group["lr"] = group["initial_lr"] = self.derived.lr
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(t.opt, T_max=length, eta_min=self.cfg.lr_final)
        start, decay = averaging(self.cfg.average, length)
        d = replace(self.derived, averaged_from=start, decay=decay)
        own = Progress()
        for it in tqdm(range(length), desc="snapshot", disable=not progress, unit="it", leave=False):
            _iterate(replace(t, sched=sched), self.cfg, d, self.data, own, None, it)
        return _averaged(self.model.net, own.shadow), _final_loss(own.history)


def _fit(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    encoder: Encoder | None,
    seed: int,
    progress: bool,
    validation: Sequence[Scene],
    writer: Any,
    device: torch.device,
    run: Run,
    resume: bool,
    start: Start | None,
) -> ScoreModel:
    """The training itself, on data :func:`fit` checked: a new model, trained, its weights averaged,
    its :class:`~scenescore.models.ModelInfo` filled (``writer``: a TensorBoard writer, or None). The
    training state goes to ``run.state`` every ``run.save_every`` iterations and at the end; ``resume``:
    start from the state there (which must exist)."""
    state, save_every = run.state, run.save_every
    tr = Training(scenes, cfg, encoder, seed, device, start)
    key = state_key(scenes, cfg, tr.derived.encoder, seed, device, start.digest() if start else None)
    if resume and state is not None:
        tr.done = read_state(state, key, tr.trainer)
    done = tr.done
    t0 = time.perf_counter() - done.seconds
    bar = tqdm(
        total=cfg.iterations,
        initial=done.iteration,
        desc="train (compiled)" if tr.compiled else "train",
        disable=not progress,
        unit="it",
        dynamic_ncols=True,
    )
    with tr.session(), bar:
        while done.iteration < cfg.iterations:
            tr.step(writer)
            done.seconds = time.perf_counter() - t0
            if state is not None and (done.iteration % save_every == 0 or done.iteration == cfg.iterations):
                write_state(state, key, done, tr.trainer)
            if done.iteration % 20 == 1:
                bar.set_postfix(loss=f"{sum(done.history[-20:]) / len(done.history[-20:]):.3f}")
            bar.update()
        weights = [_averaged(tr.model.net, done.shadow)]
        cycles = [tr.cycle(progress) for _ in range(cfg.snapshots)]
    model = tr.model
    model.net.eval()
    if cycles:
        model = _snapshot_ensemble(model, weights + [w for w, _ in cycles])
    else:
        _load_weights(model.net, weights[0])
    final = _final_loss(done.history)
    model.info = ModelInfo(
        train_config=cfg.to_dict(),
        seed=seed,
        scenes=len(scenes),
        final_loss=final,
        chance_loss=math.log(tr.derived.candidates),
        seconds=round(time.perf_counter() - t0, 2),
        compiled=tr.compiled,
        # the learning curve: the mean loss over each block of 10 iterations
        history=[
            round(sum(done.history[i : i + 10]) / len(done.history[i : i + 10]), 4)
            for i in range(0, len(done.history), 10)
        ],
        members=[
            {"seed": seed, "snapshot": k, "final_loss": loss}
            for k, loss in enumerate([final] + [c for _, c in cycles])
        ]
        if cycles
        else None,
        init=None if start is None else {"source": start.source, "digest": start.digest()},
    )
    model.info.trust = reference(model, scenes, validation, cfg.feature_noise)
    return model


def _final_loss(history: Sequence[float]) -> float:
    """A run's final loss: the mean over its last 50 iterations."""
    return float(sum(history[-50:]) / max(len(history[-50:]), 1))


def _averaged(net: torch.nn.Module, shadow: list[torch.Tensor] | None) -> list[torch.Tensor]:
    """The trained weights: the moving average where there is one, else the last iterate (copies)."""
    return [a.detach().clone() for a in (shadow if shadow is not None else net.parameters())]


@torch.no_grad()
def _load_weights(net: torch.nn.Module, weights: Sequence[torch.Tensor]) -> None:
    for p, a in zip(net.parameters(), weights, strict=True):
        p.copy_(a)


def _snapshot_ensemble(model: ScoreModel, weights: Sequence[list[torch.Tensor]]) -> ScoreModel:
    """The ensemble of one run's snapshots: a copy of ``model``'s network per set of ``weights``."""
    assert isinstance(model.net, EnergyNet)  # a run trains one network
    nets: list[EnergyNet] = []
    for w in weights:
        net = copy.deepcopy(model.net)
        _load_weights(net, w)
        nets.append(net.eval())
    return ScoreModel(EnsembleNet(nets), model.encoder)


def _iterate(
    t: Trainer, cfg: TrainConfig, d: Derived, data: SceneTensors, run: Progress, writer: Any, it: int
) -> None:
    """Iteration ``it``: one optimiser step on the loss, the learning rate's step, the weights' moving
    average and the loss history updated."""
    # one torch thread (train's setting): the network takes a large batch in pieces that run side by
    # side on the cores left free (EnergyNet.forward), so the weights never depend on the load
    loss, infonce = _loss(t.model, cfg, d, data, t.buf, t.gen, t.buf.device)
    if not torch.isfinite(loss):
        raise FloatingPointError(f"train: loss became {loss.item()} at iteration {it}; lower TrainConfig.lr")
    t.opt.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(t.model.net.parameters(), 10.0)
    t.opt.step()
    if writer is not None:
        writer.add_scalar("train/loss", loss.item(), it)
        writer.add_scalar("train/infonce", infonce.item(), it)
        writer.add_scalar("train/lr", t.opt.param_groups[0]["lr"], it)
    t.sched.step()
    if d.decay and it >= d.averaged_from:
        run.shadow = moving_average(run.shadow, list(t.model.net.parameters()), d.decay)
    run.history.append(loss.item())


def _loss(
    model: ScoreModel,
    cfg: TrainConfig,
    d: Derived,
    data: SceneTensors,
    buf: ChainBuffer,
    gen: torch.Generator,
    device: torch.device,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One iteration's ``(loss, infonce)``: a batch drawn with noise on its inputs, its chains advanced
    (with the network in eval mode), the true scenes scored against every counter-example."""
    k = cfg.negatives
    rows, batch = _batch(cfg, data, buf, gen, device, d.batch_scenes, model.config.length_scale)
    rep = batch.repeat(k)  # (batch * k, ...)
    sizes = SizeGroups(batch.mask.sum(dim=1), cfg.group_sizes)
    model.net.eval()
    # the chains need the poses' gradient alone: large batches go in pieces, side by side
    neg = buf.advance(rows, sizes.bound(model, rep, k, weight_grads=False), rep, d.chain, cfg.chain_steps)
    model.net.train()
    passes = [(batch.poses, batch, 1), (neg, rep, k)]
    if cfg.perturbed:
        pert = perturbed_negatives(batch, cfg.perturbed, cfg, gen, model.config.length_scale)
        passes.append((pert, batch.repeat(cfg.perturbed), cfg.perturbed))
    if cfg.reanchored:
        poses, moved = reanchored_negatives(batch, cfg.reanchored, gen)
        passes.append((poses, batch.repeat(cfg.reanchored), cfg.reanchored))
    e_pos, *e_counter = _pass_energies(model, batch, sizes, passes)
    bs = batch.mask.shape[0]
    e_neg = torch.cat(e_counter[: 2 if cfg.perturbed else 1], dim=1)  # the chains', the perturbed
    e_real = e_neg.flatten()  # the counter-examples that are there, for the energies' L2
    if cfg.reanchored:  # a scene too small to re-anchor an object in scores ABSENT there
        e_move, valid = e_counter[-1], moved.any(dim=1).reshape(bs, cfg.reanchored)
        e_neg = torch.cat([e_neg, e_move.masked_fill(~valid, ABSENT)], dim=1)
        e_real = torch.cat([e_real, e_move[valid]])
    return training_loss(cfg, model, e_pos[:, 0], e_neg, e_real, neg, rep)


def _batch(
    cfg: TrainConfig,
    data: SceneTensors,
    buf: ChainBuffer,
    gen: torch.Generator,
    device: torch.device,
    size: int,
    length_scale: float,
) -> tuple[torch.Tensor, SceneTensors]:
    """``size`` scenes drawn for one iteration: their rows of ``data`` and their tensors with noise on
    the features and the sizes; a share (``cfg.restart``) of their chains restarted first."""
    count = data.mask.shape[0]
    rows = torch.randperm(count, generator=gen, device=gen.device).to(device)[:size]
    buf.restart(
        (draw("rand", (count, cfg.negatives), gen, device) < cfg.restart)
        & torch.isin(torch.arange(count, device=device), rows)[:, None]
    )
    batch = data.index(rows)
    if cfg.feature_noise:
        noise = draw("randn", tuple(batch.feats.shape), gen, device, batch.feats.dtype)
        noise = noise * cfg.feature_noise
        batch = replace(batch, feats=batch.feats + noise)
    if cfg.size_noise:
        noise = draw("randn", tuple(batch.sizes.shape), gen, device, batch.sizes.dtype)
        batch = replace(batch, sizes=batch.sizes + noise * (cfg.size_noise * length_scale))
    return rows, batch


def _pass_energies(
    model: ScoreModel,
    batch: SceneTensors,
    sizes: SizeGroups,
    passes: Sequence[tuple[torch.Tensor, SceneTensors, int]],
) -> list[torch.Tensor]:
    """The energies ``(B, k)`` of each pass ``(poses (B * k, N, 3), the scenes repeated k times, k)``
    of the batch's ``B`` scenes, differentiable in the weights: one call per pass, or, where the network's
    passes are compiled, one call for them all (fewer, larger calls, whose pieces run side by side): the
    same energies to float rounding."""
    bs = batch.mask.shape[0]
    if compiled_of(model.net) is None:
        return [sizes.bound(model, st, k)(x).reshape(bs, k) for x, st, k in passes]
    m = sum(k for _, _, k in passes)
    x = torch.cat([x.reshape(bs, k, *x.shape[1:]) for x, _, k in passes], dim=1).flatten(0, 1)
    e = sizes.bound(model, batch.repeat(m), m)(x).reshape(bs, m)
    return list(e.split([k for _, _, k in passes], dim=1))


@torch.no_grad()
def moving_average(
    shadow: list[torch.Tensor] | None, params: list[torch.Tensor], decay: float
) -> list[torch.Tensor]:
    """One step of the weights' exponential moving average (started from the weights themselves)."""
    if shadow is None:
        return [p.detach().clone() for p in params]
    for a, p in zip(shadow, params, strict=True):
        a.mul_(decay).add_(p.detach(), alpha=1 - decay)
    return shadow
