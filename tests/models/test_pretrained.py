"""The models the package ships: every scenario's loads by name, offline, and reaches the figure its
index documents on the first test scenes of its split, within the stated tolerance; an unknown name is
a one-line error listing the names; the command line takes a name where it takes a checkpoint."""

from __future__ import annotations

import fnmatch
import json
import tomllib
from importlib import resources
from pathlib import Path

import pytest

from scenescore.cli import main
from scenescore.experiments.bundled import (
    PRIOR,
    RELATION_MODELS,
    RELATION_SHORTFALL,
    SCENARIOS,
    figure,
    relation_figure,
    tolerance,
)
from scenescore.experiments.prior import PRIOR_DATASETS
from scenescore.models import CheckpointError, ScoreModel, pretrained, pretrained_index, pretrained_names
from scenescore.scenarios import available

ROOT = Path(__file__).resolve().parents[2]
INDEX = pretrained_index()


def test_every_scenario_ships_a_model_with_its_record():
    assert pretrained_names() == sorted(INDEX) == sorted((*SCENARIOS, *RELATION_MODELS, PRIOR))
    assert set(SCENARIOS) | set(RELATION_MODELS) <= set(available()) and len(SCENARIOS) == 16
    for name, entry in INDEX.items():
        assert entry["seed"] == 0 and entry["train_scenes"] > 0, name
        assert entry["config"]["iterations"] > 0 and entry["commit"]["commit"], name
        assert 20_000 < entry["bytes"] < 400_000, f"{name}: {entry['bytes']} bytes"
        if name == PRIOR:  # its record: the loss its training reached, beside chance, and its data
            assert entry["final_loss"] < entry["chance_loss"] and entry["datasets"] == list(PRIOR_DATASETS)
            assert entry["length_scale_m"] == pytest.approx(1.0, rel=0.2)  # its data at unit scale
            continue
        if name in RELATION_MODELS:  # its figure: the fraction of held-out examples placed back satisfied
            assert entry["held_out"] >= 1 and 0.5 <= entry["satisfied"] <= 1.0, name
            assert entry["min_satisfied"] == pytest.approx(max(entry["satisfied"] - RELATION_SHORTFALL, 0.0))
            continue
        assert entry["test_scenes"] >= 1 and len(entry["errors_m"]) >= entry["test_scenes"], name
        stated = tolerance(entry["mean_error_m"], entry["length_scale_m"])
        assert entry["tolerance_m"] == pytest.approx(stated, abs=1e-6), name


def test_every_indexed_name_loads():
    for name in INDEX:
        model = pretrained(name)
        assert isinstance(model, ScoreModel)
        assert model.device.type == "cpu" and model.info.seed == INDEX[name]["seed"]
        assert model.config.length_scale == INDEX[name]["length_scale_m"]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(RELATION_MODELS))
def test_shipped_relation_model_places_its_held_out_examples(name):
    entry = INDEX[name]
    got = relation_figure(pretrained(name), name, entry["seed"], entry["held_out"])
    assert got["held_out"] == entry["held_out"]
    assert got["satisfied"] >= entry["min_satisfied"], (
        f"{name}: {got['satisfied']:.2f} of held-out examples satisfied, documented {entry['satisfied']:.2f} "
        f"less {RELATION_SHORTFALL}"
    )


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_shipped_model_reaches_its_documented_figure(name):
    entry = INDEX[name]
    got = figure(pretrained(name), name, entry["seed"], entry["test_scenes"])
    assert got["test_scenes"] == entry["test_scenes"]
    assert got["mean_error"] <= entry["mean_error_m"] + entry["tolerance_m"], (
        f"{name}: mean placement error {got['mean_error']:.4f} m, documented "
        f"{entry['mean_error_m']:.4f} m + {entry['tolerance_m']:.4f} m"
    )


def test_cli_trains_from_the_shipped_prior(tmp_path, capsys):
    """``scenescore train --init prior`` at the defaults: the run starts from the prior's weights and
    the checkpoint says so."""
    from scenescore.models import load
    from scenescore.scenarios import get
    from scenescore.scene.scene import write_jsonl

    data, out = tmp_path / "desk.jsonl", tmp_path / "tuned.ckpt"
    write_jsonl(data, get("desk").generate(5, 3))
    args = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(out),
        "--init",
        "prior",
        "--iterations",
        "2",
        "--val",
        "0",
    ]
    assert main([*args, "--folds", "1", "--force", "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "starting from the weights of prior" in said
    assert "`--init prior` starts" not in said  # started from it: no hint to
    init = load(out).info.init
    assert init is not None and init["source"] == "prior"


def test_unknown_name_is_one_line_naming_the_available_ones():
    with pytest.raises(CheckpointError) as err:
        pretrained("dinning")
    msg = str(err.value)
    assert "\n" not in msg and "'dinning'" in msg and "did you mean 'dining'" in msg
    assert all(n in msg for n in (*SCENARIOS, *RELATION_MODELS))


def test_the_package_data_includes_every_shipped_file():
    """pyproject's package-data globs match every file of the folder, so a wheel carries them."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    folder = resources.files("scenescore.models") / "pretrained"
    files = [f"models/pretrained/{f.name}" for f in folder.iterdir() if f.is_file()]
    assert "models/pretrained/index.json" in files and len(files) == len(INDEX) + 1
    for f in files:
        assert any(fnmatch.fnmatch(f, g) for g in globs["scenescore"]), f


@pytest.mark.slow
def test_cli_place_with_a_scenario_name(tmp_path, capsys):
    out = tmp_path / "f.json"
    assert main(["place", "dining", str(ROOT / "examples" / "dining_scene.json"), "--out", str(out)]) == 0
    pose = next(o for o in json.loads(out.read_text())["objects"] if o["name"] == "bowl_0")["pose"]
    assert pose is not None and len(pose) == 3
    assert "bowl_0" in capsys.readouterr().out


def test_cli_unknown_name_and_missing_file_are_one_line_errors(tmp_path, capsys):
    scene = str(ROOT / "examples" / "dining_scene.json")
    assert main(["inspect", "no-such-scenario"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "no pretrained model 'no-such-scenario'" in err and "dining" in err
    assert main(["place", str(tmp_path / "model.ckpt"), scene]) == 2  # a path: never a name
    assert "no such checkpoint file" in capsys.readouterr().err
