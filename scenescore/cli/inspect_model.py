"""``scenescore inspect``: what a checkpoint stores, as readable text or JSON."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import add_common, add_model, model_of

if TYPE_CHECKING:
    from ..models import ScoreModel

LONG_LIST = 8  # lists longer than this are summarised in the text output (all of them in --json)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "inspect",
        help="print what a checkpoint stores: network, length scale, walls, encoder, training, calibration",
        description=(
            "Load a checkpoint (checked as every command checks it) and print what it stores: the network's "
            "configuration (its length scale and walls among it), the encoder, the training settings, seed, "
            "scene count and losses, tidy's calibration and the held-out validation summary."
        ),
    )
    add_model(p)
    p.add_argument("--json", action="store_true", help="print everything as one JSON object, lists in full")
    add_common(p)
    p.set_defaults(func=run)


def describe(model: ScoreModel, path: str | Path) -> dict[str, Any]:
    """What the checkpoint at ``path`` (loaded as ``model``) stores, as a JSON-ready mapping."""
    info = model.info
    cfg = model.config
    return {
        "file": str(path),
        "weights": sum(p.numel() for p in model.net.parameters()),
        "members": model.members,  # networks whose mean energy the model is (an ensemble's, or 1)
        "network": cfg.to_dict(),
        "length_scale": cfg.length_scale,
        "walls": cfg.walls,
        "encoder": {"name": model.encoder.name, "dim": model.encoder.dim, "config": model.encoder.config()},
        "training": {
            "seed": info.seed,
            "scenes": info.scenes,
            "seconds": info.seconds,
            "config": info.train_config,
            "members": info.members,  # an ensemble's: each member's seed, final loss and seconds
        },
        "losses": {"final": info.final_loss, "chance": info.chance_loss, "history": info.history},
        "tidy_calibration": info.tidy.summary() if info.tidy is not None else None,
        "validation": info.validation,
        "caveats": info.caveats.to_dict() if info.caveats is not None else None,  # flagged in every placement
        "trust_reference": info.trust is not None,
        "other": info.extra or None,
    }


def text_lines(value: Any, indent: int = 0) -> list[str]:
    """``value`` (a JSON-ready mapping) as indented ``key: value`` lines; long lists summarised."""
    pad = "  " * indent
    out: list[str] = []
    for key, v in value.items():
        if isinstance(v, dict) and v:
            out.append(f"{pad}{key}:")
            out += text_lines(v, indent + 1)
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            out.append(f"{pad}{key}:")  # rows of a table, one line each
            out += [f"{pad}  - " + ", ".join(f"{k}={scalar(x)}" for k, x in row.items()) for row in v]
        elif isinstance(v, list) and len(v) > LONG_LIST:
            nums = [x for x in v if isinstance(x, (int, float)) and not isinstance(x, bool)]
            span = f", first {nums[0]:.4g}, last {nums[-1]:.4g}" if len(nums) == len(v) else ""
            out.append(f"{pad}{key}: {len(v)} values{span}")
        else:
            out.append(f"{pad}{key}: {scalar(v)}")
    return out


def scalar(v: Any) -> str:
    """One value as the text output shows it: floats to 6 digits, None as ``none``, strings bare."""
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, str):
        return v
    if isinstance(v, list):
        return "[" + ", ".join(scalar(x) for x in v) + "]"
    return json.dumps(v)


def run(args: argparse.Namespace) -> int:
    model = model_of(args)
    data = describe(model, args.model)
    if args.json:
        print(json.dumps(data, indent=1))
    else:
        print("\n".join(text_lines(data)))
    return 0
