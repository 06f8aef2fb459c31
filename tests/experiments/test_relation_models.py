"""The relation models: their validation examples, their edge, and the restart of a flat one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenescore.experiments import relation_models as RM
from scenescore.learn import TrainConfig
from scenescore.models.ensemble import member_seed
from scenescore.scenarios import get
from scenescore.scene.scene import SceneError

TINY = TrainConfig(members=1, iterations=2)


def test_validation_examples_follow_the_training_examples_in_their_stream():
    trained, _ = RM.relation_training("left_of", 3, TINY, examples=8)
    held = RM.validation_examples("left_of", 3, examples=8, count=4)
    stream = get("relation-left_of", n_train=12).split(3)[0]
    assert len(held) == 4
    for a, b in zip(trained + held, stream):
        np.testing.assert_array_equal(a.poses(), b.poses())
    assert not any(np.array_equal(h.poses(), t.poses()) for h in held for t in trained)
    with pytest.raises(SceneError, match="no relation 'leftof'"):
        RM.validation_examples("leftof", 0, 8)


@pytest.fixture(scope="module")
def tiny_left_of():
    return RM.train_relations(["left_of"], 0, TINY, examples=8)["left_of"]


def test_edge_counts_the_moves_the_checker_rejects(tiny_left_of):
    held = RM.validation_examples("left_of", 0, examples=8, count=5)
    scenario = get("relation-left_of")
    still, far = RM.edge(tiny_left_of, "left_of", held, [0.0, 0.3])
    assert still.broken == 0 and math.isnan(still.worse)  # every example holds its relation
    angles = np.arange(RM.DIRECTIONS) * (2 * math.pi / RM.DIRECTIONS)
    expected = 0
    for ex in held:
        for a in angles:
            p = ex.poses()
            p[0, :2] += 0.3 * np.array([math.cos(a), math.sin(a)])
            expected += not scenario.check(ex.with_poses(p))
    assert far.broken == expected > 0 and 0.0 <= far.worse <= 1.0 and far.move == 0.3


def _edges(monkeypatch, shares):
    """Make :func:`edge` report ``shares`` in turn, and record the seeds trained."""
    seeds: list[int] = []
    real_train = RM.fit

    def train(scenes, cfg, seed, **kw):
        assert len(scenes) == 8  # the examples asked for; the validation examples follow them
        seeds.append(seed)
        return real_train(scenes, cfg, seed=seed, **kw)

    it = iter(shares)
    monkeypatch.setattr(RM, "fit", train)
    monkeypatch.setattr(RM, "edge", lambda *a: [RM.Edge(RM.EDGE_MOVE, 10, next(it), 0.1)])
    return seeds


@pytest.mark.parametrize(
    "shares, trained, kept",
    [
        ([0.95], 1, 0),  # sharp at once: the seed's own model
        ([0.5, 0.6, 0.9], 3, 2),  # the first sharp one
        ([0.1, 0.7, 0.2, 0.3], 1 + RM.RESTARTS, 1),  # none sharp: the sharpest
    ],
)
def test_a_flat_model_is_trained_again_with_the_next_member_seed(monkeypatch, shares, trained, kept):
    seeds = _edges(monkeypatch, shares)
    told: list[str] = []
    model = RM.train_relation("left_of", 0, TINY, examples=8, log=told.append)
    assert seeds == [member_seed(0, m) for m in range(trained)]
    assert len(told) == trained - 1 and all("left_of" in t and "edge is flat" in t for t in told)
    assert model.info.seed == member_seed(0, kept)
