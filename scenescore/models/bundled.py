"""The models the package ships, one per bundled scenario, loaded by name: no training, no network.

The checkpoints lie in the package folder ``scenescore/models/pretrained`` with ``index.json``, which
records per name the seed, the training settings, the training split's size, the commit, the documented
figure (mean placement error in metres, :mod:`scenescore.experiments.bundled`) and its tolerance.
``scripts/pretrain.py`` in the repository writes them.
"""

from __future__ import annotations

import json
from importlib import resources
from importlib.resources.abc import Traversable
from typing import Any

import torch

from ..errors import nearest_name
from .checkpoint import CheckpointError
from .model import ScoreModel, load

__all__ = ["pretrained", "pretrained_names", "pretrained_index"]

_FOLDER = "pretrained"  # beside this module, shipped as package data


def _folder() -> Traversable:
    return resources.files(__package__ or "scenescore.models") / _FOLDER


def pretrained_index() -> dict[str, dict[str, Any]]:
    """Every shipped model's index entry, by scenario name (empty when the package ships none)."""
    path = _folder() / "index.json"
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        models = data["models"]
    except (ValueError, KeyError, TypeError) as e:
        raise CheckpointError(f"the pretrained models' index.json is damaged: {e}") from None
    if not isinstance(models, dict):
        raise CheckpointError("the pretrained models' index.json is damaged: 'models' is not a mapping")
    return dict(models)


def pretrained_names() -> list[str]:
    """The names :func:`pretrained` loads: the scenarios whose model the package ships, sorted."""
    folder = _folder()
    return sorted(n for n in pretrained_index() if (folder / f"{n}.ckpt").is_file())


def pretrained(name: str, device: str | torch.device | None = None) -> ScoreModel:
    """The shipped model of the scenario ``name`` (``ss.models.pretrained("dining")``), on ``device``
    (default the CPU); an unknown name is a :class:`CheckpointError` listing the available ones."""
    names = pretrained_names()
    if name not in names:
        near = nearest_name(name, names)
        hint = f" (did you mean {near!r}?)" if near else ""
        raise CheckpointError(
            f"no pretrained model {name!r}{hint}; available: {', '.join(names) or 'none in this install'}"
        )
    with resources.as_file(_folder() / f"{name}.ckpt") as path:  # a real file, even from a zip
        return load(path, device=device)
