"""Training states: where a training run stands, written every so often so that a killed run resumes.

``train(..., state=path)`` writes one every ``save_every`` iterations; ``resume=True`` reads it back and
the run goes on to the model an uninterrupted run with the same seed trains (bit for bit on the CPU).
A state holds everything the next iterations read: the weights, the optimiser's and the learning-rate
schedule's state, the weights' moving average, the counter-example chains
(:class:`~scenescore.learn.negatives.ChainBuffer`), the random generator's and torch's global random
state, the loss history, the iteration and the seconds spent. The file is a safetensors file (as a
checkpoint: tensors and JSON text, nothing unpickled), written atomically, and it names the training it
belongs to (hashes of the scenes, the settings, the encoder, the seed and the device), so a state of
another training is refused.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import save as st_save
from torch import Tensor

from ..encoders import Encoder
from ..models import CheckpointError, ScoreModel
from ..runtime.memory import check as check_memory
from ..scene.outputs import atomic_write_bytes
from ..scene.scene import Scene
from .cache import digest
from .config import TrainConfig
from .negatives import ChainBuffer

__all__ = ["SAVE_EVERY", "StateError", "Progress", "Trainer", "state_key", "write_state", "read_state"]

FORMAT = "scenescore-training-state"
FORMAT_VERSION = 1
SAVE_EVERY = 50  # iterations between two states, by default
CHAINS = ("poses", "movable", "age")  # the tensors a ChainBuffer keeps between iterations


class StateError(CheckpointError):
    """A training state that cannot be resumed from; the message names the file and what is wrong."""


@dataclass
class Progress:
    """The loop's own running values: iterations done, seconds spent, every iteration's loss and the
    weights' moving average (None before it starts)."""

    iteration: int = 0
    seconds: float = 0.0
    history: list[float] = field(default_factory=list)
    shadow: list[Tensor] | None = None


@dataclass
class Trainer:
    """What the training loop updates besides :class:`Progress`: the model, its optimiser and learning
    rate schedule, the counter-example chains and the random generator."""

    model: ScoreModel
    opt: torch.optim.Optimizer
    sched: torch.optim.lr_scheduler.LRScheduler
    buf: ChainBuffer
    gen: torch.Generator


def state_key(
    scenes: Sequence[Scene],
    cfg: TrainConfig,
    encoder: Encoder,
    seed: int,
    device: torch.device,
    start: str | None = None,
) -> dict[str, str]:
    """What a state belongs to, part by part (hashes of the scenes, settings and encoder), so that a
    refusal can say which part differs (``start``: the starting weights' digest, for a run that starts
    from another model's)."""
    key = {
        "scenes": digest([s.to_dict() for s in scenes]),
        "settings": digest(cfg.to_dict()),
        "encoder": digest({"name": encoder.name, "config": encoder.config()}),
        "seed": str(int(seed)),
        "device": str(device),
    }
    if start is not None:
        key["init"] = start
    return key


def write_state(path: str | os.PathLike, key: dict[str, str], run: Progress, t: Trainer) -> None:
    """Write where the run stands to ``path`` atomically (a failed write leaves the earlier state)."""
    tensors = {f"weights.{k}": v for k, v in t.model.net.state_dict().items()}
    opt = t.opt.state_dict()
    other: dict[str, dict[str, Any]] = {}
    for idx, entry in opt["state"].items():
        for name, value in entry.items():
            if isinstance(value, Tensor):
                tensors[f"optimiser.{idx}.{name}"] = value
            else:
                other.setdefault(str(idx), {})[name] = value
    tensors.update({f"shadow.{i}": a for i, a in enumerate(run.shadow or [])})
    tensors.update({f"chains.{name}": getattr(t.buf, name) for name in CHAINS})
    tensors["rng.generator"] = t.gen.get_state()
    tensors["rng.global"] = torch.get_rng_state()
    tensors["history"] = torch.tensor(run.history, dtype=torch.float64)
    meta = {
        "format": FORMAT,
        "format_version": str(FORMAT_VERSION),
        "key": json.dumps(key),
        "iteration": str(run.iteration),
        "seconds": repr(run.seconds),
        "shadow": str(len(run.shadow) if run.shadow is not None else -1),
        "optimiser_groups": json.dumps(opt["param_groups"]),
        "optimiser_other": json.dumps(other),
        "scheduler": json.dumps(t.sched.state_dict()),
    }
    flat = {k: v.detach().contiguous().cpu() for k, v in tensors.items()}
    atomic_write_bytes(path, st_save(flat, metadata=meta))


def read_state(path: str | os.PathLike, key: dict[str, str], t: Trainer) -> Progress:
    """Put the state in ``path`` into ``t`` and return the loop's values; a file that is not a state,
    is damaged, or belongs to another training (``key``) raises :class:`StateError` naming it."""
    path = Path(path)
    tensors, meta = _read(path)
    try:
        stored = json.loads(meta.get("key", "{}"))
        differ = [part for part in key if stored.get(part) != key[part]]
    except (json.JSONDecodeError, AttributeError) as e:  # not JSON, or not a mapping
        raise StateError(f"{path}: the training state is damaged (its key: {e})") from None
    if differ:
        raise StateError(
            f"{path}: this training state belongs to another training (its {', '.join(differ)} "
            f"differ{'s' if len(differ) == 1 else ''}); start again without resuming, or remove the file"
        )
    try:
        return _restore(tensors, meta, t)
    except (KeyError, ValueError, RuntimeError, TypeError, json.JSONDecodeError) as e:
        raise StateError(f"{path}: the training state is damaged ({e})") from None


def _read(path: Path) -> tuple[dict[str, Tensor], dict[str, str]]:
    """The tensors and metadata of a state file, its format and version checked."""
    if path.is_dir():
        raise StateError(f"{path}: is a folder; expected a training state file")
    if not path.is_file():
        raise StateError(f"{path}: no such training state file")
    size = path.stat().st_size
    check_memory(2 * size, f"{path}: reading a training state of {size:,} bytes", "its size")
    try:
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception as e:  # safetensors raises its own error types for corrupt files
        raise StateError(f"{path}: not a training state (safetensors could not read it: {e})") from None
    if meta.get("format") != FORMAT:
        raise StateError(f"{path}: not a training state (format {meta.get('format')!r}, expected {FORMAT!r})")
    if meta.get("format_version") != str(FORMAT_VERSION):
        raise StateError(
            f"{path}: training state version {meta.get('format_version')!r} is not supported (this "
            f"scenescore reads version {FORMAT_VERSION}); start again without resuming"
        )
    return tensors, meta


def _restore(tensors: dict[str, Tensor], meta: dict[str, str], t: Trainer) -> Progress:
    """Load a read state into the trainer's objects, on their device."""
    dev = t.buf.device

    def part(prefix: str) -> dict[str, Tensor]:
        return {k[len(prefix) :]: v for k, v in tensors.items() if k.startswith(prefix)}

    t.model.net.load_state_dict(part("weights."), strict=True)
    opt_state: dict[int, dict[str, Any]] = {}
    for name, value in part("optimiser.").items():
        idx, entry_name = name.split(".", 1)
        opt_state.setdefault(int(idx), {})[entry_name] = value
    for idx, entry in json.loads(meta["optimiser_other"]).items():
        opt_state.setdefault(int(idx), {}).update(entry)
    groups = json.loads(meta["optimiser_groups"])
    for g in groups:  # JSON turned tuples (AdamW's betas) into lists
        g.update({k: tuple(v) for k, v in g.items() if isinstance(v, list) and k != "params"})
    t.opt.load_state_dict({"state": opt_state, "param_groups": groups})
    t.sched.load_state_dict(json.loads(meta["scheduler"]))
    for name in CHAINS:
        old = getattr(t.buf, name)
        new = tensors[f"chains.{name}"]
        if new.shape != old.shape or new.dtype != old.dtype:
            raise ValueError(f"chains.{name}: {tuple(new.shape)} {new.dtype}, expected {tuple(old.shape)}")
        setattr(t.buf, name, new.to(dev))
    t.gen.set_state(tensors["rng.generator"])
    torch.set_rng_state(tensors["rng.global"])
    count = int(meta["shadow"])
    shadow = None if count < 0 else [tensors[f"shadow.{i}"].to(dev) for i in range(count)]
    return Progress(
        iteration=int(meta["iteration"]),
        seconds=float(meta["seconds"]),
        history=tensors["history"].tolist(),
        shadow=shadow,
    )
