"""Hostile scene JSON and JSONL datasets: each case either raises :class:`SceneError` naming the file
(and the line, object and field) or reads the scene it should."""

from __future__ import annotations

import json
import math

import pytest

from scenescore.scene.scene import Scene, SceneError, read_jsonl

from .helpers import SCENE, expect, scene, with_object, write

OBJ = {"name": "a", "category": "c", "size": [0.1, 0.1], "pose": [0.0, 0.0, 0.0]}


def deep(n: int) -> str:
    return "[" * n + "]" * n


# -- files and encodings --------------------------------------------------------------------------------
FILES = [
    ("latin1", '{"objects": [], "meta": {"x": "caf\xe9"}}'.encode("latin-1"), ("not UTF-8", ":1:")),
    ("utf16", json.dumps(SCENE).encode("utf-16"), ("not UTF-8",)),
    ("nul bytes", b"\x00" * 64, ("not valid JSON",)),
    ("empty", b"", ("not valid JSON",)),
    ("whitespace", b"  \n\t\n", ("not valid JSON",)),
    ("truncated", json.dumps(SCENE)[:-5].encode(), ("not valid JSON",)),
    ("trailing garbage", (json.dumps(SCENE) + " x").encode(), ("not valid JSON",)),
    ("two documents", (json.dumps(SCENE) + json.dumps(SCENE)).encode(), ("not valid JSON",)),
    ("NaN literal", b'{"objects": [{"name": "a", "category": "c", "size": [NaN, 1]}]}', ("'size'", "finite")),
    (
        "Infinity literal",
        b'{"objects": [{"name": "a", "category": "c", "size": [1, Infinity]}]}',
        ("finite",),
    ),
    ("top-level list", b"[]", ("expected a scene object",)),
    ("top-level string", b'"scene"', ("expected a scene object",)),
    ("top-level null", b"null", ("expected a scene object",)),
    ("duplicate key", b'{"objects": [], "objects": []}', ("duplicate key 'objects'",)),
    ("duplicate object key", b'{"objects": [{"name": "a", "name": "b"}]}', ("duplicate key 'name'",)),
    ("nested 100 deep", ('{"objects": [], "meta": {"x": ' + deep(100) + "}}").encode(), ("nested deeper",)),
    ("nested 100000 deep", deep(100_000).encode(), ("nested deeper",)),
    ("javascript comment", b'{"objects": [] // none\n}', ("not valid JSON",)),
    ("single quotes", b"{'objects': []}", ("not valid JSON",)),
    ("BOM then scene", b"\xef\xbb\xbf" + json.dumps({"objects": [OBJ]}).encode(), None),
]


@pytest.mark.parametrize("label,data,names", FILES, ids=[f[0] for f in FILES])
def test_scene_file(tmp_path, label, data, names):
    p = write(tmp_path / "s.json", data)
    if names is None:
        assert Scene.from_json(p).names == ["a"]
    else:
        expect(lambda: Scene.from_json(p), SceneError, str(p), *names)


def test_scene_path_is_a_folder(tmp_path):
    expect(lambda: Scene.from_json(tmp_path), SceneError, str(tmp_path), "folder")


def test_scene_path_missing(tmp_path):
    expect(lambda: Scene.from_json(tmp_path / "no.json"), SceneError, "no.json", "no such")


def test_scene_file_over_the_size_cap(tmp_path, monkeypatch):
    monkeypatch.setenv("SCENESCORE_MAX_FILE_MB", "0.001")
    p = write(tmp_path / "big.json", scene(meta={"pad": "x" * 5000}))
    expect(lambda: Scene.from_json(p), SceneError, str(p), "SCENESCORE_MAX_FILE_MB")


def test_size_cap_setting_itself_bad(tmp_path, monkeypatch):
    from scenescore.errors import ConfigError

    monkeypatch.setenv("SCENESCORE_MAX_FILE_MB", "lots")
    p = write(tmp_path / "s.json", SCENE)
    expect(lambda: Scene.from_json(p), ConfigError, "SCENESCORE_MAX_FILE_MB", "'lots'")


def test_dev_zero_is_refused_within_the_cap(monkeypatch):
    monkeypatch.setenv("SCENESCORE_MAX_FILE_MB", "1")
    expect(lambda: Scene.from_json("/dev/zero"), SceneError, "/dev/zero")


# -- schema, numbers and geometry, object by object ---------------------------------------------------
SQUARE = [[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]]
OBJECTS = [
    # (label, scene dict, names the message must hold; None: valid)
    ("unknown scene key", scene(walls=[]), ("unknown key", "walls")),
    ("objects not a list", scene(objects={"a": 1}), ("'objects'", "list")),
    ("missing objects", {"bounds": SCENE["bounds"]}, ("missing key 'objects'",)),
    ("object a string", scene(objects=["plate"]), ("objects[0]",)),
    ("unknown object field", with_object(0, colour=[1, 2, 3]), ("'plate'", "colour")),
    ("missing name", with_object(0, name=...), ("missing field 'name'",)),
    ("empty name", with_object(0, name=""), ("objects[0].name",)),
    ("name a number", with_object(0, name=7), ("objects[0].name",)),
    ("duplicate names", with_object(1, name="plate"), ("'plate'", "duplicate")),
    ("category null", with_object(0, category=None), ("'plate'", "'category'")),
    ("size one number", with_object(0, size=[0.2]), ("'plate'", "'size'")),
    ("size a string", with_object(0, size="0.2 0.2"), ("'plate'", "'size'")),
    ("size bool", with_object(0, size=[True, 0.2]), ("'plate'", "'size'")),
    ("size zero", with_object(0, size=[0.0, 0.2]), ("'plate'", "positive")),
    ("size negative", with_object(0, size=[-0.2, 0.2]), ("'plate'", "positive")),
    ("size 1e20 overflows the model", with_object(0, size=[1e20, 0.2]), ("'plate'", "'size'")),
    ("size 1e39 beyond float32", with_object(0, size=[1e39, 0.2]), ("'plate'", "'size'")),
    ("size 1e-300 below resolution", with_object(0, size=[1e-300, 0.2]), ("'plate'", "'size'")),
    ("pose two numbers", with_object(0, pose=[0, 0]), ("'plate'", "'pose'")),
    ("pose x 1e300", with_object(0, pose=[1e300, 0, 0]), ("'plate'", "'pose'")),
    ("pose theta 1e300", with_object(0, pose=[0, 0, 1e300]), ("'plate'", "'pose'")),
    ("pose theta 1e40 beyond float32", with_object(0, pose=[0, 0, 1e40]), ("'plate'", "'pose'")),
    ("pose string", with_object(0, pose="origin"), ("'plate'", "'pose'")),
    ("pose nested", with_object(0, pose=[[0], 0, 0]), ("'plate'", "'pose'")),
    ("pose theta 7 rad is fine", with_object(0, pose=[0, 0, 7.0]), None),
    ("color 256", with_object(0, color=[256, 0, 0]), ("'plate'", "'color'")),
    ("color negative", with_object(0, color=[-1, 0, 0]), ("'plate'", "'color'")),
    ("color fractional", with_object(0, color=[1.5, 0, 0]), ("'plate'", "'color'")),
    ("color 2.0 is an integer", with_object(0, color=[2.0, 0, 0]), None),
    ("color hex string", with_object(0, color="#ffffff"), ("'plate'", "'color'")),
    ("fixed a string", with_object(0, fixed="yes"), ("'plate'", "'fixed'")),
    ("fixed without a pose", with_object(2, fixed=True), ("'cup'", "fixed")),
    ("shape unknown", with_object(0, shape="circle"), ("'plate'", "'shape'")),
    ("shape extra key", with_object(0, shape={"polygon": SQUARE, "holes": []}), ("'plate'", "'shape'")),
    ("polygon two points", with_object(0, shape={"polygon": SQUARE[:2]}), ("'plate'", "shape.polygon")),
    (
        "polygon collinear",
        with_object(0, shape={"polygon": [[0, 0], [0.1, 0], [0.2, 0]]}),
        ("'plate'", "polygon"),
    ),
    ("polygon all one point", with_object(0, shape={"polygon": [[0.1, 0.1]] * 4}), ("'plate'", "polygon")),
    (
        "polygon self-intersecting (bow tie)",
        with_object(0, shape={"polygon": [[0, 0], [0.1, 0.1], [0.1, 0], [0, 0.1]]}),
        ("'plate'", "self-intersect"),
    ),
    (
        "polygon NaN vertex",
        with_object(0, shape={"polygon": [[0, 0], [0.1, 0], [math.nan, 0.1]]}),
        ("'plate'", "polygon"),
    ),
    (
        "polygon 1e300 vertex",
        with_object(0, shape={"polygon": [[0, 0], [0.1, 0], [0, 1e300]]}),
        ("'plate'", "polygon"),
    ),
    ("polygon clockwise is fine", with_object(0, shape={"polygon": SQUARE[::-1]}), None),
    (
        "polygon concave is fine",
        with_object(0, shape={"polygon": [[0, 0], [0.1, 0], [0.05, 0.03], [0.1, 0.1], [0, 0.1]]}),
        None,
    ),
    (
        "polygon 10 m from its 0.2 m object",
        with_object(0, shape={"polygon": [[0, 0], [10.0, 0], [10.0, 0.1]]}),
        ("'plate'", "shape.polygon[1]", "[10, 0]", "lies 10 m", "0.2 x 0.2 m", "own frame"),
    ),
    (
        # its 10 m size allows the vertices, but its pose stays in the 1.2 m bounds: the outline cannot
        "polygon 10 m from an object to place, in 1.2 m bounds",
        with_object(2, size=[10.0, 10.0], shape={"polygon": [[10.0, 0], [10.1, 0], [10.0, 0.1]]}),
        ("'cup'", "1.2 x 1.2 m", "'shape.polygon' reaches 10.1 m from its pose"),
    ),
    (
        "polygon off its origin that fits with it is fine",
        with_object(2, size=[0.5, 0.5], shape={"polygon": [[0.3, 0], [0.4, 0], [0.3, 0.1]]}),
        None,
    ),
    (
        "polygon uncentred within its size is fine",
        with_object(0, shape={"polygon": [[0, 0], [0.2, 0], [0, 0.2]]}),
        None,
    ),
    ("features a string", with_object(0, features="red"), ("'plate'", "'features'")),
    ("features NaN", with_object(0, features=[0.1, math.inf]), ("'plate'", "'features'")),
    ("features 1e39 beyond float32", with_object(0, features=[1e39]), ("'plate'", "'features'")),
    ("features empty", with_object(0, features=[]), ("'plate'", "'features'")),
    ("image a number", with_object(0, image=3), ("'plate'", "'image'")),
    ("image empty", with_object(0, image=""), ("'plate'", "'image'")),
    ("bounds flat", scene(bounds=[-0.6, -0.6, 0.6, 0.6]), ("'bounds'",)),
    ("bounds inverted", scene(bounds=[[0.6, 0.6], [-0.6, -0.6]]), ("'bounds'", "min < max")),
    ("bounds empty", scene(bounds=[[0, 0], [0, 0]]), ("'bounds'",)),
    ("bounds 1e300", scene(bounds=[[-1e300, -1], [1e300, 1]]), ("bounds",)),
    ("meta a list", scene(meta=[1]), ("'meta'",)),
    ("unknown object larger than its bounds", with_object(2, size=[2.0, 2.0]), ("'cup'", "bounds")),
    ("unknown object that fits only turned", with_object(2, size=[1.5, 0.05]), None),
    ("no objects at all is a scene", scene(objects=[]), None),
    ("a 1 mm object is fine", with_object(2, size=[0.001, 0.001]), None),
    ("a known object past the bounds is data", with_object(0, pose=[3.0, 0, 0]), None),
]


@pytest.mark.parametrize("label,data,names", OBJECTS, ids=[o[0] for o in OBJECTS])
def test_scene_content(tmp_path, label, data, names):
    p = write(tmp_path / "s.json", data)
    if names is None:
        s = Scene.from_json(p)
        assert len(s) == len(data["objects"])
        assert Scene.from_json(write(tmp_path / "again.json", s.to_json())) == s  # and it round-trips
    else:
        expect(lambda: Scene.from_json(p), SceneError, str(p), *names)


# -- JSONL datasets -------------------------------------------------------------------------------------
LINE = json.dumps(scene(objects=SCENE["objects"][:2]))
JSONL = [
    ("empty file", "", ("no scenes",)),
    ("only blank lines", "\n\n  \n", ("no scenes",)),
    ("bad line 3", f"{LINE}\n{LINE}\n{{oops\n", (":3:", "not valid JSON")),
    (
        "bad object on line 2",
        f"{LINE}\n" + json.dumps(with_object(0, size=[-1, 1])) + "\n",
        (":2:", "'plate'"),
    ),
    ("pretty-printed scene", json.dumps(SCENE, indent=1), (":1:", "not valid JSON")),
    ("a list per line", "[1, 2]\n", (":1:", "expected a scene object")),
    ("latin-1 on line 2", LINE + "\n" + '{"objects": [], "meta": {"x": "\udce9"}}', None),  # replaced below
    ("CRLF line ends are fine", f"{LINE}\r\n{LINE}\r\n", 2),
    ("blank lines between are fine", f"\n{LINE}\n\n{LINE}\n\n", 2),
]


@pytest.mark.parametrize("label,text,names", JSONL, ids=[j[0] for j in JSONL])
def test_jsonl(tmp_path, label, text, names):
    if label.startswith("latin-1"):
        data = (LINE + "\n").encode() + '{"objects": [], "meta": {"x": "caf\xe9"}}\n'.encode("latin-1")
        p = write(tmp_path / "d.jsonl", data)
        expect(lambda: read_jsonl(p), SceneError, f"{p}:2:", "not UTF-8")
        return
    p = write(tmp_path / "d.jsonl", text)
    if isinstance(names, int):
        assert len(read_jsonl(p)) == names
    else:
        expect(lambda: read_jsonl(p), SceneError, str(p), *names)


# -- writing: nothing non-finite goes out, files follow the umask -----------------------------------------
def test_nan_pose_is_not_written(tmp_path):
    s = Scene.from_dict(SCENE)
    s.objects[0].pose = (math.nan, 0.0, 0.0)
    expect(lambda: s.to_json(tmp_path / "out.json"), SceneError, "'plate'", "pose")
    assert not (tmp_path / "out.json").exists()


def test_inf_size_is_not_written_to_jsonl(tmp_path):
    from scenescore.scene.scene import write_jsonl

    s = Scene.from_dict(SCENE)
    s.objects[1].size = (math.inf, 0.1)
    expect(lambda: write_jsonl(tmp_path / "d.jsonl", [s]), SceneError, "'fork'", "size")
    assert not (tmp_path / "d.jsonl").exists()


@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_follow_the_umask(tmp_path, umask, mode):
    import os

    old = os.umask(umask)
    try:
        Scene.from_dict(SCENE).to_json(tmp_path / "s.json")
    finally:
        os.umask(old)
    assert (tmp_path / "s.json").stat().st_mode & 0o777 == mode
