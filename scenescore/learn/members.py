"""Training an ensemble (:func:`train_members`): its members, one after another or in worker processes.

Each member is the single model of its own seed (:func:`~scenescore.models.ensemble.member_seed`),
trained on one torch thread, so its weights do not depend on the process it trains in: with ``jobs``
of 2 or more the members train side by side in that many worker processes (:mod:`scenescore.workers`)
and the ensemble is the one a single process trains, bit for bit, in about ``1 / jobs`` of the time on
free cores. Each worker writes its member to a checkpoint (no pickle) that this process reads back.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import torch

from ..devices import resolve_device
from ..encoders import Encoder
from ..errors import ConfigError
from ..models import ModelInfo, ScoreModel, load
from ..models.ensemble import EnsembleNet, member_seed, members_of
from ..models.trust import reference
from ..scene import Scene
from ..workers import Log, default_jobs, map_in_workers
from .config import TrainConfig
from .training_state import SAVE_EVERY

__all__ = ["train_members", "member_state", "training_jobs", "Run"]

Train = Callable[..., ScoreModel]  # train(scenes, cfg, encoder, seed, progress, validation, ...) as loop's


@dataclass(frozen=True)
class Run:
    """How :func:`~scenescore.learn.loop.train` was asked to run (everything but the data, the settings
    and the seed), passed on to each member's training."""

    encoder: Encoder | None = None
    progress: bool = True
    validation: Sequence[Scene] = ()
    log_dir: str | os.PathLike | None = None
    device: str | torch.device | None = None
    cache: str | os.PathLike | None = None
    state: str | os.PathLike | None = None
    resume: bool = False
    save_every: int = SAVE_EVERY
    keep_state: bool = False


def member_state(state: str | os.PathLike, member: int) -> Path:
    """Where member ``member`` of an ensemble keeps its training state: beside ``state``."""
    path = Path(state)
    return path.with_name(f"{path.stem}.member{member}{path.suffix}")


def training_jobs(jobs: int | None, tasks: int, device: torch.device) -> int:
    """The worker processes ``tasks`` trainings (an ensemble's members, cross-validation's folds) run in:
    ``jobs``, at most one per task, by default one per usable core
    (:func:`~scenescore.workers.default_jobs`); 1 (this process) inside a worker process, which cannot
    start workers of its own."""
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ConfigError(
            f"train: jobs: expected a whole number of worker processes, 1 or more, got {jobs!r}"
        )
    if multiprocessing.current_process().daemon:
        return 1
    return min(default_jobs(device) if jobs is None else jobs, tasks)


def train_members(
    one: Train, scenes: Sequence[Scene], cfg: TrainConfig, seed: int, run: Run, jobs: int | None = 1
) -> ScoreModel:
    """``cfg.members`` networks, each trained by ``one`` (:func:`~scenescore.learn.loop.train`, which
    hands ensembles here) as the single model of its seed (kept in and loaded from the cache as that
    model, resumable from its own state file, :func:`member_state`), in ``jobs`` worker processes
    (:func:`training_jobs`); then their mean energy, its trust reference its own."""
    dev = resolve_device(run.device)
    n = training_jobs(jobs, cfg.members, dev)
    seeds = [member_seed(seed, m) for m in range(cfg.members)]
    if n == 1:
        models = [_member(one, scenes, cfg, run, m, s) for m, s in enumerate(seeds)]
    else:
        if run.progress:
            print(f"training {cfg.members} members in {n} worker processes", file=sys.stderr)
        with tempfile.TemporaryDirectory(prefix="scenescore-members-") as tmp:
            quiet = replace(run, progress=False)
            work = partial(_member_in_worker, one, scenes, cfg, quiet, tmp)
            paths = map_in_workers(work, list(enumerate(seeds)), jobs=n, log=_stderr, bar="members")
            models = [load(p, encoder=run.encoder, device=dev) for p in paths]
    return _mean_of(models, cfg, seed, scenes, run.validation)


def _member(one: Train, scenes: Sequence[Scene], cfg: TrainConfig, run: Run, m: int, seed: int) -> ScoreModel:
    """Member ``m`` of the ensemble of ``cfg``: the single model of ``seed``, trained in this process."""
    if run.progress:
        print(f"member {m + 1} of {cfg.members} (seed {seed})", file=sys.stderr)
    return one(
        scenes,
        replace(cfg, members=1),
        run.encoder,
        seed,
        run.progress,
        run.validation,
        None if run.log_dir is None else Path(run.log_dir) / f"member{m}",
        run.device,
        run.cache,
        None if run.state is None else member_state(run.state, m),
        run.resume,
        run.save_every,
        run.keep_state,
    )


def _member_in_worker(
    one: Train, scenes: Sequence[Scene], cfg: TrainConfig, run: Run, tmp: str, task: tuple[int, int], log: Log
) -> str:
    """In a worker: member ``task = (m, seed)`` trained and written to a checkpoint in ``tmp``; its path."""
    m, seed = task
    model = _member(one, scenes, cfg, run, m, seed)
    path = str(Path(tmp) / f"member{m}.ckpt")
    model.save(path)
    log(f"member {m + 1} of {cfg.members} (seed {seed}) trained in {model.info.seconds or 0:.0f} s")
    return path


def _mean_of(
    models: Sequence[ScoreModel],
    cfg: TrainConfig,
    seed: int,
    scenes: Sequence[Scene],
    validation: Sequence[Scene],
) -> ScoreModel:
    """The ensemble of the trained ``models``: their networks' mean energy, its info and trust reference."""
    infos = [x.info for x in models]
    curves = [i.history or [] for i in infos]
    model = ScoreModel(EnsembleNet([n for x in models for n in members_of(x.net)]), models[0].encoder)
    model.info = ModelInfo(
        train_config=cfg.to_dict(),
        seed=seed,
        scenes=len(scenes),
        final_loss=sum(i.final_loss or 0.0 for i in infos) / len(infos),
        chance_loss=infos[0].chance_loss,
        seconds=round(sum(i.seconds or 0.0 for i in infos), 2),
        history=[round(sum(c) / len(c), 4) for c in zip(*curves)],
        members=[{"seed": i.seed, "final_loss": i.final_loss, "seconds": i.seconds} for i in infos],
    )
    model.info.trust = reference(model, scenes, validation, cfg.feature_noise)
    return model


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)
