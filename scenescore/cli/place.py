"""``scenescore place``: fill every unknown pose of a scene with the learned energy."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    from ..solvers.langevin import MAX_PARTICLES
    from . import add_common, add_device, add_model, number

    p = sub.add_parser(
        "place",
        help="predict every null pose in a scene",
        description=(
            "Fill every `pose: null` of a scene by Langevin on the learned energy plus non-overlap with the "
            "other objects (which stay where they are); print the placed poses and warn about any overlap "
            "left (exact check)."
        ),
    )
    add_model(p)
    p.add_argument("scene", type=Path, help="scene JSON with some poses null")
    p.add_argument("--out", type=Path, help="write the filled scene here")
    p.add_argument("--plot", type=Path, help="draw the scene, placed objects marked, to this PNG")
    p.add_argument(
        "--particles",
        type=number(1, MAX_PARTICLES, integer=True),
        default=None,
        help="Langevin particles (default 64)",
    )
    p.add_argument(
        "--energy-only",
        action="store_true",
        help="place by the learned energy alone, overlaps allowed (the paper's protocol)",
    )
    p.add_argument(
        "--examples",
        type=Path,
        help="a .jsonl of example scenes whose own relative poses join the cost (ExampleRelations): "
        "with a handful of examples, they hold what the network has not learned",
    )
    p.add_argument(
        "--examples-weight",
        type=number(0.0, 1e6),
        default=1.0,
        help="the weight of --examples' term beside the learned energy (default 1)",
    )
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys
    from dataclasses import replace

    from ..planning.placement import PLACE, covering, overlapping, place
    from ..scene.scene import Scene
    from ..scene.units import UNITS, length_unit
    from ..viz.plot import plot_scene
    from . import UserError, device_of, model_of

    device = device_of(args)
    model = model_of(args, device)
    scene = Scene.from_json(args.scene)
    names = scene.unknown
    if not names:
        raise UserError(f"{args.scene}: no object has `pose: null`; nothing to place")
    cfg = covering(PLACE, model, [scene])
    cfg = cfg if args.particles is None else replace(cfg, particles=args.particles)
    extra = None
    if args.examples is not None:
        from ..costs import ExampleRelations
        from ..scene.scene import read_jsonl

        extra = args.examples_weight * ExampleRelations(read_jsonl(args.examples))
    filled = place(model, scene, cfg, seed=args.seed, energy_only=args.energy_only, extra=extra)
    trust = filled.meta.get("placement", {})
    unit = length_unit(scene)  # lengths as the scene's file gives them
    unit = unit if unit in UNITS else f"({unit})"
    for n in names:
        pose = filled[n].pose
        assert pose is not None
        x, y, t = pose
        conf = trust.get(n, {}).get("confidence")
        print(
            f"{n:20s} x={x:+.4g} y={y:+.4g} {unit}  theta={t:+.3f} rad"
            + ("" if conf is None else f"  confidence {conf:.2f}")
        )
        for note in trust.get(n, {}).get("notes", []):
            print(f"  {n}: {note}")
    for n in names:
        for flag in trust.get(n, {}).get("flags", []):
            print(f"warning: {n}: {flag}", file=sys.stderr)
    for a, b in overlapping(model, filled, names):
        print(f"warning: {a}: overlaps {b} (exact check)", file=sys.stderr)
    if args.out:
        filled.to_json(args.out)
        print(f"wrote {args.out}")
    if args.plot:
        plot_scene(filled, args.plot, highlight=names, title=f"placed: {', '.join(names)}")
        print(f"wrote {args.plot}")
    return 0
