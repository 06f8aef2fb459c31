"""The README runs as written: its shell session and Python snippets run in a copy of the examples,
its JSON and YAML examples load, and every command in its tables parses."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import scenescore as ss
from scenescore.cli import build_parser
from scenescore.problem.files import load_problem

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_the_two_install_commands_come_first_and_match_ci():
    """The README opens with the install-and-demo and install-and-test commands; CI runs the second."""
    shell = _blocks("bash")
    install = [b for b in shell if "pip install" in b]
    assert shell[:2] == install and len(install) == 2
    assert install[0].strip().endswith(".venv/bin/scenescore demo")
    ci = (ROOT / ".ci" / "run").read_text()
    for step in ("pip install torch==2.13.0", '-e ".[test]"', "install_clip.sh", "install_minilm.sh"):
        assert step.split()[-1] in install[1] and step.split()[-1] in ci, step
    test = "-m pytest -q -n auto --dist loadfile tests"  # one worker per core, each test file on one
    assert install[1].strip().endswith(test) and test in ci


def test_table_commands_parse():
    """Every `scenescore ...` in the README's tables names a command and options that exist, with and
    without its optional parts in brackets; a typo in an option fails here."""
    rows = [line for line in README.splitlines() if line.startswith("|")]
    commands = [c for line in rows for c in re.findall(r"`(scenescore [^`]+)`", line)]
    assert len(commands) >= 12
    parser = build_parser()
    for cmd in commands:
        for form in (re.sub(r"\[[^\]]*\]", "", cmd), cmd.replace("[", "").replace("]", "")):
            try:
                parser.parse_args(shlex.split(form)[1:])
            except SystemExit as e:
                raise AssertionError(f"README command does not parse: {form}") from e


def test_json_and_yaml_examples_load(tmp_path):
    (scene_text,) = _blocks("json")
    scene = ss.Scene.from_dict(json.loads(scene_text))
    assert scene.objects[0].name == "fork_0"
    (problem_text,) = _blocks("yaml")
    shutil.copy(ROOT / "examples" / "dining_scene.json", tmp_path / "dining_scene.json")
    from scenescore.encoders import FootprintEncoder
    from scenescore.models import ScoreModel

    ScoreModel.create(FootprintEncoder(), hidden=8, layers=1).save(tmp_path / "dining.ckpt")
    loaded = load_problem(tmp_path / "problem.yaml", text=problem_text)
    assert loaded.problem.movable == ["bowl_0"]


def test_session_and_python_snippets_run(tmp_path, capsys, own_registries):
    """The shell session, then each Python snippet, in a folder holding a copy of the examples."""
    shutil.copytree(ROOT / "examples", tmp_path / "examples", ignore=shutil.ignore_patterns("*.ckpt"))
    bindir = str(Path(sys.executable).parent)
    env = {**os.environ, "PATH": bindir + os.pathsep + os.environ.get("PATH", ""), "OMP_NUM_THREADS": "1"}
    sessions = [b for b in _blocks("bash") if "pip install" not in b]
    assert sessions, "the README has no shell session"
    for block in sessions:
        for line in block.strip().splitlines():
            if "--quiet" not in line and line.startswith("scenescore "):
                line += " --quiet"
            r = subprocess.run(
                ["bash", "-o", "pipefail", "-c", line], cwd=tmp_path, env=env, capture_output=True, text=True
            )
            assert r.returncode == 0, f"README line failed: {line}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
    for name in (
        "model.ckpt",
        "filled.json",
        "filled.png",
        "tidy.json",
        "tidy.png",
        "heat.png",
        "result.json",
        "solved.png",
    ):
        assert (tmp_path / name).is_file(), name
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for k, code in enumerate(_blocks("python")):
            exec(compile(code, f"README.md:python-{k}", "exec", dont_inherit=True), {"__name__": "readme"})
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "feasible" in out


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
