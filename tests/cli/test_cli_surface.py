"""The command line's surface: --device wherever a model runs, range-checked counts, experiment options
refused where they do not apply, `info`, `inspect`, training settings from --config and --set, help texts."""

from __future__ import annotations

import argparse
import json

import pytest
import torch
from cli_model import train_tiny  # tests/cli, the test files' own folder

from scenescore.cli import build_parser, main
from scenescore.cli.experiment import EXPERIMENTS, OWN_OPTIONS
from scenescore.cli.train_settings import build_config, overridden, parse_overrides, read_config, setting_keys
from scenescore.errors import ConfigError
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.models import load

MODEL_COMMANDS = [
    "train",
    "evaluate",
    "place",
    "tidy",
    "heatmap",
    "explain",
    "demo",
    "solve",
    "compare",
    "experiment",
]


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {s: a for a in parser._actions for s in a.option_strings}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """Six dining scenes and a model trained on them for two iterations."""
    torch.set_num_threads(1)
    d = tmp_path_factory.mktemp("surface")
    train_tiny(d, 2, "--set", "feature_noise=0.3", "--set", "network.hidden=16")
    scene = json.loads((d / "data.jsonl").read_text().splitlines()[0])
    (d / "scene.json").write_text(json.dumps(scene))
    return d


# --device


@pytest.mark.parametrize("command", MODEL_COMMANDS)
def test_every_model_command_takes_device(command):
    action = _options(_subparsers()[command])["--device"]
    assert action.default == "cpu" and "cuda" in action.help


@pytest.mark.parametrize(
    "argv",
    [
        ["evaluate", "{m}", "{d}/data.jsonl"],
        ["heatmap", "{m}", "{d}/scene.json", "--object", "fork", "--out", "{d}/h.png"],
        ["tidy", "{m}", "{d}/scene.json"],
        ["demo", "--out", "{d}/demo"],
    ],
)
def test_a_bad_device_is_one_line(tiny, argv, capsys):
    argv = [a.format(m=tiny / "m.ckpt", d=tiny) for a in argv]
    assert main(argv + ["--device", "tpu", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--device tpu" in err


def test_evaluate_on_the_cpu_device(tiny, capsys):
    assert (
        main(["evaluate", str(tiny / "m.ckpt"), str(tiny / "data.jsonl"), "--device", "cpu", "--quiet"]) == 0
    )
    assert "leave-one-object-out" in capsys.readouterr().out


# range-checked counts


def test_no_option_is_a_bare_int():
    bare = [
        f"{name} {a.option_strings[0]}"
        for name, sp in _subparsers().items()
        for a in sp._actions
        if a.option_strings and a.type is int
    ]
    assert not bare, bare


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "x.jsonl", "--out", "m.ckpt", "--iterations", "0"],
        ["train", "x.jsonl", "--out", "m.ckpt", "--negatives", "-1"],
        ["place", "m.ckpt", "s.json", "--particles", "0"],
        ["export", "m.ckpt", "--onnx", "m.onnx", "--opset", "5"],
        ["generate", "dining", "--n", "0"],
        ["experiment", "tidy", "--seeds", "0"],
        ["experiment", "tidy", "--jobs", "0"],
        ["experiment", "tidy", "--iterations", "1.5"],
        ["experiment", "tidy", "--test-scenes", "0"],
        ["compare", "p.yaml", "--seeds", "0"],
        ["demo", "--iterations", "0"],
        ["demo", "--test-scenes", "0"],
        ["evaluate", "m.ckpt", "d.jsonl", "--per-category", "0"],
    ],
)
def test_counts_are_range_checked(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2
    assert f"argument {argv[-2]}: expected an integer" in err.splitlines()[-1]


# experiment options


def test_an_option_of_another_experiment_is_refused(capsys):
    assert main(["experiment", "missing", "--efforts", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "--efforts" in err and "tidy" in err and "missing" in err


def test_experiment_options_are_owned_and_default_to_unset():
    parser = _subparsers()["experiment"]
    options = _options(parser)
    common = {"-h", "--help", "--seeds", "--out", "--quick", "--seed", "--quiet", "--memory-gb", "--threads"}
    common |= {"--jobs", "--fresh", "--model-cache", "--executor"} | {
        o for o in options if o.startswith("--slurm-")
    }
    assert set(options) - common - {"--device"} == set(OWN_OPTIONS)
    for option, owners in OWN_OPTIONS.items():
        assert options[option].default in (None, False), option  # "given" is "not the default"
        assert set(owners) <= set(EXPERIMENTS)


# info and inspect


def test_info(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    for word in (
        "scenescore",
        "torch",
        "numpy",
        "casadi",
        "osqp",
        "tensorboard",
        "cuda",
        "threads",
        "memory",
    ):
        assert word in out, word
    assert "SCENESCORE_MEMORY_GB" in out and "SCENESCORE_CLIP_WEIGHTS" in out
    assert main(["info", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["extras"]) == {"clip", "minilm", "pretrained", "export", "tensorboard"}
    assert isinstance(data["cuda"]["available"], bool) and data["threads"]["budget"] >= 1


def test_inspect(tiny, capsys):
    assert main(["inspect", str(tiny / "m.ckpt")]) == 0
    out = capsys.readouterr().out
    for word in ("length_scale", "walls", "encoder", "seed", "losses", "tidy_calibration", "validation"):
        assert word in out, word
    assert main(["inspect", str(tiny / "m.ckpt"), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["network"]["hidden"] == 16 and data["training"]["config"]["feature_noise"] == 0.3
    assert data["training"]["config"]["iterations"] == 2
    assert main(["inspect", str(tiny / "none.ckpt")]) == 2


# training settings


def test_set_reaches_the_checkpoint(tiny):
    cfg = load(tiny / "m.ckpt").info.train_config
    assert cfg is not None and cfg["feature_noise"] == 0.3 and cfg["network"]["hidden"] == 16


@pytest.mark.parametrize(
    ("key", "nearest"), [("feature_nois", "feature_noise"), ("netwrk.hiden", "network.hidden")]
)
def test_an_unknown_key_names_the_nearest(tiny, key, nearest, capsys):
    argv = ["train", str(tiny / "data.jsonl"), "--out", str(tiny / "x.ckpt"), "--set", f"{key}=1"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and repr(nearest) in err and not (tiny / "x.ckpt").exists()


def test_values_are_yaml_scalars_and_typed():
    got = parse_overrides(
        ["walls=true", "edge_range=null", "perturb_pos=[0.1, 1]", "lr=1e-3", "chain.steps=40"]
    )
    assert got == {"walls": True, "edge_range": None, "perturb_pos": (0.1, 1), "lr": 1e-3, "chain.steps": 40}
    for bad in ["walls=maybe", "iterations=2.5", "feature_noise=yes", "network=3", "noequals"]:
        with pytest.raises(ConfigError):
            parse_overrides([bad])
    assert "network.hidden" in setting_keys() and "chain.steps" in setting_keys()


def test_config_file_and_precedence(tmp_path):
    f = tmp_path / "train.yaml"
    f.write_text(
        "iterations: 7\nnegatives: 4\nnetwork:\n  hidden: 8\nchain:\n  steps: 10\nfeature_noise: 0.2\n"
    )
    file = read_config(f)
    cfg = build_config(file, {"iterations": 5}, parse_overrides(["network.hidden=12"]))
    assert (cfg.iterations, cfg.negatives, cfg.network.hidden, cfg.chain.steps) == (5, 4, 12, 10)
    assert cfg.feature_noise == 0.2
    assert build_config() == TrainConfig()  # nothing given: the defaults, exactly
    assert TrainConfig().members == 3  # an ensemble of three by default
    (tmp_path / "bad.yaml").write_text("iterations: 3\nnetwrk:\n  hidden: 8\n")
    with pytest.raises(ConfigError, match="'network'"):
        read_config(tmp_path / "bad.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n")
    with pytest.raises(ConfigError, match="mapping"):
        read_config(tmp_path / "list.yaml")


def test_settings_change_a_given_config_and_keep_the_rest():
    base = TrainConfig(iterations=100, negatives=4, network=NetworkConfig(hidden=8))
    cfg = overridden(base, parse_overrides(["perturbed=8", "chain.steps=12", "network.layers=2"]))
    assert (cfg.iterations, cfg.negatives, cfg.perturbed) == (100, 4, 8)
    assert (cfg.network.hidden, cfg.network.layers, cfg.chain.steps) == (8, 2, 12)
    assert cfg.chain.step_init == base.chain.step_init and base.perturbed == 0  # the base is unchanged
    assert overridden(base, {}) == base
    with pytest.raises(ConfigError, match="iterations"):
        overridden(base, {"iterations": 0})


# help texts


@pytest.mark.parametrize("command", sorted(_subparsers()))
def test_help_has_no_markup(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = capsys.readouterr().out
    assert "``" not in out and "earlier default" not in out


@pytest.mark.parametrize("command", ["experiment", "compare"])
def test_seeds_say_which_seeds(command):
    assert "N-1" in _options(_subparsers()[command])["--seeds"].help


def test_docs_table_of_experiment_options_matches():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    table: dict[str, tuple[str, ...]] = {}
    for row in doc.splitlines():
        cells = [c.strip() for c in row.strip("|").split("|")]
        if row.startswith("| `--") and len(cells) == 2:
            for option in cells[0].replace("`", "").split(", "):
                table[option] = tuple(cells[1].split(", "))
    assert table == OWN_OPTIONS
