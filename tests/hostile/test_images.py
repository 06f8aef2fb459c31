"""Hostile image folders (``train FOLDER``, ``generate --images``) and object images: each case a
:class:`SceneError` naming the image, the folder's index or the object, or the scenes it should read."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from scenescore.encoders import encode_scene, make_encoder
from scenescore.learn import check_training_data
from scenescore.scene.scene import Scene, SceneError
from scenescore.vision.graph import scenes_from_image_folder

from .helpers import cli_error, expect, with_object, write


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Two rendered dining scenes at 200 px/m, with their sidecars and dataset.json."""
    from scenescore.cli import main

    d = tmp_path_factory.mktemp("img") / "imgs"
    assert main(["generate", "dining", "--n", "2", "--images", str(d), "--ppm", "200", "--quiet"]) == 0
    return d


@pytest.fixture
def folder(tmp_path, rendered):
    d = tmp_path / "imgs"
    shutil.copytree(rendered, d)
    return d


def _png(path, image):
    cv2.imwrite(str(path), image)
    return path


def test_rendered_folder_reads(folder):
    scenes = scenes_from_image_folder(folder, make_encoder("image", {"ppm": 200}))
    assert len(scenes) == 2 and all(len(s) > 0 for s in scenes)
    assert scenes[0].origin == str(folder / "scene_00000.png")


def _no_sidecars(folder):
    for f in folder.glob("scene_*.json"):
        f.unlink()


FOLDERS = [
    (
        "dataset.json not JSON",
        lambda d: write(d / "dataset.json", "{bad"),
        {},
        ("dataset.json", "not valid JSON"),
    ),
    (
        "dataset.json not UTF-8",
        lambda d: write(d / "dataset.json", b'{"ppm": "\xff"}'),
        {},
        ("dataset.json", "not UTF-8"),
    ),
    (
        "dataset.json ppm a word",
        lambda d: (_no_sidecars(d), write(d / "dataset.json", {"ppm": "lots"})),
        {},
        ("dataset.json", "'ppm'", "'lots'"),
    ),
    ("dataset.json ppm 0", lambda d: write(d / "dataset.json", {"ppm": 0}), {}, ("dataset.json", "'ppm'")),
    (
        "dataset.json ppm negative",
        lambda d: write(d / "dataset.json", {"ppm": -200}),
        {},
        ("dataset.json", "'ppm'"),
    ),
    ("--ppm disagrees with dataset.json", lambda d: None, {"ppm": 3.0}, ("ppm 3", "dataset.json", "200")),
    ("ppm NaN", lambda d: None, {"ppm": float("nan")}, ("ppm",)),
    ("ppm negative", lambda d: None, {"ppm": -3.0}, ("ppm",)),
    (
        "sidecar not JSON",
        lambda d: write(d / "scene_00001.json", "{"),
        {},
        ("scene_00001.json", "not valid JSON"),
    ),
    (
        "sidecar ppm a string",
        lambda d: write(d / "scene_00001.json", {"objects": [], "meta": {"ppm": "x"}}),
        {},
        ("scene_00001.json", "ppm"),
    ),
    (
        "no index, no sidecar, no ppm",
        lambda d: (_no_sidecars(d), (d / "dataset.json").unlink()),
        {},
        ("scene_00000.png", "no ppm"),
    ),
    (
        "corrupt png",
        lambda d: write(d / "scene_00001.png", b"\x89PNG\r\n\x1a\n garbage"),
        {},
        ("scene_00001.png", "not a readable image"),
    ),
    (
        "empty png",
        lambda d: write(d / "scene_00001.png", b""),
        {},
        ("scene_00001.png", "not a readable image"),
    ),
    ("text named .png", lambda d: write(d / "scene_00001.png", "hello"), {}, ("scene_00001.png",)),
    (
        "image of the wrong size for its sidecar",
        lambda d: _png(d / "scene_00001.png", np.zeros((10, 10, 3), np.uint8)),
        {},
        ("10x10",),
    ),
    (
        "a folder named .png",
        lambda d: ((d / "scene_00001.png").unlink(), (d / "scene_00001.png").mkdir()),
        {},
        ("scene_00001.png",),
    ),
]


@pytest.mark.parametrize("label,edit,kw,names", FOLDERS, ids=[f[0] for f in FOLDERS])
def test_image_folder(folder, label, edit, kw, names):
    edit(folder)
    expect(
        lambda: scenes_from_image_folder(folder, make_encoder("image", {"ppm": 200}), **kw),
        SceneError,
        *names,
    )


def test_not_a_folder(tmp_path):
    expect(lambda: scenes_from_image_folder(tmp_path / "none"), SceneError, "none", "not a folder")


def test_folder_without_images(tmp_path):
    write(tmp_path / "a.txt", "x")
    expect(lambda: scenes_from_image_folder(tmp_path, ppm=200), SceneError, str(tmp_path), "no .png")


def test_only_mask_images(folder):
    for f in folder.glob("scene_?????.png"):
        f.unlink()
    expect(lambda: scenes_from_image_folder(folder, ppm=200), SceneError, "no .png")


def test_blank_images_are_named_when_training_refuses_them(tmp_path):
    for name in ("a.png", "b.png"):
        _png(tmp_path / name, np.full((100, 100, 3), 200, np.uint8))
    scenes = scenes_from_image_folder(tmp_path, make_encoder("image", {"ppm": 200}), ppm=200)
    assert [len(s) for s in scenes] == [0, 0]
    expect(lambda: check_training_data(scenes), SceneError, "a.png", "no objects")


def test_train_on_blank_images_cli(tmp_path, capsys):
    d = tmp_path / "blank"
    d.mkdir()
    for name in ("a.png", "b.png"):
        _png(d / name, np.full((100, 100, 3), 200, np.uint8))
    cli_error(
        capsys,
        "train",
        d,
        "--out",
        tmp_path / "m.ckpt",
        "--ppm",
        "200",
        "--quiet",
        names=("a.png", "no objects"),
    )


def test_train_with_a_ppm_that_contradicts_the_folder_cli(folder, tmp_path, capsys):
    cli_error(
        capsys,
        "train",
        "--members",
        "1",
        folder,
        "--out",
        tmp_path / "m.ckpt",
        "--ppm",
        "3",
        "--quiet",
        names=("ppm 3", "dataset.json"),
    )


# -- an object's own image (the ``image`` field) ------------------------------------------------------------
def _scene_with_image(tmp_path, image):
    p = write(tmp_path / "s.json", with_object(0, image=str(image)))
    return Scene.from_json(p)


OBJECT_IMAGES = [
    ("missing file", lambda t: t / "nope.png", ("'plate'", "nope.png", "no such image")),
    ("a folder", lambda t: t, ("'plate'", "no such image")),
    (
        "corrupt file",
        lambda t: write(t / "bad.png", b"\x89PNG garbage"),
        ("'plate'", "bad.png", "not a readable image"),
    ),
    (
        "blank image, nothing found",
        lambda t: _png(t / "blank.png", np.full((40, 40, 3), 200, np.uint8)),
        ("'plate'", "blank.png"),
    ),
    (
        "transparent image, empty mask",
        lambda t: _png(t / "clear.png", np.zeros((40, 40, 4), np.uint8)),
        ("'plate'", "clear.png", "empty"),
    ),
]


@pytest.mark.parametrize("label,make,names", OBJECT_IMAGES, ids=[o[0] for o in OBJECT_IMAGES])
def test_object_image(tmp_path, label, make, names):
    s = _scene_with_image(tmp_path, make(tmp_path))
    expect(lambda: encode_scene(s, make_encoder("image")), SceneError, str(tmp_path / "s.json"), *names)


def test_object_image_that_is_fine(tmp_path):
    img = np.zeros((60, 60, 4), np.uint8)
    img[20:40, 10:50] = (40, 40, 200, 255)
    s = _scene_with_image(tmp_path, _png(tmp_path / "ok.png", img))
    enc = make_encoder("image")
    assert np.isfinite(encode_scene(s, enc)).all()


def test_object_image_unused_by_the_footprint_encoder_is_warned_once(tmp_path, capsys):
    """A footprint encoder reads no images: a named crop (here missing) is said unused, once per file."""
    s = _scene_with_image(tmp_path, tmp_path / "nope.png")
    enc = make_encoder("footprint")
    plain = encode_scene(Scene.from_json(write(tmp_path / "plain.json", with_object(0))), enc)
    for _ in range(2):
        assert np.array_equal(encode_scene(s, enc), plain)  # the image changes nothing
    assert capsys.readouterr().err == (
        f"warning: {tmp_path / 's.json'}: the footprint encoder reads no images; unused: the image of "
        f"object 'plate' ({tmp_path / 'nope.png'}: no such file)\n"
    )


def test_place_with_a_footprint_model_warns_of_an_unused_image(tmp_path, capsys, model_path):
    from .helpers import run_cli

    p = write(tmp_path / "s.json", with_object(0, image="crops/plate.png"))
    code, _, err = run_cli(capsys, "place", model_path, p, "--out", tmp_path / "o.json", "--quiet")
    assert code == 0
    assert "the footprint encoder reads no images" in err and "'plate' (crops/plate.png: no such file)" in err
