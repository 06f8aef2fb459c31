"""One object moving in a local graph's scene: the nodes it reaches recomputed, the rest kept, the same
energies and pose gradients as the whole network's."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs.energy import LearnedEnergy
from scenescore.models.ensemble import EnsembleNet
from scenescore.models.moving import PIECE_ROWS, MovingMean, MovingOne, moving_one, stack_movers
from scenescore.models.network import EnergyConfig, EnergyNet

pytestmark = pytest.mark.float_order


def _room(n: int = 48, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """A room of ``n`` objects on a jittered grid (no two overlap, so no neighbour list has a tie), the
    last four padding, every fourth object round."""
    g = torch.Generator().manual_seed(seed)
    k = torch.arange(n)
    grid = torch.stack([(k % 8).double() * 1.2, (k // 8).double() * 1.2], -1)
    pos = grid + 0.3 * torch.rand(n, 2, generator=g, dtype=torch.float64)
    poses = torch.cat([pos, 2 * math.pi * torch.rand(n, 1, generator=g, dtype=torch.float64)], -1)
    feats = torch.randn(n, 6, generator=g, dtype=torch.float64)
    sizes = 0.2 + 0.3 * torch.rand(n, 2, generator=g, dtype=torch.float64)
    mask = torch.ones(n, dtype=torch.bool)
    mask[-4:] = False
    rnd = k % 4 == 0
    return poses, feats, sizes, mask, rnd


def _net(**kw: object) -> EnergyNet:
    torch.manual_seed(0)
    cfg = dict(feat_dim=6, length_scale=0.25, radius=3.0, neighbours=5, edge_encoder=16, layers=3)
    return EnergyNet(EnergyConfig(**{**cfg, **kw})).double()


def _mover(
    net: EnergyNet, poses: torch.Tensor, feats: torch.Tensor, sizes: torch.Tensor, mask: torch.Tensor, o: int
) -> MovingOne:
    """``net``'s evaluator of a room of :func:`_room`'s with object ``o`` moving (no round flags)."""
    nodes = net.node_embedding(feats[None], sizes[None]).detach()
    mover = MovingOne.of(net, poses, nodes[0], mask, None, o)
    assert mover is not None
    return mover


def _candidates(b: int, seed: int = 1) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.rand(b, 3, generator=g, dtype=torch.float64) * torch.tensor([9.0, 7.0, 2 * math.pi])


@pytest.mark.parametrize("o", [0, 21, 43])  # a corner (round), the middle, the last real object
@pytest.mark.parametrize("round_invariant", [False, True])
def test_the_energies_and_pose_gradients_are_the_whole_networks(o, round_invariant):
    net = _net(round_invariant=round_invariant)
    poses, feats, sizes, mask, rnd = _room()
    nodes = net.node_embedding(feats[None], sizes[None]).detach()
    mover = MovingOne.of(net, poses, nodes[0], mask, rnd if round_invariant else None, o)
    assert mover is not None
    b = PIECE_ROWS + 9  # two pieces
    x = _candidates(b)
    x[0] = poses[o]  # where it stands
    batch = poses.expand(b, -1, -1).clone()
    batch[:, o] = x
    batch.requires_grad_(True)
    whole = net(
        batch, None, None, mask.expand(b, -1), nodes=nodes, round=rnd[None] if round_invariant else None
    )
    (g_whole,) = torch.autograd.grad(whole.sum(), batch)
    mine_in = batch.detach().clone().requires_grad_(True)
    mine = mover(mine_in)
    (g_mine,) = torch.autograd.grad(mine.sum(), mine_in)
    torch.testing.assert_close(mine, whole.detach(), rtol=0, atol=1e-12)
    torch.testing.assert_close(g_mine[:, o], g_whole[:, o], rtol=0, atol=1e-12)
    assert not g_mine[:, :o].any() and not g_mine[:, o + 1 :].any()  # the fixed objects get none
    with torch.no_grad():
        torch.testing.assert_close(mover(batch.detach()), whole.detach(), rtol=0, atol=1e-12)


def test_only_the_nodes_within_reach_are_recomputed():
    net = _net()
    poses, feats, sizes, mask, _ = _room()
    mover = _mover(net, poses, feats, sizes, mask, 21)
    x = _candidates(32)
    pos = torch.cat([poses[None, :21].expand(32, -1, -1), x[:, None], poses[None, 22:].expand(32, -1, -1)], 1)
    pid = torch.zeros(32, dtype=torch.long)
    reach = mover._reach(pos[..., :2] / 0.25, pid)
    rec, _, widths = mover._graph(reach, pid)
    enters = reach.enters
    assert widths == sorted(widths) and widths[-1] == rec.shape[1] < int(mask.sum())
    assert bool(enters.any())  # o enters some lists, so layer one recomputes more than o
    assert widths[0] > 1


def test_pose_sets_of_like_reach_share_a_piece():
    net = _net()
    poses, feats, sizes, mask, _ = _room()
    mover = _mover(net, poses, feats, sizes, mask, 21)
    batch = poses.expand(2 * PIECE_ROWS, -1, -1).clone()
    batch[:, 21] = _candidates(2 * PIECE_ROWS, seed=3)
    x, pid, reach, order = mover.sorted(batch)
    counts = (reach.first <= 3).sum(dim=1)
    assert bool((counts[1:] >= counts[:-1]).all()) and counts[0] < counts[-1]
    assert order is not None  # more than one piece
    assert torch.equal(x, batch[order, 21]) and torch.equal(order.sort().values, torch.arange(len(batch)))
    again = mover._reach(batch[order][..., :2] / 0.25, pid)
    assert all(torch.equal(a, b) for a, b in zip(again, reach))
    assert mover.sorted(batch[:PIECE_ROWS])[3] is None  # one piece: its order kept
    # the first piece recomputes fewer nodes than the batch's widest pose set needs
    first_piece = mover._graph(reach.take(slice(0, PIECE_ROWS)), pid[:PIECE_ROWS])[2]
    assert first_piece[-1] < int(counts.max())


def test_gradcheck_of_the_moving_objects_pose():
    net = _net(layers=2)
    poses, feats, sizes, mask, rnd = _room(n=24)
    mover = _mover(net, poses, feats, sizes, mask, 9)
    x = _candidates(3, seed=5).requires_grad_(True)
    assert torch.autograd.gradcheck(mover.energy, (x,), eps=1e-6, atol=1e-6)


def test_other_pose_sets_and_other_networks_take_the_whole_network():
    poses, feats, sizes, mask, _ = _room()
    net = _net()
    mover = _mover(net, poses, feats, sizes, mask, 21)
    batch = poses.expand(4, -1, -1).clone()
    batch[:, 3, 0] += 0.1  # another object moved too
    assert mover(batch) is None
    assert mover(batch[:, :-1]) is None  # another scene's width
    for other in (_net(neighbours=None, radius=None), _net(walls=True, wall_lines=True)):
        nodes = other.node_embedding(feats[None], sizes[None]).detach()
        assert MovingOne.of(other, poses, nodes[0], mask, None, 21) is None
    few = mask.clone()
    few[6:] = False  # six objects: lists of five leave one without o
    assert MovingOne.of(net, poses, nodes[0], few, None, 2) is None


def test_a_learned_energy_with_one_moving_object_gives_the_models_energies():
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=8, layers=2, neighbours=4, radius=3.0)
    scene = ss.scenarios.get("zoo-classroom").generate(1, 0)[0]
    name = scene.names[5]
    movable = np.array([n == name for n in scene.names])
    term = LearnedEnergy(model).bind(scene, movable)
    assert isinstance(term, LearnedEnergy) and term._mover is not None
    poses = torch.as_tensor(scene.poses(), dtype=torch.float32)[None].repeat(40, 1, 1)
    poses[:, 5, :2] += torch.randn(40, 2, generator=torch.Generator().manual_seed(0))
    st = model.tensors([scene])
    torch.testing.assert_close(term(poses), model.energy(poses, st, weight_grads=False), rtol=1e-5, atol=1e-5)
    two = LearnedEnergy(model).bind(scene, movable | (np.arange(len(movable)) == 0))
    assert two._mover is None  # two moving objects: the whole network
    fused = LearnedEnergy.stack([term, term], [20, 20])
    torch.testing.assert_close(fused(poses), term(poses))


def test_an_ensembles_mover_gives_its_mean_energy_and_pose_gradient():
    nets = []
    for seed in range(3):
        torch.manual_seed(seed)
        cfg = dict(feat_dim=6, length_scale=0.25, radius=3.0, neighbours=5, edge_encoder=16, layers=3)
        nets.append(EnergyNet(EnergyConfig(**cfg)).double())
    ens = EnsembleNet(nets)
    poses, feats, sizes, mask, _ = _room()
    nodes = ens.node_embedding(feats[None], sizes[None]).detach()  # the members' side by side
    mover = moving_one(ens.nets, poses, nodes[0], mask, None, 21)
    assert isinstance(mover, MovingMean) and len(mover.movers) == 3
    b = 12
    batch = poses.expand(b, -1, -1).clone()
    batch[:, 21] = _candidates(b)
    batch.requires_grad_(True)
    whole = ens(batch, None, None, mask.expand(b, -1), nodes=nodes)
    (g_whole,) = torch.autograd.grad(whole.sum(), batch)
    mine_in = batch.detach().clone().requires_grad_(True)
    mine = mover(mine_in)
    assert mine is not None
    (g_mine,) = torch.autograd.grad(mine.sum(), mine_in)
    torch.testing.assert_close(mine, whole.detach(), rtol=0, atol=1e-12)
    torch.testing.assert_close(g_mine[:, 21], g_whole[:, 21], rtol=0, atol=1e-12)
    assert not g_mine[:, :21].any() and not g_mine[:, 22:].any()  # the fixed objects get none
    other = batch.detach().clone()
    other[:, 3, 0] += 0.1
    assert mover(other) is None  # another object moved too: the whole ensemble
    assert moving_one(ens.nets, poses, nodes[0], mask, None, 21) is not None
    one = moving_one(nets[:1], poses, nodes[0, :, : nodes.shape[-1] // 3], mask, None, 21)
    assert isinstance(one, MovingOne)  # a single network's own


def test_a_learned_energy_of_an_ensemble_moves_one_object_through_each_member():
    enc = ss.FootprintEncoder()
    nets = [
        ss.models.ScoreModel.create(enc, hidden=8, layers=2, neighbours=4, radius=3.0).net for _ in range(2)
    ]
    model = ss.models.ScoreModel(EnsembleNet(nets), enc)
    scene = ss.scenarios.get("zoo-classroom").generate(1, 0)[0]
    movable = np.array([i == 5 for i in range(len(scene.names))])
    term = LearnedEnergy(model).bind(scene, movable)
    assert isinstance(term, LearnedEnergy) and isinstance(term._mover, MovingMean)
    poses = torch.as_tensor(scene.poses(), dtype=torch.float32)[None].repeat(40, 1, 1)
    poses[:, 5, :2] += torch.randn(40, 2, generator=torch.Generator().manual_seed(0))
    st = model.tensors([scene])
    torch.testing.assert_close(term(poses), model.energy(poses, st, weight_grads=False), rtol=1e-5, atol=1e-5)


def _moved(poses: torch.Tensor, o: int, b: int, seed: int) -> torch.Tensor:
    batch = poses.expand(b, -1, -1).clone()
    batch[:, o] = _candidates(b, seed)
    return batch


@pytest.mark.parametrize("members", [1, 3])
def test_stacked_scenes_give_each_scenes_own_energies_and_pose_gradients(members):
    nets = [_net(layers=3) for _ in range(members)]
    for k, net in enumerate(nets):  # members of different weights
        torch.manual_seed(k)
        for p in net.parameters():
            p.data.normal_(0.0, 0.3)
    rooms = [_room(seed=s) for s in (0, 1, 2)]
    spots, sizes = [0, 21, 43], [PIECE_ROWS + 5, 7, 30]  # the first scene's rows span two pieces
    movers = []
    for (poses, feats, sizes_, mask, rnd), o in zip(rooms, spots):
        nodes = torch.cat([n.node_embedding(feats[None], sizes_[None]).detach() for n in nets], -1)
        movers.append(moving_one(nets, poses, nodes[0], mask, rnd, o))
    together = stack_movers(movers, sizes)
    assert together is not None and type(together) is type(movers[0])
    batch = torch.cat(
        [_moved(r[0], o, b, seed) for seed, (r, o, b) in enumerate(zip(rooms, spots, sizes))]
    ).requires_grad_(True)
    mine = together(batch)
    assert mine is not None
    (g_mine,) = torch.autograd.grad(mine.sum(), batch)
    a = 0
    for m, o, b in zip(movers, spots, sizes):
        part = batch[a : a + b].detach().clone().requires_grad_(True)
        alone = m(part)
        (g_alone,) = torch.autograd.grad(alone.sum(), part)
        torch.testing.assert_close(mine[a : a + b], alone.detach(), rtol=0, atol=1e-12)
        torch.testing.assert_close(g_mine[a : a + b], g_alone, rtol=0, atol=1e-12)
        assert not g_mine[a : a + b, :o].any() and not g_mine[a : a + b, o + 1 :].any()
        a += b
    with torch.no_grad():
        torch.testing.assert_close(together(batch.detach()), mine.detach(), rtol=0, atol=1e-12)
    other = batch.detach().clone()
    other[-1, 3, 0] += 0.1  # another object of the last scene moved too: the whole network
    assert together(other) is None
    assert together(batch.detach()[:-1]) is None  # not the rows it was stacked for
    wide = _room(n=52)
    nodes = torch.cat([n.node_embedding(wide[1][None], wide[2][None]).detach() for n in nets], -1)
    assert (
        stack_movers([*movers, moving_one(nets, wide[0], nodes[0], wide[3], wide[4], 5)], [*sizes, 3]) is None
    )
