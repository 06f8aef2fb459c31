"""Fixtures of the hostile-input suite: a tiny untrained checkpoint and a valid scene file."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from .helpers import SCENE, write


@pytest.fixture(scope="session")
def model_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained footprint-encoder checkpoint (tiny widths): enough to load, place and solve."""
    from scenescore.encoders import make_encoder
    from scenescore.models import ScoreModel

    torch.manual_seed(0)
    p = tmp_path_factory.mktemp("model") / "m.ckpt"
    ScoreModel.create(make_encoder("footprint"), hidden=8, embed_dim=8).save(p)
    return p


@pytest.fixture(scope="session")
def scene_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("scene") / "scene.json", SCENE)


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)
