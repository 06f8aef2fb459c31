"""Scenes: JSON round trip and every malformed-input error naming file, line, object and field."""

import json

import pytest

from scenescore import Scene, SceneError, read_jsonl, write_jsonl
from scenescore.scenarios import DiningScenario


def _obj(**kw):
    d = {
        "name": "fork_0",
        "category": "fork",
        "size": [0.19, 0.025],
        "pose": [0.12, -0.31, 1.5708],
        "color": [180, 180, 190],
    }
    d.update(kw)
    return d


def test_json_round_trip(tmp_path):
    scenes = DiningScenario().generate(3, seed=1)
    scenes[0].objects[0].fixed = True
    scenes[1].objects[1].pose = None
    scenes[2].objects[2].shape = {"polygon": [[0, 0], [0.1, 0], [0.05, 0.08]]}
    scenes[2].objects[3].features = [0.5, -1.0]
    write_jsonl(tmp_path / "s.jsonl", scenes)
    back = read_jsonl(tmp_path / "s.jsonl")
    assert [s.to_dict() for s in back] == [s.to_dict() for s in scenes]
    scenes[0].to_json(tmp_path / "one.json")
    assert Scene.from_json(tmp_path / "one.json").to_dict() == scenes[0].to_dict()
    assert back[1].unknown == [scenes[1].objects[1].name]


def test_design_example_parses():
    s = Scene.from_dict({"objects": [_obj()], "bounds": [[-0.6, -0.6], [0.6, 0.6]]})
    assert s["fork_0"].pose == (0.12, -0.31, 1.5708) and s.bounds == ((-0.6, -0.6), (0.6, 0.6))


@pytest.mark.parametrize(
    "objects, words",
    [
        ([_obj(size=[0.19])], ["fork_0", "size", "2 numbers"]),
        ([_obj(size=[0.19, -1])], ["fork_0", "size", "positive"]),
        ([_obj(pose=[0, 0])], ["fork_0", "pose", "3 numbers"]),
        ([_obj(pose=[0, "a", 0])], ["fork_0", "pose", "number"]),
        ([_obj(color=[0, 0, 300])], ["fork_0", "color", "0..255"]),
        ([_obj(fixed="yes")], ["fork_0", "fixed", "true or false"]),
        ([_obj(fixed=True, pose=None)], ["fork_0", "fixed", "pose"]),
        ([_obj(shape="triangle")], ["fork_0", "shape", "box"]),
        ([_obj(shape={"polygon": [[0, 0], [1, 1]]})], ["fork_0", "polygon", "3"]),
        ([_obj(colour=[1, 2, 3])], ["fork_0", "unknown field", "colour"]),
        ([_obj(), _obj()], ["fork_0", "duplicate"]),
        ([{"name": "x", "size": [1, 1]}], ["'x'", "category"]),
        (["fork"], ["objects[0]", "expected an object"]),
    ],
)
def test_malformed_object_errors(tmp_path, objects, words):
    path = tmp_path / "bad.jsonl"
    good = json.dumps({"objects": [_obj(name="ok")]})
    path.write_text(good + "\n" + json.dumps({"objects": objects}) + "\n")
    with pytest.raises(SceneError) as e:
        read_jsonl(path)
    msg = str(e.value)
    assert f"{path}:2" in msg  # file and line
    for w in words:
        assert w in msg, (w, msg)


def test_scene_level_errors(tmp_path):
    p = tmp_path / "s.json"
    p.write_text('{"objects": [}')
    with pytest.raises(SceneError, match=r"s\.json:1: not valid JSON"):
        Scene.from_json(p)
    with pytest.raises(SceneError, match="missing key 'objects'"):
        Scene.from_dict({"bounds": [[0, 0], [1, 1]]}, source="f.json")
    with pytest.raises(SceneError, match="min < max"):
        Scene.from_dict({"objects": [], "bounds": [[1, 0], [0, 1]]})
    with pytest.raises(SceneError, match="unknown key"):
        Scene.from_dict({"objects": [], "bound": 1})
    with pytest.raises(SceneError, match="missing.json: no such scene file"):
        Scene.from_json(tmp_path / "missing.json")
    (tmp_path / "empty.jsonl").write_text("\n")
    with pytest.raises(SceneError, match="no scenes"):
        read_jsonl(tmp_path / "empty.jsonl")
    with pytest.raises(SceneError, match="no object named 'spoon'"):
        Scene.from_dict({"objects": [_obj()]})["spoon"]


def test_dining_is_seeded_and_oracle_is_close():
    sc = DiningScenario()
    a, b = sc.generate(4, seed=3), sc.generate(4, seed=3)
    assert [s.to_dict() for s in a] == [s.to_dict() for s in b]
    assert a[0].to_dict() != sc.generate(1, seed=4)[0].to_dict()
    for s in a:
        assert len(s) == 8 and {o.category for o in s.objects} == {"plate", "fork", "knife", "bowl"}
        for name in ("fork_0", "knife_1", "bowl_0"):
            x, y, _ = sc.oracle(s.without(name), name)
            tx, ty, _ = s[name].pose
            assert ((x - tx) ** 2 + (y - ty) ** 2) ** 0.5 < 0.04


def test_atomic_writes_take_the_umask_not_0600(tmp_path):
    import os

    from scenescore.scene.outputs import atomic_write_text

    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
