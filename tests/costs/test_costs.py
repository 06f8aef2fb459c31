"""Cost algebra, per-term breakdowns, violations, gradients, and clear errors."""

from __future__ import annotations

import math

import pytest
import torch

import scenescore as ss
from scenescore.costs import (
    Bounds,
    CostError,
    CostFn,
    HingeCollision,
    LearnedEnergy,
    PoseTarget,
    ReachLimit,
    Sum,
)
from scenescore.scene.scene import Scene, SceneObject


def _scene() -> Scene:
    return Scene(
        [
            SceneObject("table_box", "box", (0.3, 0.2), (0.0, 0.0, 0.3), fixed=True),
            SceneObject("mug", "mug", (0.1, 0.1), (0.12, 0.05, 0.0), shape="disk"),
            SceneObject("book", "book", (0.2, 0.15), (-0.3, 0.3, 1.0)),
            SceneObject(
                "tri", "tri", (0.1, 0.1), (0.3, -0.3, 0.5), shape={"polygon": [[0, 0], [0.1, 0], [0, 0.08]]}
            ),
        ],
        bounds=((-0.5, -0.5), (0.5, 0.5)),
    )


def _sq(poses: torch.Tensor) -> torch.Tensor:
    return (poses[..., :2] ** 2).sum((-1, -2))


def test_weighted_sums_are_flat_and_scale():
    a, b, c = CostFn(_sq, name="a"), HingeCollision(0.01), ReachLimit((0, 0), 1.0)
    s = 2.0 * (a + 3.0 * b) + c
    assert isinstance(s, Sum) and len(s) == 3  # no nesting
    assert [c_.name for _, c_ in s] == ["a", "collision", "reach"]
    assert [w for w, _ in s] == [2.0, 6.0, 1.0]
    assert sum([a, b]).names == ["a", "collision"]


def test_duplicate_names_are_an_error():
    with pytest.raises(CostError, match="named 'collision'.*name="):
        HingeCollision(0.01) + HingeCollision(0.02)
    HingeCollision(0.01) + HingeCollision(0.02, name="collision_2")  # renamed: fine


def test_terms_report_value_weight_weighted_and_violation():
    scene = _scene()
    s = (
        CostFn(_sq, name="pull") + 10.0 * HingeCollision(0.01) + Bounds() + ReachLimit((0.0, 0.0), 0.2)
    ).bind(scene)
    x = torch.tensor(scene.poses())[None]
    terms = s.terms(x)
    assert set(terms) == {"pull", "collision", "bounds", "reach"}
    col = terms["collision"]
    sd = s["collision"].signed_distance(x)[0]
    assert col.weight == 10.0
    assert torch.allclose(col.weighted, 10.0 * col.value)
    assert float(col.value) == pytest.approx(float(torch.relu(0.01 - sd).sum()))
    assert float(col.violation) == pytest.approx(float(torch.relu(0.01 - sd).max()))
    assert float(col.violation) > 0.05  # the mug sits on the fixed box
    assert terms["pull"].violation is None
    # reach: the book at |(-0.3, 0.3)| = 0.424 m is 0.224 m beyond 0.2 m
    assert float(terms["reach"].violation) == pytest.approx(math.hypot(0.3, 0.3) - 0.2, abs=1e-9)
    assert float(s(x)) == pytest.approx(sum(float(t.weighted) for t in terms.values()))
    label, v = s["collision"].worst(x[0])
    assert label == "table_box / mug" and v == pytest.approx(float(col.violation))


def test_every_term_is_evaluable_alone_and_unbound_use_is_clear():
    scene = _scene()
    x = torch.tensor(scene.poses())[None]
    assert HingeCollision(0.0).bind(scene)(x).shape == (1,)
    assert CostFn(_sq)(x).shape == (1,)  # needs no scene
    with pytest.raises(CostError, match="not bound to a scene"):
        HingeCollision(0.0)(x)
    with pytest.raises(CostError, match=r"shape \(B, N, 3\)"):
        HingeCollision(0.0).bind(scene)(x[0])
    with pytest.raises(CostError, match="poses have 3 objects, the scene has 4"):
        HingeCollision(0.0).bind(scene)(x[:, :3])
    with pytest.raises(CostError, match="no object named 'cup'"):
        PoseTarget("cup", (0, 0)).bind(scene)
    with pytest.raises(CostError, match="weight"):
        -1.0 * HingeCollision(0.0)
    with pytest.raises(CostError, match="'bad' is not finite"):
        (CostFn(lambda p: p.sum((-1, -2)) * float("nan"), name="bad") + HingeCollision(0.0)).bind(scene)(x)


def test_fixed_objects_collide_but_are_not_in_pairs_with_each_other():
    scene = _scene()
    scene.objects[2].fixed = True  # book fixed too
    c = HingeCollision(0.0).bind(scene, movable=["mug"])
    names = c.labels()
    assert "table_box / mug" in names and "table_box / book" not in names  # neither moves: no row


def test_gradients_pass_gradcheck():
    scene = _scene()
    s = (
        HingeCollision(0.01, power=2)
        + Bounds(power=2)
        + ReachLimit((0.0, 0.0), 0.3, power=2)
        + PoseTarget("mug", (0.2, 0.1))
    ).bind(scene)
    gen = torch.Generator().manual_seed(0)
    for _ in range(3):
        x = torch.tensor(scene.poses())[None] + 0.02 * torch.randn(
            1, 4, 3, generator=gen, dtype=torch.float64
        )
        x.requires_grad_(True)
        assert torch.autograd.gradcheck(s, (x,), eps=1e-6, atol=1e-6)
        for _, c in s:
            assert torch.autograd.gradcheck(c, (x,), eps=1e-6, atol=1e-6)


def test_learned_energy_is_differentiable_and_conditioned_on_the_scene():
    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=16, layers=2).double()
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    e = LearnedEnergy(model).bind(scene)
    x = torch.tensor(scene.poses())[None].requires_grad_(True)
    assert torch.autograd.gradcheck(e, (x,), eps=1e-6, atol=1e-5)
    assert float(e(x).detach()) == pytest.approx(float(model.energy_fn(scene)(x).detach()))
    with pytest.raises(CostError, match="ScoreModel"):
        LearnedEnergy("model.ckpt")


def test_projections_restore_bounds_and_reach():
    scene = _scene()
    b = Bounds().bind(scene)
    r = ReachLimit((0.0, 0.0), 0.4).bind(scene)
    x = torch.tensor(scene.poses())[None].repeat(2, 1, 1)
    x[:, 2, :2] = torch.tensor([0.49, -0.49])  # the book sticks out of the table
    mov = torch.ones(4, dtype=torch.bool)
    xb = b.project(x, mov)
    assert float(b.violation(xb).max()) < 1e-12 and float(b.violation(x).max()) > 0.05
    xr = r.project(x, mov)
    assert float(r.violation(xr).max()) < 1e-9
