"""``scenescore train`` validates on held-out scenes; ``scenescore evaluate`` prints the same figures."""

from __future__ import annotations

import json

import pytest
import torch

from scenescore.cli import main


@pytest.mark.slow
def test_train_validation_equals_evaluate(tmp_path, capsys):
    torch.set_num_threads(1)
    data = tmp_path / "d.jsonl"
    assert main(["generate", "dining", "--n", "8", "--out", str(data), "--seed", "2", "--quiet"]) == 0
    ckpt = tmp_path / "m.ckpt"
    args = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(ckpt),
        "--iterations",
        "8",
        "--force",  # a short run: its loss may not be below chance yet
        "--folds",  # one hold-out (eight scenes would be cross-validated: test_crossval)
        "1",
        "--quiet",
        "--plot",
        str(tmp_path / "t.png"),
    ]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "leave-one-object-out on 4 held-out scenes" in out and "held-out InfoNCE loss" in out
    report = json.loads((tmp_path / "train_report.json").read_text())
    val = report["validation"]
    assert val["scenes"] == 4 and val["placements"] == 32 and val["baseline"] == "Nearest-Nbr"
    assert {c["category"] for c in val["categories"]} == {"plate", "fork", "knife", "bowl"}
    assert report["tidy"] == {
        "scenes": 4,
        "seed": 0,
        "measured": False,
    }  # the held-out scenes, measured at the first tidy
    assert "tidy: what a move must gain is measured on 4 held-out scenes when the model first tidies" in out
    assert (tmp_path / "t.png").stat().st_size > 0
    held = tmp_path / "m.val.jsonl"
    ev_json = tmp_path / "ev.json"
    again = ["evaluate", str(ckpt), str(held), "--per-category", "32", "--train-data", str(data)]
    assert f"`scenescore evaluate {ckpt} {held} --per-category 32 --train-data {data} --seed 0`" in out
    assert main([*again, "--out", str(ev_json), "--quiet"]) == 0
    assert json.loads(ev_json.read_text()) == val  # the same figures, to the last digit
    assert main([*again[:3], "--per-category", "3", "--out", str(ev_json), "--quiet"]) == 0
    assert json.loads(ev_json.read_text())["placements"] == 12  # three of each of the four categories
    # the checkpoint carries them too
    from scenescore.models import load

    assert load(ckpt).info.validation == val
    # --val 0: no validation; --objects restricts evaluate
    capsys.readouterr()
    assert (
        main(
            [
                "train",
                "--members",
                "1",
                str(data),
                "--out",
                str(tmp_path / "n.ckpt"),
                "--iterations",
                "2",
                "--force",
                "--val",
                "0",
                "--quiet",
            ]
        )
        == 0
    )
    assert "held-out" not in capsys.readouterr().out
    rc = main(["evaluate", str(ckpt), str(held), "--objects", "fork_0", "--out", str(ev_json), "--quiet"])
    assert rc == 0 and json.loads(ev_json.read_text())["placements"] == 4
    assert main(["evaluate", str(ckpt), str(held), "--objects", "spoon_9", "--quiet"]) == 2
