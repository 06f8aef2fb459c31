"""Where a model cache keeps a trained model: one file per training, named by what decides its weights.

``train(..., cache=folder)`` loads the model from there when it was trained before, else trains it and
keeps it there. The name hashes the scenes, the settings, the seed, the device and the code's version
(:func:`~scenescore.runtime.provenance.code_version`: the package's source and the versions of torch and numpy), so a
folder kept across runs never serves a model that other code trained. ``scenescore experiment all``
passes one folder to every experiment, so a model two experiments train alike is trained once;
``--model-cache DIR`` keeps them for the next run.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import torch

from ..encoders import Encoder
from ..runtime.provenance import code_version
from ..scene.scene import Scene
from .config import TrainConfig

__all__ = ["cached_path", "digest", "run_cache"]


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
    start: str | None = None,
) -> Path | None:
    """The file in ``folder`` for the model of this training: the same scenes, validation scenes,
    settings, seed, device, starting weights (``start``: their digest, None for a fresh start) and code
    (not the thread count, which the weights do not depend on:
    :mod:`scenescore.runtime.threads`). None without a folder, and with an encoder given (a model of another
    encoder is not kept)."""
    if folder is None or encoder is not None:
        return None
    what = {
        "scenes": [s.to_dict() for s in scenes],
        "validation": [s.to_dict() for s in validation],
        "config": cfg.to_dict(),
        "seed": int(seed),
        "device": str(device),
        "code": code_version(),
    }
    if start is not None:
        what["init"] = start
    return Path(folder) / f"{digest(what)}.ckpt"


@contextmanager
def run_cache(folder: str | os.PathLike | None, within: str | os.PathLike | None = None) -> Iterator[Path]:
    """The model cache of one run: ``folder`` when given (kept), else a new folder (in ``within``, or
    the system's temporary folder) that lives as long as the ``with`` block."""
    if folder is not None:
        yield Path(folder)
        return
    with tempfile.TemporaryDirectory(prefix=".models-", dir=within) as tmp:
        yield Path(tmp)
