"""The vision pipeline against the renderer's ground truth: render, segment, pose, crop, encode, graph."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import scenescore as ss
from scenescore.encoders import make_encoder
from scenescore.encoders.image import ImageEncoder
from scenescore.scene.scene import Scene, SceneError, SceneObject
from scenescore.vision import (
    DEFAULT_LOOKS,
    TABLE_COLOR,
    ClassicalDetector,
    Detection,
    GroundTruthDetector,
    angle_error,
    pose_from_mask,
    rectify_crop,
    render_object,
    render_scene,
    write_rendered_dataset,
)
from scenescore.vision.graph import graphs_from_renders, scene_from_image, scenes_from_image_folder
from scenescore.vision.render import pixel_to_world

BOUNDS = ((-0.3, -0.3), (0.3, 0.3))


def obj(cat, pose=None, name="a", **kw):
    size, color = DEFAULT_LOOKS[cat]
    shape = "disk" if cat in ("plate", "bowl") else "box"
    return SceneObject(name, cat, kw.get("size", size), pose, kw.get("color", color), shape=shape)


@pytest.fixture(scope="module")
def dining():
    return ss.scenarios.get("dining").generate(6, 7)


# -- renderer ------------------------------------------------------------------------------------------
def test_render_geometry_and_masks(dining):
    scene = dining[0]
    image, masks = render_scene(scene, ppm=500)
    assert image.shape == (600, 600, 3) and image.dtype == np.uint8
    assert len(masks) == len(scene.objects)
    stack = np.stack(masks)
    assert stack.sum(axis=0).max() == 1  # visible masks never overlap
    assert (image[~stack.any(axis=0)] == TABLE_COLOR).all()  # the rest is plain table
    for o, m in zip(scene.objects, masks):
        rows, cols = np.nonzero(m)
        x, y = pixel_to_world(cols, rows, scene.bounds, 500)
        if o.category == "bowl":  # on top of everything: the full disk, centred on its pose
            assert abs(x.mean() - o.pose[0]) < 5e-4 and abs(y.mean() - o.pose[1]) < 5e-4
            assert m.sum() / 500**2 == pytest.approx(math.pi * 0.07**2, rel=0.02)
    # resolution: twice the ppm, four times the pixels
    image2, masks2 = render_scene(scene, ppm=250)
    assert image2.shape == (300, 300, 3)
    assert masks[3].sum() == pytest.approx(4 * masks2[3].sum(), rel=0.03)


def test_render_direction_follows_theta():
    """A fork's tines (the heavier half) point along theta: +x at 0, +y at 90 degrees."""
    for theta, axis, sign in ((0.0, 0, 1), (math.pi / 2, 1, 1), (math.pi, 0, -1)):
        scene = Scene([obj("fork", (0.0, 0.0, theta))], BOUNDS)
        _, (m,) = render_scene(scene)
        rows, cols = np.nonzero(m)
        xy = np.stack(pixel_to_world(cols, rows, BOUNDS, 500), axis=1)
        assert sign * xy[:, axis].mean() > 0.01  # the mass centroid sits towards the tines


def test_unknown_category_drawn_as_footprint_in_its_colour():
    tri = SceneObject(
        "t",
        "gizmo",
        (0.1, 0.1),
        (0.05, 0.0, 0.3),
        (10, 200, 30),
        shape={"polygon": [[-0.05, -0.05], [0.05, -0.05], [0.0, 0.05]]},
    )
    box = SceneObject("b", "widget", (0.12, 0.06), (-0.15, 0.1, 0.0), (200, 20, 200))
    image, (mt, mb) = render_scene(Scene([tri, box], BOUNDS))
    assert (image[mt] == (10, 200, 30)).all() and (image[mb] == (200, 20, 200)).all()
    assert mt.sum() / 500**2 == pytest.approx(0.005, rel=0.05)  # the triangle's area
    assert mb.sum() / 500**2 == pytest.approx(0.0072, rel=0.03)


def test_write_rendered_dataset(tmp_path, dining):
    paths = write_rendered_dataset(dining[:2], tmp_path / "imgs", ppm=400)
    assert [p.name for p in paths] == ["scene_00000.png", "scene_00001.png"]
    gt = Scene.from_json(tmp_path / "imgs" / "scene_00001.json")
    assert gt.meta["ppm"] == 400 and gt.meta["image"] == "scene_00001.png"
    assert np.allclose(gt.poses(), dining[1].poses())
    index = json.loads((tmp_path / "imgs" / "dataset.json").read_text())
    assert index["images"] == ["scene_00000.png", "scene_00001.png"]
    import cv2

    labels = cv2.imread(str(tmp_path / "imgs" / "scene_00000.masks.png"), cv2.IMREAD_UNCHANGED)
    _, masks = render_scene(dining[0], ppm=400)
    assert all(((labels == i + 1) == m).all() for i, m in enumerate(masks))


# -- segmentation -------------------------------------------------------------------------------------
def _ious(truth_masks, dets):
    return np.array([[(g & d.mask).sum() / max((g | d.mask).sum(), 1) for d in dets] for g in truth_masks])


def test_classical_detector_separates_touching_objects_by_colour():
    """A bowl overlapping a plate and a knife touching it come out as three instances."""
    scene = Scene(
        [
            obj("plate", (0.0, 0.0, 0.0), "p"),
            obj("bowl", (0.15, 0.0, 0.0), "b"),
            obj("knife", (0.0, -0.131, 0.0), "k"),
        ],
        BOUNDS,
    )
    image, masks = render_scene(scene)
    dets = ClassicalDetector().detect(image)
    assert len(dets) == 3
    iou = _ious(masks, dets)
    assert (iou.max(axis=1) > 0.97).all()


def test_classical_detector_splits_touching_disks_of_one_colour():
    scene = Scene([obj("plate", (-0.12, 0.0, 0.0), "p"), obj("plate", (0.1195, 0.0, 0.0), "q")], BOUNDS)
    image, masks = render_scene(scene)
    dets = ClassicalDetector().detect(image)
    assert len(dets) == 2
    assert (_ious(masks, dets).max(axis=1) > 0.97).all()
    assert len(ClassicalDetector(split_touching=False).detect(image)) == 1  # the split is what did it


@pytest.mark.parametrize("cat", sorted(DEFAULT_LOOKS))
def test_every_sprite_is_one_instance(cat):
    det = ClassicalDetector()
    for theta in np.linspace(-3.0, 3.0, 5):
        image, mask, _ = render_object(obj(cat), theta=theta)
        (d,) = det.detect(image)
        assert (d.mask == mask).mean() > 0.999


def test_detector_protocol_and_validation():
    class Bad:
        def detect(self, image):
            return [np.zeros((3, 3), bool)]

    image, masks = render_scene(Scene([obj("bowl", (0.0, 0.0, 0.0))], BOUNDS))
    with pytest.raises(SceneError, match="shape"):
        scene_from_image(image, 500, BOUNDS, detector=Bad())
    s = scene_from_image(image, 500, BOUNDS, detector=GroundTruthDetector(masks))
    assert len(s.objects) == 1
    labelled = scene_from_image(
        image,
        500,
        BOUNDS,
        detector=type(
            "D", (), {"detect": lambda self, im: [Detection(masks[0], category="bowl", score=0.9)]}
        )(),
    )
    assert labelled.objects[0].category == "bowl"


# -- pose from moments ---------------------------------------------------------------------------------
@pytest.mark.parametrize("cat", ["fork", "knife", "spoon", "pen", "mug", "television"])
def test_moment_pose_directional_objects(cat):
    rng = np.random.default_rng(1)
    for theta in rng.uniform(-math.pi, math.pi, 6):
        x, y = rng.uniform(-0.02, 0.02, 2)
        o = obj(cat, (x, y, theta))
        bounds = ((-0.5, -0.5), (0.5, 0.5))
        _, (m,) = render_scene(Scene([o], bounds))
        p = pose_from_mask(m, 500, bounds)
        assert p.symmetry == 1
        assert math.hypot(p.x - x, p.y - y) < 0.002
        assert math.degrees(angle_error(p.theta, theta)) < 1.5  # the direction is resolved, not mod 180
        length, w = o.size
        assert abs(p.length - length) < 0.004 and abs(p.width - w) < 0.004


def test_moment_pose_symmetric_objects():
    for cat in ("plate", "bowl"):
        _, m, b = render_object(obj(cat), theta=1.234)
        p = pose_from_mask(m, 500, b)
        assert p.symmetric and p.theta == 0.0
        assert p.length == pytest.approx(DEFAULT_LOOKS[cat][0][0], abs=0.002)
    _, m, b = render_object(obj("book"), theta=2.5)
    p = pose_from_mask(m, 500, b)
    assert p.symmetry == 2 and -math.pi / 2 <= p.theta < math.pi / 2
    assert math.degrees(angle_error(p.theta, 2.5, 2)) < 1.0
    assert angle_error(0.1, 0.1 + math.pi, 2) == pytest.approx(0.0, abs=1e-12)
    assert angle_error(0.1, 0.1 + math.pi, 1) == pytest.approx(math.pi)


# -- rectify, crop and encode --------------------------------------------------------------------------
def test_rectified_crop_is_canonical():
    _, m0, b = render_object(obj("fork"), theta=0.0)
    image, m, b = render_object(obj("fork"), theta=2.2)
    crop = rectify_crop(image, m, pose_from_mask(m, 500, b), 500, b)
    h, w = crop.mask.shape
    assert w > h  # length along the crop's x
    cols = np.nonzero(crop.mask)[1]
    assert np.median(cols) > (w - 1) / 2  # the heavier (tines) half on the right
    assert crop.size == pytest.approx((0.19, 0.03), abs=0.003)


def test_image_encoder_is_rotation_invariant():
    enc = ImageEncoder()
    for cat in ("knife", "mug", "book"):
        vecs = []
        for theta in np.linspace(0, 2 * math.pi, 12, endpoint=False):
            image, m, b = render_object(obj(cat), theta=theta)
            vecs.append(enc.encode_crop(rectify_crop(image, m, pose_from_mask(m, 500, b), 500, b)))
        v = np.array(vecs)
        spread = np.linalg.norm(v - v.mean(axis=0), axis=1).max()
        assert spread < 0.4, (cat, spread)
        assert np.abs(v - v.mean(axis=0)).max() < 0.15
    # the tolerance is small against the distance between categories
    assert np.linalg.norm(enc.encode(obj("knife")) - enc.encode(obj("fork"))) > 1.0


def test_image_encoder_separates_categories_nearest_centroid():
    """Held-out crops (random angle, size +-10 %, colour +-12 levels) go to their category's centroid."""
    rng = np.random.default_rng(0)
    enc = ImageEncoder()
    cats = sorted(DEFAULT_LOOKS)

    def sample(cat):
        (ln, w), col = DEFAULT_LOOKS[cat]
        s = rng.uniform(0.9, 1.1)
        color = tuple(int(np.clip(c + rng.integers(-12, 13), 0, 255)) for c in col)
        o = obj(cat, size=(ln * s, w * s if cat not in ("plate", "bowl") else ln * s), color=color)
        image, m, b = render_object(o, theta=rng.uniform(-math.pi, math.pi))
        return enc.encode_crop(rectify_crop(image, m, pose_from_mask(m, 500, b), 500, b))

    train = {c: np.mean([sample(c) for _ in range(4)], axis=0) for c in cats}
    centroids = np.stack([train[c] for c in cats])
    correct = total = 0
    for i, c in enumerate(cats):
        for _ in range(5):
            v = sample(c)
            correct += int(np.argmin(np.linalg.norm(centroids - v, axis=1)) == i)
            total += 1
    assert correct / total >= 0.95, f"{correct}/{total}"


def test_image_encoder_registered_and_encodes_objects_and_crop_files(tmp_path):
    enc = make_encoder("image", {"ppm": 500})
    assert enc.dim == 29 and enc.config() == {"ppm": 500.0}
    o = obj("spoon")
    v = enc.encode(o)
    assert v.shape == (29,) and np.isfinite(v).all()
    # a crop file (RGBA: alpha is the mask) of the same object, rotated: nearly the same vector
    import cv2

    image, m, _ = render_object(o, theta=0.7)
    rgba = np.dstack([image, (m * 255).astype(np.uint8)])
    cv2.imwrite(str(tmp_path / "spoon.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    o2 = SceneObject("s", "spoon", o.size, None, o.color, image=str(tmp_path / "spoon.png"))
    assert np.linalg.norm(enc.encode(o2) - v) < 0.4


# -- image -> graph ------------------------------------------------------------------------------------
def test_scene_from_image(dining):
    scene = dining[1]
    image, _ = render_scene(scene)
    est = scene_from_image(image, 500, scene.bounds)
    assert [o.name for o in est.objects] == [f"obj_{i}" for i in range(8)]
    assert all(o.category == "unknown" and len(o.features) == 29 for o in est.objects)
    assert len(est.meta["symmetric"]) == 4  # plates and bowls
    disks = [o for o in est.objects if o.name in est.meta["symmetric"]]
    assert all(o.shape == "disk" and o.pose[2] == 0.0 for o in disks)
    Scene.from_dict(json.loads(est.to_json()))  # valid scene JSON
    with pytest.raises(SceneError, match="does not cover"):
        scene_from_image(image, 400, scene.bounds)


def test_graphs_from_renders_accuracy(dining):
    graphs = graphs_from_renders(dining[:4])
    pos, ori = [], []
    for truth, g in zip(dining, graphs):
        assert g.names == truth.names and [o.category for o in g.objects] == [
            o.category for o in truth.objects
        ]
        v = g.meta["vision"]
        assert v["missed"] == [] and v["false_positives"] == 0
        for o in g.objects:
            e = v["errors"][o.name]
            pos.append(e["position_cm"])
            if e["orientation_deg"] is not None:
                ori.append(e["orientation_deg"])
        assert set(g.meta["symmetric"]) == {o.name for o in truth.objects if o.category in ("plate", "bowl")}
        assert not np.allclose(g.poses(), truth.poses())  # estimated, not copied
    assert np.median(pos) < 0.3 and max(pos) < 1.0
    assert np.median(ori) < 2.0 and len(ori) == 16


def test_graphs_from_renders_reports_missed_objects():
    truth = Scene([obj("plate", (0.0, 0.0, 0.0), "p"), obj("fork", (0.2, 0.0, 0.0), "f")], BOUNDS)
    (g,) = graphs_from_renders(
        [truth],
        detector=type("OnlyFirst", (), {"detect": lambda self, im: ClassicalDetector().detect(im)[:1]})(),
    )
    assert len(g.meta["vision"]["missed"]) == 1
    missed = g[g.meta["vision"]["missed"][0]]
    assert missed.pose == truth[missed.name].pose  # keeps its true pose, as documented
    assert len(missed.features) == 29


def test_scenes_from_image_folder(tmp_path, dining):
    write_rendered_dataset(dining[:2], tmp_path, ppm=500)
    scenes = scenes_from_image_folder(tmp_path)
    assert len(scenes) == 2 and len(scenes[0].objects) == 8
    assert scenes[1].meta["image"] == "scene_00001.png"
    # a bare PNG folder needs the ppm
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "a.png").write_bytes((tmp_path / "scene_00000.png").read_bytes())
    with pytest.raises(SceneError, match="ppm"):
        scenes_from_image_folder(bare)
    (s,) = scenes_from_image_folder(bare, ppm=500)
    assert len(s.objects) == 8 and s.bounds == ((-0.6, -0.6), (0.6, 0.6))
