"""NeatNet-R: regression from class-name embeddings (a stub embedding here; MiniLM where installed)."""

import math

import numpy as np
import pytest

from scenescore.evaluation.baselines import NeatNetR
from scenescore.evaluation.baselines.word_embed import available, minilm
from scenescore.evaluation.cases import make_cases
from scenescore.experiments.novel import position_error_cm
from scenescore.scenarios import OrderingScenario

WORDS = ["fork", "knife", "spoon", "board"]


def onehot(words):
    return np.eye(len(WORDS), dtype=np.float32)[[WORDS.index(w) for w in words]]


def test_neatnet_r_learns_class_means_not_sizes():
    sc = OrderingScenario("class_size")
    train, test = sc.split(0)
    model = NeatNetR(embed=onehot, epochs=300).fit(train, seed=0)
    cases = make_cases(test[:4], sc.missing)
    pred = model.predict([c.scene for c in cases])
    err = position_error_cm(cases, pred)
    # it can place a class's pieces near that class's slots (better than the row's far end) ...
    assert err < 10.0
    # ... but not order pieces of one class by size: every fork gets the same offset from the board
    forks = [p[c.name].pose for c, p in zip(cases, pred) if c.category == "fork"]
    boards = [c.scene["board"].pose for c in cases if c.category == "fork"]
    offsets = {round(f[0] - b[0], 6) for f, b in zip(forks, boards)}
    assert len(offsets) == 1
    assert err > 1.0  # the oracle's floor is ~0.4 cm; a size-blind regression cannot reach it
    known = pred[0].with_poses(pred[0].poses())
    assert model.predict([known])[0].unknown == []


def test_neatnet_r_needs_fit_and_data():
    with pytest.raises(RuntimeError):
        NeatNetR(embed=onehot).predict(OrderingScenario().generate(1, 0))
    s = OrderingScenario().generate(1, 0)[0]
    with pytest.raises(ValueError):
        NeatNetR(embed=onehot).fit(
            [s.without(o.name) for o in s.objects][:0] or [s.with_poses(s.poses())][:0]
        )


@pytest.mark.skipif(not available(), reason="the minilm extra is not installed")
def test_minilm_embeddings_are_unit_and_semantic():
    v = minilm(["fork", "spoon", "television"])
    assert v.shape == (3, 384)
    assert np.allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-4)
    cos = v @ v.T
    assert cos[0, 1] > cos[0, 2]  # fork is nearer spoon than television
    assert math.isfinite(float(cos.sum()))
