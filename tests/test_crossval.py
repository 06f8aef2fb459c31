"""Cross-validation for little data: every scene held out once, the folds' figures pooled exactly, the
final model trained on every scene and carrying the pooled figures and their caveats."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from test_workflow import SMALL, _pairs  # scenes of two boxes, a tiny config (tests/ is on the path)

import scenescore as ss
from scenescore.cli import main
from scenescore.encoders import FootprintEncoder
from scenescore.evaluation.report import CategoryErrors, EvalReport
from scenescore.learn import Run
from scenescore.scene.scene import SceneError
from scenescore.workflow import Outputs
from scenescore.workflow.crossval import (
    CROSS_VALIDATE_BELOW,
    FOLDS,
    LEAVE_ONE_OUT_FROM,
    MIN_SCENES,
    fold_splits,
    folds_for,
    pooled,
)


def test_every_scene_is_held_out_exactly_once_and_trained_on_by_the_other_folds():
    scenes = _pairs(11)
    names = [id(s) for s in scenes]
    splits = fold_splits(scenes, 3, seed=4)
    held = [id(s) for _, h in splits for s in h]
    assert sorted(held) == sorted(names)  # each scene once
    assert sorted(len(h) for _, h in splits) == [3, 4, 4]
    for train, h in splits:
        assert {id(s) for s in train} == set(names) - {id(s) for s in h}
    assert [[id(s) for s in h] for _, h in fold_splits(scenes, 3, seed=4)] == [
        [id(s) for s in h] for _, h in splits
    ]
    assert [[id(s) for s in h] for _, h in fold_splits(scenes, 3, seed=5)] != [
        [id(s) for s in h] for _, h in splits
    ]
    with pytest.raises(ValueError, match="too few"):
        fold_splits(_pairs(2), 3)


def test_little_data_is_cross_validated_by_default_and_folds_can_be_asked_for():
    assert folds_for(12, None, 0.15, False) == FOLDS
    assert folds_for(MIN_SCENES, None, 0.15, False) == FOLDS
    assert folds_for(MIN_SCENES - 1, None, 0.15, False) == MIN_SCENES - 1  # leave one scene out
    assert folds_for(LEAVE_ONE_OUT_FROM, None, 0.15, False) == LEAVE_ONE_OUT_FROM
    assert folds_for(LEAVE_ONE_OUT_FROM - 1, None, 0.15, False) == 0  # too few: trained on without validation
    assert folds_for(MIN_SCENES - 1, 1, 0.15, False) == 0  # one hold-out asked for
    assert folds_for(CROSS_VALIDATE_BELOW, None, 0.15, False) == 0  # enough for one hold-out
    assert folds_for(12, None, 0.15, True) == 0  # held-out scenes given
    assert folds_for(12, None, 0.0, False) == 0  # no validation asked for
    assert folds_for(12, 1, 0.15, False) == 0  # one hold-out asked for
    assert folds_for(100, 5, 0.15, False) == 5
    with pytest.raises(SceneError, match="folds=5: 4 scenes are too few"):
        folds_for(4, 5, 0.15, False)
    with pytest.raises(SceneError, match="held-out scenes were given"):
        folds_for(12, 3, 0.15, True)
    with pytest.raises(SceneError, match="validation fraction is 0"):
        folds_for(12, 3, 0.0, False)


def _report(rows: list[CategoryErrors], scenes: int, loss: float, flagged: int) -> EvalReport:
    return EvalReport(
        categories=rows,
        scenes=scenes,
        placements=sum(r.placements for r in rows),
        mean_t_cm=float(np.mean([r.t_cm for r in rows])),
        mean_R_deg=None,
        heldout_loss=loss,
        chance_loss=2.8,
        seed=0,
        baseline="Nearest-Nbr",
        flagged=flagged,
    )


def test_the_folds_pool_into_the_figures_of_all_their_placements():
    a = _report(
        [
            CategoryErrors("cup", 2, 1.0, 10.0, baseline_t_cm=4.0, baseline_R_deg=20.0),
            CategoryErrors("plate", 1, 3.0, None, baseline_t_cm=None, baseline_missed=1),
        ],
        scenes=2,
        loss=2.0,
        flagged=1,
    )
    b = _report(
        [CategoryErrors("cup", 6, 2.0, 30.0, baseline_t_cm=1.0, baseline_R_deg=10.0, baseline_missed=2)],
        scenes=4,
        loss=3.0,
        flagged=2,
    )
    p = pooled([a, b])
    cup, plate = p.categories
    assert (cup.category, cup.placements, plate.category, plate.placements) == ("cup", 8, "plate", 1)
    assert cup.t_cm == pytest.approx((2 * 1.0 + 6 * 2.0) / 8)
    assert cup.R_deg == pytest.approx((2 * 10.0 + 6 * 30.0) / 8)
    assert cup.baseline_t_cm == pytest.approx((2 * 4.0 + 4 * 1.0) / 6)  # weighted by the cases it filled
    assert cup.baseline_missed == 2 and plate.baseline_missed == 1 and plate.baseline_t_cm is None
    assert plate.R_deg is None and p.mean_R_deg == pytest.approx(cup.R_deg)
    assert p.mean_t_cm == pytest.approx((cup.t_cm + plate.t_cm) / 2)
    assert p.heldout_loss == pytest.approx((2 * 2.0 + 4 * 3.0) / 6)
    assert (p.scenes, p.placements, p.flagged, p.folds) == (6, 9, 3, 2)
    assert "2-fold cross-validation, 6 scenes, 9 placements" in p.table()
    assert not math.isnan(p.mean_t_cm)


@pytest.mark.slow
def test_train_on_a_dozen_scenes_trains_on_all_and_carries_the_cross_validated_figures(tmp_path, capsys):
    scenes = _pairs(9)
    lines: list[str] = []
    model = ss.train(
        scenes,
        SMALL,
        seed=2,
        force=True,
        progress=False,
        outputs=Outputs(log=lines.append, checkpoint=tmp_path / "m.ckpt"),
    )
    v = model.info.validation
    assert model.info.scenes == 9  # the final model saw every scene
    assert v["folds"] == FOLDS and v["scenes"] == 9 and v["placements"] == 18  # both boxes of every scene
    assert sum("cross-validation fold" in line for line in lines) == FOLDS
    assert any("each held out once (3-fold cross-validation; seed 2)" in line for line in lines)
    # a dozen scenes or fewer from random weights: train suggests the shipped prior
    assert any(line.startswith("`--init prior` starts the training") for line in lines)
    assert not (tmp_path / "m.val.jsonl").exists()  # no one set of held-out scenes to write
    # three iterations learn nothing: the pooled held-out loss is not below chance, and the checkpoint
    # carries it, so that placements from the model say so
    assert not v["heldout_loss"] < v["chance_loss"]
    assert "not below chance" in capsys.readouterr().err
    loaded = ss.load_model(tmp_path / "m.ckpt")
    assert loaded.info.validation == v and loaded.info.caveats is not None and loaded.info.caveats.model
    # --folds 1 keeps one hold-out whatever the data's size
    data = tmp_path / "d.jsonl"
    ss.write_jsonl(data, scenes)
    argv = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(tmp_path / "h.ckpt"),
        "--iterations",
        "3",
        "--negatives",
        "2",
    ]
    assert main([*argv, "--folds", "1", "--force", "--quiet"]) == 0
    held = ss.load_model(tmp_path / "h.ckpt").info
    assert held.scenes == 5 and held.validation["folds"] is None and held.validation["scenes"] == 4


def test_five_scenes_are_validated_by_leaving_one_out_and_train_says_what_they_pin_down(tmp_path):
    scenes = _pairs(5)
    for s in scenes:
        s.meta["unit"] = "m"  # spreads said in centimetres, as reports say lengths in metres
    lines: list[str] = []
    model = ss.train(
        scenes,
        SMALL,
        seed=0,
        force=True,
        progress=False,
        outputs=Outputs(log=lines.append, report=tmp_path / "r.json"),
    )
    v = model.info.validation
    assert model.info.scenes == 5 and v["folds"] == 5 and v["scenes"] == 5
    assert sum("cross-validation fold" in line for line in lines) == 5
    assert any("validating by leaving one scene out at a time (5 more trainings)" in line for line in lines)
    assert any("each held out once (leave one scene out; seed 0)" in line for line in lines)
    said = [line for line in lines if line.startswith(("the examples pin down:", "they leave free:"))]
    assert len(said) == 2 and " cm), " in said[0] and " m)" not in said[0]
    assert any("`scenescore place MODEL SCENE --examples DATA.jsonl`" in line for line in lines)
    assert any(line.startswith("`--init prior` starts the training") for line in lines)
    pinned = json.loads((tmp_path / "r.json").read_text())["pinned"]
    ref = model.trust
    assert ref is not None and ref.spreads is not None and set(pinned) == set(ref.spreads)
    for c, row in pinned.items():
        spread = ref.spread(c)
        assert spread is not None and row["free"] == spread.free and row["anchor"] == spread.anchor


@pytest.mark.parametrize("members", [1, 2])
def test_the_final_model_and_the_folds_train_in_one_pool_as_they_would_alone(members):
    """With jobs, the final model's networks and the folds' train side by side in one pool of worker
    processes: the checkpoint's weights, trust reference and cross-validated figures are those of the
    one-process run."""
    import torch

    scenes = _pairs(6)
    cfg = replace(SMALL, members=members)
    given = FootprintEncoder()  # as the command line gives one: training sets the unit it reads sizes in
    one, two = (
        ss.train(
            scenes,
            cfg,
            seed=2,
            force=True,
            progress=False,
            encoder=given,
            outputs=Outputs(log=None),
            run=Run(jobs=j),
        )
        for j in (1, 2)
    )
    mine, theirs = one.net.state_dict(), two.net.state_dict()
    assert mine.keys() == theirs.keys()
    assert all(torch.equal(mine[k], theirs[k]) for k in mine)
    assert one.info.trust.to_dict() == two.info.trust.to_dict()
    assert one.info.validation == two.info.validation and one.info.validation["folds"] == FOLDS
    assert one.info.final_loss == two.info.final_loss and one.info.scenes == 6
    assert one.info.tidy.to_dict() == two.info.tidy.to_dict()
    assert one.encoder.config() == two.encoder.config() != given.config()


def test_a_cross_validated_model_keeps_its_log_where_it_was_asked_for(tmp_path):
    """The final model of a cross-validated training (one network) logs its training loss to ``log_dir``
    itself, as a held-out one does; an ensemble's members each to their own folder in it."""
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    def tags(folder):
        acc = EventAccumulator(str(folder))
        acc.Reload()
        return set(acc.Tags()["scalars"])

    ss.train(
        _pairs(6),
        SMALL,
        seed=2,
        force=True,
        progress=False,
        outputs=Outputs(log=None),
        run=Run(log_dir=tmp_path / "one"),
    )
    assert "train/loss" in tags(tmp_path / "one")
    two = replace(SMALL, members=2)
    ss.train(
        _pairs(6),
        two,
        seed=2,
        force=True,
        progress=False,
        outputs=Outputs(log=None),
        run=Run(log_dir=tmp_path / "two"),
    )
    assert "train/loss" in tags(tmp_path / "two" / "member0") and "train/loss" in tags(
        tmp_path / "two" / "member1"
    )


def test_an_ensembles_folds_train_one_network_each(monkeypatch):
    """The final model trains as many members as asked; each fold's model is one network (FOLD_MEMBERS),
    so that little data's folds do not multiply the ensemble's trainings."""
    from scenescore.workflow import crossval

    seen = {}

    class Stop(Exception):
        pass

    def spy(one, groups, cfg, seed, jobs=1):
        seen["groups"], seen["cfg"] = groups, cfg
        raise Stop

    monkeypatch.setattr(crossval, "train_groups", spy)
    with pytest.raises(Stop):
        ss.train(
            _pairs(6),
            replace(SMALL, members=3),
            seed=2,
            force=True,
            progress=False,
            outputs=Outputs(log=None),
        )
    final, *folds = seen["groups"]
    assert seen["cfg"].members == 3 and final.config is None  # the final model: the pool's three members
    assert len(folds) == FOLDS and all(g.config.members == crossval.FOLD_MEMBERS == 1 for g in folds)
