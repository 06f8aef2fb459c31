"""Train the models the package ships (``scenescore.models.pretrained(name)``), one per scenario of
``scenescore.experiments.bundled.SCENARIOS`` (the paper's four and the zoo's) and of ``RELATION_MODELS``
(three relations: left of, in front of, near), and the arrangement prior ``PRIOR`` (every bundled table
top's training scenes at unit length scale, :func:`scenescore.experiments.prior.train_prior`), recorded
with its final loss beside chance and the datasets it saw.

Each scenario's model is trained on its training split (``get(name).split(seed)[0]``, all of it, as
``scenescore experiment zoo`` trains) with the default ``TrainConfig`` and the seed recorded (a relation
model: as ``scenescore experiment relations`` trains its models, on 2048 example scenes), written to
``scenescore/models/pretrained/<name>.ckpt`` (atomically), then loaded back from that file and measured
on its documented figure (:mod:`scenescore.experiments.bundled`; a relation model's is the fraction of
its held-out examples placed back where the checker accepts them). ``index.json`` beside the checkpoints
records, per name: the seed, the training settings, the training split's size, the commit, the figure
and its tolerance. ``--only`` retrains some and keeps the others' entries.

    OMP_NUM_THREADS=1 python scripts/pretrain.py                 # every scenario (about an hour on a CPU)
    OMP_NUM_THREADS=1 python scripts/pretrain.py --only dining,tv
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

import scenescore.models
from scenescore.experiments.bundled import (
    PRIOR,
    RELATION_MODELS,
    RELATION_SHORTFALL,
    SCENARIOS,
    figure,
    relation_figure,
    tolerance,
)
from scenescore.experiments.prior import PRIOR_DATASETS, train_prior
from scenescore.experiments.relation_models import train_config as relations_train_config
from scenescore.experiments.relation_models import train_relation
from scenescore.learn import ONE_NETWORK, TrainConfig, fit
from scenescore.models import load
from scenescore.runtime.provenance import git_commit
from scenescore.scenarios import get
from scenescore.scene.outputs import atomic_write_text

FOLDER = Path(scenescore.models.__file__).resolve().parent / "pretrained"
INDEX_VERSION = 1


def read_index(path: Path) -> dict[str, Any]:
    """The index at ``path``, or an empty one when there is none yet."""
    if not path.exists():
        return {"version": INDEX_VERSION, "models": {}}
    index = json.loads(path.read_text(encoding="utf-8"))
    if index.get("version") != INDEX_VERSION or not isinstance(index.get("models"), dict):
        sys.exit(f"{path}: not a version-{INDEX_VERSION} index of pretrained models")
    return index


def pretrain_one(name: str, seed: int, folder: Path, iterations: int | None) -> dict[str, Any]:
    """Train and write ``name``'s model; its index entry, less the figure (:func:`measure`). A scenario's
    model, and the prior, train with the trainer's defaults; a relation model as the relations experiment's do
    (:func:`train_relation`: 2048 examples, with counter-examples that move one object a little, trained
    again with the next member seed while its edge is flat). ``iterations``: instead of either default."""
    t0 = time.perf_counter()
    config = (
        TrainConfig(**ONE_NETWORK)
        if iterations is None
        else TrainConfig(iterations=iterations, **ONE_NETWORK)
    )
    if name == PRIOR:
        model = train_prior(seed=seed, progress=True, config=config)
    elif name in RELATION_MODELS:
        model = train_relation(
            name.removeprefix("relation-"), seed, relations_train_config(iterations), progress=True
        )
    else:
        train_s, _ = get(name).split(seed)
        model = fit(train_s, config, seed=seed, progress=True)
    seconds = time.perf_counter() - t0
    path = folder / f"{name}.ckpt"
    model.save(path)
    return {
        "seed": seed,
        "config": model.info.train_config,  # the settings it trained with
        "train_scenes": model.info.scenes,
        "commit": git_commit(),
        "train_seconds": round(seconds, 1),
        "bytes": path.stat().st_size,
    }


def measure(name: str, entry: dict[str, Any], folder: Path) -> dict[str, Any]:
    """The figure of the checkpoint ``name`` in ``folder`` (loaded from the file, as a user loads it),
    with its tolerance: the index entry's figure fields."""
    t0 = time.perf_counter()
    model = load(folder / f"{name}.ckpt")
    if name == PRIOR:
        return {
            "final_loss": model.info.final_loss,
            "chance_loss": model.info.chance_loss,
            "datasets": list(PRIOR_DATASETS),
            "length_scale_m": model.config.length_scale,
            "figure_seconds": round(time.perf_counter() - t0, 1),
        }
    if name in RELATION_MODELS:
        rel = relation_figure(model, name, int(entry["seed"]))
        return {
            "satisfied": rel["satisfied"],
            "held_out": rel["held_out"],
            "min_satisfied": round(max(rel["satisfied"] - RELATION_SHORTFALL, 0.0), 6),
            "length_scale_m": model.config.length_scale,
            "figure_seconds": round(time.perf_counter() - t0, 1),
        }
    fig = figure(model, name, int(entry["seed"]))
    return {
        "mean_error_m": round(fig["mean_error"], 6),
        "errors_m": [round(e, 6) for e in fig["errors"]],
        "test_scenes": fig["test_scenes"],
        "length_scale_m": model.config.length_scale,
        "tolerance_m": round(tolerance(fig["mean_error"], model.config.length_scale), 6),
        "figure_seconds": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="comma-separated scenario names to (re)train; default all of them")
    ap.add_argument("--seed", type=int, default=0, help="the training seed, split seed and placement seed")
    ap.add_argument("--out", type=Path, default=FOLDER, help=f"folder of the checkpoints (default {FOLDER})")
    ap.add_argument("--iterations", type=int, default=None, help="override the training iterations (trials)")
    ap.add_argument(
        "--measure-only", action="store_true", help="no training: measure the checkpoints there again"
    )
    args = ap.parse_args(argv)
    known = (*SCENARIOS, *RELATION_MODELS, PRIOR)
    names = list(known) if not args.only else [n.strip() for n in args.only.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if unknown:
        ap.error(f"no pretrained model for {', '.join(unknown)}; choose from {', '.join(known)}")
    args.out.mkdir(parents=True, exist_ok=True)
    index_path = args.out / "index.json"
    index = read_index(index_path)
    for name in tqdm(names, desc="pretrain", unit="model"):
        if args.measure_only:
            if name not in index["models"]:
                sys.exit(f"{name}: no entry in {index_path} to measure again; train it first")
            entry = index["models"][name]
        else:
            entry = pretrain_one(name, args.seed, args.out, args.iterations)
        entry.update(measure(name, entry, args.out))
        index["models"][name] = entry
        index["models"] = dict(sorted(index["models"].items()))
        atomic_write_text(index_path, json.dumps(index, indent=1) + "\n")  # after each model: resumable
        shown = (
            f"final loss {entry['final_loss']:.3f}, chance {entry['chance_loss']:.3f}"
            if name == PRIOR
            else f"{entry['satisfied']:.0%} of {entry['held_out']} held-out examples placed back satisfied"
            if name in RELATION_MODELS
            else f"mean error {entry['mean_error_m']:.4f} m over {entry['test_scenes']} test scenes"
        )
        tqdm.write(
            f"{name}: {entry['bytes'] / 1000:.0f} kB, trained in {entry['train_seconds']:.0f} s, "
            f"{shown} ({entry['figure_seconds']:.0f} s)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
