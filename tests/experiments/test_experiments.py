"""Table 2 (novel objects) and the cost heatmap, at tiny sizes."""

import json
import math

import pytest
import torch

from scenescore.cli import main
from scenescore.experiments import heatmap, novel
from scenescore.experiments.execution import Execution
from scenescore.experiments.tasks import Sweep
from scenescore.learn import TrainConfig, fit
from scenescore.planning.heatmap import energy_grid, grid_minimum
from scenescore.scenarios import DeskScenario


def test_novel_oracle_row_is_near_zero():
    res = novel.run(
        seeds=1,
        methods=["Oracle"],
        rules=("class_size", "unseen_class"),
        n_test=2,
        execution=Execution(log=lambda s: None),
    )
    (row,) = res.rows()
    assert row.method == "Oracle"
    assert row.figures["class_size_cm"] < 1.0 and row.figures["unseen_class_cm"] < 1.0
    assert math.isclose(
        row.figures["mean_cm"], (row.figures["class_size_cm"] + row.figures["unseen_class_cm"]) / 2
    )
    md = novel.format_novel(res, ("class_size", "unseen_class"))
    assert "| Oracle |" in md and "Unseen-Class" in md


def test_novel_rejects_unknown_method():
    with pytest.raises(ValueError):
        novel.run(
            seeds=1, methods=["Nope"], rules=("all_size",), n_test=1, execution=Execution(log=lambda s: None)
        )


def test_experiment_novel_cli_writes_results(tmp_path):
    rc = main(
        [
            "experiment",
            "novel",
            "--seeds",
            "1",
            "--methods",
            "Oracle",
            "--jobs",
            "1",
            "--quiet",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    rows = json.loads((tmp_path / "results.json").read_text())["experiments"][0]["rows"]
    assert rows[0]["method"] == "Oracle" and rows[0]["mean_cm"] < 1.0
    assert "Table 2" in (tmp_path / "table.md").read_text()


@pytest.fixture(scope="module")
def desk_model():
    torch.manual_seed(0)
    return fit(
        DeskScenario().generate(4, 0),
        TrainConfig(members=1, iterations=3, batch_scenes=4),
        seed=0,
        progress=False,
    )


def test_energy_grid_and_minimum(desk_model):
    scene = DeskScenario().arrange((0, 0, 0), 0.2)
    xs, ys, e = energy_grid(desk_model, scene, "mug", resolution=0.05)
    assert e.shape == (len(ys), len(xs)) and e.shape == (16, 24)
    mn = grid_minimum(xs, ys, e)
    j, i = list(ys).index(mn[1]), list(xs).index(mn[0])
    assert e[j, i] == e.min()
    # the mug's own heading does not matter to the grid, the rest is fixed: values differ over the grid
    assert e.max() > e.min()


def test_heatmap_command(tmp_path, desk_model, capsys):
    ckpt = tmp_path / "m.safetensors"
    desk_model.save(ckpt)
    scene = DeskScenario().arrange((0, 0, 0), 0.2, mug=False)
    scene.to_json(tmp_path / "s.json")
    png = tmp_path / "h.png"
    rc = main(
        ["heatmap", str(ckpt), str(tmp_path / "s.json"), "--object", "mug", "--out", str(png)]
        + ["--resolution", "0.05"]
    )
    assert rc == 0 and png.read_bytes()[:4] == b"\x89PNG"
    assert "minimum at" in capsys.readouterr().out
    assert main(["heatmap", str(ckpt), str(tmp_path / "s.json"), "--object", "lamp", "--out", str(png)]) != 0


def test_heatmap_run_quick(tmp_path):
    torch.manual_seed(0)
    lines: list[str] = []
    kw = dict(seeds=1, quick=True, out=tmp_path, resolution=0.05, n_train=4, iterations=3)
    ex = Execution(progress=False, log=lines.append, sweep=Sweep(tmp_path / "tasks"))
    res = heatmap.run(execution=ex, **kw)
    again = heatmap.run(execution=ex, **kw)  # the seed's record reused
    assert "heatmap: reused 1 of 1 tasks" in lines[-1] and again.per_seed == res.per_seed
    pen, pencil = res.rows()
    assert pen.method == "SceneScore, pen" and pencil.method == "SceneScore, pencil"
    for key in ("relation_error_cm", "mug_distance_cm_at_21cm"):
        assert math.isfinite(pen.figures[key]) and math.isfinite(pencil.figures[key])
    assert "from_pen_minimum_cm" in pencil.figures
    assert len(res.figures) == 6 and all((tmp_path / p.split("/")[-1]).exists() for p in res.figures)
    assert "relation error" in heatmap.format_heatmap(res)


def test_novel_and_missing_in_worker_processes_give_the_same_figures():
    from scenescore.experiments import missing

    kw = dict(seeds=2, methods=["Oracle"], rules=("class_size", "all_size"), n_test=2)
    quiet = lambda s: None  # noqa: E731
    one = novel.run(execution=Execution(log=quiet, jobs=1), **kw)
    two = novel.run(execution=Execution(log=quiet, jobs=2), **kw)
    assert two.per_seed == one.per_seed and len(two.per_seed["Oracle"]) == 2
    kw = dict(seeds=2, methods=["Nearest-Nbr", "Oracle"])
    one = missing.run(execution=Execution(progress=False, log=quiet, jobs=1), **kw)
    two = missing.run(execution=Execution(progress=False, log=quiet, jobs=2), **kw)
    assert two.per_seed == one.per_seed and list(two.per_seed) == ["Nearest-Nbr", "Oracle"]
