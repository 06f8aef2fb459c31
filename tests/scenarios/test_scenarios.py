"""The ordering, television and desk scenarios: seeded, with oracles that reproduce the process."""

import math

import numpy as np
import pytest

from scenescore.scenarios import DeskScenario, OrderingScenario, TVScenario, get
from scenescore.scenarios.ordering import TEST_LENGTHS, TRAIN_LENGTHS
from scenescore.scene.scene import SceneError


@pytest.mark.parametrize("rule", ["class_size", "all_size", "unseen_class"])
def test_ordering_oracle_and_sizes(rule):
    sc = get("ordering", rule=rule)
    train, test = sc.split(0)
    assert len(train) == 16 and len(test) == 16
    train_len = {o.size[0] for s in train for o in s.objects if o.category != "board"}
    test_len = {o.size[0] for s in test for o in s.objects if o.category != "board"}
    assert train_len <= set(TRAIN_LENGTHS) and test_len <= set(TEST_LENGTHS)
    assert not train_len & test_len
    cats = {o.category for s in test for o in s.objects}
    assert ("spoon" in cats) == (rule == "unseen_class")
    assert "spoon" not in {o.category for s in train for o in s.objects}
    errs = []
    for s in test:
        for o in s.objects:
            if o.category in sc.missing:
                x, y, _ = sc.oracle(s.without(o.name), o.name)
                errs.append(math.hypot(x - o.pose[0], y - o.pose[1]))
    assert max(errs) < 0.015  # only noise separates the oracle from the truth


def test_ordering_rules_differ_and_seeded():
    a = OrderingScenario("class_size").generate(3, 5)
    b = OrderingScenario("class_size").generate(3, 5)
    assert np.allclose(a[0].poses(), b[0].poses())
    items = [("fork_0", "fork", 0.14), ("knife_0", "knife", 0.24), ("fork_1", "fork", 0.2)]
    assert OrderingScenario("class_size").order(items) == ["fork_1", "fork_0", "knife_0"]
    assert OrderingScenario("all_size").order(items) == ["knife_0", "fork_1", "fork_0"]
    with pytest.raises(SceneError):
        OrderingScenario("nonsense")


def test_tv_correct_and_clutter():
    sc = TVScenario()
    train, _ = sc.split(0)
    assert len(train) == 36
    assert all(sc.correct(s) for s in train[:6])
    s = train[0]
    bad = s.with_poses([[s["speaker_0"].pose[0], s["speaker_0"].pose[1] + 0.3, 0.0]], ["speaker_0"])
    assert not sc.correct(bad)
    cl = sc.clutter(s, 4, seed=1)
    assert sum(o.category == "clutter" for o in cl.objects) == 4
    assert all(o.fixed for o in cl.objects if o.category == "clutter")
    assert cl.unknown == ["television", "speaker_0", "speaker_1"]
    name = "speaker_0"
    x, y, _ = sc.oracle(s.without(name), name)
    assert math.hypot(x - s[name].pose[0], y - s[name].pose[1]) < 0.03


def test_tv_collision_is_incorrect():
    sc = TVScenario()
    s = sc.generate(1, 3)[0]
    cl = sc.clutter(s, 1, seed=0, keep=True)
    tv = cl["television"].pose
    hit = cl.with_poses([[tv[0], tv[1], 0.0]], ["clutter_0"])
    assert sc.aligned(hit) and not sc.correct(hit)


def test_desk_relation_and_oracle():
    sc = DeskScenario()
    scenes = sc.generate(8, 0)
    for s in scenes:
        b, p, m = s["book"].pose, s["pen"].pose, s["mug"].pose
        d = math.hypot(p[0] - b[0], p[1] - b[1])
        dm = math.hypot(m[0] - b[0], m[1] - b[1])
        assert abs(dm - sc.mug_distance(d)) < 0.02
        x, y, _ = sc.oracle(s.without("mug"), "mug")
        assert math.hypot(x - m[0], y - m[1]) < 0.02
    near, far = sc.arrange((0, 0, 0), 0.12), sc.arrange((0, 0, 0), 0.28, pen="pencil")
    assert abs(far["mug"].pose[0]) > abs(near["mug"].pose[0]) + 0.1
    assert far.unknown == [] and sc.arrange((0, 0, 0), 0.2, mug=False).unknown == ["mug"]
