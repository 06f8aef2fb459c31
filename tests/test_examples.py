"""The examples run end to end (with a quickly trained model standing in for the 300-iteration one)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
sys.path.insert(0, str(EXAMPLES))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """A copy of the examples with a model trained for 15 iterations (seconds, not the 45 s of the real one)."""
    import train_model

    d = tmp_path_factory.mktemp("examples")
    for f in ("place_bowl.yaml", "dining_scene.json"):
        shutil.copy(EXAMPLES / f, d / f)
    train_model.main(["--iterations", "15", "--out", str(d / "dining.ckpt"), "--quiet"])
    return d


@pytest.mark.slow
def test_compose_costs_example(workdir, capsys):
    import compose_costs

    r = compose_costs.main(["--model", str(workdir / "dining.ckpt")])
    assert r.solver == "langevin>osqp" and r.max_violation <= 1e-4 and r.feasible, r.summary()
    out = capsys.readouterr().out
    assert "solver langevin:" in out and "bowl_0 ->" in out


@pytest.mark.slow
def test_yaml_example_solves_and_compares(workdir):
    import compare_solvers

    from scenescore.problem.files import load_problem
    from scenescore.solvers import solve

    lp = load_problem(workdir / "place_bowl.yaml")
    assert lp.problem.movable == ["bowl_0"]
    r = solve(lp.problem, lp.solver, seed=lp.seed, options=lp.options)
    assert r.feasible and r.max_violation <= 1e-4, r.summary()
    cmp = compare_solvers.main(
        [
            "--problem",
            str(workdir / "place_bowl.yaml"),
            "--seeds",
            "1",
            "--solvers",
            "langevin,langevin>osqp,langevin>casadi",
        ]
    )
    assert [row["solver"] for row in cmp.rows] == ["langevin", "langevin>osqp", "langevin>casadi"]
    assert cmp.rows[1]["feasible_rate"] == 1.0 and cmp.rows[2]["feasible_rate"] == 1.0


def test_relations_example_solves_with_the_shipped_relation_models():
    """examples/relations.yaml: three shipped relation models bound to five objects, collision and
    bounds; its solve is feasible and every relation's checker accepts the arrangement."""
    from scenescore.costs import Relation
    from scenescore.problem.files import load_problem
    from scenescore.scenarios.relations import RELATIONS
    from scenescore.solvers import solve

    lp = load_problem(EXAMPLES / "relations.yaml")
    r = solve(lp.problem, lp.solver, seed=lp.seed, options=lp.options)
    assert r.feasible and r.max_violation <= 1e-4, r.summary()
    scene = lp.problem.scene.with_poses(r.poses)
    terms = [c for _, c in lp.problem.cost.items if isinstance(c, Relation)]
    asked = [(t.name.split("(")[0].removeprefix("relation-"), row) for t in terms for row in t.instances]
    assert len(terms) == 3 and len(scene) == 5 and len(asked) == 4
    assert [a for a in asked if not RELATIONS[a[0]].check(scene, a[1])] == []
