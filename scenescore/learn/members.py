"""Training an ensemble (:func:`train_members`), or several models at once (:func:`train_groups`: a
final model and its cross-validation's folds): their networks one after another or in worker processes.

Each member is the single model of its own seed (:func:`~scenescore.models.ensemble.member_seed`),
trained on one torch thread, so its weights do not depend on the process it trains in: with ``jobs``
of 2 or more the networks train side by side in that many worker processes (:mod:`scenescore.runtime.workers`)
and each model is the one a single process trains, bit for bit, in about ``1 / jobs`` of the time on
free cores. Each worker writes its network to a checkpoint (no pickle) that this process reads back.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import torch

from ..encoders import Encoder
from ..errors import ConfigError
from ..models import ModelInfo, ScoreModel, load
from ..models.ensemble import EnsembleNet, member_seed, members_of
from ..models.trust import reference
from ..runtime.devices import resolve_device
from ..runtime.workers import Log, balanced_jobs, default_jobs, map_in_workers
from ..scene.scene import Scene
from .config import TrainConfig, derive
from .run import Run

__all__ = ["train_members", "train_groups", "member_state", "training_jobs", "Job", "Group"]

Train = Callable[..., ScoreModel]  # fit(scenes, cfg, seed=..., encoder=..., ...) as loop's


@dataclass(frozen=True)
class Job:
    """How :func:`~scenescore.learn.fit` was asked to train (everything but the data, the settings and
    the seed), passed on to each member's training."""

    encoder: Encoder | None = None
    progress: bool = True
    validation: Sequence[Scene] = ()
    device: str | torch.device | None = None
    run: Run = field(default_factory=Run)


def member_state(state: str | os.PathLike, member: int) -> Path:
    """Where member ``member`` of an ensemble keeps its training state: beside ``state``."""
    path = Path(state)
    return path.with_name(f"{path.stem}.member{member}{path.suffix}")


def training_jobs(jobs: int | None, tasks: int, device: torch.device) -> int:
    """The worker processes ``tasks`` trainings (an ensemble's members, cross-validation's folds) run in:
    ``jobs``, at most one per task; by default one per usable core
    (:func:`~scenescore.runtime.workers.default_jobs`), and on a CPU up to two per core where the tasks
    then end sooner (:func:`~scenescore.runtime.workers.balanced_jobs`: three members on two cores side
    by side); 1 (this process) inside a worker process, which cannot start workers of its own."""
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ConfigError(
            f"train: jobs: expected a whole number of worker processes, 1 or more, got {jobs!r}"
        )
    if multiprocessing.current_process().daemon:
        return 1
    if jobs is not None:
        return min(jobs, tasks)
    if device.type == "cpu":
        return balanced_jobs(tasks, default_jobs(device))
    return min(default_jobs(device), tasks)


@dataclass(frozen=True)
class Group:
    """One model to train: on ``scenes``, as ``job`` says (its ``validation`` its trust reference), named
    ``label`` in the log lines of worker processes ("fold 2 of 3"; empty: the model); ``config``: its
    own settings instead of the pool's (cross-validation's folds: one network each)."""

    scenes: Sequence[Scene]
    job: Job
    label: str = ""
    config: TrainConfig | None = None


def train_members(one: Train, scenes: Sequence[Scene], cfg: TrainConfig, seed: int, job: Job) -> ScoreModel:
    """``cfg.members`` networks, each trained by ``one`` (:func:`~scenescore.learn.loop.train`, which
    hands ensembles here) as the single model of its seed (kept in and loaded from the cache as that
    model, resumable from its own state file, :func:`member_state`), in ``jobs`` worker processes
    (:func:`training_jobs`); then their mean energy, its trust reference its own."""
    return train_groups(one, [Group(scenes, job)], cfg, seed, job.run.jobs)[0]


def train_groups(
    one: Train, groups: Sequence[Group], cfg: TrainConfig, seed: int, jobs: int | None = 1
) -> list[ScoreModel]:
    """Each group's model, with ``cfg`` and ``seed``: one network, or an ensemble of ``cfg.members``
    (:func:`train_members`). Every network of every group trains in one pool of ``jobs`` worker
    processes (:func:`training_jobs`), so that a final model and its cross-validation's folds train side
    by side; each network is the one it would be alone, whatever the number of processes."""
    dev = resolve_device(groups[0].job.device)
    cfgs = [g.config or cfg for g in groups]
    tasks = [(g, m, member_seed(seed, m)) for g, c in enumerate(cfgs) for m in range(c.runs)]
    n = training_jobs(jobs, len(tasks), dev)
    if n == 1:
        nets = [_member(one, groups[g].scenes, cfgs[g], groups[g].job, m, s) for g, m, s in tasks]
    else:
        if groups[0].job.progress:
            what = f"{cfg.runs} members" if len(groups) == 1 else f"{len(tasks)} networks"
            print(f"training {what} in {n} worker processes", file=sys.stderr)
        with tempfile.TemporaryDirectory(prefix="scenescore-members-") as tmp:
            quiet = [replace(g, job=replace(g.job, progress=False), config=c) for g, c in zip(groups, cfgs)]
            work = partial(_member_in_worker, one, quiet, tmp)
            bar = "members" if len(groups) == 1 else "trainings"
            paths = map_in_workers(work, tasks, jobs=n, log=_stderr, bar=bar)
            # each with the encoder its training derived (a footprint encoder reads sizes in the data's
            # unit), not the one given: a checkpoint read with that would encode the objects otherwise
            used = [derive(_one_run(c), g.scenes, g.job.encoder).encoder for g, c in zip(groups, cfgs)]
            nets = [load(p, encoder=used[g], device=dev) for p, (g, _, _) in zip(paths, tasks)]
    models, start = [], 0
    for grp, c in zip(groups, cfgs):
        mine, start = nets[start : start + c.runs], start + c.runs
        models.append(mine[0] if c.runs == 1 else _mean_of(mine, c, seed, grp.scenes, grp.job.validation))
    return models


def _member(one: Train, scenes: Sequence[Scene], cfg: TrainConfig, job: Job, m: int, seed: int) -> ScoreModel:
    """Member ``m`` of the ensemble of ``cfg`` (the whole model for one network): the single model of
    ``seed``, trained in this process."""
    alone = cfg.runs == 1
    if job.progress and not alone:
        print(f"member {m + 1} of {cfg.runs} (seed {seed})", file=sys.stderr)
    run = job.run
    if not alone:  # each member logs and keeps its state beside the others'
        run = replace(
            run,
            log_dir=None if run.log_dir is None else Path(run.log_dir) / f"member{m}",
            state=None if run.state is None else member_state(run.state, m),
        )
    return one(
        scenes,
        _one_run(cfg),
        seed=seed,
        encoder=job.encoder,
        validation=job.validation,
        device=job.device,
        progress=job.progress,
        run=replace(run, jobs=1),
    )


def _member_in_worker(
    one: Train, groups: Sequence[Group], tmp: str, task: tuple[int, int, int], log: Log
) -> str:
    """In a worker: member ``m`` of group ``g`` (``task = (g, m, seed)``, the group's ``config`` its
    settings) trained and written to a checkpoint in ``tmp``; its path."""
    g, m, seed = task
    grp = groups[g]
    cfg = grp.config
    assert cfg is not None  # set by train_groups
    model = _member(one, grp.scenes, cfg, grp.job, m, seed)
    path = str(Path(tmp) / f"group{g}-member{m}.ckpt")
    model.save(path)
    who = f"member {m + 1} of {cfg.runs} (seed {seed})" if cfg.runs > 1 else ""
    name = " ".join(x for x in (grp.label, who) if x) or "the model"
    log(f"{name} trained in {model.info.seconds or 0:.0f} s")
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
        compiled=infos[0].compiled,
        history=[round(sum(c) / len(c), 4) for c in zip(*curves)],
        members=[{"seed": i.seed, "final_loss": i.final_loss, "seconds": i.seconds} for i in infos],
        init=infos[0].init,
    )
    model.info.trust = reference(model, scenes, validation, cfg.feature_noise)
    return model


def _one_run(cfg: TrainConfig) -> TrainConfig:
    """The settings of one of ``cfg``'s runs: a seeds ensemble's member, else ``cfg`` itself (a snapshot
    ensemble is one run)."""
    return replace(cfg, members=1) if cfg.runs > 1 else cfg


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)
