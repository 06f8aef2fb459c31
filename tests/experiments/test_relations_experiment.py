"""The relations experiment: its problems are consistent and seeded, 'solved' is the checkers' verdict
on hand-built cases, and a tiny run from the command line writes the documented rows."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from scenescore.cli import main
from scenescore.experiments.execution import Execution
from scenescore.experiments.relations import (
    METHODS,
    RelationSettings,
    best_tries,
    relation_cost_problem,
    run,
    train_relations,
)
from scenescore.learn import TrainConfig
from scenescore.scenarios.relation_problems import (
    PROBLEM_RELATIONS,
    RelationProblem,
    relation_problem,
    relation_problems,
)
from scenescore.scene.scene import Scene, SceneError, SceneObject

BOUNDS = ((-0.6, -0.4), (0.6, 0.4))


def _problem() -> RelationProblem:
    """a left of b, c near b; a solution: a at the left, b in the middle, c just right of b."""
    objs = [
        SceneObject("a", "a", (0.1, 0.1), (-0.4, 0.0, 0.0)),
        SceneObject("b", "b", (0.1, 0.1), (0.0, 0.0, 0.0), shape="disk"),
        SceneObject("c", "c", (0.1, 0.06), (0.12, 0.0, 0.0)),
    ]
    return RelationProblem(Scene(objs, BOUNDS), (("left_of", ("a", "b")), ("near", ("c", "b"))))


def test_solved_is_every_checker_and_non_overlap_and_bounds():
    p = _problem()
    good = p.scene.poses()
    assert p.solved(good)
    swapped = good.copy()
    swapped[[0, 1]] = swapped[[1, 0]]  # b left of a
    assert not p.solved(swapped)
    far = good.copy()
    far[2, 0] = 0.4  # c 30 cm from b: not near
    assert not p.solved(far)
    overlapping = good.copy()
    overlapping[2, 0] = 0.08  # c overlaps b (near needs them apart too)
    assert not p.solved(overlapping)
    outside = good.copy()
    outside[0, 0] = -0.58  # a's footprint leaves the table, still left of b
    assert not p.solved(outside)
    with pytest.raises(SceneError, match="shape"):
        p.solved(good[:2])


@pytest.mark.parametrize("n", [2, 3, 6, 10])
def test_problems_are_consistent_seeded_and_about_one_and_a_half_relations_per_object(n):
    ps = relation_problems(n, 4, seed=3)
    for p in ps:
        assert len(p.scene) == n and all(o.pose is not None for o in p.scene.objects)
        assert all(o.pose is None for o in p.unposed.objects)
        assert p.solved(p.scene.poses())  # the arrangement it was drawn from solves it
        assert 1 <= len(p.relations) <= round(1.5 * n) and {r for r, _ in p.relations} <= set(
            PROBLEM_RELATIONS
        )
        assert len(set(p.relations)) == len(p.relations)
    if n >= 3:
        assert all(len(p.relations) == round(1.5 * n) for p in ps)
    again = relation_problems(n, 2, seed=3)
    assert [p.relations for p in again] == [p.relations for p in ps[:2]]
    np.testing.assert_array_equal(again[1].scene.poses(), ps[1].scene.poses())
    assert relation_problems(n, 1, seed=4)[0].relations != ps[0].relations
    few = relation_problems(n, 8, seed=0, relations=["left_of", "near"])
    assert all(p.relations and p.solved(p.scene.poses()) for p in few)  # drawn again until one holds


def test_bad_problem_requests_are_clear_errors():
    empty = relation_problem(2, 0)
    with pytest.raises(SceneError, match="names no relation"):
        relation_cost_problem(replace(empty, relations=()), {})
    with pytest.raises(SceneError, match="2 to 10"):
        relation_problem(11, 0)
    with pytest.raises(SceneError, match="centred_on"):
        relation_problem(3, 0, relations=("centred_on",))
    with pytest.raises(SceneError, match="pool"):
        run(seeds=1, settings=RelationSettings(problems=1, pool=0))


def test_tiny_run_writes_rows_with_solved_fractions(tmp_path, capsys):
    out = tmp_path / "rel"
    argv = ["experiment", "relations", "--seeds", "1", "--problems", "2", "--sizes", "2,3", "--tries", "2"]
    argv += [
        "--pool",
        "3",
        "--iterations",
        "5",
        "--examples",
        "8",
        "--restarts",
        "0",
        "--jobs",
        "1",
        "--quiet",
    ]
    argv += ["--out", str(out)]
    assert main(argv) == 0
    doc = json.loads((out / "results.json").read_text())
    rows = doc["experiments"][0]["rows"]
    assert [r["method"] for r in rows] == METHODS
    for r in rows:
        for n in (2, 3):
            assert 0.0 <= r[f"solved_{n}"] <= 1.0 and r[f"solved_{n}"] * 2 == int(r[f"solved_{n}"] * 2)
            assert r[f"seconds_{n}"] > 0
    assert (out / "solved.png").stat().st_size > 0
    table = (out / "table.md").read_text()
    assert "trained again with the next member seed, at most 0 times" in table
    assert "each try is the best of 3 particles" in table and "draws up to 600 uniform" in table
    printed = capsys.readouterr()
    assert "| Rejection (uniform) |" in printed.out and "N=3" in printed.out
    assert "train:" not in printed.err  # --quiet: no model's training bar, the whole-scene one's included
    assert main(["experiment", "relations", "--sizes", "1,2", "--out", str(out)]) == 2
    assert "--sizes" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["experiment", "relations", "--pool", "0", "--out", str(out)])
    assert "--pool" in capsys.readouterr().err


@pytest.fixture(scope="module")
def tiny_models():
    return train_relations(
        ["facing", "left_of"], 0, TrainConfig(members=1, iterations=2), examples=8, restarts=0
    )


def test_relation_models_see_a_round_subjects_heading_only_where_the_relation_reads_it(tiny_models):
    assert tiny_models["facing"].config.round_invariant is False  # a disk can face a plate
    assert tiny_models["left_of"].config.round_invariant is True


def test_the_tries_are_the_best_particles_by_the_methods_own_cost(tiny_models):
    problem = relation_problem(2, 0, relations=("left_of",))
    prob = relation_cost_problem(problem, tiny_models)
    good = problem.scene.poses()
    outside = good.copy()
    outside[0, :2] = (0.9, 0.9)  # off the table: violates the bounds constraint
    others = good[None] + np.random.default_rng(0).normal(0, 0.05, (6, 2, 3)) * [1, 1, 0]
    samples = np.concatenate([outside[None], others, good[None]])
    chosen = best_tries(prob, samples, 3)
    assert chosen.shape == (3, 2, 3)
    x = torch.as_tensor(samples)
    feasible = (prob.violation(x) <= 1e-4).numpy()
    costs = prob.evaluate(x).detach().numpy()
    expected = sorted(np.flatnonzero(feasible), key=lambda k: costs[k])[:3]
    np.testing.assert_allclose(chosen, samples[expected])
    assert not any(np.allclose(c, outside) for c in chosen)


def test_each_seed_and_size_is_a_task_and_a_seeds_models_are_trained_once(tmp_path, monkeypatch):
    from scenescore.experiments.tasks import Sweep
    from scenescore.learn import loop

    fits = []
    real = loop._fit

    def counted(*a, **k):
        fits.append(1)
        return real(*a, **k)

    monkeypatch.setattr(loop, "_fit", counted)
    lines: list[str] = []
    settings = dict(
        problems=1, tries=1, pool=2, methods=["Relations (langevin>alm)"], relations=["left_of", "near"],
        examples=8, restarts=0, config=TrainConfig(members=1, iterations=2),
    )  # fmt: skip
    ex = Execution(progress=False, log=lines.append, sweep=Sweep(tmp_path / "tasks"))
    both = run(seeds=2, settings=RelationSettings(sizes=[2, 3], **settings), execution=ex)
    assert len(fits) == 4  # two relations for each of two seeds, whatever the sizes: the run's own cache
    assert lines[-1] == "relations: reused 0 of 4 tasks (" + str(tmp_path / "tasks") + ")"
    (per_seed,) = both.per_seed.values()
    assert [list(f) for f in per_seed] == [["solved_2", "seconds_2", "solved_3", "seconds_3"]] * 2
    # a run split by size
    three = run(seeds=2, settings=RelationSettings(sizes=[3], **settings), execution=ex)
    assert lines[-1].startswith("relations: reused 2 of 2 tasks") and len(fits) == 4
    assert [f["solved_3"] for f in three.per_seed["Relations (langevin>alm)"]] == [
        f["solved_3"] for f in per_seed
    ]
