"""Training data that cannot teach is refused by name; a run that learned nothing writes no checkpoint."""

from __future__ import annotations

import json

import pytest
import torch

from scenescore.cli import main
from scenescore.learn import check_training_data
from scenescore.scenarios import DiningScenario
from scenescore.scene.scene import SceneError, read_jsonl, write_jsonl


@pytest.fixture(scope="module")
def lines(tmp_path_factory):
    path = tmp_path_factory.mktemp("d") / "d.jsonl"
    write_jsonl(path, DiningScenario().generate(6, seed=0))
    return [json.loads(x) for x in path.read_text().splitlines()]


def _file(tmp_path, lines, edit=None, name="d.jsonl"):
    rows = [json.loads(json.dumps(d)) for d in lines]
    if edit:
        edit(rows)
    p = tmp_path / name
    p.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return p


def _empty_third(rows):
    rows[2]["objects"] = []


def _null_pose(rows):
    rows[3]["objects"][1]["pose"] = None


def _far(rows):
    rows[1]["objects"][0]["pose"] = [
        1e3,
        0.0,
        0.0,
    ]  # metres where the table is 1.2 m (1e9 the reader refuses)


def _one_object(rows):
    for r in rows:
        r["objects"] = r["objects"][:1]


def _all_fixed(rows):
    for r in rows:
        for o in r["objects"]:
            o["fixed"] = True


@pytest.mark.parametrize(
    "edit, needle",
    [
        (_empty_third, ":3: the scene has no objects"),
        (_null_pose, ":4: objects without a pose"),
        (_far, ":2: object 'plate_0' at (1000, 0) lies far outside the bounds"),
        (_one_object, "no example scene has a movable object beside another"),
        (_all_fixed, "no example scene has a movable object beside another"),
    ],
)
def test_data_that_cannot_teach_is_refused_by_name(tmp_path, lines, edit, needle):
    p = _file(tmp_path, lines, edit)
    with pytest.raises(SceneError, match=needle.replace("(", r"\(").replace(")", r"\)").replace("+", r"\+")):
        check_training_data(read_jsonl(p))


def test_the_cli_refuses_before_training_and_writes_nothing(tmp_path, lines, capsys):
    p = _file(tmp_path, lines, _empty_third)
    assert main(["train", str(p), "--out", str(tmp_path / "m.ckpt"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{p}:3" in err[0] and not (tmp_path / "m.ckpt").exists()


def test_a_run_that_learned_nothing_writes_no_checkpoint_unless_forced(tmp_path, lines, capsys):
    torch.set_num_threads(1)
    p = _file(tmp_path, lines)
    out = tmp_path / "m.ckpt"
    out.write_bytes(b"an earlier checkpoint")
    argv = [
        "train",
        "--members",
        "1",
        str(p),
        "--out",
        str(out),
        "--iterations",
        "1",
        "--val",
        "0",
        "--quiet",
    ]
    assert main(argv) == 2
    assert "learned nothing" in capsys.readouterr().err
    assert out.read_bytes() == b"an earlier checkpoint"  # nothing lost
    assert main([*argv, "--force"]) == 0
    assert out.read_bytes() != b"an earlier checkpoint"
