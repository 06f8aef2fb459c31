"""``ExampleRelations``: the examples' relative poses as a density, exact on what it saw, free of units."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import CostError, ExampleRelations

BOUNDS = ((-0.6, -0.6), (0.6, 0.6))


def _scene(rng: np.random.Generator) -> ss.Scene:
    """A plate anywhere, a fork 0.15 m to its left in its frame, a knife 0.15 m to its right."""
    plate = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
    c, s = math.cos(plate[2]), math.sin(plate[2])
    return ss.Scene(
        [
            ss.SceneObject("plate_0", "plate", (0.2, 0.2), plate, shape="disk"),
            ss.SceneObject(
                "fork_0", "fork", (0.18, 0.03), (plate[0] - 0.15 * c, plate[1] - 0.15 * s, plate[2])
            ),
            ss.SceneObject(
                "knife_0", "knife", (0.2, 0.03), (plate[0] + 0.15 * c, plate[1] + 0.15 * s, plate[2])
            ),
        ],
        BOUNDS,
        meta={"unit": "m"},
    )


@pytest.fixture
def five() -> list[ss.Scene]:
    rng = np.random.default_rng(0)
    return [_scene(rng) for _ in range(5)]


def _bound(cost: ExampleRelations, scene: ss.Scene, movable: list[str]) -> ExampleRelations:
    return cost.bind(scene, movable)  # type: ignore[return-value]


def test_an_arrangement_like_the_examples_costs_least(five):
    scene = _scene(np.random.default_rng(9))
    term = _bound(ExampleRelations(five), scene, ["fork_0"])
    p = torch.as_tensor(scene.poses())[None].repeat(4, 1, 1)
    p[1, 1, 0] += 0.03  # the fork 3 cm off
    p[2, 1, 2] += 0.5  # turned
    p[3, 1, :2] = torch.tensor([0.5, -0.5])  # far away
    e = term(p)
    assert e[0] < e[1] and e[0] < e[2] and e[1] < e[3]
    assert torch.isfinite(e).all()


def test_its_gradient_is_the_derivative_of_its_value(five):
    scene = _scene(np.random.default_rng(9))
    term = _bound(ExampleRelations(five), scene, ["fork_0", "knife_0"])
    p = torch.as_tensor(scene.poses(), dtype=torch.float64)[None].repeat(2, 1, 1)
    p[1, 1, :2] += 0.02
    p.requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x: term.evaluate(x), (p,), eps=1e-6, atol=1e-5)


def test_the_same_in_millimetres(five):
    scene = _scene(np.random.default_rng(9))
    mm = [s.scaled(1000.0) for s in five]
    a = _bound(ExampleRelations(five), scene, ["fork_0"])
    b = _bound(ExampleRelations(mm), scene.scaled(1000.0), ["fork_0"])
    p = torch.as_tensor(scene.poses())[None].repeat(2, 1, 1)
    p[1, 1, :2] += 0.02
    q = p.clone()
    q[..., :2] *= 1000.0
    torch.testing.assert_close(b(q), a(p), rtol=1e-9, atol=1e-9)


def test_it_places_a_missing_fork_where_the_examples_put_one(five):
    truth = _scene(np.random.default_rng(9))
    scene = truth.without("fork_0")
    r = ss.solve(ss.Problem(scene, ExampleRelations(five), movable=["fork_0"]), "langevin", seed=0)
    got, want = r.poses[1], np.asarray(truth["fork_0"].pose)
    assert np.hypot(*(got[:2] - want[:2])) < 0.01
    assert abs(math.remainder(got[2] - want[2], 2 * math.pi)) < 0.1


def test_it_proposes_the_example_poses_beside_the_known_objects(five):
    truth = _scene(np.random.default_rng(9))
    term = _bound(ExampleRelations(five), truth, ["fork_0"])
    x = torch.zeros(32, 3, 3, dtype=torch.float64)
    x[:] = torch.as_tensor(truth.poses())
    x[:, 1] = 0.0
    y = term.propose(x, torch.Generator().manual_seed(0))
    assert y is not None
    # each proposal is an example's fork pose beside the plate or beside the knife: here both are the truth
    np.testing.assert_allclose(
        y[:, 1].numpy(), np.repeat(np.asarray(truth["fork_0"].pose)[None], 32, 0), atol=1e-9
    )
    np.testing.assert_array_equal(y[:, [0, 2]].numpy(), x[:, [0, 2]].numpy())


def test_bad_examples_are_refused(five):
    with pytest.raises(CostError, match="at least one example"):
        ExampleRelations([])
    with pytest.raises(CostError, match=r"without a pose \(\['fork_0'\]\)"):
        ExampleRelations([five[0].without("fork_0")])


def test_a_model_s_checkpoint_keeps_its_examples_relations(five, tmp_path):
    from scenescore.problem.files import load_problem

    model = ss.learn.fit(five, ss.learn.TrainConfig(members=1, iterations=3), seed=0, progress=False)
    kept, direct = ExampleRelations.of_model(model), ExampleRelations(five)
    assert set(kept.tables) == set(direct.tables)
    for key, rows in direct.tables.items():  # five scenes: every pose kept, in length scales and back
        np.testing.assert_allclose(np.sort(kept.tables[key], axis=0), np.sort(rows, axis=0), atol=1e-9)
    model.save(tmp_path / "m.ckpt")
    scene = _scene(np.random.default_rng(9)).without("fork_0")
    scene.to_json(tmp_path / "s.json")
    text = "scene: s.json\nmodel: m.ckpt\ncosts:\n  - {type: examples, weight: 2.0}\nsolver: langevin\n"
    loaded = load_problem(tmp_path / "p.yaml", text=text)
    ((weight, term),) = list(loaded.problem.cost)
    assert weight == 2.0 and isinstance(term, ExampleRelations) and term.name == "examples"
    bare = ss.models.ScoreModel.create(ss.encoders.FootprintEncoder(), hidden=8, layers=1)
    with pytest.raises(CostError, match="keeps no relations"):
        ExampleRelations.of_model(bare)
