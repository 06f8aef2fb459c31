"""A learned relation bound to named objects: gradients, instances batched, the YAML form, and one
relation model trained briefly that tells left from right in a scene it never saw."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.costs import CostError, Relation
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.problem.files import load_problem
from scenescore.problem.problem import ProblemError
from scenescore.scenarios import get
from scenescore.scene.scene import Scene, SceneObject


def _scene() -> Scene:
    return Scene(
        [
            SceneObject("cup", "cup", (0.08, 0.08), (-0.2, 0.1, 0.3), shape="disk", color=(250, 250, 250)),
            SceneObject("plate", "plate", (0.25, 0.25), (0.1, 0.0, 0.0), shape="disk"),
            SceneObject("fork", "fork", (0.18, 0.02), (0.3, 0.05, 1.2)),
            SceneObject("book", "book", (0.2, 0.15), (-0.3, -0.3, 0.7)),
        ],
        bounds=((-0.6, -0.5), (0.6, 0.5)),
    )


def _model(double: bool = False) -> ss.models.ScoreModel:
    torch.manual_seed(0)
    m = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=16, layers=2)
    return m.double() if double else m


@pytest.mark.parametrize("frame", [False, True])
def test_relation_gradients_pass_gradcheck_in_float64(frame):
    scene = _scene()
    r = Relation(_model(double=True), objects=[("cup", "plate"), ("fork", "plate")], frame=frame).bind(scene)
    gen = torch.Generator().manual_seed(1)
    x = torch.tensor(scene.poses())[None] + 0.05 * torch.randn(2, 4, 3, generator=gen, dtype=torch.float64)
    assert torch.autograd.gradcheck(r, (x.requires_grad_(True),), eps=1e-6, atol=1e-5)


def test_instances_are_one_call_summing_each_instance_alone():
    """Two instances in one term give the sum of the two terms alone; the unnamed objects do not count."""
    scene, model = _scene(), _model(double=True)
    both = Relation(model, objects=[("cup", "plate"), ("fork", "plate")], frame=True).bind(scene)
    one = Relation(model, objects=("cup", "plate"), frame=True).bind(scene)
    two = Relation(model, objects=("fork", "plate"), frame=True).bind(scene)
    x = torch.tensor(scene.poses())[None].repeat(3, 1, 1)
    x[1, 3] += torch.tensor([0.2, 0.1, 1.0], dtype=torch.float64)  # the book moves: nothing changes
    x[2, 0, :2] += 0.1  # the cup moves
    e = both(x).detach()
    torch.testing.assert_close(e, (one(x) + two(x)).detach())
    assert abs(float(e[1] - e[0])) < 1e-12 and abs(float(e[2] - e[0])) > 1e-6
    assert both.name == "relation(cup, plate; fork, plate)"


def test_the_model_sees_roles_not_the_objects_looks():
    """Recoloured objects give the same energy: the role, not the colour, reaches the model."""
    scene, model = _scene(), _model()
    other = Scene([dataclasses.replace(o, color=(1, 2, 3)) for o in scene.objects], scene.bounds)
    x = torch.tensor(scene.poses(), dtype=torch.float32)[None]
    a = Relation(model, ("cup", "plate")).bind(scene)(x)
    b = Relation(model, ("cup", "plate")).bind(other)(x)
    torch.testing.assert_close(a, b)


def test_bad_objects_are_clear_errors():
    model = _model()
    with pytest.raises(CostError, match="objects: expected names"):
        Relation(model, objects="cup")
    with pytest.raises(CostError, match="twice"):
        Relation(model, objects=("cup", "cup"))
    with pytest.raises(CostError, match="as many objects"):
        Relation(model, objects=[("cup", "plate"), ("cup", "plate", "fork")])
    with pytest.raises(CostError, match="no object named 'mug'"):
        Relation(model, objects=("mug", "plate")).bind(_scene())
    with pytest.raises(CostError, match="ScoreModel"):
        Relation("left_of.ckpt", objects=("cup", "plate"))  # type: ignore[arg-type]


def test_yaml_relation_terms_round_trip(tmp_path):
    """`{type: relation, model, objects}` builds the Python term (one model loaded per file), names it by
    the checkpoint, and a wrong object or a missing checkpoint names the line and key."""
    model = _model()
    model.save(tmp_path / "left_of.ckpt")
    scene = _scene()
    scene.to_json(tmp_path / "scene.json")
    text = (
        "scene: scene.json\n"
        "costs:\n"
        "  - {type: relation, model: left_of.ckpt, objects: [cup, plate]}\n"
        "  - {type: relation, model: left_of.ckpt, objects: [[fork, plate], [book, plate]], weight: 2.0}\n"
        "  - {type: collision}\n"
    )
    (tmp_path / "p.yaml").write_text(text)
    lp = load_problem(tmp_path / "p.yaml")
    cost = lp.problem.cost
    assert cost.names[:2] == ["left_of(cup, plate)", "left_of(fork, plate; book, plate)"]
    a, b = cost[cost.names[0]], cost[cost.names[1]]
    assert isinstance(a, Relation) and a.model is b.model and cost.weight(b.name) == 2.0
    x = torch.tensor(scene.poses(), dtype=torch.float32)[None]
    want = Relation(model, [("fork", "plate"), ("book", "plate")]).bind(scene)(x)
    torch.testing.assert_close(b(x), want)
    (tmp_path / "bad.yaml").write_text(text.replace("[cup, plate]", "[cup, platter]"))
    with pytest.raises(ProblemError, match=r"bad.yaml:3: costs\[0\].objects\[1\]: no object named 'platter'"):
        load_problem(tmp_path / "bad.yaml")
    (tmp_path / "none.yaml").write_text(
        text.replace("model: left_of.ckpt, objects: [cup", "model: x.ckpt, objects: [cup")
    )
    with pytest.raises(ProblemError, match=r"none.yaml:3: costs\[0\].model: model checkpoint .*x.ckpt"):
        load_problem(tmp_path / "none.yaml")


def test_a_trained_left_of_prefers_left_of_to_its_mirror_in_a_new_scene():
    """Trained briefly on generated left_of examples (objects a, b), the relation bound to a cup and a
    plate elsewhere in a larger scene, in other colours, is lower for held-out left_of arrangements than
    for their mirror images (the plate left of the cup), on average and for most pairs."""
    scenario = get("relation-left_of")
    cfg = TrainConfig(
        members=1, iterations=100, batch_scenes=16, negatives=8, network=NetworkConfig(hidden=32, layers=2)
    )
    model = fit(scenario.generate(64, 0), cfg, seed=0, progress=False)
    gaps = []
    for s in scenario.generate(12, 5):
        objs = [
            dataclasses.replace(o, name=n, category=n, color=(200, 200, 200))
            for o, n in zip(s.objects[:2], ["cup", "plate"])
        ]
        p = np.array([o.pose for o in objs])
        p[:, :2] += (0.7, -0.4)  # elsewhere than any example
        mirror = p.copy()
        mirror[:, 0] = 2 * p[:, 0].mean() - p[:, 0]
        mirror[:, 2] = np.pi - p[:, 2]
        r = Relation(model, objects=("cup", "plate")).bind(Scene(objs, ((-1.5, -1.5), (1.5, 1.5))))
        e = r(torch.tensor(np.stack([p, mirror]), dtype=torch.float32)).detach()
        gaps.append(float(e[1] - e[0]))
    assert r.frame  # trained with the axes marker, read from the model
    assert np.mean(gaps) > 0 and np.mean(np.array(gaps) > 0) >= 0.75, gaps
