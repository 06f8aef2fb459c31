"""The command line: generate -> train -> place end to end on tiny settings, and one-line errors."""

import json

import pytest
import torch
from cli_model import train_tiny  # tests/cli, the test files' own folder

from scenescore.cli import main


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    torch.set_num_threads(1)
    d = tmp_path_factory.mktemp("cli")
    train_tiny(d, 5)
    return d


def test_generate_train_place(trained, capsys):
    d = trained
    lines = (d / "data.jsonl").read_text().splitlines()
    scene = json.loads(lines[0])
    scene["objects"][1]["pose"] = None
    (d / "q.json").write_text(json.dumps(scene))
    rc = main(
        [
            "place",
            str(d / "m.ckpt"),
            str(d / "q.json"),
            "--out",
            str(d / "f.json"),
            "--plot",
            str(d / "f.png"),
            "--particles",
            "8",
            "--quiet",
        ]
    )
    assert rc == 0
    filled = json.loads((d / "f.json").read_text())
    assert all(o["pose"] is not None for o in filled["objects"])
    assert (d / "f.png").read_bytes()[:4] == b"\x89PNG"
    name = scene["objects"][1]["name"]
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(name))
    pose = json.loads((d / "f.json").read_text())["objects"][1]["pose"]
    assert f"x={pose[0]:+.4g} y={pose[1]:+.4g} m  theta=" in line  # generated data names metres
    meta = {k: v for k, v in scene.get("meta", {}).items() if k != "unit"}
    for unit, said in (("mm", " mm  theta="), (None, " (data units)  theta=")):
        q = {**scene, "meta": {**meta, "unit": unit} if unit else meta}
        (d / "q_unit.json").write_text(json.dumps(q))
        assert main(["place", str(d / "m.ckpt"), str(d / "q_unit.json"), "--particles", "8", "--quiet"]) == 0
        assert said in capsys.readouterr().out
    # the paper's protocol places by the energy alone; an overlap left is named by the exact check
    from scenescore.models import load
    from scenescore.planning.placement import overlapping
    from scenescore.scene.scene import Scene

    rc = main(["place", str(d / "m.ckpt"), str(d / "q.json"), "--energy-only", "--out", str(d / "e.json")])
    assert rc == 0
    left = overlapping(load(d / "m.ckpt"), Scene.from_json(d / "e.json"), [name])
    err = capsys.readouterr().err
    assert all(f"{a}: overlaps {b} (exact check)" in err for a, b in left)


def test_train_raw_edges_has_no_edge_encoder(trained, tmp_path):
    from scenescore.models import load

    args = [
        "train",
        "--members",
        "1",
        str(trained / "data.jsonl"),
        "--iterations",
        "3",
        "--val",
        "0",
        "--quiet",
        "--force",
    ]
    assert main([*args, "--out", str(tmp_path / "raw.ckpt"), "--raw-edges"]) == 0
    assert load(tmp_path / "raw.ckpt").config.edge_encoder is None
    assert load(trained / "m.ckpt").config.edge_encoder == 32  # the default network has it


def test_threads_is_scoped_and_a_seeded_placement_repeats(trained, capsys):
    """``--threads N`` sets torch's threads for the run only; the same seed places the same poses."""
    d = trained
    scene = json.loads((d / "data.jsonl").read_text().splitlines()[2])
    scene["objects"][0]["pose"] = None
    (d / "t.json").write_text(json.dumps(scene))
    before = torch.get_num_threads()
    outs = []
    for k, n in enumerate(["1", "1", "2"]):
        argv = ["place", str(d / "m.ckpt"), str(d / "t.json"), "--particles", "8", "--seed", "3", "--quiet"]
        assert main([*argv, "--threads", n, "--out", str(d / f"t{k}.json")]) == 0
        assert torch.get_num_threads() == before
        outs.append(json.loads((d / f"t{k}.json").read_text()))
        capsys.readouterr()
    assert outs[0] == outs[1]
    poses = [[v for o in out["objects"] for v in o["pose"]] for out in outs]
    # another thread count sums in another order: the same chains, their float32 rounding amplified by the
    # steps, far below a millimetre
    assert poses[2] == pytest.approx(poses[0], abs=1e-4)


def test_user_errors_are_one_line(trained, tmp_path, capsys):
    d = trained
    assert main(["place", str(d / "m.ckpt"), str(tmp_path / "none.json")]) == 2
    assert "none.json: no such scene file" in capsys.readouterr().err
    assert main(["place", str(tmp_path / "none.ckpt"), str(d / "q.json")]) == 2
    assert "no such checkpoint" in capsys.readouterr().err
    (tmp_path / "bad.jsonl").write_text('{"objects": [{"name": "a", "category": "c", "size": [1]}]}\n')
    assert main(["train", str(tmp_path / "bad.jsonl"), "--out", str(tmp_path / "x.ckpt")]) == 2
    err = capsys.readouterr().err
    assert "bad.jsonl:1" in err and "'a'" in err and "size" in err and "Traceback" not in err
    assert main(["generate", "kitchen", "--out", str(tmp_path / "k.jsonl")]) == 2
    assert "unknown scenario 'kitchen'" in capsys.readouterr().err
    # nothing to place
    full = json.loads((d / "data.jsonl").read_text().splitlines()[0])
    (tmp_path / "full.json").write_text(json.dumps(full))
    assert main(["place", str(d / "m.ckpt"), str(tmp_path / "full.json")]) == 2
    assert "nothing to place" in capsys.readouterr().err


def test_bad_settings_and_outputs_fail_before_any_work(trained, tmp_path, capsys):
    """Out-of-range numbers and unwritable outputs: one line, exit 2, nothing trained or written."""
    d = trained
    scene = json.loads((d / "data.jsonl").read_text().splitlines()[0])
    scene["objects"][1]["pose"] = None
    (tmp_path / "q.json").write_text(json.dumps(scene))
    data, ckpt, q = str(d / "data.jsonl"), str(d / "m.ckpt"), str(tmp_path / "q.json")
    (tmp_path / "afile").write_text("x")
    cases = [
        (
            ["train", data, "--out", str(tmp_path / "n.ckpt"), "--iterations", "-5"],
            "iterations: expected an integer >= 1",
        ),
        (
            ["train", data, "--out", str(tmp_path / "n.ckpt"), "--negatives", "0"],
            "negatives: expected an integer >= 1",
        ),
        (
            ["train", data, "--out", str(tmp_path / "afile" / "m.ckpt")],
            "is a file, not a folder",
        ),
        (["place", ckpt, q, "--particles", "0"], "particles: expected an integer >= 1"),
        (["place", ckpt, q, "--out", str(tmp_path)], "is a folder; expected a file"),
        (
            ["heatmap", ckpt, q, "--object", "x", "--out", str(tmp_path / "h.png"), "--resolution", "0"],
            "resolution",
        ),
        (["demo", "--out", str(tmp_path / "afile")], "expected a folder"),
        (["experiment", "tidy", "--efforts", "1,-2", "--out", str(tmp_path / "t")], "--efforts: expected"),
        (
            ["experiment", "compose", "--alm", "{tol_grad: 1}", "--out", str(tmp_path / "c")],
            "--alm: expected a JSON",
        ),
        (
            ["experiment", "compose", "--alm", "[1]", "--out", str(tmp_path / "c")],
            "--alm: expected a JSON object",
        ),
        (
            ["experiment", "compose", "--alm", '{"tolgrad": 1}', "--out", str(tmp_path / "c")],
            "--alm: solver 'alm': unknown option 'tolgrad'; did you mean 'tol_grad'?",
        ),
        (
            ["experiment", "compose", "--alm", '{"tol_grad": -1}', "--out", str(tmp_path / "c")],
            "--alm: solver 'alm': alm: tol_grad",
        ),
    ]
    for argv, msg in cases:
        try:
            code = main([*argv, "--quiet"])
        except SystemExit as e:  # argparse's own range checks: usage, then one error line
            code = e.code  # type: ignore[assignment]
        assert code == 2, argv
        err = capsys.readouterr().err
        lines = [ln for ln in err.strip().splitlines() if not ln.startswith(("usage:", " "))]
        assert msg in err and "Traceback" not in err and len(lines) == 1, (argv, err)
    assert not (tmp_path / "n.ckpt").exists()


def test_experiment_missing_quick_writes_outputs(tmp_path):
    torch.set_num_threads(1)
    out = tmp_path / "exp"
    rc = main(
        [
            "experiment",
            "missing",
            "--seeds",
            "1",
            "--quick",
            "--methods",
            "Nearest-Nbr,Oracle",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    rows = json.loads((out / "results.json").read_text())["experiments"][0]["rows"]
    assert [r["method"] for r in rows] == ["Nearest-Nbr", "Oracle"]
    assert {"fork_t_cm", "fork_R_deg", "bowl_t_cm", "mean_t_cm"} <= set(rows[0])
    assert "mean_t_cm_std" not in rows[0] and "±" not in (out / "table.md").read_text()  # one seed
    assert rows[1]["mean_t_cm"] < rows[0]["mean_t_cm"]  # the oracle is the floor
    assert "paper 7.90" in (out / "table.md").read_text()


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for cmd in ("demo", "generate", "train", "place", "solve", "compare", "experiment"):
        assert cmd in out


def test_generate_images_and_train_on_the_folder(tmp_path, capsys):
    torch.set_num_threads(1)
    imgs = tmp_path / "imgs"
    assert main(["generate", "dining", "--n", "2", "--images", str(imgs), "--quiet"]) == 0
    assert sorted(p.name for p in imgs.glob("*.png")) == [
        "scene_00000.masks-preview.png",
        "scene_00000.masks.png",
        "scene_00000.png",
        "scene_00001.masks-preview.png",
        "scene_00001.masks.png",
        "scene_00001.png",
    ]
    ckpt = tmp_path / "m.ckpt"
    assert (
        main(
            [
                "train",
                "--members",
                "1",
                str(imgs),
                "--out",
                str(ckpt),
                "--iterations",
                "2",
                "--quiet",
                "--force",
            ]
        )
        == 0
    )
    from scenescore.models import load

    assert load(ckpt).encoder.name == "image"  # a folder of images trains on the image encoder's vectors
    assert "trained on 2 scenes" in capsys.readouterr().out


def test_options_for_stages_the_chosen_chain_skips_are_named(capsys):
    from scenescore.cli.problems import warn_unused_options

    warn_unused_options("p.yaml", {"langevin": {}, "osqp": {"max_iter": 5}}, ["langevin"])
    err = capsys.readouterr().err
    assert "p.yaml" in err and "osqp" in err and "langevin" in err.split("used by")[1]
    warn_unused_options("p.yaml", {"langevin": {}, "osqp": {}}, ["langevin", "langevin>osqp"])
    assert capsys.readouterr().err == ""


def test_experiment_tidy_quick_writes_every_case(tmp_path):
    torch.set_num_threads(1)
    out = tmp_path / "tidy"
    argv = ["experiment", "tidy", "--quick", "--scenarios", "desk", "--iterations", "2", "--efforts", "1,3"]
    assert main([*argv, "--seeds", "2", "--seed", "4", "--out", str(out), "--quiet"]) == 0
    cases = json.loads((out / "cases.json").read_text())
    rows = json.loads((out / "results.json").read_text())["experiments"][0]["rows"]
    assert cases and rows[0]["cases"] == len(cases)
    # each seed its own split and displacements, the cases pooled
    assert {c["seed"] for c in cases} == {4, 5} and "seeds 4 to 5" in (out / "table.md").read_text()
    assert set(cases[0]["methods"]) == {
        "tidy (effort 1) default",
        "tidy (effort 3)",
        "re-place all",
        "missing placement",
    }
    assert all(c["scenario"] == "desk" and c["displaced"] for c in cases)
    assert (out / "pareto.png").stat().st_size > 1000 and "cases.json" in (out / "table.md").read_text()
