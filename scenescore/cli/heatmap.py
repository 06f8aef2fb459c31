"""``scenescore heatmap``: the energy over one object's position, the others fixed, as a PNG."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import UserError, add_common, add_device, add_model, device_of, model_of, number


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "heatmap",
        help="draw the energy over one object's position, the rest fixed",
        description=(
            "Evaluate a trained energy on a grid of positions of one object (heading --theta), every other "
            "object where the scene puts it, and draw the heatmap with the minimum marked."
        ),
    )
    add_model(p)
    p.add_argument("scene", type=Path, help="scene JSON; every object but --object needs a pose")
    p.add_argument("--object", required=True, help="the object to move over the grid")
    p.add_argument("--out", type=Path, required=True, help="PNG to write")
    p.add_argument("--resolution", type=float, default=0.01, help="grid spacing in m (default 0.01)")
    p.add_argument(
        "--theta", type=number(-1e3, 1e3), default=0.0, help="the object's heading on the grid (rad)"
    )
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..planning.heatmap import energy_grid, grid_minimum
    from ..scene.scene import Scene
    from ..viz.plot import draw_heatmap

    device = device_of(args)
    if args.resolution <= 0:
        raise UserError(f"--resolution must be positive, got {args.resolution}")
    scene = Scene.from_json(args.scene)
    if args.object not in scene.names:
        raise UserError(f"{args.scene}: no object {args.object!r}; objects are {scene.names}")
    others = [n for n in scene.unknown if n != args.object]
    if others:
        raise UserError(f"{args.scene}: {others} have no pose; only --object may be null")
    model = model_of(args, device)
    xs, ys, e = energy_grid(model, scene, args.object, args.resolution, theta=args.theta)
    mn = grid_minimum(xs, ys, e)
    pose = scene[args.object].pose  # the scene's own pose of the object, when it gives one
    truth = None if pose is None else (pose[0], pose[1])
    title = f"energy over {args.object}'s position (heading {args.theta:+.2f} rad)"
    draw_heatmap(scene, args.object, xs, ys, e, mn, args.out, title, truth, "its pose in the scene")
    print(f"minimum at x={mn[0]:+.3f} m  y={mn[1]:+.3f} m  (energy {float(e.min()):.3f})")
    print(f"wrote {args.out}")
    return 0
