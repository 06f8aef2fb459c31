"""``scenescore tidy``: move as few objects as little as possible to make a scene right, and in what order."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    from ..planning.tidying import EFFORT
    from . import add_common, add_device, add_model

    p = sub.add_parser(
        "tidy",
        help="tidy a messy scene: which objects to move where, and in what order",
        description=(
            "Every pose of the scene is where the object is now. Minimise the learned energy plus the effort "
            "of moving objects (a smooth count of moved objects and their displacement), keeping objects "
            "off each other and inside the bounds (and the reach); print which objects move where, the "
            "total displacement, and a pick-and-place plan that never puts an object down on another "
            "(parking one at a buffer pose where two objects swap places)."
        ),
    )
    add_model(p)
    p.add_argument("scene", type=Path, help="scene JSON, every pose known (the current state)")
    p.add_argument(
        "--effort",
        type=float,
        default=EFFORT,
        help=f"weight of the robot's effort against the learned energy (default {EFFORT:g}; 0: re-arrange freely)",
    )
    p.add_argument("--stay", default=None, help="comma-separated objects that must not move")
    p.add_argument(
        "--reach",
        default=None,
        metavar="X,Y,R",
        help="the robot's base (x, y) and reach radius in metres: targets and buffer poses within it",
    )
    p.add_argument("--out", type=Path, help="write the moves, targets, plan and tidy scene here (JSON)")
    p.add_argument(
        "--plot", type=Path, help="draw current and target poses with the plan's moves to this PNG"
    )
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def _reach(text: str | None) -> tuple[tuple[float, float], float] | None:
    from . import UserError

    if text is None:
        return None
    try:
        x, y, r = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--reach: expected X,Y,R in metres, got {text!r}") from None
    if not r > 0:
        raise UserError(f"--reach: the radius must be > 0 m, got {r!r}")
    return (x, y), r


def run(args: argparse.Namespace) -> int:
    import sys

    from ..planning.tidying import tidy
    from ..scene.scene import Scene
    from ..viz.plot import plot_tidy
    from . import device_of, model_of

    device = device_of(args)
    reach = _reach(args.reach)
    model = model_of(args, device)
    scene = Scene.from_json(args.scene)
    stay = [n.strip() for n in args.stay.split(",") if n.strip()] if args.stay else []
    r = tidy(model, scene, effort=args.effort, seed=args.seed, stay=stay, reach=reach)
    if not r.moved:
        print("nothing to move: the scene is tidy at this effort weight")
    for n in r.moved:
        a, b = r.before[n].pose, r.after[n].pose
        assert a is not None and b is not None
        print(
            f"{n:20s} ({a[0]:+.3f}, {a[1]:+.3f}, {a[2]:+.2f}) -> ({b[0]:+.3f}, {b[1]:+.3f}, {b[2]:+.2f})"
            f"  {r.distance[n]:.3f} m, turn {r.turn[n]:.2f} rad"
        )
    print(
        f"moved {len(r.moved)} of {len(scene)} objects; total displacement {r.total_displacement:.3f} m "
        f"(a move costs {r.count:.3f} in energy at effort {r.effort:g})"
    )
    for k, s in enumerate(r.steps, start=1):
        x, y, t = s.goal
        where = "buffer" if s.buffer else "target"
        print(f"step {k}: {s.name} to its {where} ({x:+.3f}, {y:+.3f}, {t:+.2f})")
    print(f"plan: {len(r.steps)} steps, {r.buffers} via a buffer, {r.check.describe()} when replayed")
    for w in r.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if args.out:
        r.to_json(args.out)
        print(f"wrote {args.out}")
    if args.plot:
        plot_tidy(r, args.plot, reach=[reach] if reach else [])
        print(f"wrote {args.plot}")
    return 0 if r.check.valid else 1
