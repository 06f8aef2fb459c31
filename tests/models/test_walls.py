"""Walls: the bounds' sides as fixed objects in every graph, for data that stands against them."""

from __future__ import annotations

import math

import numpy as np
import torch

import scenescore as ss
from scenescore.models.batching import wall_objects
from scenescore.training import TrainConfig, stands_against_walls, train


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
    cfg = TrainConfig(iterations=2, batch_scenes=4, negatives=2, model={"hidden": 8, "layers": 1})
    assert train(lounge, cfg, seed=0, progress=False).config.walls
    assert not train(dining, cfg, seed=0, progress=False).config.walls
    from dataclasses import replace

    assert not train(lounge, replace(cfg, walls=False), seed=0, progress=False).config.walls
