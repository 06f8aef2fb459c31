"""YAML problem files: a good file solves; every error names the file, line and key path."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from scenescore.cli import UserError
from scenescore.cli import problems as cli_problems
from scenescore.problem.files import load_problem
from scenescore.problem.problem import ProblemError

SCENE = {
    "objects": [
        {"name": "box", "category": "box", "size": [0.3, 0.3], "pose": [0, 0, 0], "fixed": True},
        {"name": "mug", "category": "mug", "size": [0.1, 0.1], "pose": None, "shape": "disk"},
    ],
    "bounds": [[-0.6, -0.6], [0.6, 0.6]],
}

GOOD = """scene: scene.json
costs:
  - {type: target, object: mug, xy: [0.1, 0.05], weight: 100.0}
  - type: collision
    weight: 100.0
    margin: 0.01
  - {type: bounds}
  - {type: reach, base: [0.0, -0.5], radius: 1.0}
solver: osqp
options:
  osqp: {max_iter: 80}
seed: 0
"""


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    return tmp_path


def _err(folder: Path, text: str) -> str:
    f = folder / "p.yaml"
    f.write_text(text)
    with pytest.raises(ProblemError) as e:
        load_problem(f)
    return str(e.value)


def test_good_file_loads_and_solves(folder):
    (folder / "p.yaml").write_text(GOOD)
    lp = load_problem(folder / "p.yaml")
    assert lp.solver == "osqp" and lp.options == {"osqp": {"max_iter": 80}}
    assert lp.problem.cost.names == ["target_mug", "collision", "bounds", "reach"]
    assert lp.problem.cost.weight("collision") == 100.0 and lp.problem.movable == ["mug"]


@pytest.mark.parametrize(
    "old,new,expected",
    [
        (
            "margin: 0.01",
            "margn: 0.01",
            r"p.yaml:6: costs\[1\].margn: unknown key 'margn'; did you mean 'margin'",
        ),
        (
            "weight: 100.0\n    margin",
            "weight: heavy\n    margin",
            r"p.yaml:5: costs\[1\].weight: Input should be a valid number",
        ),
        (
            "object: mug",
            "object: mugg",
            r"p.yaml:3: costs\[0\].object: no object named 'mugg'.*did you mean 'mug'",
        ),
        (
            "scene: scene.json",
            "scene: nothere.json",
            r"p.yaml:1: scene: scene file .*nothere.json' does not exist",
        ),
        (
            "solver: osqp",
            "solver: langevin>osq",
            r"p.yaml:9: solver: unknown solver 'osq'; did you mean 'osqp'",
        ),
        (
            "type: collision",
            "type: collide",
            r"p.yaml:4: costs\[1\]: cost 'type' must be one of energy, collision",
        ),
        ("seed: 0", "sed: 0", r"p.yaml:12: sed: unknown key 'sed'; did you mean 'seed'"),
        ("seed: 0", "seed: zero", r"p.yaml:12: seed: Input should be a valid integer"),
        (
            "options:\n  osqp:",
            "options:\n  osq:",
            r"p.yaml:11: options.osq: unknown solver 'osq'; did you mean 'osqp'",
        ),
        ("seed: 0", "model: nothere.ckpt\nseed: 0", None),  # a model nobody uses is not loaded
        ("  - {type: bounds}", "  - {type: energy}", r"costs\[2\]: an 'energy' cost needs a 'model'"),
        ("seed: 0", "movable: [cup]", r"p.yaml:12: movable\[0\]: no object named 'cup'"),
        ("seed: 0", "seed: [1", r"p.yaml:1[23]: not valid YAML"),
        ("radius: 1.0", "radius: -1.0", r"costs\[3\].radius: Input should be greater than 0"),
    ],
)
def test_yaml_errors_name_line_and_key(folder, old, new, expected):
    text = GOOD.replace(old, new)
    assert text != GOOD
    if expected is None:
        (folder / "p.yaml").write_text(text)
        load_problem(folder / "p.yaml")
        return
    msg = _err(folder, text)
    import re

    assert re.search(expected, msg), msg
    assert "\n" not in msg  # one line


def test_missing_model_file_and_missing_problem_file(folder):
    text = GOOD.replace("  - {type: bounds}", "  - {type: energy}").replace("seed: 0", "model: gone.ckpt")
    assert "model: model checkpoint" in _err(folder, text) and "gone.ckpt' does not exist" in _err(
        folder, text
    )
    with pytest.raises(ProblemError, match="no such problem file"):
        load_problem(folder / "absent.yaml")


def test_inline_scene_and_cli_solve_writes_json_and_plot(folder, capsys):
    import argparse

    text = GOOD.replace("scene: scene.json", "scene: " + json.dumps(SCENE))
    (folder / "p.yaml").write_text(text)
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    cli_problems.register(sub)
    args = parser.parse_args(
        [
            "solve",
            str(folder / "p.yaml"),
            "--out",
            str(folder / "r.json"),
            "--plot",
            str(folder / "r.png"),
            "--quiet",
        ]
    )
    assert args.func(args) == 0
    out = json.loads((folder / "r.json").read_text())
    assert out["success"] and np.allclose(out["poses"]["mug"][:2], [0.21, 0.05], atol=1e-4)
    assert (folder / "r.png").stat().st_size > 1000
    assert "target_mug" in capsys.readouterr().out
    args = parser.parse_args(
        [
            "compare",
            str(folder / "p.yaml"),
            "--solvers",
            "osqp,casadi",
            "--seeds",
            "2",
            "--out",
            str(folder / "cmp"),
            "--quiet",
        ]
    )
    assert args.func(args) == 0
    # --out is a folder holding exactly the table and its JSON
    assert sorted(p.name for p in (folder / "cmp").iterdir()) == ["comparison.json", "table.md"]
    table = (folder / "cmp" / "table.md").read_text()
    assert "| osqp | 100% | 100% |" in table
    rows = json.loads((folder / "cmp" / "comparison.json").read_text())["rows"]
    assert [r["solver"] for r in rows] == ["osqp", "casadi"]
    # a file name where the folder belongs is refused before anything runs
    args = parser.parse_args(["compare", str(folder / "p.yaml"), "--out", str(folder / "c.md"), "--quiet"])
    with pytest.raises(UserError, match="a folder"):
        args.func(args)
    assert not (folder / "c.md").exists()
    # unknown, empty or repeated names are refused before anything runs
    for bad, said in (
        ("osqp,nope", "unknown solver 'nope'"),
        ("langevin,,osqp", "empty"),
        ("osqp,osqp", "more than once"),
        ("langevin>", "empty"),
    ):
        args = parser.parse_args(["compare", str(folder / "p.yaml"), "--solvers", bad, "--quiet"])
        with pytest.raises(UserError, match=said):
            args.func(args)


def test_cli_solve_seed_defaults_to_the_files_and_any_integer_is_a_seed(folder, capsys):
    """``solve`` without --seed takes the file's ``seed``; -1 is a seed like any other, not a sentinel."""
    from scenescore.cli import main

    (folder / "p.yaml").write_text(GOOD.replace("seed: 0", "seed: 7"))
    assert main(["solve", str(folder / "p.yaml")]) == 0
    assert "(seed 7)" in capsys.readouterr().out
    assert main(["solve", str(folder / "p.yaml"), "--seed", "-1"]) == 0
    assert "(seed -1)" in capsys.readouterr().out
