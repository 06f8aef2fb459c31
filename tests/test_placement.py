"""One placement path: ``place`` is the learned energy's problem solved by the ``langevin`` solver."""

from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import CostFn
from scenescore.encoders import FootprintEncoder
from scenescore.geometry.poses import relative_poses
from scenescore.models import ScoreModel
from scenescore.models.layout import overlapping_categories
from scenescore.models.trust import reference
from scenescore.planning.placement import (
    PLACE,
    _in_pairs,
    in_turn,
    non_overlap,
    overlapping,
    place,
    place_many,
    placement_problem,
    refining,
)
from scenescore.problem.problem import Problem
from scenescore.solvers.langevin import LangevinSolver

pytestmark = pytest.mark.float_order

SMALL = replace(PLACE, particles=16, candidates=128, chain=replace(PLACE.chain, steps=10, final_descent=5))


def _model() -> ScoreModel:
    torch.manual_seed(0)
    return ScoreModel.create(FootprintEncoder(), hidden=16, layers=2)


def _scenes() -> list[ss.Scene]:
    return ss.scenarios.get("dining").generate(3, 5)


def test_place_and_solve_give_the_same_answer():
    """The same model, seed and options through ``place`` and through ``ss.solve`` with YAML-style options."""
    model, scene = _model(), _scenes()[0].without("fork_0")
    placed = place(model, scene, SMALL, seed=3)
    flat = {"particles": SMALL.particles, "candidates": SMALL.candidates, **asdict(SMALL.chain)}
    r = ss.solve(placement_problem(model, scene), "langevin", seed=3, options={"langevin": flat})
    assert np.array_equal(np.asarray(placed["fork_0"].pose), r.poses[scene.index("fork_0")])
    other = place(model, scene, SMALL, seed=4)
    assert other["fork_0"].pose != placed["fork_0"].pose


def test_solve_many_of_one_problem_is_solve():
    model, scene = _model(), _scenes()[0].without("bowl_1")
    p = placement_problem(model, scene)
    solver = LangevinSolver(SMALL)
    (many,) = solver.solve_many([p], seed=7)
    one = solver.solve(p, seed=7)
    assert np.array_equal(many.poses, one.poses) and np.array_equal(many.samples, one.samples)


def test_place_many_fills_every_scene_and_keeps_the_rest():
    model = _model()
    scenes = [s.without(n) for s, n in zip(_scenes(), ["fork_0", "knife_1", "bowl_0"])]
    out = place_many(model, scenes, SMALL, seed=0)
    for s, o in zip(scenes, out):
        assert not o.unknown
        for obj in s.objects:
            if obj.pose is not None:
                assert o[obj.name].pose == obj.pose
        (lo, hi), (x, y, _) = np.array(s.bounds), o[s.unknown[0]].pose
        assert lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1]
    # batched energies equal each scene's own energy (the fused LearnedEnergy.stack)
    probs = [placement_problem(model, s, energy_only=True) for s in scenes]
    x = torch.cat([p.initial(4, torch.Generator().manual_seed(k)) for k, p in enumerate(probs)])
    fused = ss.costs.LearnedEnergy.stack([p.cost["energy"] for p in probs], [4, 4, 4])(x)
    each = torch.cat([p.evaluate(x[4 * k : 4 * k + 4]) for k, p in enumerate(probs)])
    assert torch.allclose(fused, each, rtol=1e-5, atol=1e-6)


def _crowded() -> ss.Scene:
    """A dining scene with its bowl to place and four fixed boxes over much of the table."""
    scene = _scenes()[0].without("bowl_0")
    boxes = [
        ss.SceneObject(f"box_{k}", "clutter", (0.25, 0.25), (x, y, 0.3), fixed=True)
        for k, (x, y) in enumerate([(-0.3, -0.3), (0.3, -0.3), (-0.3, 0.3), (0.3, 0.3)])
    ]
    return ss.Scene(scene.objects + boxes, scene.bounds)


def test_place_keeps_off_the_other_objects_by_default():
    model, scene = _model(), _crowded()
    problem = placement_problem(model, scene)
    assert [c.name for _, c in problem.cost.items] == ["energy", "overlap"]
    assert [c.name for _, c in placement_problem(model, scene, energy_only=True).cost.items] == ["energy"]
    filled = place(model, scene, SMALL, seed=0)
    assert overlapping(model, filled, ["bowl_0"]) == []
    # the check itself: the bowl put on a box is reported against that box
    on_box = filled.with_poses([(0.3, 0.3, 0.0)], ["bowl_0"])
    assert ("bowl_0", "box_3") in overlapping(model, on_box, ["bowl_0"])


def test_categories_that_overlap_in_the_data_may_overlap_when_placed():
    """A lamp stands on its nightstand in every example: placement's non-overlap leaves that pair be."""
    scenes = [
        ss.Scene(
            [
                ss.SceneObject("stand_0", "nightstand", (0.4, 0.4), (x, 0.0, 0.0)),
                ss.SceneObject("lamp_0", "lamp", (0.2, 0.2), (x + 0.05, 0.0, 0.0), shape="disk"),
                ss.SceneObject("rug_0", "rug", (0.5, 0.3), (x, 0.8, 0.0)),
            ],
            ((-2.0, -2.0), (2.0, 2.0)),
        )
        for x in (-1.0, 0.0, 1.0)
    ]
    assert overlapping_categories(scenes, 0.01) == [["lamp", "nightstand"]]
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    model.info.trust = reference(model, scenes)
    hinge = non_overlap(model, scenes[0].without("lamp_0"))
    assert hinge is not None and hinge.pairs == [["lamp_0", "rug_0"]]
    assert overlapping(model, scenes[0], ["lamp_0"]) == []
    # the model's trust is the reference its info holds
    assert model.trust is model.info.trust
    model.info.trust = None
    assert model.trust is None


def test_covering_screens_more_candidates_where_the_objects_are_small_for_the_bounds():
    """Placement's defaults cover the bounds at CANDIDATE_DENSITY per square length scale: the dining table
    (1.2 m, length scale 0.1 m) keeps PLACE's 2048; the same scene in bounds 8 times wider asks for more,
    and the same count at every scale (free of units); options given by hand are used as given."""
    from scenescore.planning.placement import CANDIDATE_DENSITY, MAX_COVERING, covering

    model, scene = _model(), _scenes()[0]
    assert covering(PLACE, model, [scene]) is PLACE
    wide = scene.copy()
    wide.bounds = ((-4.8, -4.8), (4.8, 4.8))
    got = covering(PLACE, model, [scene, wide]).candidates  # the largest bounds of the batch
    assert got >= CANDIDATE_DENSITY * 9.6**2 / 0.1**2 > PLACE.candidates and got % 1024 == 0
    assert got == min(MAX_COVERING, got)
    small = ScoreModel.create(FootprintEncoder(), hidden=16, layers=2, length_scale=0.1 / 8)
    tiny = scene.copy()
    tiny.bounds = tuple(tuple(v / 8 for v in b) for b in wide.bounds)  # type: ignore[assignment]
    assert covering(PLACE, small, [tiny]).candidates == got
    assert covering(replace(PLACE, candidates=0), model, [wide]).candidates == 0
    # place without options uses the covering defaults; with options, those
    a = place(model, wide.without("fork_0"), None, seed=1)
    b = place(model, wide.without("fork_0"), covering(PLACE, model, [wide]), seed=1)
    assert a["fork_0"].pose == b["fork_0"].pose


def test_pair_moves_leave_a_trap_that_no_single_move_leaves():
    """A cost that is lowest with a fork at its pose and a knife beside it as in the data, and higher with
    one of the two than with neither: from particles with both elsewhere, no move of one object improves,
    and ``_in_pairs`` (the fork drawn anew, the knife beside it as the data puts it) finds the minimum."""
    model, scenes = _model(), _scenes()
    model.info.trust = reference(model, scenes)
    truth = scenes[0]
    scene = truth.without("fork_0").without("knife_0")
    ia, ib = scene.index("fork_0"), scene.index("knife_0")
    fork, knife = (torch.tensor(truth[n].pose, dtype=torch.float64) for n in ("fork_0", "knife_0"))
    beside = relative_poses(fork, knife)[:2]  # the knife's place in the fork's frame

    def trap(x: torch.Tensor) -> torch.Tensor:
        near_a = torch.exp(-((x[:, ia, :2] - fork[:2]) ** 2).sum(-1) / 0.3**2)
        rel = relative_poses(x[:, ia], x[:, ib])[:, :2]
        near_b = torch.exp(-((rel - beside) ** 2).sum(-1) / 0.05**2)
        return 0.5 + near_a + near_b - 2.5 * near_a * near_b  # both 0, one 1.5, neither 0.5

    problem = Problem(scene, CostFn(trap), movable=scene.unknown)
    start = problem.base_poses()[None].repeat(8, 1, 1)
    start[:, [ia, ib]] = torch.tensor([[0.5, -0.5, 0.0], [-0.5, -0.5, 0.0]], dtype=torch.float64)
    assert float(trap(start).min()) == pytest.approx(0.5, abs=1e-4)
    one = start.clone()
    one[:, ia] = fork  # the fork alone at its pose: worse than neither
    assert float(trap(one).min()) > 1.4
    got = _in_pairs(model, problem, start, 8192, 0.5, torch.Generator().manual_seed(0))
    assert got.shape == start.shape and float(trap(got).min()) < 0.1
    known = [scene.index(o.name) for o in scene.objects if o.pose is not None]
    assert torch.equal(got[:, known], start[:, known])


def test_several_unknown_objects_start_from_particles_found_one_at_a_time():
    """The unknown objects are screened one at a time, each beside the next (the ones after it left
    out), then moved in pairs; ``place`` is the descent from those particles, the same as ``ss.solve`` with
    ``init=in_turn(...)`` and ``refining`` options."""
    model = _model()
    scene = _scenes()[0].without("fork_0").without("knife_1")
    start = in_turn(model, scene, SMALL, seed=2)
    assert start.shape == (SMALL.particles, len(scene), 3) and start.dtype == torch.float64
    known = [scene.index(o.name) for o in scene.objects if o.pose is not None]
    assert np.array_equal(start[:, known].numpy(), np.repeat(scene.poses()[None, known], SMALL.particles, 0))
    assert not torch.equal(in_turn(model, scene, SMALL, seed=3), start)
    placed = place(model, scene, SMALL, seed=2)
    r = ss.solve(placement_problem(model, scene), LangevinSolver(refining(SMALL)), start, seed=2)
    for name in ("fork_0", "knife_1"):
        assert np.array_equal(np.asarray(placed[name].pose), r.poses[scene.index(name)])
