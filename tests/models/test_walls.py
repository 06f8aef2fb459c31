"""Walls: the bounds' sides as fixed objects in every graph, for data that stands against them."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.learn.data import stands_against_walls
from scenescore.models.batching import wall_objects
from scenescore.models.network import WALLS, edge_features, wall_nodes

pytestmark = pytest.mark.float_order


def _model(walls: bool) -> ss.models.ScoreModel:
    torch.manual_seed(0)
    return ss.models.ScoreModel.create(
        ss.FootprintEncoder(), hidden=16, layers=2, walls=walls, edge_range=4.0
    ).double()


def test_walls_surround_the_bounds_and_face_inward():
    ws = wall_objects(((-1.0, -0.5), (1.0, 0.5)))
    assert [w.name for w in ws] == ["wall_s", "wall_n", "wall_w", "wall_e"] and all(w.fixed for w in ws)
    for w in ws:
        x, y, t = w.pose
        inward = np.array([-math.sin(t), math.cos(t)])  # the wall's own +y
        assert np.dot(inward, -np.array([x, y])) > 0
        poly = w.world_polygon()
        inside = (np.abs(poly[:, 0]) < 1.0 - 1e-9) & (np.abs(poly[:, 1]) < 0.5 - 1e-9)
        assert not inside.any()  # just outside the bounds


def test_energy_with_walls_sees_the_room_and_moves_with_it():
    model = _model(True)
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    st = model.tensors([scene])
    assert st.poses.shape[1] == len(scene) + 4 and bool(st.fixed[0, -4:].all())
    x = torch.tensor(scene.poses())[None]
    e = model.energy_fn(scene)(x)
    assert torch.allclose(e, model.energy(st.poses, st))  # the function pads the walls' poses
    moved = scene.with_poses(scene.poses() + np.array([0.3, -0.2, 0.0]))
    moved.bounds = ((-0.3, -0.8), (0.9, 0.4))  # the whole room moved with the objects
    assert torch.allclose(model.energy_fn(moved)(torch.tensor(moved.poses())[None]), e, atol=1e-9)
    # objects moved inside a fixed room: the walls notice
    assert not torch.allclose(model.energy_fn(scene)(torch.tensor(moved.poses())[None]), e)
    assert torch.allclose(
        _model(False).energy_fn(scene)(torch.tensor(moved.poses())[None]), _model(False).energy_fn(scene)(x)
    )


def test_training_decides_walls_from_the_data():
    lounge = ss.scenarios.get("zoo-lounge").generate(8, 0)
    dining = ss.scenarios.get("dining").generate(8, 0)
    assert stands_against_walls(lounge) and not stands_against_walls(dining)
    cfg = TrainConfig(
        members=1, iterations=2, batch_scenes=4, negatives=2, network=NetworkConfig(hidden=8, layers=1)
    )
    assert fit(lounge, cfg, seed=0, progress=False).config.walls
    assert not fit(dining, cfg, seed=0, progress=False).config.walls
    from dataclasses import replace

    assert not fit(lounge, replace(cfg, walls=False), seed=0, progress=False).config.walls


def _wall_model(wall_range: float | None, wall_lines: bool = False) -> ss.models.ScoreModel:
    torch.manual_seed(0)
    return ss.models.ScoreModel.create(
        ss.FootprintEncoder(),
        hidden=16,
        layers=2,
        walls=True,
        edge_encoder=8,
        round_invariant=True,
        wall_range=wall_range,
        wall_lines=wall_lines,
        length_scale=0.1,
    ).double()


def test_wall_nodes_are_the_last_four_real_nodes_of_each_row():
    mask = torch.tensor([[True] * 7 + [False] * 2, [True] * 9])
    walls = wall_nodes(mask)
    assert walls[0].tolist() == [False] * 3 + [True] * 4 + [False] * 2
    assert walls[1].tolist() == [False] * 5 + [True] * 4
    assert len(wall_objects(((-1.0, -1.0), (1.0, 1.0)))) == WALLS


def test_edges_touching_a_wall_saturate_per_axis_and_the_rest_do_not():
    poses = torch.tensor([[[0.0, 0.0, 0.3], [5.0, -0.4, 1.0], [0.2, 3.0, -0.5]]], dtype=torch.float64)
    walls = torch.tensor([[False, False, True]])
    plain = edge_features(poses, 0.5)
    e = edge_features(poses, 0.5, walls=walls, wall_range=2.0)
    assert torch.equal(e[0, :2, :2], plain[0, :2, :2])  # object to object: unchanged
    touch = torch.tensor([[False, False, True], [False, False, True], [True, True, False]])
    u = plain[0, ..., :2]
    expect = u / torch.sqrt(1 + (u / 2.0) ** 2)  # each axis on its own
    assert torch.allclose(e[0, ..., :2][touch], expect[touch], atol=1e-12)
    assert torch.equal(e[0, ..., 2:], plain[0, ..., 2:])  # headings as they were
    assert float(e[0, ..., :2][touch].abs().max()) < 2.0  # bounded by the range


def test_wall_lines_read_the_height_above_a_wall_and_the_foot_of_the_perpendicular():
    # a wall along y = -1 facing +y (south), an object at (0.7, 0.2) turned 0.4, a round one at (-0.3, 0.5)
    poses = torch.tensor([[[0.7, 0.2, 0.4], [-0.3, 0.5, 1.1], [0.0, -1.0, 0.0]]], dtype=torch.float64)
    walls = torch.tensor([[False, False, True]])
    rnd = torch.tensor([[False, True, False]])
    e = edge_features(poses, 0.5, round=rnd, walls=walls, wall_lines=True)
    plain = edge_features(poses, 0.5, round=rnd)
    assert torch.equal(e[0, :2, :2], plain[0, :2, :2])  # object to object: unchanged
    assert torch.allclose(e[0, 0, 2, :2], torch.tensor([0.0, 1.2 / 0.5], dtype=torch.float64))  # height only
    assert torch.allclose(e[0, 1, 2, :2], torch.tensor([0.0, 1.5 / 0.5], dtype=torch.float64))
    # the wall from the object: the foot (0.7, -1) in the object's frame
    c, s = math.cos(0.4), math.sin(0.4)
    foot = torch.tensor([c * 0.0 + s * -1.2, -s * 0.0 + c * -1.2], dtype=torch.float64) / 0.5
    assert torch.allclose(e[0, 2, 0, :2], foot, atol=1e-12)
    assert torch.allclose(
        e[0, 2, 1, :2], torch.tensor([1.5 / 0.5, 0.0], dtype=torch.float64)
    )  # round: distance
    # sliding the object along the wall changes nothing the wall's edges read
    slid = poses.clone()
    slid[0, 0, 0] += 0.9
    e2 = edge_features(slid, 0.5, round=rnd, walls=walls, wall_lines=True)
    assert torch.allclose(e2[0, 0, 2], e[0, 0, 2]) and torch.allclose(e2[0, 2, 0], e[0, 2, 0])


@pytest.mark.parametrize("wall_range, wall_lines", [(2.0, False), (None, True), (2.0, True)])
def test_walls_read_as_such_keep_the_invariances(wall_range, wall_lines):
    scene = ss.scenarios.get("zoo-lounge").generate(1, 0)[0]
    model, linear = _wall_model(wall_range, wall_lines), _wall_model(None)
    x = torch.tensor(scene.poses())[None]
    assert not torch.allclose(model.energy_fn(scene)(x), linear.energy_fn(scene)(x))
    # the whole room moved with its objects: the same energy
    (x0, y0), (x1, y1) = scene.bounds
    moved = scene.with_poses(scene.poses() + np.array([0.7, -0.4, 0.0]))
    moved.bounds = ((x0 + 0.7, y0 - 0.4), (x1 + 0.7, y1 - 0.4))
    e = model.energy_fn(scene)(x)
    assert torch.allclose(model.energy_fn(moved)(torch.tensor(moved.poses())[None]), e, atol=1e-9)
    # padded beside a larger scene, each row finds its own walls: the same energy as alone
    other = ss.scenarios.get("zoo-lounge").generate(8, 1)
    big = max(other, key=len)
    assert len(big) > len(scene)
    st = model.tensors([scene, big])
    assert torch.allclose(model.energy(st.poses, st)[0], e[0], atol=1e-9)
    # first derivatives, exactly
    fn = model.energy_fn(scene)
    xg = x.clone().repeat(2, 1, 1)
    xg[1, :, :2] += 0.05
    xg.requires_grad_(True)
    assert torch.autograd.gradcheck(fn, (xg,), eps=1e-6, atol=1e-6)


def test_training_reads_walls_as_lines_by_default_and_only_with_walls():
    from dataclasses import replace

    lounge = ss.scenarios.get("zoo-lounge").generate(8, 0)
    dining = ss.scenarios.get("dining").generate(8, 0)
    cfg = TrainConfig(
        members=1, iterations=1, batch_scenes=4, negatives=2, network=NetworkConfig(hidden=8, layers=1)
    )
    m = fit(lounge, cfg, seed=0, progress=False)
    assert m.config.wall_lines and m.config.wall_range is None  # the defaults: lines, linear
    boxes = replace(cfg, wall_lines=False)
    assert not fit(lounge, boxes, seed=0, progress=False).config.wall_lines
    plain = fit(dining, cfg, seed=0, progress=False).config
    assert not plain.wall_lines and plain.wall_range is None  # no walls: neither
    m = fit(lounge, replace(boxes, wall_range=2.0), seed=0, progress=False)
    assert not m.config.wall_lines and m.config.wall_range == 2.0
