"""The evaluation report says what the model has not learned: a held-out loss not below chance, a
category placed no better than nearest neighbour; training says it on stderr, keeps it in the
checkpoint (``info.caveats``), and the model's placements carry it among their flags."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

import scenescore as ss
from scenescore.evaluation.report import CategoryErrors, EvalReport, evaluate
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.models import Caveats, ModelInfo
from scenescore.planning.placement import PLACE
from scenescore.scenarios import get
from scenescore.workflow import Outputs, Validation, train

# placement cut short: the flags, not the poses, are under test
QUICK = replace(PLACE, particles=8, candidates=64, chain=replace(PLACE.chain, steps=8, final_descent=4))


def _report(loss: float, chance: float, cats: list[CategoryErrors], unit: str | None = "m") -> EvalReport:
    return EvalReport(cats, scenes=4, placements=8, mean_t_cm=3.0, mean_R_deg=None, heldout_loss=loss,
                      chance_loss=chance, seed=0, baseline="nearest neighbour", unit=unit)  # fmt: skip


def test_a_model_that_learned_its_data_gets_no_warning():
    good = CategoryErrors("fork", 4, 1.5, 2.0, baseline_t_cm=9.0, baseline_R_deg=12.0)
    rep = _report(1.2, 2.83, [good])
    assert rep.warnings() == [] and rep.to_dict()["warnings"] == [] and rep.caveats() is None


def test_loss_at_chance_and_a_category_no_better_than_nearest_neighbour_are_named():
    worse = CategoryErrors("mouse", 4, 52.0, None, baseline_t_cm=44.0)
    fine = CategoryErrors("keyboard", 4, 2.0, None, baseline_t_cm=8.0)
    missed = CategoryErrors("lamp", 4, 5.0, None, baseline_t_cm=None)  # no baseline: nothing to compare
    rep = _report(6.38, 2.83, [worse, fine, missed])
    w = rep.warnings()
    assert len(w) == 2
    assert "held-out InfoNCE loss (6.380) is not below chance (2.830)" in w[0]
    assert w[1] == "mouse: held-out error 52.00 cm, no better than nearest neighbour's 44.00 cm"
    assert "more iterations" in w[0] and rep.to_dict()["warnings"] == w
    cav = rep.caveats()
    assert cav is not None and cav.categories == {"mouse": w[1]}  # the warning's words, not recomputed
    assert len(cav.model) == 1 and "loss (6.380) was not below chance (2.830)" in cav.model[0]
    assert cav.reasons("mouse") == [cav.model[0], w[1]] and cav.reasons("keyboard") == cav.model
    # millimetre data says millimetres; data naming no unit says its own unit
    mm = _report(1.0, 2.83, [worse], unit="mm").warnings()
    assert mm == ["mouse: held-out error 0.52 mm, no better than nearest neighbour's 0.44 mm"]
    own = _report(1.0, 2.83, [worse], unit=None).warnings()
    assert own == [
        "mouse: held-out error 0.5200 data units, no better than nearest neighbour's 0.4400 data units"
    ]


def test_a_loss_above_chance_with_one_scene_left_out_is_a_warning_not_a_caveat():
    """Leaving one of a handful of scenes out, the held-out loss is warned of, not carried by placements;
    a category no better than nearest neighbour still is, and 3-fold cross-validation keeps both."""
    worse = CategoryErrors("mouse", 4, 52.0, None, baseline_t_cm=44.0)
    one_out = replace(_report(6.38, 2.83, [worse]), folds=4)  # four scenes, four folds
    w = one_out.warnings()
    assert "not below chance (2.830)" in w[0] and "placements, which do not carry it" in w[0]
    cav = one_out.caveats()
    assert cav is not None and cav.model == [] and list(cav.categories) == ["mouse"]
    assert replace(_report(6.38, 2.83, []), folds=4).caveats() is None
    folded = replace(_report(6.38, 2.83, [worse]), scenes=9, folds=3).caveats()
    assert folded is not None and len(folded.model) == 1


def test_caveats_survive_the_checkpoints_json_and_older_checkpoints_load():
    cav = Caveats(["loss at chance"], {"mouse": "mouse: no better"})
    info = ModelInfo(seed=3, caveats=cav)
    back = ModelInfo.from_dict(json.loads(json.dumps(info.to_dict())))
    assert back.caveats == cav and back.extra == {}
    older = ModelInfo.from_dict({"seed": 3, "scenes": 12})  # a checkpoint from before caveats were kept
    assert older.caveats is None and "caveats" not in older.to_dict() and older.scenes == 12
    with pytest.raises(ValueError, match=r"^info\.caveats: categories: expected a mapping"):
        ModelInfo.from_dict({"caveats": {"model": [], "categories": ["mouse"]}})


@pytest.mark.slow
def test_training_on_a_dozen_scenes_warns_and_every_placement_of_the_model_says_so(tmp_path, capsys):
    """Two iterations on a dozen scenes learn nothing a held-out scene shows: training keeps the model
    (force), warns with both losses, the checkpoint keeps the caveats and placements carry them."""
    scenes = get("dining").generate(12, seed=0)
    cfg = TrainConfig(
        members=1, iterations=2, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=8, layers=1)
    )
    # one hold-out (cross-validation, the default for a dozen scenes, pools the same figures: test_crossval)
    model = train(
        scenes,
        cfg,
        seed=0,
        force=True,
        progress=False,
        validation=Validation(folds=1),
        outputs=Outputs(log=None, checkpoint=tmp_path / "m.ckpt"),
    )
    err = capsys.readouterr().err
    v = model.info.validation
    assert v is not None and not v["heldout_loss"] < v["chance_loss"]  # the case under test
    loss, chance = f"{v['heldout_loss']:.3f}", f"{v['chance_loss']:.3f}"
    assert f"warning: the held-out InfoNCE loss ({loss}) is not below chance ({chance})" in err
    assert v["warnings"] and all(f"warning: {w}" in err for w in v["warnings"])
    loaded = ss.load_model(tmp_path / "m.ckpt")
    cav = loaded.info.caveats
    assert (
        cav is not None
        and cav == model.info.caveats
        and f"({loss}) was not below chance ({chance})" in cav.model[0]
    )
    scene = get("dining").generate(1, seed=5)[0]
    fork = next(o for o in scene.objects if o.category == "fork")
    placed = ss.place(loaded, scene.without(fork.name), QUICK, seed=0)
    flags = placed.meta["placement"][fork.name]["flags"]
    assert [f for f in flags if f.startswith("validation: ")] == [
        f"validation: {r}" for r in cav.reasons("fork")
    ]
    # the caveats flag every placement, but they are not "out of distribution": evaluating the saved
    # model on its held-out scenes counts what training counted
    held = ss.read_jsonl(tmp_path / "m.val.jsonl")
    assert evaluate(loaded, held, seed=0).flagged == v["flagged"]
