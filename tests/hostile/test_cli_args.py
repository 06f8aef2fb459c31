"""Hostile command lines: every case exits 2 with one line ``scenescore CMD: error: ...`` naming the
argument or file (no traceback), before any work is done; or does what a valid extreme asks."""

from __future__ import annotations

import json
import os
import shutil

import pytest

from .helpers import SCENE, cli_error, run_cli, scene, with_object, write

ROOT = os.geteuid() == 0


@pytest.fixture
def w(tmp_path, model_path, scene_path):
    """A folder with m.ckpt, scene.json (cup to place), full.json (every pose known), data.jsonl,
    p.yaml and a regular file ``file``."""
    shutil.copy(model_path, tmp_path / "m.ckpt")
    shutil.copy(scene_path, tmp_path / "scene.json")
    write(tmp_path / "full.json", with_object(2, pose=[0.3, 0.3, 0.0]))
    line = json.dumps(with_object(2, pose=[0.3, 0.3, 0.0]))
    write(tmp_path / "data.jsonl", (line + "\n") * 3)
    write(tmp_path / "one.jsonl", (json.dumps(scene(objects=SCENE["objects"][:1])) + "\n") * 3)
    full = json.dumps(with_object(2, pose=[0.3, 0.3, 0.0]))
    write(tmp_path / "empty_scene.jsonl", f"{full}\n{json.dumps(scene(objects=[]))}\n")
    write(tmp_path / "null_pose.jsonl", f"{full}\n{json.dumps(SCENE)}\n")
    write(tmp_path / "far.jsonl", f"{full}\n" + json.dumps(with_object(2, pose=[500.0, 0.0, 0.0])) + "\n")
    write(
        tmp_path / "fixed.jsonl",
        (
            json.dumps(
                scene(
                    objects=[
                        dict(o, pose=[0.1 * i, 0, 0], fixed=True) for i, o in enumerate(SCENE["objects"])
                    ]
                )
            )
            + "\n"
        )
        * 2,
    )
    write(
        tmp_path / "p.yaml", "scene: scene.json\nmodel: m.ckpt\ncosts: [{type: energy}, {type: collision}]\n"
    )
    write(tmp_path / "file", "a regular file\n")
    return tmp_path


# argv templates: {w} is the folder above
CASES = [
    # train: settings, data, outputs (outputs and settings before the data is read)
    ("train --iterations -5", "train {w}/data.jsonl --out {w}/x.ckpt --iterations -5", ("iterations", "-5")),
    ("train --iterations 0", "train {w}/data.jsonl --out {w}/x.ckpt --iterations 0", ("iterations",)),
    (
        "train --iterations abc",
        "train {w}/data.jsonl --out {w}/x.ckpt --iterations abc",
        ("--iterations", "'abc'"),
    ),
    ("train --negatives 0", "train {w}/data.jsonl --out {w}/x.ckpt --negatives 0", ("negatives",)),
    ("train --negatives -3", "train {w}/data.jsonl --out {w}/x.ckpt --negatives -3", ("negatives",)),
    ("train --val 1.5", "train {w}/data.jsonl --out {w}/x.ckpt --val 1.5", ("--val", "1.5")),
    ("train --val -0.1", "train {w}/data.jsonl --out {w}/x.ckpt --val -0.1", ("--val",)),
    ("train --val nan", "train {w}/data.jsonl --out {w}/x.ckpt --val nan", ("--val",)),
    ("train --ppm 0", "train {w} --out {w}/x.ckpt --ppm 0", ("--ppm",)),
    ("train --ppm nan", "train {w} --out {w}/x.ckpt --ppm nan", ("--ppm",)),
    ("train --ppm -3", "train {w} --out {w}/x.ckpt --ppm -3", ("--ppm",)),
    ("train --encoder bogus", "train {w}/data.jsonl --out {w}/x.ckpt --encoder bogus", ("'bogus'",)),
    ("train data missing", "train {w}/none.jsonl --out {w}/x.ckpt", ("none.jsonl",)),
    (
        "train data cannot teach",
        "train {w}/one.jsonl --out {w}/x.ckpt --iterations 1",
        ("no example scene has a movable object",),
    ),
    (
        "train data with an empty scene",
        "train {w}/empty_scene.jsonl --out {w}/x.ckpt",
        ("empty_scene.jsonl:2", "no objects"),
    ),
    (
        "train data with a null pose",
        "train {w}/null_pose.jsonl --out {w}/x.ckpt",
        ("null_pose.jsonl:2", "cup"),
    ),
    (
        "train data far outside the bounds",
        "train {w}/far.jsonl --out {w}/x.ckpt",
        ("far.jsonl:2", "'cup'", "outside the bounds"),
    ),
    ("train data all fixed", "train {w}/fixed.jsonl --out {w}/x.ckpt", ("every object is fixed",)),
    ("train data a folder without images", "train {w}/none_dir --out {w}/x.ckpt", ("none_dir",)),
    ("train --out under a file", "train {w}/none.jsonl --out {w}/file/x.ckpt", ("--out", "is a file")),
    ("train --out a folder", "train {w}/none.jsonl --out {w}", ("--out", "is a folder")),
    (
        "train --report under a file",
        "train {w}/none.jsonl --out {w}/x.ckpt --report {w}/file/r.json",
        ("--report",),
    ),
    ("train --plot a folder", "train {w}/none.jsonl --out {w}/x.ckpt --plot {w}", ("--plot",)),
    ("train --log-dir a file", "train {w}/none.jsonl --out {w}/x.ckpt --log-dir {w}/file", ("--log-dir",)),
    (
        "train --val-data missing",
        "train {w}/data.jsonl --out {w}/x.ckpt --val-data {w}/none.jsonl",
        ("none.jsonl",),
    ),
    (
        "train --seed 1e30",
        "train {w}/data.jsonl --out {w}/x.ckpt --seed 1000000000000000000000000000000",
        ("--seed",),
    ),
    # place
    ("place --particles 0", "place {w}/m.ckpt {w}/scene.json --particles 0", ("particles",)),
    ("place --particles -8", "place {w}/m.ckpt {w}/scene.json --particles -8", ("particles",)),
    ("place --particles 10**9", "place {w}/m.ckpt {w}/scene.json --particles 1000000000", ("particles",)),
    (
        "place --particles eight",
        "place {w}/m.ckpt {w}/scene.json --particles eight",
        ("--particles", "'eight'"),
    ),
    ("place model missing", "place {w}/none.ckpt {w}/scene.json", ("none.ckpt",)),
    (
        "place model is the scene",
        "place {w}/scene.json {w}/scene.json",
        ("scene.json", "not a scenescore checkpoint"),
    ),
    ("place scene missing", "place {w}/m.ckpt {w}/none.json", ("none.json",)),
    ("place scene a folder", "place {w}/m.ckpt {w}", ("folder",)),
    ("place nothing to place", "place {w}/m.ckpt {w}/full.json", ("full.json", "pose: null")),
    ("place --out under a file", "place {w}/m.ckpt {w}/scene.json --out {w}/file/o.json", ("--out",)),
    ("place --out a folder", "place {w}/m.ckpt {w}/scene.json --out {w}", ("--out", "folder")),
    ("place --seed text", "place {w}/m.ckpt {w}/scene.json --seed one", ("--seed",)),
    # solve and compare
    ("solve problem missing", "solve {w}/none.yaml", ("none.yaml",)),
    ("solve --solver bogus", "solve {w}/p.yaml --solver bogus", ("'bogus'",)),
    ("solve --solver empty stage", "solve {w}/p.yaml --solver langevin>>osqp", ("solver",)),
    ("solve --solver trailing >", "solve {w}/p.yaml --solver langevin>", ("solver",)),
    ("solve --out under a file", "solve {w}/p.yaml --out {w}/file/r.json", ("--out",)),
    ("solve --scene-out a folder", "solve {w}/p.yaml --scene-out {w}", ("--scene-out",)),
    ("solve --plot under a file", "solve {w}/p.yaml --plot {w}/file/p.png", ("--plot",)),
    (
        "compare --solvers 'langevin,,bogus'",
        "compare {w}/p.yaml --solvers langevin,,bogus",
        ("--solvers", "empty"),
    ),
    (
        "compare --solvers duplicate",
        "compare {w}/p.yaml --solvers langevin,langevin",
        ("--solvers", "more than once"),
    ),
    ("compare --solvers bogus", "compare {w}/p.yaml --solvers langevin,bogus", ("'bogus'",)),
    ("compare --solvers empty", "compare {w}/p.yaml --solvers ,", ("--solvers", "empty")),
    ("compare --solvers blank", "compare {w}/p.yaml --solvers ' '", ("--solvers", "empty")),
    ("compare --seeds 0", "compare {w}/p.yaml --solvers langevin --seeds 0", ("--seeds",)),
    ("compare --seeds -2", "compare {w}/p.yaml --solvers langevin --seeds -2", ("--seeds",)),
    # heatmap
    (
        "heatmap --resolution 0",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/h.png --resolution 0",
        ("resolution",),
    ),
    (
        "heatmap --resolution nan",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/h.png --resolution nan",
        ("resolution",),
    ),
    (
        "heatmap --resolution -0.01",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/h.png --resolution -0.01",
        ("resolution",),
    ),
    (
        "heatmap --theta nan",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/h.png --theta nan",
        ("--theta",),
    ),
    (
        "heatmap --theta inf",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/h.png --theta inf",
        ("--theta",),
    ),
    (
        "heatmap --object unknown",
        "heatmap {w}/m.ckpt {w}/scene.json --object mug --out {w}/h.png",
        ("'mug'",),
    ),
    (
        "heatmap --out under a file",
        "heatmap {w}/m.ckpt {w}/scene.json --object cup --out {w}/file/h.png",
        ("--out",),
    ),
    # generate
    ("generate unknown scenario", "generate dinner --out {w}/d.jsonl", ("'dinner'",)),
    ("generate --n 0", "generate dining --n 0 --out {w}/d.jsonl", ("--n",)),
    ("generate --n -4", "generate dining --n -4 --out {w}/d.jsonl", ("--n",)),
    ("generate no output", "generate dining", ("--out",)),
    ("generate --ppm 0", "generate dining --n 1 --images {w}/img --ppm 0", ("--ppm",)),
    ("generate --ppm nan", "generate dining --n 1 --images {w}/img --ppm nan", ("--ppm",)),
    ("generate --images a file", "generate dining --n 1 --images {w}/file", ("--images", "is a file")),
    ("generate --out a folder", "generate dining --n 1 --out {w}", ("--out", "folder")),
    # evaluate
    ("evaluate model missing", "evaluate {w}/none.ckpt {w}/data.jsonl", ("none.ckpt",)),
    ("evaluate data missing", "evaluate {w}/m.ckpt {w}/none.jsonl", ("none.jsonl",)),
    ("evaluate --out under a file", "evaluate {w}/m.ckpt {w}/data.jsonl --out {w}/file/e.json", ("--out",)),
    # demo and experiment: folders, checked before the long run
    ("demo --out a file", "demo --out {w}/file", ("--out", "is a file")),
    ("demo --iterations -1", "demo --out {w}/demo --iterations -1", ("iterations",)),
    ("experiment --out a file", "experiment missing --out {w}/file", ("--out", "is a file")),
    ("experiment --seeds 0", "experiment missing --out {w}/exp --seeds 0", ("--seeds",)),
    # --threads, on every command: an integer >= 1
    (
        "place --threads 0",
        "place {w}/m.ckpt {w}/scene.json --threads 0",
        ("--threads", "integer >= 1", "'0'"),
    ),
    ("train --threads -2", "train {w}/data.jsonl --out {w}/x.ckpt --threads -2", ("--threads", "'-2'")),
    ("solve --threads 1.5", "solve {w}/p.yaml --threads 1.5", ("--threads", "'1.5'")),
    ("demo --threads two", "demo --out {w}/demo --threads two", ("--threads", "'two'")),
]


@pytest.mark.parametrize("label,argv,names", CASES, ids=[c[0] for c in CASES])
def test_cli_error(w, capsys, label, argv, names):
    import shlex

    args = [a.format(w=w) for a in shlex.split(argv)]
    cli_error(capsys, *args, names=names)
    assert not (w / "x.ckpt").exists()


@pytest.mark.skipif(ROOT, reason="root may write into a read-only folder")
@pytest.mark.parametrize(
    "cmd", ["train {w}/none.jsonl --out {w}/ro/x.ckpt", "place {w}/m.ckpt {w}/scene.json --out {w}/ro/o.json"]
)
def test_output_in_a_read_only_folder(w, capsys, cmd):
    (w / "ro").mkdir()
    (w / "ro").chmod(0o500)
    try:
        cli_error(capsys, *[a.format(w=w) for a in cmd.split()], names=("--out", "not writable"))
    finally:
        (w / "ro").chmod(0o700)


def test_output_on_a_read_only_filesystem(capsys):
    from pathlib import Path

    ro = next((p for p in ("/proc/sys", "/sys") if Path(p).is_dir() and not os.access(p, os.W_OK)), None)
    if ro is None:
        pytest.skip("no read-only filesystem here")
    cli_error(capsys, "train", "/nonexistent.jsonl", "--out", f"{ro}/x.ckpt", names=("--out", "not writable"))


def test_unknown_command(capsys):
    with pytest.raises(SystemExit) as e:
        run_cli(capsys, "trian")
    assert e.value.code == 2
    assert "invalid choice: 'trian'" in capsys.readouterr().err


def test_place_writes_a_new_nested_folder(w, capsys):
    code, out, err = run_cli(
        capsys,
        "place",
        w / "m.ckpt",
        w / "scene.json",
        "--out",
        w / "a/b/c.json",
        "--particles",
        "4",
        "--quiet",
    )
    assert code == 0, err
    placed = json.loads((w / "a/b/c.json").read_text())
    assert all(o["pose"] is not None for o in placed["objects"])


def test_compare_with_one_solver_and_one_seed(w, capsys):
    write(
        w / "q.yaml",
        "scene: scene.json\ncosts: [{type: bounds}]\noptions: {langevin: {particles: 4, steps: 3, final_descent: 0}}\nsolver: langevin\n",
    )
    code, out, err = run_cli(
        capsys, "compare", w / "q.yaml", "--solvers", "langevin", "--seeds", "1", "--quiet"
    )
    assert code == 0, err
    assert "langevin" in out


def test_scene_with_an_object_that_cannot_fit(w, capsys):
    write(w / "big.json", with_object(2, size=[5.0, 5.0]))
    cli_error(capsys, "place", w / "m.ckpt", w / "big.json", names=("big.json", "'cup'", "does not fit"))


def test_scene_with_unicode_names_places(w, capsys):
    d = scene()
    d["objects"][2]["name"] = "tasse \u2615"
    write(w / "u.json", d)
    code, out, err = run_cli(capsys, "place", w / "m.ckpt", w / "u.json", "--particles", "4", "--quiet")
    assert code == 0, err
    assert "tasse \u2615" in out
