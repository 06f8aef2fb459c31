"""``scenescore train`` and ``ss.train`` are one workflow: the same data and seed give the same model,
weights and metadata (held-out figures and tidy's calibration included)."""

from __future__ import annotations

import json
import math

import pytest
import torch

import scenescore as ss
from scenescore.cli import main
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.workflow import Outputs, Validation
from scenescore.workflow.training import NothingLearned, holdout

SMALL = TrainConfig(
    members=1,
    iterations=3,
    batch_scenes=2,
    negatives=2,
    reanchored=1,
    network=NetworkConfig(hidden=8, layers=1),
)


def _pairs(n: int) -> list[ss.Scene]:
    """A red box and a blue box 0.2 m ahead of it, at random places and headings."""
    g = torch.Generator().manual_seed(0)
    out = []
    for _ in range(n):
        x, y = (torch.rand(2, generator=g) * 0.6 - 0.3).tolist()
        t = float(torch.rand(1, generator=g) * 2 * math.pi - math.pi)
        a = ss.SceneObject("a", "red", (0.1, 0.05), (x, y, t), (200, 30, 30))
        b = ss.SceneObject("b", "blue", (0.08, 0.08), (x + 0.2 * math.cos(t), y + 0.2 * math.sin(t), t))
        out.append(ss.Scene([a, b]))
    return out


def _cli_model(tmp_path) -> tuple[ss.models.ScoreModel, str]:
    """``scenescore train`` on six pairs, 3 iterations of 2 counter-examples per scene, seed 1."""
    data = tmp_path / "d.jsonl"
    ss.write_jsonl(data, _pairs(6))
    out = tmp_path / "m.ckpt"
    argv = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(out),
        "--iterations",
        "3",
        "--negatives",
        "2",
        "--force",
        "--quiet",
    ]
    assert main([*argv, "--seed", "1"]) == 0
    return ss.load_model(out), str(data)


def _same(a: ss.models.ScoreModel, b: ss.models.ScoreModel) -> None:
    sa, sb = a.net.state_dict(), b.net.state_dict()
    assert list(sa) == list(sb)
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k
    da, db = (json.loads(json.dumps(m.info.to_dict())) for m in (a, b))  # as a checkpoint stores it
    assert da.pop("seconds") >= 0 and db.pop("seconds") >= 0  # the one figure that is the clock's
    assert da == db


@pytest.mark.slow
def test_the_cli_saves_the_model_the_library_returns(tmp_path, capsys):
    cfg = TrainConfig(members=1, iterations=3, negatives=2)
    saved, data = _cli_model(tmp_path)
    printed = capsys.readouterr().out
    lines: list[str] = []
    model = ss.train(
        ss.read_jsonl(data), cfg, seed=1, force=True, progress=False, outputs=Outputs(log=lines.append)
    )
    _same(saved, model)
    # six scenes: all trained on, each placed back once by 3-fold cross-validation
    assert model.info.validation is not None and model.info.validation["scenes"] == 6
    assert model.info.validation["folds"] == 3
    # tidying's calibration waits for the first tidy: the six scenes are kept for it
    assert model.info.tidy is not None and model.info.tidy.scenes == 6 and model.info.trust is not None
    assert model.info.tidy.pending is not None and len(model.info.tidy.pending) == 6
    assert model.info.tidy.gains is None
    trained = [s for s in lines if s.startswith("trained on 6 scenes")]
    assert len(trained) == 1 and trained[0].split(" s ")[1] in printed
    assert [s for s in lines[1:] if "when the model first tidies" in s][0] in printed
    report = json.loads((tmp_path / "train_report.json").read_text())
    assert (
        report["tidy"] == {"scenes": 6, "seed": 1, "measured": False}
        and report["validation"] == model.info.validation
    )


def test_given_held_out_scenes_are_validated_on_and_every_scene_trained_on(tmp_path, capsys):
    scenes, held = _pairs(4), _pairs(6)[4:]
    assert holdout(scenes, heldout=held) == (scenes, held)
    assert holdout(scenes, 0.15) == (scenes, [])  # too few to hold out 4: all trained on, with a warning
    assert "too few to hold out 4" in capsys.readouterr().err
    model = ss.train(
        scenes,
        SMALL,
        force=True,
        progress=False,
        validation=Validation(heldout=held),
        outputs=Outputs(log=None, checkpoint=tmp_path / "m.ckpt"),
    )
    assert model.info.scenes == 4 and model.info.validation["scenes"] == 2
    assert not (tmp_path / "m.val.jsonl").exists()  # scenes given, not split here: not written again
    assert json.loads((tmp_path / "train_report.json").read_text())["checkpoint"] == str(tmp_path / "m.ckpt")
    _same(ss.load_model(tmp_path / "m.ckpt"), model)


@pytest.mark.parametrize("folds", [1, None])  # one hold-out; cross-validation (six scenes)
def test_a_model_that_learned_nothing_is_refused_unless_forced(tmp_path, monkeypatch, folds):
    from scenescore.workflow import crossval, training

    def flat(scenes, *a, **k):
        model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=1)
        model.info = ss.models.ModelInfo(scenes=len(scenes), seconds=0.0, final_loss=1.1, chance_loss=1.1)
        return model

    monkeypatch.setattr(training, "fit", flat)
    monkeypatch.setattr(crossval, "fit", flat)  # the final model's and the folds' trainings
    with pytest.raises(NothingLearned, match=r"never fell below chance \(1.100\)") as e:
        ss.train(
            _pairs(6),
            SMALL,
            progress=False,
            validation=Validation(folds=folds),
            outputs=Outputs(log=None, checkpoint=tmp_path / "m.ckpt"),
        )
    assert e.value.final_loss == e.value.chance_loss == 1.1 and not list(tmp_path.iterdir())
