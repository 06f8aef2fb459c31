"""A chain's steps never read a tensor's values back (on a GPU each read waits for the device to finish
its queue): the round objects and the walls are settled once per batch of scenes, and a chain checks
its gradients and its cost terms' values once, at its end."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import pytest
import torch
from torch.utils._python_dispatch import TorchDispatchMode

import scenescore as ss
from scenescore.costs import CostFn, HingeCollision, LearnedEnergy
from scenescore.costs.base import stack_sums
from scenescore.costs.terms import CostError
from scenescore.learn.size_groups import SizeGroups
from scenescore.models.network import round_flags
from scenescore.planning.placement import placement_problem
from scenescore.problem.problem import Problem
from scenescore.solvers.kernel import PLACEMENT, Limits, chain


class Reads(TorchDispatchMode):
    """Counts the reads of a tensor's value into Python (``bool(t)``, ``t.item()``) inside the block."""

    def __init__(self) -> None:
        super().__init__()
        self.count = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):  # noqa: ANN001, ANN204
        if func is torch.ops.aten._local_scalar_dense.default:
            self.count += 1
        return func(*args, **(kwargs or {}))


def _model(**config: object) -> ss.models.ScoreModel:
    torch.manual_seed(0)
    return ss.models.ScoreModel.create(
        ss.FootprintEncoder(), hidden=8, layers=2, round_invariant=True, **config
    )


def _reads_of_a_chain(
    energy: Callable[[torch.Tensor], torch.Tensor], x: torch.Tensor, steps: int, limits: Limits | None = None
) -> int:
    limits = limits or Limits(
        torch.ones(x.shape[:2], dtype=torch.bool), torch.tensor([-1.0, -1.0]), torch.tensor([1.0, 1.0])
    )
    cfg = replace(PLACEMENT, steps=steps, heading_sweep=0, final_descent=0, resample=0)
    with Reads() as reads:
        chain(energy, x, limits, cfg, torch.Generator().manual_seed(0))
    return reads.count


@pytest.mark.parametrize(
    "config",
    [{}, {"walls": True}, {"neighbours": 3, "radius": 4.0}, {"neighbours": 3, "radius": 4.0, "walls": True}],
)
def test_a_chain_reads_the_device_once_whatever_its_length(config):
    model = _model(**config)
    scenes = ss.scenarios.get("zoo-jars").generate(4, 0)  # round jars
    st = model.tensors(scenes)
    assert round_flags(model.config, st.round) is not None
    rep = st.repeat(2)
    energy = SizeGroups(rep.mask.sum(dim=1)).bound(model, rep, 1, weight_grads=False)  # training's
    n = len(scenes[0])
    fn = model.energy_fn(scenes[0])  # placement's
    for steps in (2, 6):  # the same one read, at the chain's end, for any number of steps
        assert _reads_of_a_chain(energy, rep.poses.clone(), steps) == 1
        assert _reads_of_a_chain(fn, st.poses[:1, :n].repeat(3, 1, 1), steps) == 1


def test_a_batch_without_round_objects_takes_the_plain_path_with_the_same_numbers():
    model = _model(neighbours=3, radius=4.0, walls=True)
    st = model.tensors(ss.scenarios.get("zoo-classroom").generate(2, 0))
    assert round_flags(model.config, st.round) is None
    args = (st.poses, st.feats, st.sizes, st.mask)
    # given, an all-false round tensor takes the round path, whose numbers are the plain path's
    assert torch.equal(model.net(*args, round=st.round), model.net(*args, round=None))
    assert torch.equal(model.energy(st.poses, st), model.net(*args, round=None))


def _placement(model: ss.models.ScoreModel, seed: int) -> Problem:
    scene = ss.scenarios.get("zoo-jars").generate(1, seed)[0]
    for o in scene.objects[1:3]:  # two to place: the whole network (one object alone takes MovingOne's
        o.pose = None  # CPU-only path, which reads its pose sets' sizes)
    return placement_problem(model, scene)


def test_a_placements_chain_reads_the_device_once_and_names_a_cost_term_that_is_not_finite():
    model = _model(neighbours=3, radius=4.0)
    problem = _placement(model, 0)
    assert [type(c) for _, c in problem.cost.items] == [LearnedEnergy, HingeCollision]
    x = problem.initial(32, torch.Generator().manual_seed(0))  # enough rows that the hinge screens pairs
    limits = Limits(torch.as_tensor(problem.movable_mask), problem.lo, problem.hi)
    twice = stack_sums([problem.cost, _placement(model, 0).cost], [32, 32])  # two problems in one chain
    for steps in (2, 6):
        assert _reads_of_a_chain(problem.cost, x, steps, limits) == 1
        assert _reads_of_a_chain(twice, x.repeat(2, 1, 1), steps, limits) == 1
    bad = (problem.cost + CostFn(lambda p: p[..., 0].sum(-1) * float("nan"), name="bad")).bind(
        problem.scene, problem.scene.unknown
    )
    with pytest.raises(CostError, match="'bad' is not finite"):  # called alone: at once, its row named
        bad(x)
    with pytest.raises(CostError, match="'bad' is not finite .* of the chain"):  # in a chain: at its end
        _reads_of_a_chain(bad, x, 3, limits)
