"""The evaluation report says what the model has not learned: a held-out loss not below chance, a
category placed no better than nearest neighbour; training says it on stderr."""

from __future__ import annotations

import pytest

from scenescore.evaluation import CategoryErrors, EvalReport
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.learn.workflow import train_model
from scenescore.scenarios import get


def _report(loss: float, chance: float, cats: list[CategoryErrors]) -> EvalReport:
    return EvalReport(cats, scenes=4, placements=8, mean_t_cm=3.0, mean_R_deg=None, heldout_loss=loss,
                      chance_loss=chance, seed=0, baseline="nearest neighbour")  # fmt: skip


def test_a_model_that_learned_its_data_gets_no_warning():
    good = CategoryErrors("fork", 4, 1.5, 2.0, baseline_t_cm=9.0, baseline_R_deg=12.0)
    rep = _report(1.2, 2.83, [good])
    assert rep.warnings() == [] and rep.to_dict()["warnings"] == []


def test_loss_at_chance_and_a_category_no_better_than_nearest_neighbour_are_named():
    worse = CategoryErrors("mouse", 4, 52.0, None, baseline_t_cm=44.0)
    fine = CategoryErrors("keyboard", 4, 2.0, None, baseline_t_cm=8.0)
    missed = CategoryErrors("lamp", 4, 5.0, None, baseline_t_cm=None)  # no baseline: nothing to compare
    rep = _report(6.38, 2.83, [worse, fine, missed])
    w = rep.warnings()
    assert len(w) == 2
    assert "held-out InfoNCE loss (6.380) is not below chance (2.830)" in w[0]
    assert w[1] == "mouse: held-out error 52.00 cm, no better than nearest neighbour's 44.00 cm"
    assert rep.to_dict()["warnings"] == w


@pytest.mark.slow
def test_training_on_a_dozen_scenes_warns_on_stderr(capsys):
    """Two iterations learn nothing a held-out scene shows: training keeps the model (force) and warns."""
    scenes = get("dining").generate(12, seed=0)
    cfg = TrainConfig(iterations=2, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=8, layers=1))
    model = train_model(scenes, cfg, seed=0, force=True, progress=False)
    err = capsys.readouterr().err
    assert model.info.validation is not None
    assert model.info.validation["warnings"] and all(
        f"warning: {w}" in err for w in model.info.validation["warnings"]
    )
