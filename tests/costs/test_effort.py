"""Effort costs: displacement, smooth move count, anchors; gradients, CasADi forms and YAML specs."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
import torch

from scenescore.costs import Anchor, CostError, Displacement, MoveCount
from scenescore.costs.symbolic import SymbolicProblem, casadi_form
from scenescore.problem.files import load_problem
from scenescore.problem.problem import Problem, ProblemError
from scenescore.scene.scene import Scene, SceneObject


def _scene() -> Scene:
    return Scene(
        [
            SceneObject("plate", "plate", (0.24, 0.24), (0.0, 0.0, 0.0), shape="disk"),
            SceneObject("fork", "fork", (0.2, 0.02), (0.2, 0.0, 0.5)),
            SceneObject("book", "book", (0.2, 0.1), (-0.3, 0.2, 1.0)),
            SceneObject("lamp", "lamp", (0.1, 0.1), None, shape="disk"),
        ]
    )


def _moved(scene: Scene, name: str, dx: float, dy: float, dt: float) -> torch.Tensor:
    x = torch.as_tensor(scene.poses(), dtype=torch.float64).clone()
    i = scene.index(name)
    x[i] += torch.tensor([dx, dy, dt], dtype=torch.float64)
    return x[None]


def test_effort_is_zero_at_rest_and_about_the_move_length_far_from_it():
    s = _scene()
    d = Displacement(delta=0.01).bind(s)
    c = MoveCount(sigma=0.02).bind(s)
    rest = _moved(s, "plate", 0, 0, 0)
    assert float(d(rest)) == 0.0 and float(c(rest)) == 0.0
    far = _moved(s, "book", 0.3, 0.4, 0.0)  # 0.5 m
    assert float(d(far)) == pytest.approx(0.5 - 0.01, abs=2e-4)
    assert float(c(far)) == pytest.approx(1.0, abs=2e-3)
    # the lamp (pose null) has no current pose and counts nothing
    assert d.objects_index == [0, 1, 2]


def test_headings_count_by_the_tip_and_not_for_round_objects():
    s = _scene()
    d = Displacement(delta=1e-6).bind(s)
    turn_fork = float(d(_moved(s, "fork", 0, 0, math.pi)))  # the tip travels 2 * rho = the length
    assert turn_fork == pytest.approx(0.2, rel=1e-4)
    assert float(d(_moved(s, "plate", 0, 0, 2.0))) == 0.0  # a round plate's heading is free


def test_weights_and_subsets():
    s = _scene()
    far = _moved(s, "book", 0.3, 0.4, 0.0)
    base = float(Displacement().bind(s)(far))
    heavy = float(Displacement(weights={"book": 3.0}).bind(s)(far))
    assert heavy == pytest.approx(3 * base)
    assert float(Displacement(objects=["fork"]).bind(s)(far)) == 0.0
    with pytest.raises(CostError, match="weights: no object named 'bok'"):
        Displacement(weights={"bok": 2.0}).bind(s)
    with pytest.raises(CostError, match="weights: 'book'"):
        Displacement(weights={"book": -1.0})
    with pytest.raises(CostError, match="delta"):
        Displacement(delta=0.0)
    with pytest.raises(CostError, match="'lamp' has no pose"):
        Displacement(objects=["lamp"]).bind(s)


def test_anchor_pulls_to_the_current_pose():
    s = _scene()
    a = Anchor(["fork"], theta_weight=0.5).bind(s)
    assert float(a(_moved(s, "fork", 0, 0, 0))) == 0.0
    assert float(a(_moved(s, "fork", 0.1, 0, 0))) == pytest.approx(0.01)
    assert float(a(_moved(s, "fork", 0, 0, math.pi))) == pytest.approx(1.0)
    with pytest.raises(CostError, match="non-empty list"):
        Anchor([])


def test_gradients_pass_gradcheck_in_float64():
    s = _scene()
    terms = [Displacement(delta=0.02), MoveCount(sigma=0.05), Anchor(["fork", "book"], theta_weight=0.3)]
    gen = torch.Generator().manual_seed(0)
    x = torch.as_tensor(s.poses(), dtype=torch.float64)[None].repeat(2, 1, 1)
    x = x + 0.05 * torch.randn(x.shape, generator=gen, dtype=torch.float64)
    for t in terms:
        b = t.bind(s, np.array([True, True, True, False]))
        assert torch.autograd.gradcheck(lambda p, b=b: b(p), (x.clone().requires_grad_(True),))


def test_casadi_forms_match_torch():
    s = _scene()
    movable = np.array([True, True, True, False])
    base = torch.as_tensor(s.poses(), dtype=torch.float64)
    x = _moved(s, "book", 0.1, -0.05, 0.7)[0] + torch.tensor([0.01, 0.02, 0.3], dtype=torch.float64)
    weights = {"fork": 2.0}
    for t in [
        Displacement(delta=0.02, weights=weights),
        MoveCount(weights=weights),
        Anchor(["book", "fork"]),
    ]:
        b = t.bind(s, movable)
        nlp = SymbolicProblem(s, movable, base, {})
        casadi_form(b)(b, 2.0, nlp)
        f = ca.Function("f", [nlp.z, nlp.p], [nlp.objective])
        z = x[movable].reshape(-1).numpy()
        got = float(f(z, base.numpy()))
        assert got == pytest.approx(2.0 * float(b(x[None])), rel=1e-9, abs=1e-12), type(t).__name__


def test_yaml_specs(tmp_path):
    scene = _scene().to_dict()
    scene["objects"][3]["pose"] = [0.3, 0.3, 0.0]
    import json

    (tmp_path / "s.json").write_text(json.dumps(scene))
    text = """scene: s.json
movable: [fork, book]
costs:
  - {type: displacement, weight: 2.0, delta: 0.02, weights: {book: 3.0}}
  - {type: move_count, weight: 0.5, sigma: 0.03, objects: [fork]}
  - {type: anchor, objects: [plate]}
  - {type: collision}
"""
    lp = load_problem(tmp_path / "p.yaml", text=text)
    p: Problem = lp.problem
    assert p.cost.names == ["displacement", "moves", "anchor", "collision"]
    assert p.cost.weight("displacement") == 2.0 and p.cost["displacement"].weights == {"book": 3.0}
    assert p.cost["moves"].objects_index == [1]
    bad = text.replace("weights: {book: 3.0}", "weights: {bok: 3.0}")
    with pytest.raises(ProblemError, match=r"p.yaml:4: costs\[0\].weights.bok: no object named 'bok'"):
        load_problem(tmp_path / "p.yaml", text=bad)
    with pytest.raises(ProblemError, match="greater than or equal to 0"):
        load_problem(tmp_path / "p.yaml", text=text.replace("{book: 3.0}", "{book: -3.0}"))
