"""``scenescore export``: a trained energy as ONNX, for planners outside Python."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import UserError, add_common, add_model, model_of, number


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="export the learned energy as ONNX",
        description=(
            "Write the energy of B arrangements of a scene's N objects as ONNX (B and N dynamic), its inputs "
            "the poses and the scene's node embeddings, computed once per scene (scenescore.models.export "
            "documents what to feed). --check compares onnxruntime with torch on a scene."
        ),
    )
    add_model(p)
    p.add_argument(
        "--out",
        "--onnx",
        dest="out",
        type=Path,
        required=True,
        help="the energy graph to write (.onnx); --onnx is the same option",
    )
    p.add_argument(
        "--embed-onnx",
        type=Path,
        default=None,
        help="also write the node-embedding step (encoder features and sizes -> nodes) here",
    )
    p.add_argument("--opset", type=number(13, 30, integer=True), default=17, help="ONNX opset (default 17)")
    p.add_argument(
        "--check",
        type=Path,
        default=None,
        metavar="SCENE",
        help="scene JSON: run onnxruntime on random arrangements of it and print the largest difference "
        "from torch",
    )
    add_common(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..models.export import energy_inputs, export_embedding_onnx, export_onnx, require
    from ..scene.outputs import check_output_path
    from ..scene.scene import Scene

    # outputs, settings, the packages and the check's scene first: nothing is exported when any is wrong
    check_output_path(args.out, "--out")
    if args.embed_onnx is not None:
        check_output_path(args.embed_onnx, "--embed-onnx")
        if args.embed_onnx.resolve() == args.out.resolve():
            raise UserError("--embed-onnx and --out name the same file")
    require("onnx")
    scene = None
    if args.check is not None:
        require("onnxruntime")
        if not args.check.exists():
            raise UserError(f"--check {args.check}: no such file")
        scene = Scene.from_json(args.check)
    model = model_of(args)
    export_onnx(model, args.out, opset=args.opset)
    if args.embed_onnx is not None:
        export_embedding_onnx(model, args.embed_onnx, opset=args.opset)
    inputs = ", ".join(energy_inputs(model))
    also = f", the node embedding to {args.embed_onnx}" if args.embed_onnx is not None else ""
    print(f"wrote the energy ({inputs} -> energy) to {args.out}{also}")
    if scene is not None:
        diff, b = _check(model, scene, args)
        print(
            f"check on {args.check}: max |onnxruntime - torch| = {diff:.2e} over {b} arrangements of "
            f"{len(scene)} objects" + (" (nodes from the exported embedding)" if args.embed_onnx else "")
        )
    return 0


def _check(model, scene, args: argparse.Namespace) -> tuple[float, int]:
    """The largest difference between onnxruntime's energies and torch's on random arrangements of
    ``scene`` inside its bounds (and its own, when complete); the nodes through the exported embedding
    when there is one."""
    import numpy as np
    import onnxruntime as ort
    import torch

    from ..models.export import scene_inputs

    rng = np.random.default_rng(args.seed)
    (x0, y0), (x1, y1) = scene.bounds
    n, b = len(scene), 16
    poses = np.stack(
        [rng.uniform(x0, x1, (b, n)), rng.uniform(y0, y1, (b, n)), rng.uniform(-np.pi, np.pi, (b, n))], -1
    )
    if not scene.unknown:
        poses = np.concatenate([scene.poses()[None], poses])
    poses = poses.astype(np.float32)
    inputs = scene_inputs(model, scene)
    cpu = ["CPUExecutionProvider"]
    if args.embed_onnx is not None:
        st = model.tensors([scene])
        feeds = {"feats": st.feats[0].float().numpy(), "sizes": st.sizes[0].float().numpy()}
        (inputs.nodes,) = ort.InferenceSession(str(args.embed_onnx), providers=cpu).run(None, feeds)
    (got,) = ort.InferenceSession(str(args.out), providers=cpu).run(None, inputs.feeds(poses))
    with torch.no_grad():
        want = model.energy_fn(scene)(torch.as_tensor(poses, dtype=model.dtype)).double().numpy()
    return float(np.abs(got.astype(np.float64) - want).max()), len(poses)
