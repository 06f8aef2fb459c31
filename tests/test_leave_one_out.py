"""The leave-one-object-out cases: every movable object once, or a few of each category spread over the
scenes."""

from __future__ import annotations

from collections import Counter

from scenescore.evaluation.cases import leave_one_out
from scenescore.scene.scene import Scene, SceneObject


def _scene(name: str, chairs: int, forks: int) -> Scene:
    objs = [SceneObject(f"chair_{k}", "chair", (0.4, 0.4), (float(k), 0.0, 0.0)) for k in range(chairs)]
    objs += [SceneObject(f"fork_{k}", "fork", (0.02, 0.18), (0.0, float(k), 0.0)) for k in range(forks)]
    objs.append(SceneObject("table", "table", (1.0, 1.0), (0.0, 0.0, 0.0), fixed=True))
    return Scene(objs, meta={"id": name})


def test_every_movable_object_once_in_scene_order():
    cases = leave_one_out([_scene("a", 3, 1), _scene("b", 2, 2)])
    assert [c.name for c in cases] == ["chair_0", "chair_1", "chair_2", "fork_0", "chair_0", "chair_1"] + [
        "fork_0",
        "fork_1",
    ]
    assert all(c.scene[c.name].pose is None and c.scene["table"].pose is not None for c in cases)


def test_per_category_spreads_over_the_scenes_and_keeps_the_few():
    scenes = [_scene(s, 40, 1) for s in "abc"]
    cases = leave_one_out(scenes, per_category=5)
    assert Counter(c.category for c in cases) == {"chair": 5, "fork": 3}  # a hall's chairs capped, every fork
    chairs = [(c.scene.meta["id"], c.name) for c in cases if c.category == "chair"]
    # each scene's first chair, then each one's second, in scene order
    assert chairs == [
        ("a", "chair_0"),
        ("a", "chair_1"),
        ("b", "chair_0"),
        ("b", "chair_1"),
        ("c", "chair_0"),
    ]
    assert leave_one_out(scenes, per_category=1000) == leave_one_out(scenes)
    assert [c.name for c in leave_one_out(scenes, ["fork_0"], per_category=2)] == ["fork_0", "fork_0"]
