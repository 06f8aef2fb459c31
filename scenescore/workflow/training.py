"""The training workflow, as ``scenescore train`` runs it and ``ss.train`` returns it (:func:`train`).

Hold scenes out, train on the rest, refuse a model that learned nothing, evaluate on the held-out
scenes (with little data: train on every scene and cross-validate, :mod:`~scenescore.workflow.crossval`),
draw the learning curve, calibrate what a tidying move must gain, save the checkpoint and the report.
The command line only reads its files and calls :func:`train`, so the model a script gets from
``ss.train(scenes, seed=s)`` is the one ``scenescore train data.jsonl --seed s`` saves.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch

from ..encoders import Encoder
from ..evaluation.report import EvalReport, evaluate
from ..learn.config import TrainConfig
from ..learn.data import (
    VALIDATION_FRACTION,
    VALIDATION_PER_CATEGORY,
    check_training_data,
    split_validation,
)
from ..learn.logs import log_validation
from ..learn.loop import fit
from ..learn.members import Group, Job, member_state, train_groups
from ..learn.run import Run
from ..models import ScoreModel
from ..models.freedom import describe_spreads
from ..planning.tidying.calibration import defer
from ..scene.outputs import atomic_write_text
from ..scene.scene import Scene, write_jsonl
from ..scene.units import ShownUnit, declared_unit
from ..viz.plot import training_figure
from .crossval import fold_config, folds_for, train_and_cross_validate

__all__ = ["NothingLearned", "Outputs", "Validation", "holdout", "train"]

Log = Callable[[str], None]
TIDY_SCENES = 16  # training scenes calibrated on when none are held out
# with this many scenes or fewer, train suggests placing with the examples' relations and, for a
# training from random weights, starting from the shipped arrangement prior
FEW_SCENES = 12


class NothingLearned(ValueError):
    """The training loss never fell below chance: the model tells the data from its counter-examples no
    better than a constant energy does."""

    def __init__(self, final_loss: float, chance_loss: float):
        self.final_loss, self.chance_loss = final_loss, chance_loss
        super().__init__(
            f"the training loss ({final_loss:.3f}) never fell below chance ({chance_loss:.3f}): the model "
            "learned nothing; train longer (TrainConfig.iterations) or pass force=True to keep it anyway"
        )


def holdout(
    scenes: Sequence[Scene],
    fraction: float = VALIDATION_FRACTION,
    heldout: Sequence[Scene] | None = None,
    seed: int = 0,
) -> tuple[list[Scene], list[Scene]]:
    """``(train, held_out)``: every scene and ``heldout`` when given; else about ``fraction`` of the scenes
    held out (:func:`~scenescore.learn.data.split_validation`, chosen by ``seed``), except that fewer than
    six scenes are all trained on, with a warning (four held out would leave fewer than two)."""
    if heldout is not None:
        return list(scenes), list(heldout)
    if fraction > 0 and len(scenes) < 6:
        print(
            f"warning: {len(scenes)} scenes are too few to hold out 4 for validation and train on 2; "
            "training on all of them without validation (give held-out scenes with --val-data)",
            file=sys.stderr,
        )
        return list(scenes), []
    return split_validation(scenes, fraction, seed=seed)


@dataclass(frozen=True)
class Validation:
    """How :func:`train` validates: on ``heldout`` scenes when given (every scene of the data is then
    trained on); else ``fraction`` of the scenes held out (:func:`holdout`), or, with ``folds`` of 2 or
    more (by default with fewer than :data:`~scenescore.workflow.crossval.CROSS_VALIDATE_BELOW`
    scenes), the model trained on every scene and validated by ``folds``-fold cross-validation
    (``folds=1``: one hold-out whatever the data's size)."""

    heldout: Sequence[Scene] | None = None
    fraction: float = VALIDATION_FRACTION
    folds: int | None = None


@dataclass(frozen=True)
class Outputs:
    """Where :func:`train`'s results go: ``checkpoint``, the model (with ``report``, default
    ``train_report.json`` beside it, and, for held-out scenes split here, ``<stem>.val.jsonl``);
    ``plot``, the learning curve and a few held-out placements; ``log``, the summary lines (None:
    nowhere); ``source``, where the scenes were read from, named in the line that says how to evaluate
    the model again."""

    checkpoint: str | os.PathLike | None = None
    report: str | os.PathLike | None = None
    plot: str | os.PathLike | None = None
    log: Log | None = print
    source: str | os.PathLike | None = None


def train(
    scenes: Sequence[Scene],
    config: TrainConfig | None = None,
    *,
    seed: int = 0,
    encoder: Encoder | None = None,
    validation: Validation | None = None,
    outputs: Outputs | None = None,
    device: str | torch.device | None = None,
    progress: bool = True,
    run: Run | None = None,
    force: bool = False,
) -> ScoreModel:
    """Train a model on ``scenes`` as ``scenescore train`` does, and return it evaluated and calibrated.

    ``validation`` (:class:`Validation`): held-out scenes, the fraction held out or the folds of
    cross-validation, each fold's model trained with ``config`` and ``seed``. The held-out scenes
    become the trust reference, are placed back object by object (the figures in
    ``model.info.validation``) and calibrate tidying (``model.info.tidy``; without held-out scenes,
    the first :data:`TIDY_SCENES` training ones). ``outputs`` (:class:`Outputs`): the checkpoint, the
    report, the plot and where the summary lines go. A model whose loss never fell below chance raises
    :class:`NothingLearned` unless ``force``. ``encoder``, ``device``, ``progress`` and ``run`` (its log,
    resumable state, starting model and worker processes): as for
    :func:`~scenescore.learn.fit`; with folds, ``run.jobs`` worker processes train the final model's
    networks and the folds' side by side in one pool (:func:`~scenescore.workflow.crossval.train_and_cross_validate`);
    the training state is kept until the checkpoint is written.
    """
    cfg = config or TrainConfig()
    val, out, run = validation or Validation(), outputs or Outputs(), run or Run()
    say: Log = out.log or (lambda line: None)
    out_path = None if out.checkpoint is None else Path(out.checkpoint)
    check_training_data(scenes)
    k = folds_for(len(scenes), val.folds, val.fraction, val.heldout is not None)
    train_s, held = (list(scenes), []) if k else holdout(scenes, val.fraction, val.heldout, seed)
    # keep_state: a run killed before the checkpoint is written resumes with no more training
    if run.start is not None:
        say(f"starting from the weights of {run.start.source}")
    job = Job(encoder, progress, held, device, replace(run, keep_state=True))
    if k:  # the final model and the folds' models train side by side
        how = "leaving one scene out at a time" if k == len(scenes) else f"{k}-fold cross-validation"
        say(f"{len(scenes)} scenes: validating by {how} ({k} more trainings{_each(cfg)})")
        final, folded = train_and_cross_validate(scenes, cfg, k, job, seed=seed, say=say)
        assert final is not None
        model = final
    else:
        model = train_groups(fit, [Group(train_s, job)], cfg, seed, run.jobs)[0]
    info = model.info
    assert info.final_loss is not None and info.chance_loss is not None  # set by training
    took = f"in {info.seconds:.0f} s"
    if cfg.runs > 1:  # the members' times summed: they may have trained side by side
        took = f"as {cfg.members} members, {info.seconds:.0f} s of training in all"
    elif cfg.members > 1:
        took = f"as {cfg.members} snapshots of one run, {took}"
    say(
        f"trained on {info.scenes} scenes {took} "
        f"(final loss {info.final_loss:.3f}, chance {info.chance_loss:.3f})"
    )
    if not info.final_loss < info.chance_loss and not force:
        raise NothingLearned(info.final_loss, info.chance_loss)
    record: dict[str, Any] = {"checkpoint": None if out_path is None else str(out_path)}
    record["training"] = info.training()
    record["pinned"] = _pinned(model, scenes, out.source, say, started=run.start is not None)
    examples: list[Any] = []
    if held:
        ev = evaluate(
            model, held, train_s, seed=seed, progress=progress, per_category=VALIDATION_PER_CATEGORY
        )
        examples = _adopt(model, ev, record, run.log_dir, cfg, say)
        if val.heldout is None and out_path is not None:
            _write_heldout(held, out_path, record, seed, out.source, say)
    elif k:
        examples = _adopt(model, folded, record, run.log_dir, cfg, say)
    if out.plot is not None:
        training_figure(info.history or [], info.chance_loss, examples, out.plot)
        say(f"wrote {out.plot}")
    _calibrate(model, held, train_s, seed, say)
    record["tidy"] = None if info.tidy is None else info.tidy.summary()
    _save(model, out_path, out.report, record, say)
    _remove_state(run.state, cfg.runs)
    return model


def _each(cfg: TrainConfig) -> str:
    """What cross-validation's folds train where it is fewer networks than the final model's."""
    return ", one network each" if fold_config(cfg).members < cfg.members else ""


def _pinned(
    model: ScoreModel,
    scenes: Sequence[Scene],
    source: str | os.PathLike | None,
    say: Log,
    started: bool = False,
) -> dict[str, Any] | None:
    """Say which categories the examples pin down and which they leave free (the trust reference's
    spreads, :mod:`~scenescore.models.freedom`), and, for :data:`FEW_SCENES` or fewer, how to place
    with the examples' own relations (``source``: the data's file) and, for a training from random
    weights (not ``started``), how to start from the shipped prior; the report's record of it."""
    if len(scenes) <= FEW_SCENES:
        data = source if source is not None else "DATA.jsonl"
        say(
            f"with {len(scenes)} examples, `scenescore place MODEL SCENE --examples {data}` adds their own "
            'relations to the learned energy (docs/your-data.md, "A handful of examples")'
        )
        if not started:
            say(
                "`--init prior` starts the training from the shipped arrangement prior instead of random "
                "weights: on the zoo's table tops it left fewer catastrophic placements at five, eight and "
                "twelve scenes (docs/your-data.md)"
            )
    ref = model.trust
    if ref is None or ref.spreads is None:
        return None
    table = {c: s for c in ref.spreads if (s := ref.spread(c)) is not None}
    shown = ShownUnit(declared_unit(scenes))  # metres said as centimetres, as reports say them
    for line in describe_spreads(table, shown.value(100 * ref.length_scale), shown.words):
        say(line)
    return {
        c: {
            "spread": None if not math.isfinite(s.spread) else s.spread * ref.length_scale,
            "anchor": s.anchor,
            "free": s.free,
        }
        for c, s in table.items()
    }


def _remove_state(state: str | os.PathLike | None, members: int) -> None:
    """The training state removed once the checkpoint is written (an ensemble's members each kept
    their own)."""
    if state is None:
        return
    Path(state).unlink(missing_ok=True)
    if members > 1:
        for m in range(members):
            member_state(state, m).unlink(missing_ok=True)


def _adopt(
    model: ScoreModel,
    ev: EvalReport,
    record: dict[str, Any],
    log_dir: str | os.PathLike | None,
    cfg: TrainConfig,
    say: Log,
) -> list[Any]:
    """Keep the validation figures ``ev`` (held-out objects placed back, beside nearest neighbour) in
    the model's info, the record and the TensorBoard log; say the table, and warn of what it finds
    unlearned, kept as the model's caveats, which its placements then carry among their flags. A few
    placements are returned, for the plot."""
    model.info.validation = record["validation"] = ev.to_dict()
    model.info.caveats = ev.caveats()
    if log_dir is not None:
        log_validation(log_dir, ev.to_dict(), cfg.iterations - 1)
    how = (
        f"{ev.scenes} scenes, each held out once ({ev.cross_validation}; seed {ev.seed})"
        if ev.folds
        else f"{ev.scenes} held-out scenes (seed {ev.seed})"
    )
    say(f"\nleave-one-object-out on {how}:\n{ev.table()}")
    for w in ev.warnings():
        print(f"warning: {w}", file=sys.stderr)
    return ev.examples


def _write_heldout(
    held: list[Scene],
    out: Path,
    record: dict[str, Any],
    seed: int,
    source: str | os.PathLike | None,
    say: Log,
) -> None:
    """Write the scenes held out here beside the checkpoint, so that the evaluation can be run again."""
    held_file = out.with_name(out.stem + ".val.jsonl")
    write_jsonl(held_file, held)
    record["held_out_file"] = str(held_file)
    again = f"scenescore evaluate {out} {held_file} --per-category {VALIDATION_PER_CATEGORY}" + (
        f" --train-data {source}" if source is not None else ""
    )
    say(f"held-out scenes -> {held_file}; `{again} --seed {seed}` prints the same figures")


def _calibrate(model: ScoreModel, held: list[Scene], train_s: list[Scene], seed: int, say: Log) -> None:
    """Keep the scenes taken as right (the held-out ones, else some training ones) that tidying
    calibrates what a move must gain on, when the model first tidies (:func:`defer`)."""
    right = held or train_s[:TIDY_SCENES]
    defer(model, right, seed=seed)
    say(
        f"tidy: what a move must gain is measured on {len(right)} {'held-out' if held else 'training'} "
        "scenes when the model first tidies"
    )


def _save(
    model: ScoreModel,
    out: Path | None,
    report: str | os.PathLike | None,
    record: dict[str, Any],
    say: Log,
) -> None:
    """Write the checkpoint (when ``out``), then the report (``report``, default beside the checkpoint)."""
    path = None if report is None else Path(report)
    if out is not None:
        model.save(out)
        path = path or out.with_name("train_report.json")
    if path is None:
        return
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")
    say(f"wrote {out} and {path}" if out is not None else f"wrote {path}")
