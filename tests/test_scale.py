"""Defaults hold at any scale: scaling every pose, size and bound of a dataset by a power of two and
training with the same seed gives the same placements times k (any constant left in metres breaks it)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.evaluation.cases import make_cases
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.learn.data import data_scale
from scenescore.planning.placement import PLACE, place_many

CFG = TrainConfig(
    members=1,
    iterations=12,
    batch_scenes=4,
    negatives=4,
    perturbed=2,
    network=NetworkConfig(hidden=16, layers=2),
)
SMALL = replace(PLACE, particles=8, candidates=64, chain=replace(PLACE.chain, steps=8, final_descent=4))


def _run(k: float) -> tuple[np.ndarray, ss.models.ScoreModel]:
    torch.set_num_threads(1)
    sc = ss.scenarios.get("dining")
    scenes = [s.scaled(k) for s in sc.generate(8, 1)]
    cases = make_cases([s.scaled(k) for s in sc.generate(2, 2)], ("fork", "bowl"))[:3]
    model = fit(scenes, CFG, seed=0, progress=False)
    placed = place_many(model, [c.scene for c in cases], SMALL, seed=0)
    return np.array([p[c.name].pose for c, p in zip(cases, placed)]), model


@pytest.mark.slow
@pytest.mark.parametrize("k", [8.0, 1 / 8])
def test_scaling_the_data_scales_the_placements(k):
    base, m1 = _run(1.0)
    scaled, mk = _run(k)
    assert mk.config.length_scale == m1.config.length_scale * k
    assert mk.config.edge_range == m1.config.edge_range
    assert mk.encoder.config() == {"length_scale": m1.encoder.config()["length_scale"] * k}
    np.testing.assert_allclose(scaled[:, :2], k * base[:, :2], rtol=1e-6, atol=1e-9 * k)
    np.testing.assert_allclose(scaled[:, 2], base[:, 2], rtol=1e-6, atol=1e-9)


def test_data_scale_is_derived_from_the_data():
    scenes = ss.scenarios.get("dining").generate(6, 0)
    length, far = data_scale(scenes)
    assert 0.05 < length < 0.2 and 5 < far < 15
    l8, f8 = data_scale([s.scaled(8) for s in scenes])
    assert l8 == 8 * length and f8 == far
    model = fit(scenes, replace(CFG, iterations=1), seed=0, progress=False)
    assert model.config.length_scale == length and model.config.edge_range is None  # linear by default
    saturating = fit(scenes, replace(CFG, iterations=1, saturate_edges=True), seed=0, progress=False)
    assert saturating.config.edge_range == far
    pinned = fit(scenes, replace(CFG, iterations=1, length_scale=0.3, edge_range=4.0), seed=0, progress=False)
    assert pinned.config.length_scale == 0.3 and pinned.config.edge_range == 4.0
