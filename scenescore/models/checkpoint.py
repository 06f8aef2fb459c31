"""Checkpoint files: safetensors weights plus JSON metadata (format, version, configs, info).

Reading never unpickles code; writing goes through a temporary file and a rename, so a failed write
leaves the earlier file intact. This module knows the file format only; :mod:`scenescore.models.model`
turns its contents into a :class:`~scenescore.models.model.ScoreModel`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from safetensors import safe_open
from safetensors.torch import save as st_save
from torch import Tensor

from ..runtime import check_memory
from ..scene.outputs import atomic_write_bytes

__all__ = ["FORMAT", "FORMAT_VERSION", "CheckpointError", "Checkpoint", "read_checkpoint", "write_checkpoint"]

FORMAT = "scenescore-energy"
FORMAT_VERSION = 1


class CheckpointError(ValueError):
    """A checkpoint that cannot be loaded; the message names the file and what is wrong."""


@dataclass
class Checkpoint:
    """What a checkpoint file holds."""

    tensors: dict[str, Tensor]
    energy_config: dict[str, Any]
    encoder: dict[str, Any]  # {"name": ..., "config": {...}}
    info: dict[str, Any]


def write_checkpoint(
    path: str | os.PathLike,
    state: Mapping[str, Tensor],
    energy_config: dict[str, Any],
    encoder: dict[str, Any],
    info: dict[str, Any],
) -> None:
    """Write weights and metadata to ``path`` atomically."""
    meta = {
        "format": FORMAT,
        "format_version": str(FORMAT_VERSION),
        "energy_config": json.dumps(energy_config),
        "encoder": json.dumps(encoder),
        "info": json.dumps(info),
    }
    tensors = {k: v.detach().contiguous().cpu() for k, v in state.items()}
    atomic_write_bytes(path, st_save(tensors, metadata=meta))


def read_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read and check a checkpoint's format and version; every error names the file."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no such checkpoint file")
    if path.is_dir():
        raise CheckpointError(f"{path}: is a folder; expected a checkpoint file")
    if path.is_file():  # its weights are read whole, then copied into the network
        check_memory(
            2 * path.stat().st_size,
            f"{path}: loading a checkpoint of {path.stat().st_size:,} bytes",
            "its size",
        )
    try:
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception as e:  # safetensors raises its own error types for corrupt files
        raise CheckpointError(
            f"{path}: not a scenescore checkpoint (safetensors could not read it: {e})"
        ) from None
    if meta.get("format") != FORMAT:
        raise CheckpointError(
            f"{path}: not a scenescore checkpoint (format {meta.get('format')!r}, expected {FORMAT!r})"
        )
    version = meta.get("format_version")
    if version != str(FORMAT_VERSION):
        raise CheckpointError(
            f"{path}: checkpoint format version {version!r} is not supported by this scenescore "
            f"(it reads version {FORMAT_VERSION}); retrain with `scenescore train` or use a matching release"
        )
    try:
        energy_config = json.loads(meta["energy_config"])
        encoder = json.loads(meta["encoder"])
        info = json.loads(meta.get("info", "{}"))
        if not isinstance(energy_config, dict) or not isinstance(encoder, dict) or "name" not in encoder:
            raise TypeError("expected JSON objects, the encoder with a 'name'")
        if not isinstance(info, dict):
            raise TypeError(f"info: expected a JSON object, got {type(info).__name__}")
    except (KeyError, TypeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{path}: checkpoint metadata is damaged ({e})") from None
    return Checkpoint(tensors, energy_config, encoder, info)
