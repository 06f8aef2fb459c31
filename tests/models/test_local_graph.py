"""The local graph for rooms: each object reads its nearest neighbours and the walls, edges fading out."""

from __future__ import annotations

import math

import pytest
import torch

import scenescore as ss
from scenescore.errors import ConfigError
from scenescore.learn import TrainConfig, derive
from scenescore.learn.config import LOCAL_FROM, LR_DENSE, LR_LOCAL
from scenescore.learn.data import local_radius
from scenescore.models.export import export_onnx
from scenescore.models.graph import fade, neighbour_graph
from scenescore.models.network import EnergyConfig, EnergyNet
from scenescore.scenarios.zoo.classroom import ClassroomScenario

pytestmark = pytest.mark.float_order


def _room(b: int = 3, n: int = 30, seed: int = 0) -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(seed)
    poses = torch.rand(b, n, 3, generator=g, dtype=torch.float64) * torch.tensor([10.0, 8.0, 2 * math.pi])
    feats = torch.randn(b, n, 8, generator=g, dtype=torch.float64)
    sizes = 0.2 + 0.3 * torch.rand(b, n, 2, generator=g, dtype=torch.float64)
    mask = torch.ones(b, n, dtype=torch.bool)
    if b > 1:
        mask[1, n - 6 :] = False  # a smaller scene padded
    return poses, feats, sizes, mask


def _nets(neighbours: int, walls: bool = False, **kw) -> tuple[EnergyNet, EnergyNet]:
    """A local network reading ``neighbours`` objects and the same weights reading every object."""
    torch.manual_seed(0)
    cfg = dict(
        feat_dim=8, length_scale=0.25, radius=3.0, walls=walls, wall_lines=walls, edge_encoder=16, **kw
    )
    few = EnergyNet(EnergyConfig(neighbours=neighbours, **cfg)).double()
    every = EnergyNet(EnergyConfig(neighbours=4096, **cfg)).double()
    every.load_state_dict(few.state_dict())
    return few, every


@pytest.mark.parametrize("walls", [False, True])
def test_neighbour_lists_give_the_energy_of_every_pair_when_no_list_cuts_a_weighted_edge(walls):
    few, every = _nets(12, walls=walls, round_invariant=True)
    poses, feats, sizes, mask = _room()
    rnd = torch.zeros(mask.shape, dtype=torch.bool)
    rnd[:, ::5] = True
    # no object has more than 12 others within the radius here: the lists cut no edge of weight
    pos = poses[..., :2] / 0.25
    reach = 0.5 * (sizes / 0.25).amax(-1)
    _, weight = neighbour_graph(pos, reach, mask, None, 4096, 3.0)
    assert int((weight > 0).sum(-1).max()) <= 12
    x = poses.clone().requires_grad_(True)
    e_few = few(x, feats, sizes, mask, round=rnd)
    (g_few,) = torch.autograd.grad(e_few.sum(), x)
    e_all = every(x, feats, sizes, mask, round=rnd)
    (g_all,) = torch.autograd.grad(e_all.sum(), x)
    assert torch.allclose(e_few, e_all, rtol=0, atol=1e-10)
    assert torch.allclose(g_few, g_all, rtol=0, atol=1e-10)


def test_local_energy_is_invariant_to_rigid_motion_and_permutation():
    few, _ = _nets(6)
    poses, feats, sizes, mask = _room(b=1, n=24)
    mask[:] = True
    e0 = few(poses, feats, sizes, mask)
    a = 0.9
    rot = torch.tensor([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]], dtype=poses.dtype)
    moved = torch.cat([poses[..., :2] @ rot.T + torch.tensor([2.0, -3.0]), poses[..., 2:] + a], dim=-1)
    assert torch.allclose(few(moved, feats, sizes, mask), e0, rtol=0, atol=1e-10)
    perm = torch.randperm(24, generator=torch.Generator().manual_seed(3))
    assert torch.allclose(few(poses[:, perm], feats[:, perm], sizes[:, perm], mask), e0, rtol=0, atol=1e-10)


def test_neighbour_lists_hold_the_nearest_and_far_edges_weigh_nothing():
    pos = torch.tensor([[[0.0, 0.0], [0.6, 0.0], [30.0, 0.0], [30.6, 0.2]]], dtype=torch.float64)
    reach = torch.full((1, 4), 1.0, dtype=torch.float64)
    index, weight = neighbour_graph(pos, reach, torch.ones(1, 4, dtype=torch.bool), None, 2, 3.0)
    assert index is not None and index[0, 0].tolist() == [1, 2] and index[0, 2].tolist() == [3, 1]
    assert weight[0, 0].tolist() == [1.0, 0.0]  # touching circles: full weight; 28 apart: none
    assert weight[0, 2, 0] == 1.0
    dense, w_all = neighbour_graph(pos, reach, torch.ones(1, 4, dtype=torch.bool), None, 3, 3.0)
    assert dense is None and w_all.shape == (1, 4, 4) and w_all[0, 0].tolist() == [0.0, 1.0, 0.0, 0.0]


def test_fade_is_one_at_touching_and_zero_at_the_radius_with_zero_slope():
    gap = torch.tensor([0.0, 1.5, 3.0, 4.0], dtype=torch.float64, requires_grad=True)
    w = fade(gap, 3.0)
    assert w.tolist()[0] == 1.0 and w.tolist()[2:] == [0.0, 0.0] and 0 < w.tolist()[1] < 1
    (g,) = torch.autograd.grad(w.sum(), gap)
    assert g[0] == 0 and abs(float(g[2])) < 1e-12


def test_local_energy_gradcheck_float64():
    few, _ = _nets(4)
    poses, feats, sizes, mask = _room(b=2, n=10, seed=1)
    mask[:] = True
    x = poses.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda p: few(p, feats, sizes, mask), (x,), eps=1e-6, atol=1e-6)


def test_config_needs_both_neighbours_and_radius():
    with pytest.raises(ConfigError, match="neighbours and radius"):
        EnergyConfig(feat_dim=4, neighbours=6)
    with pytest.raises(ConfigError, match="graph"):
        TrainConfig(graph="sparse")  # type: ignore[arg-type]


def test_training_chooses_the_graph_from_the_data_and_scales_its_radius_with_the_unit():
    room = ClassroomScenario().generate(6, 0)
    small = ClassroomScenario(desks=(5, 5)).generate(6, 0)
    assert max(len(s) for s in room) > LOCAL_FROM >= max(len(s) for s in small)
    big = derive(TrainConfig(), room).energy
    assert big.local and big.neighbours == 6 and big.radius is not None and big.radius >= 1
    assert not derive(TrainConfig(), small).energy.local
    assert derive(TrainConfig(graph="local"), small).energy.local
    assert not derive(TrainConfig(graph="dense"), room).energy.local
    mm = [s.scaled(1000.0) for s in room]  # millimetres: the radius is in length scales, so the same
    assert derive(TrainConfig(), mm).energy.radius == pytest.approx(big.radius, rel=1e-9)
    assert local_radius(room, big.length_scale, 6) == big.radius
    # the length scale of the objects to place (the chairs), not the fixed desks
    assert big.length_scale == pytest.approx(max(ClassroomScenario().chair) / 2)
    assert derive(TrainConfig(), small).energy.length_scale > big.length_scale


def test_the_learning_rate_is_the_graphs_unless_set():
    room = ClassroomScenario().generate(6, 0)
    small = ClassroomScenario(desks=(5, 5)).generate(6, 0)
    assert derive(TrainConfig(), room).lr == LR_LOCAL and derive(TrainConfig(), small).lr == LR_DENSE
    assert derive(TrainConfig(graph="local"), small).lr == LR_LOCAL
    assert derive(TrainConfig(graph="dense"), room).lr == LR_DENSE
    assert derive(TrainConfig(lr=1e-3), room).lr == 1e-3 and derive(TrainConfig(lr=1e-3), small).lr == 1e-3


def test_a_local_model_round_trips_its_graph_and_refuses_onnx_export(tmp_path):
    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=1, neighbours=6, radius=2.5)
    path = tmp_path / "room.pt"
    model.save(path)
    back = ss.load_model(path)
    assert back.config.neighbours == 6 and back.config.radius == 2.5
    pytest.importorskip("onnx")
    with pytest.raises(ss.SceneError, match="local graph"):
        export_onnx(back, tmp_path / "room.onnx")
