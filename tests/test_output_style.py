"""What the tool shows: help texts, plots in one style, mask previews, statuses and tables that agree."""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from scenescore.cli import build_parser, main  # noqa: E402
from scenescore.costs import Bounds, HingeCollision, PoseTarget, ReachLimit  # noqa: E402
from scenescore.experiments.report import SeedResults, format_table, over_seeds  # noqa: E402
from scenescore.problem.problem import FEASIBILITY_TOL, Problem  # noqa: E402
from scenescore.scene.scene import Scene, SceneObject  # noqa: E402
from scenescore.solvers.result import Status, make_result  # noqa: E402
from scenescore.vision.render import mask_preview  # noqa: E402
from scenescore.viz.plot import draw_scene, legend_handles, plot_result  # noqa: E402


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_option_with_a_default_says_it():
    missing = []
    for name, sp in _subparsers().items():
        for a in sp._actions:
            if not a.option_strings or isinstance(a, (argparse._HelpAction, argparse._StoreTrueAction)):
                continue
            if a.default not in (None, False) and "default" not in (a.help or ""):
                missing.append(f"{name} {a.option_strings[0]}")
    assert not missing, missing


def test_methods_help_lists_every_experiments_methods():
    from scenescore.experiments import compose, missing, novel

    text = next(a.help for a in _subparsers()["experiment"]._actions if "--methods" in a.option_strings)
    for m in missing.METHODS + missing.EXTRA_METHODS + novel.METHODS + compose.METHODS:
        assert m in text, m


def test_solve_seed_default_is_explained():
    """The default is the problem file's own seed: no sentinel value that is also a seed."""
    action = next(a for a in _subparsers()["solve"]._actions if "--seed" in a.option_strings)
    assert action.default is None and "problem file's own seed" in action.help and "-1" not in action.help


def test_generate_list_describes_each_scenario(capsys):
    from scenescore.scenarios import available

    assert main(["generate", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == available()
    assert all(len(ln.split()) > 3 for ln in lines)  # a name and a sentence


def _scene(mug=(-0.3, 0.2, 0.0)) -> Scene:
    return Scene(
        [
            SceneObject("table", "table", (0.4, 0.3), (0.0, 0.0, 0.0), fixed=True),
            SceneObject("box", "clutter", (0.1, 0.1), (0.3, 0.3, 0.2)),
            SceneObject("mug", "mug", (0.08, 0.08), mug, shape="disk"),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )


def test_draw_scene_reports_what_it_drew_and_the_legend_names_it():
    fig, ax = plt.subplots()
    truth = _scene().with_poses([[-0.2, 0.1, 0.0]], ["mug"])
    roles = draw_scene(ax, _scene(), highlight=["mug"], ghosts=truth, reach=[((0.0, -0.7), 0.9)])
    plt.close(fig)
    assert set(roles) == {"bounds", "truth", "moved", "fixed", "clutter", "reach"}
    labels = [h.get_label() for h in legend_handles(roles, moved="moved")]
    assert labels == ["moved", "truth", "fixed", "clutter", "bounds", "reach"]
    fig, ax = plt.subplots()
    assert set(draw_scene(ax, _scene())) == {"bounds", "fixed", "clutter"}  # nothing moved, no truth
    plt.close(fig)


def test_a_name_label_at_the_top_edge_goes_below_its_object():
    scene = Scene(
        [
            SceneObject("top", "box", (0.2, 0.05), (0.0, 0.57, 0.0)),
            SceneObject("middle", "box", (0.2, 0.05), (0.0, 0.0, 0.0)),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )
    fig, ax = plt.subplots()
    draw_scene(ax, scene, names="all")
    where = {t.get_text(): t for t in ax.texts}
    plt.close(fig)
    assert where["top"].get_va() == "top" and where["top"].xyann[1] < 0  # inside the bounds
    assert where["middle"].get_va() == "bottom" and where["middle"].xyann[1] > 0


def test_plot_result_draws_the_reach_circle_and_names_moving_objects(tmp_path):
    scene = _scene(mug=None)
    cost = PoseTarget("mug", (-0.3, 0.2)) + 10 * HingeCollision() + Bounds() + ReachLimit((0.0, -0.7), 1.2)
    problem = Problem(scene, cost)
    r = make_result(
        problem, "test", np.array([[0, 0, 0], [0.3, 0.3, 0.2], [-0.3, 0.2, 0]]), Status.CONVERGED, 1, 0, 0
    )
    plot_result(r, tmp_path / "r.png")
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_violations_within_the_tolerance_name_no_term_and_converged_means_feasible():
    scene = _scene(mug=None)
    problem = Problem(scene, PoseTarget("mug", (-0.3, 0.2)) + 10 * HingeCollision() + Bounds())
    base = np.array([[0, 0, 0], [0.3, 0.3, 0.2], [-0.3, 0.2, 0]], dtype=float)
    # the mug just inside the table's edge by a tenth of the tolerance: feasible, nothing named
    inside = base.copy()
    inside[2, :2] = (-0.2 - 0.04 + 0.1 * FEASIBILITY_TOL, 0.0)
    r = make_result(problem, "test", inside, Status.CONVERGED, 1, 0, 0)
    assert 0 < r.max_violation <= FEASIBILITY_TOL and r.violated is None and r.status == "converged"
    assert "violation" not in r.message
    # 1 cm into the table: a solver that says converged is corrected, and the term is named
    deep = base.copy()
    deep[2, :2] = (-0.2 - 0.04 + 0.01, 0.0)
    r = make_result(problem, "test", deep, Status.CONVERGED, 1, 0, 0)
    assert r.status == "infeasible" and not r.success and r.violated and "collision" in r.violated


def test_one_seed_has_no_spread():
    class One(SeedResults):
        pass

    one = One(per_seed={"m": [{"t": 1.0}]})
    two = One(per_seed={"m": [{"t": 1.0}, {"t": 3.0}]})
    assert "t_std" not in one.rows()[0].figures and two.rows()[0].figures["t_std"] == 1.0
    assert "±" not in format_table(one.rows(), [("t", "t")], {"t": "t_std"})
    assert "± 1.00" in format_table(two.rows(), [("t", "t")], {"t": "t_std"})
    assert "std" not in over_seeds(1) and "std over 3" in over_seeds(3)


def test_mask_preview_colours_each_label_and_greys_the_table():
    labels = np.zeros((20, 30), np.uint16)
    labels[2:8, 2:8] = 1
    labels[10:18, 10:28] = 2
    image = np.full((20, 30, 3), 200, np.uint8)
    prev = mask_preview(labels, image)
    assert prev.shape == (20, 30, 3) and prev.dtype == np.uint8
    a, b, table = prev[4, 4], prev[12, 12], prev[0, 0]
    assert not np.array_equal(a, b) and table[0] == table[1] == table[2]


@pytest.mark.parametrize("command", ["generate", "train", "place", "solve", "experiment", "export"])
def test_help_runs(command, capsys):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0 and "usage" in capsys.readouterr().out
