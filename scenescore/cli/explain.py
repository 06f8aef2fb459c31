"""``scenescore explain``: which relations hold an object where it stands, by the learned energy."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    from . import add_common, add_device, add_model, number

    p = sub.add_parser(
        "explain",
        help="say which neighbours hold an object where it stands",
        description=(
            "Break an object's learned energy into the relations that hold it: the well's depth (how much "
            "the energy rises when the object alone moves away) and each neighbour's part in it, by "
            "integrated gradients through the edges between them, so the parts add up to the depth; "
            "each relation beside how many example pairs the model saw stand that way. A scene with "
            "null poses is placed first, as `place` does."
        ),
    )
    add_model(p)
    p.add_argument("scene", type=Path, help="scene JSON (null poses are placed first)")
    p.add_argument("--object", required=True, help="the object to explain")
    p.add_argument(
        "--data", type=Path, help="the example scenes (.jsonl), to name the ones showing each relation"
    )
    p.add_argument(
        "--neighbours",
        type=number(1, 1000, integer=True),
        default=8,
        help="relations listed, the largest parts first (default 8)",
    )
    p.add_argument("--plot", type=Path, help="draw the object and its relations as edges to this PNG")
    p.add_argument("--out", type=Path, help="write the explanation as JSON here")
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from ..models.explain import explain
    from ..planning.placement import place
    from ..scene.outputs import atomic_write_text
    from ..scene.scene import Scene, read_jsonl
    from ..viz.explanation import plot_explanation
    from . import UserError, device_of, model_of

    model = model_of(args, device_of(args))
    scene = Scene.from_json(args.scene)
    if args.object not in scene.names:
        raise UserError(f"{args.scene}: no object {args.object!r}; objects are {', '.join(scene.names)}")
    if model.config.absolute:
        raise UserError(f"{args.model}: the model reads absolute poses (--absolute), not relations")
    examples = read_jsonl(args.data) if args.data is not None else None
    if scene.unknown:
        print(f"placing {', '.join(scene.unknown)} first (seed {args.seed})")
        scene = place(model, scene, seed=args.seed)
    why = explain(model, scene, args.object, examples, args.neighbours)
    print(why.table())
    if args.out is not None:
        atomic_write_text(args.out, json.dumps(why.to_dict(), indent=1) + "\n")
        print(f"wrote {args.out}")
    if args.plot is not None:
        plot_explanation(scene, why, args.plot)
        print(f"wrote {args.plot}")
    return 0
