"""Rivals: another answer far off that costs nearly as little, objects of one category matched."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import LearnedEnergy
from scenescore.costs.guide import Alternatives
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.models.rivals import RIVAL_DISTANCE, RIVAL_MARGIN, matched_distances, rivals
from scenescore.solvers import Samples, Status, make_result


def test_objects_of_one_category_are_matched_and_others_are_not():
    answer = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    swapped = answer[[1, 0, 2]][None]  # the two chairs swapped
    assert np.allclose(matched_distances(answer, swapped, ["chair", "chair", "desk"]), 0.0)
    # of different categories, a swap moves both by their distance
    assert np.allclose(matched_distances(answer, swapped, ["chair", "stool", "desk"]), [[1.0, 1.0, 0.0]])
    moved = answer.copy()[None]
    moved[0, 2, :2] = [3.0, 6.0]
    assert np.allclose(matched_distances(answer, moved, ["chair", "chair", "desk"]), [[0.0, 0.0, 5.0]])


def test_a_rival_is_far_and_nearly_as_cheap():
    answer = np.zeros((2, 3))
    L = 0.1
    far = 2 * RIVAL_DISTANCE * L
    others = np.zeros((5, 2, 3))
    others[0, 0, 0] = far  # object 0 far, within the margin: a rival
    others[1, 0, 0] = 2 * far  # farther, but a larger margin
    others[2, 1, 0] = far  # object 1 far, beyond the margin: none
    others[3, 1, 1] = 0.5 * RIVAL_DISTANCE * L  # object 1 near, within the margin: none
    others[4, 1, 0] = far  # object 1 far, a cost that is not a number: ignored
    margins = np.array([0.1, 0.3, RIVAL_MARGIN + 0.01, 0.0, np.nan])
    got = rivals(answer, others, margins, ["book", "lamp"], L)
    assert set(got) == {0}
    assert got[0].distance == pytest.approx(far) and got[0].margin == pytest.approx(0.1)
    assert "0.4 m away" in got[0].reason() and "costs only 0.1 more" in got[0].reason()
    assert rivals(answer, others, np.full(5, RIVAL_MARGIN + 0.5), ["book", "lamp"], L) == {}


@pytest.fixture(scope="module")
def model():
    torch.set_num_threads(1)
    sc = ss.scenarios.get("dining")
    cfg = TrainConfig(
        members=1, iterations=20, batch_scenes=6, negatives=6, network=NetworkConfig(hidden=16, layers=2)
    )
    return fit(sc.generate(12, 3), cfg, seed=0, progress=False), sc.generate(1, 4)[0]


def _placing(scene: ss.Scene, name: str) -> ss.Scene:
    """``scene`` with ``name``'s pose unknown."""
    out = scene.copy()
    i = out.index(name)
    out.objects[i] = replace(out.objects[i], pose=None)
    return out


def _shifted(poses: np.ndarray, i: int, by: float) -> list[np.ndarray]:
    """``poses`` with object ``i`` moved ``by`` along each axis direction, and mirrored through 0."""
    out = []
    for d in ([by, 0.0], [-by, 0.0], [0.0, by], [0.0, -by]):
        p = poses.copy()
        p[i, :2] += d
        out.append(p)
    p = poses.copy()
    p[i, :2] *= -1
    return out + [p]


def test_the_learned_energy_flags_the_moving_object_a_rival_moves(model):
    net, scene = model
    name = scene.objects[0].name
    problem = ss.Problem(_placing(scene, name), LearnedEnergy(net), movable=[name])
    term = [c for _, c in problem.cost][0]
    poses, far = scene.poses(), 3 * RIVAL_DISTANCE * net.config.length_scale
    other = _shifted(poses, 0, far)[0]
    got = term.rivals(poses, Alternatives(other[None], np.array([0.2])))
    assert list(got) == [name] and got[name].startswith("rival: another placement")
    assert term.rivals(poses, Alternatives(other[None], np.array([RIVAL_MARGIN * 2]))) == {}
    # a known object that a sample moves is not the placement's rival
    assert term.rivals(poses, Alternatives(_shifted(poses, 1, far)[0][None], np.array([0.0]))) == {}


def test_a_result_flags_rivals_only_among_feasible_undoubted_samples(model):
    net, scene = model
    name = scene.objects[2].name  # a knife: some of its shifted poses are where the data has knives
    problem = ss.Problem(_placing(scene, name), LearnedEnergy(net), movable=[name])
    poses = scene.poses()
    with torch.no_grad():
        objective = float(problem.cost(problem.full(poses))[0])
    shifted = np.stack(_shifted(poses, 2, 1.2 * RIVAL_DISTANCE * net.config.length_scale))
    doubted = problem.doubted(torch.as_tensor(shifted)).numpy()
    assert doubted.any() and not doubted.all()  # the data has no plate in some of them

    def flags(rows: np.ndarray, margin: float) -> list[str]:
        samples = np.concatenate([poses[None], shifted[rows]])
        costs = np.concatenate([[objective], np.full(len(samples) - 1, objective + margin)])
        r = make_result(
            problem, "langevin", poses, Status.SAMPLED, 1, 0.0, 0.0, samples=Samples(samples, costs)
        )
        return [f for f in r.confidence[name].flags if f.startswith("rival:")]

    assert len(flags(~doubted, 0.1)) == 1
    assert flags(~doubted, RIVAL_MARGIN + 0.1) == []
    assert flags(doubted, 0.0) == []  # a doubted sample is no rival: the answer was chosen over it
