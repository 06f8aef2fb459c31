"""``scenescore evaluate``: leave-one-object-out placement errors of a model on any labelled set."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import PLACEMENTS, UserError, add_common, add_device, add_model, device_of, model_of


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="leave-one-object-out placement error per category on labelled scenes",
        description=(
            "Mask each movable object of every scene in turn (or only --objects), place it back with the "
            "model and print the errors per category (position in the unit the scenes' meta.unit names, cm "
            "for metres, else in the data's own unit; orientation deg), the held-out InfoNCE "
            "loss and, with --train-data, the nearest-neighbour baseline: the table `scenescore train` prints."
        ),
    )
    add_model(p)
    p.add_argument("data", type=Path, help=".jsonl of scenes with every pose known")
    p.add_argument("--train-data", type=Path, default=None, help="the training .jsonl, for the baseline")
    p.add_argument(
        "--objects", default=None, help="comma-separated object names to mask (default: every one)"
    )
    p.add_argument(
        "--per-category",
        type=PLACEMENTS,
        default=None,
        metavar="K",
        help="at most K placements of each category, spread over the scenes (default: every object; "
        "`scenescore train` validates on 32)",
    )
    p.add_argument("--out", type=Path, default=None, help="also write the figures as JSON here")
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from ..evaluation.report import evaluate
    from ..scene.outputs import atomic_write_text
    from ..scene.scene import read_jsonl

    device = device_of(args)
    for f in (args.data, args.train_data):
        if f is not None and not f.exists():
            raise UserError(f"{f}: no such file")
    model = model_of(args, device)
    scenes = read_jsonl(args.data)
    train = read_jsonl(args.train_data) if args.train_data else None
    objects = [n.strip() for n in args.objects.split(",")] if args.objects else None
    if objects:
        names = {o.name for s in scenes for o in s.objects}
        missing = [n for n in objects if n not in names]
        if missing:
            raise UserError(f"--objects: no object named {missing} in {args.data}")
    ev = evaluate(
        model,
        scenes,
        train,
        objects=objects,
        seed=args.seed,
        progress=not args.quiet,
        per_category=args.per_category,
    )
    print(f"leave-one-object-out on {len(scenes)} scenes of {args.data} (seed {args.seed}):\n{ev.table()}")
    for w in ev.warnings():
        print(f"warning: {w}", file=sys.stderr)
    if args.out:
        atomic_write_text(args.out, json.dumps(ev.to_dict(), indent=1) + "\n")
        print(f"wrote {args.out}")
    return 0
