"""The arrangement prior's data (:mod:`scenescore.experiments.prior`): every bundled table top's training
scenes, each dataset at unit length scale, a dataset left out by name and an unknown one refused."""

from __future__ import annotations

import pytest

from scenescore.errors import ConfigError
from scenescore.experiments.prior import PRIOR_DATASETS, prior_scenes
from scenescore.learn.data import data_scale
from scenescore.scenarios import get
from scenescore.scenarios.zoo import ROOMS


def test_the_prior_pools_every_table_top_at_unit_scale():
    assert not set(ROOMS) & set(PRIOR_DATASETS) and "zoo-pcb" in PRIOR_DATASETS
    sizes = {n: len(get(n).split(0)[0]) for n in PRIOR_DATASETS}
    scenes = prior_scenes(["zoo-books"])
    assert len(scenes) == sum(sizes.values()) - sizes["zoo-books"]
    start = 0
    for name in PRIOR_DATASETS:
        if name == "zoo-books":
            continue
        part = scenes[start : start + sizes[name]]
        start += sizes[name]
        assert data_scale(part)[0] == pytest.approx(1.0), name  # each dataset at its own unit scale
    assert start == len(scenes)
    categories = {o.category for s in scenes for o in s.objects}
    books = {o.category for s in get("zoo-books").split(0)[0][:4] for o in s.objects}
    assert not books <= categories  # the held-out scenario's objects are not in it


def test_an_unknown_dataset_is_refused_by_name():
    with pytest.raises(ConfigError, match="zoo-cafe.*its datasets: zoo-"):
        prior_scenes(["zoo-cafe"])
