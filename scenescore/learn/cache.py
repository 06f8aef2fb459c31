"""Where a model cache keeps a trained model: one file per training, named by what decides its weights.

``train(..., cache=folder)`` loads the model from there when it was trained before, else trains it and
keeps it there. ``scenescore experiment all`` passes one folder to every experiment, so a model two
experiments train alike is trained once; the folder lives as long as the run, so no model of another
version of the code is ever read.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

from ..encoders import Encoder
from ..scene import Scene
from .config import TrainConfig

__all__ = ["cached_path", "digest"]


def digest(value: Any) -> str:
    """A short hash of a JSON value (its keys sorted): what names a training's files."""
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()[:24]


def cached_path(
    folder: str | os.PathLike | None,
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    encoder: Encoder | None,
    seed: int,
    validation: Sequence[Scene],
    device: torch.device,
) -> Path | None:
    """The file in ``folder`` for the model of this training: the same scenes, validation scenes,
    settings, seed and device (not the thread count, which the weights do not depend on:
    :mod:`scenescore.threads`). None without a folder, and with an encoder given (a model of another
    encoder is not kept)."""
    if folder is None or encoder is not None:
        return None
    what = {
        "scenes": [s.to_dict() for s in scenes],
        "validation": [s.to_dict() for s in validation],
        "config": cfg.to_dict(),
        "seed": int(seed),
        "device": str(device),
    }
    return Path(folder) / f"{digest(what)}.ckpt"
