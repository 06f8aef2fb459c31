"""Cross-validation for little data: every scene validated on once, the final model trained on all.

With a dozen scenes, holding four out for validation trains the model on two thirds of the data and
judges it on four scenes. Instead, :func:`cross_validate` splits the scenes into ``folds`` parts, trains
one model on all but each part and places that part's objects back with it; the figures of the folds
are pooled into one report (:func:`pooled`), which stands for the final model trained on every scene
(:func:`~scenescore.workflow.training.train` does that, through :func:`train_and_cross_validate`,
which trains the final model's networks and the folds' in one pool of worker processes). It costs
``folds`` more trainings of one network each: a fold's model is the network an ensemble's member 0
would be (:data:`FOLD_MEMBERS`), so the figures stand for one network of the final model and leave out
what its members' mean adds. Under six scenes each fold is one scene (leave one scene out).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial

import numpy as np
import torch

from ..encoders import Encoder
from ..evaluation.report import CategoryErrors, EvalReport, evaluate
from ..learn.config import TrainConfig
from ..learn.data import VALIDATION_PER_CATEGORY
from ..learn.loop import fit
from ..learn.members import Group, Job, train_groups, training_jobs
from ..learn.run import Run
from ..models import ScoreModel
from ..runtime.devices import resolve_device
from ..runtime.workers import map_in_workers
from ..scene.scene import Scene, SceneError

__all__ = [
    "CROSS_VALIDATE_BELOW",
    "FOLDS",
    "LEAVE_ONE_OUT_FROM",
    "MIN_SCENES",
    "FOLD_MEMBERS",
    "fold_config",
    "fold_splits",
    "cross_validate",
    "train_and_cross_validate",
    "pooled",
    "folds_for",
]

#: data of fewer scenes than this is validated by cross-validation (by default), not by one hold-out
CROSS_VALIDATE_BELOW = 24
FOLDS = 3  # the folds cross-validation makes by default: a third of the scenes held out at a time
MIN_SCENES = 6  # fewer scenes are validated by leaving one scene out at a time (two per fold at three folds)
LEAVE_ONE_OUT_FROM = 3  # the fewest scenes validated at all: each fold's model trains on two or more
#: the networks of a fold's model, whatever the final model's: an ensemble's folds would multiply the
#: trainings that little data already multiplies by the folds
FOLD_MEMBERS = 1


def fold_config(cfg: TrainConfig) -> TrainConfig:
    """The settings a fold's model trains with: ``cfg`` in :data:`FOLD_MEMBERS` network."""
    return replace(cfg, members=FOLD_MEMBERS)


def _fits(n: int, folds: int) -> bool:
    """Whether ``n`` scenes make ``folds`` non-empty folds, each fold's model training on 2 or more."""
    return folds >= 2 and n >= folds and n - math.ceil(n / folds) >= 2


def folds_for(n: int, folds: int | None, fraction: float, heldout_given: bool) -> int:
    """How many folds a training of ``n`` scenes validates with, 0 for one hold-out (or none): ``folds``
    when given (1 meaning one hold-out); else, when no held-out scenes were given and ``fraction`` holds
    some out, :data:`FOLDS` for fewer than :data:`CROSS_VALIDATE_BELOW` scenes and at least
    :data:`MIN_SCENES`, and ``n`` (leave one scene out) for fewer than that and at least
    :data:`LEAVE_ONE_OUT_FROM`. SceneError for folds asked of data too small for them, or beside held-out scenes given or
    a ``fraction`` of 0."""
    if folds is not None and folds >= 2:
        if heldout_given or fraction == 0:
            why = "held-out scenes were given" if heldout_given else "the validation fraction is 0"
            raise SceneError(f"folds={folds}: cross-validation asked for, but {why}")
        if not _fits(n, folds):
            raise SceneError(f"folds={folds}: {n} scenes are too few (each fold's model trains on 2 or more)")
        return folds
    if heldout_given or fraction == 0 or folds is not None:
        return 0
    if LEAVE_ONE_OUT_FROM <= n < MIN_SCENES:  # leave one scene out: each fold's model trains on the rest
        return n
    return FOLDS if MIN_SCENES <= n < CROSS_VALIDATE_BELOW else 0


def fold_splits(scenes: Sequence[Scene], folds: int, seed: int = 0) -> list[tuple[list[Scene], list[Scene]]]:
    """``folds`` pairs ``(train, held_out)``: the scenes in a random order of ``seed``, cut into ``folds``
    parts of sizes differing by at most one, each held out once. ValueError when a part would be empty or
    leave fewer than two scenes to train on."""
    n = len(scenes)
    if not _fits(n, folds):
        raise ValueError(f"{n} scenes are too few for {folds}-fold cross-validation")
    order = np.random.default_rng(seed).permutation(n)
    parts = [set(p.tolist()) for p in np.array_split(order, folds)]
    return [
        ([s for i, s in enumerate(scenes) if i not in part], [s for i, s in enumerate(scenes) if i in part])
        for part in parts
    ]


def cross_validate(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    folds: int,
    *,
    encoder: Encoder | None = None,
    seed: int = 0,
    device: str | torch.device | None = None,
    progress: bool = True,
    say: Callable[[str], None] = print,
    jobs: int | None = 1,
) -> EvalReport:
    """Train one model per fold on the other folds' scenes (with ``cfg`` and ``seed``, as the final model
    trains, but one network: :func:`fold_config`) and place the fold's objects back with it, beside
    nearest neighbour on the same training scenes; the pooled report of every fold. ``jobs``: worker
    processes the folds' trainings and placements run in, side by side (the report the same whatever
    their number; None: one per usable core)."""
    job = Job(encoder=encoder, progress=progress, device=device, run=Run(jobs=jobs))
    return train_and_cross_validate(scenes, cfg, folds, job, seed=seed, say=say, final=False)[1]


def train_and_cross_validate(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    folds: int,
    job: Job,
    *,
    seed: int = 0,
    say: Callable[[str], None] = print,
    final: bool = True,
) -> tuple[ScoreModel | None, EvalReport]:
    """:func:`cross_validate`, the folds trained as ``job`` says (its encoder, device and progress), and
    with ``final`` the final model on every scene too, trained as ``job`` says in full (its state file,
    log, ...), its networks in one pool of ``job.run.jobs`` worker processes with the folds'
    (:func:`~scenescore.learn.members.train_groups`): ``(final model or None, pooled report)``. Each
    model is the one it would be trained alone."""
    splits = fold_splits(scenes, folds, seed)
    jobs = job.run.jobs
    fold_run = Run(jobs=jobs, init=job.run.init)
    fold_job = Job(encoder=job.encoder, progress=job.progress, device=job.device, run=fold_run)
    groups = [Group(scenes, job, "the final model")] if final else []
    for f, (train_s, held) in enumerate(splits):
        say(
            f"cross-validation fold {f + 1} of {folds}: training on {len(train_s)} scenes, placing {len(held)}"
        )
        label = f"fold {f + 1} of {folds}"
        groups.append(Group(train_s, replace(fold_job, validation=held), label, fold_config(cfg)))
    models = train_groups(fit, groups, cfg, seed, jobs)
    n = training_jobs(jobs, folds, resolve_device(job.device))
    place = partial(_place_fold, seed, job.progress and n == 1)
    tasks = [(m, held, train_s) for m, (train_s, held) in zip(models[-folds:], splits)]
    reports = map_in_workers(place, tasks, jobs=n, log=say, bar="folds" if job.progress else None)
    return (models[0] if final else None), pooled(reports)


def _place_fold(
    seed: int, progress: bool, task: tuple[ScoreModel, list[Scene], list[Scene]], log: Callable[[str], None]
) -> EvalReport:
    """A fold's held-out objects placed back with its model ``task = (model, held, train)``."""
    model, held, train_s = task
    return evaluate(model, held, train_s, seed=seed, progress=progress, per_category=VALIDATION_PER_CATEGORY)


def _weighted(values: Sequence[tuple[float | None, int]]) -> float | None:
    """The mean of values given with their counts, the missing and non-finite ones left out (None when
    none is left)."""
    kept = [(v, n) for v, n in values if v is not None and math.isfinite(v) and n > 0]
    total = sum(n for _, n in kept)
    return sum(v * n for v, n in kept) / total if total else None


def _number(value: float | None) -> float:
    return math.nan if value is None else float(value)


def pooled(reports: Sequence[EvalReport]) -> EvalReport:
    """The folds' reports as one: each category's errors over all its placements (weighted by the
    placements each fold made), the held-out loss over all scenes, the flags summed."""
    first = reports[0]
    names: list[str] = []
    for r in reports:
        names += [c.category for c in r.categories if c.category not in names]
    rows = []
    for name in names:
        cs = [c for r in reports for c in r.categories if c.category == name]
        row = CategoryErrors(
            name,
            sum(c.placements for c in cs),
            _number(_weighted([(c.t_cm, c.placements) for c in cs])),
            _weighted([(c.R_deg, c.placements) for c in cs]),
        )
        if first.baseline is not None:
            filled = [(c, c.placements - c.baseline_missed) for c in cs]
            row.baseline_t_cm = _weighted([(c.baseline_t_cm, n) for c, n in filled])
            row.baseline_R_deg = _weighted([(c.baseline_R_deg, n) for c, n in filled])
            row.baseline_missed = sum(c.baseline_missed for c in cs)
        rows.append(row)
    r_means = [r.R_deg for r in rows if r.R_deg is not None]
    return EvalReport(
        categories=rows,
        scenes=sum(r.scenes for r in reports),
        placements=sum(r.placements for r in reports),
        mean_t_cm=float(np.mean([r.t_cm for r in rows])),
        mean_R_deg=float(np.mean(r_means)) if r_means else None,
        heldout_loss=_number(_weighted([(r.heldout_loss, r.scenes) for r in reports])),
        chance_loss=first.chance_loss,
        seed=first.seed,
        baseline=first.baseline,
        flagged=sum(r.flagged for r in reports),
        unit=first.unit,
        folds=len(reports),
        examples=[e for r in reports for e in r.examples][:3],
    )
