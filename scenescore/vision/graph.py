"""Images to scene graphs: detect, pose from moments, rectify and crop, encode, scale descriptor.

:func:`scene_from_image` is the pipeline on one image; :func:`graphs_from_renders` runs it on rendered
ground-truth scenes and matches its detections back to the true objects (to train and test on image-
derived graphs and measure every stage); :func:`scenes_from_image_folder` reads a folder of images (as
:func:`~scenescore.vision.render.write_rendered_dataset` writes, or any top-down PNGs at a known ppm).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..encoders import Encoder
from ..scene.scene import Bounds, Scene, SceneError, SceneObject
from .crop import rectify_crop
from .pose import MomentPose, angle_error, pose_from_mask
from .render import DEFAULT_PPM, MASK_PREVIEW, image_shape, read_image, render_object, render_scene
from .segment import ClassicalDetector, Detector, as_detections

__all__ = [
    "scene_from_image",
    "scene_and_poses_from_image",
    "graphs_from_renders",
    "scenes_from_image_folder",
    "gt_symmetry",
    "match_objects",
]


def _encode(encoder: Encoder, crop, obj: SceneObject) -> np.ndarray:
    if hasattr(encoder, "encode_crop"):
        return np.asarray(encoder.encode_crop(crop), dtype=np.float32)
    return np.asarray(
        encoder.encode(obj), dtype=np.float32
    )  # e.g. the footprint encoder: size, shape, colour


def _check_ppm(ppm: Any, what: str) -> None:
    if isinstance(ppm, bool) or not isinstance(ppm, (int, float)) or not (math.isfinite(ppm) and ppm > 0):
        raise SceneError(f"{what}: expected pixels per metre, a number > 0, got {ppm!r}")


def scene_from_image(
    image: np.ndarray | str | os.PathLike,
    ppm: float = DEFAULT_PPM,
    bounds: Bounds | None = None,
    encoder: Encoder | None = None,
    detector: Detector | None = None,
    min_area: float = 2e-5,
) -> Scene:
    """One top-down image (``HxWx3`` uint8 RGB, or a path) -> a :class:`Scene` of what it shows.

    ``bounds``: the world rectangle the image covers (default: centred on the origin, from its size and
    ``ppm``). Objects are named ``obj_0, obj_1, ...`` in the detector's order, with category
    ``"unknown"`` (or the detector's label), ``pose`` from the moments, ``size`` the scale descriptor,
    ``color`` the median colour of the mask, ``shape`` ``"disk"`` for a round mask and ``"box"``
    otherwise, and ``features`` the encoder's vector of the rectified crop (``encoder`` default: the
    built-in ``"image"`` encoder at this ppm). ``scene.meta`` holds ``symmetric`` (the names of the
    round objects, whose angle is the canonical 0), ``symmetry`` (name -> 0 round, 1 directional, 2 or 4
    n-fold: the angle is canonical modulo 360/n degrees), ``ppm`` and ``encoder``. Detections smaller than
    ``min_area`` square metres are dropped. :func:`scene_and_poses_from_image` also returns the
    :class:`MomentPose` of each object.
    """
    return scene_and_poses_from_image(image, ppm, bounds, encoder, detector, min_area)[0]


def scene_and_poses_from_image(
    image: np.ndarray | str | os.PathLike,
    ppm: float = DEFAULT_PPM,
    bounds: Bounds | None = None,
    encoder: Encoder | None = None,
    detector: Detector | None = None,
    min_area: float = 2e-5,
) -> tuple[Scene, list[MomentPose]]:
    """As :func:`scene_from_image`, with the :class:`MomentPose` of each object (symmetry, centroid, ...)."""
    _check_ppm(ppm, "scene_from_image: ppm")
    if not isinstance(image, np.ndarray):
        image = read_image(image)
    h, w = image.shape[:2]
    if bounds is None:
        hw, hh = w / ppm / 2, h / ppm / 2
        bounds = ((-hw, -hh), (hw, hh))
    if image_shape(bounds, ppm) != (h, w):
        raise SceneError(
            f"scene_from_image: an image of {w}x{h} px does not cover bounds {bounds} at {ppm} px/m "
            f"(that would be {image_shape(bounds, ppm)[::-1]})"
        )
    if encoder is None:
        from ..encoders.image import ImageEncoder

        encoder = ImageEncoder(ppm=ppm)
    detector = detector or ClassicalDetector()
    dets = as_detections(detector.detect(image), (h, w))
    objects: list[SceneObject]
    objects, symmetry, details = [], {}, []
    for det in dets:
        if det.mask.sum() / ppm**2 < min_area or det.mask.sum() < 3:
            continue
        pose = pose_from_mask(det.mask, ppm, bounds)
        crop = rectify_crop(image, det.mask, pose, ppm, bounds)
        name = f"obj_{len(objects)}"
        color = cast(tuple[int, int, int], tuple(int(v) for v in np.median(image[det.mask], axis=0)))
        obj = SceneObject(
            name=name,
            category=det.category or "unknown",
            size=pose.size,
            pose=pose.pose,
            color=color,
            shape="disk" if pose.symmetric else "box",
        )
        obj.features = [float(v) for v in _encode(encoder, crop, obj)]
        objects.append(obj)
        symmetry[name] = pose.symmetry
        details.append(pose)
    meta: dict[str, Any] = {
        "source": "image",
        "ppm": float(ppm),
        "encoder": {"name": encoder.name, "config": encoder.config()},
        "symmetric": [n for n, s in symmetry.items() if s == 0],
        "symmetry": symmetry,
    }
    return Scene(objects, bounds, meta), details


def gt_symmetry(obj: SceneObject) -> int:
    """The symmetry order a mask of ``obj`` shows (round 0, else as drawn), for scoring orientation."""
    image, mask, bounds = render_object(obj)
    return pose_from_mask(mask, DEFAULT_PPM, bounds).symmetry


def _canonical_gt(obj: SceneObject) -> tuple[float, float]:
    """The true angle and size in the moments' convention (the length is the longer side)."""
    assert obj.pose is not None
    length, width = obj.size
    if length < width:
        return obj.pose[2] + math.pi / 2, width
    return obj.pose[2], length


def match_objects(truth: Scene, estimate: Scene, gate: float = 0.5) -> list[tuple[int, int]]:
    """Hungarian matching on centroid distance: ``[(true index, estimated index)]``; a pair farther apart
    than ``gate`` times the true object's longer side (at least 2 cm) is not a match."""
    t_idx = [i for i, o in enumerate(truth.objects) if o.pose is not None]
    if not t_idx or not estimate.objects:
        return []
    tp = np.array([truth.objects[i].pose[:2] for i in t_idx])  # type: ignore[index]
    ep = np.array([o.pose[:2] for o in estimate.objects])  # type: ignore[index]
    cost = np.linalg.norm(tp[:, None] - ep[None], axis=2)
    r, c = linear_sum_assignment(cost)
    out = []
    for i, j in zip(r, c):
        o = truth.objects[t_idx[i]]
        if cost[i, j] <= max(gate * max(o.size), 0.02):
            out.append((t_idx[i], int(j)))
    return out


def graphs_from_renders(
    scenes: Sequence[Scene],
    ppm: float = DEFAULT_PPM,
    encoder: Encoder | None = None,
    detector: Detector | None = None,
    progress: bool = False,
) -> list[Scene]:
    """Render each ground-truth scene, run :func:`scene_from_image`, match detections to true objects.

    Each returned scene has the true objects in their order, names, categories, colours, shapes and
    ``fixed`` flags, with the *estimated* pose, size (scale descriptor) and features. An object with no
    pose in the truth is not drawn: it keeps ``pose: null`` and its true size, with features from its
    sprite rendered alone. An object the detector missed keeps its true pose
    and size, features from its sprite alone, and is listed in ``meta["vision"]["missed"]``; detections
    matching no true object are counted in ``meta["vision"]["false_positives"]``. ``meta["vision"]`` also
    holds per-object errors (``errors``: name -> ``{"position_cm", "orientation_deg" or None, "symmetry"}``;
    the orientation error is modulo the symmetry the mask shows, None for round objects).
    ``meta["symmetric"]`` lists the objects whose angle is canonical (round).
    """
    if encoder is None:
        from ..encoders.image import ImageEncoder

        encoder = ImageEncoder(ppm=ppm)
    it: Any = scenes
    if progress:
        from tqdm import tqdm

        it = tqdm(scenes, desc="images -> graphs", unit="scene")
    out = []
    for truth in it:
        image, _ = render_scene(truth, ppm)
        est, poses = scene_and_poses_from_image(image, ppm, truth.bounds, encoder, detector)
        pairs = dict(match_objects(truth, est))
        matched_est = set(pairs.values())
        objects, missed, errors, symmetric, symmetry = [], [], {}, [], {}
        for i, t in enumerate(truth.objects):
            o = SceneObject(t.name, t.category, t.size, t.pose, t.color, t.fixed, t.shape, None, t.image)
            if i in pairs:
                e, mp = est.objects[pairs[i]], poses[pairs[i]]
                o.pose, o.size, o.features = e.pose, e.size, e.features
                symmetry[t.name] = mp.symmetry
                if mp.symmetric:
                    symmetric.append(t.name)
                gsym = gt_symmetry(t)
                sym = mp.symmetry if mp.symmetry != 1 else gsym
                gt_theta, _ = _canonical_gt(t)
                errors[t.name] = {
                    "position_cm": float(100 * math.hypot(e.pose[0] - t.pose[0], e.pose[1] - t.pose[1])),  # type: ignore[index]
                    "orientation_deg": None
                    if sym == 0 or gsym == 0
                    else float(math.degrees(angle_error(e.pose[2], gt_theta, max(sym, gsym)))),  # type: ignore[index]
                    "symmetry": int(mp.symmetry),
                }
            else:
                o.features = [float(v) for v in encoder.encode(t)]
                if t.pose is not None:
                    missed.append(t.name)
            objects.append(o)
        scene = Scene(objects, truth.bounds, {**truth.meta})
        scene.meta["symmetric"] = symmetric
        scene.meta["symmetry"] = symmetry
        scene.meta["vision"] = {
            "ppm": float(ppm),
            "encoder": {"name": encoder.name, "config": encoder.config()},
            "detections": len(est.objects),
            "missed": missed,
            "false_positives": len(est.objects) - len(matched_est),
            "errors": errors,
        }
        out.append(scene)
    return out


def scenes_from_image_folder(
    folder: str | os.PathLike,
    encoder: Encoder | None = None,
    ppm: float | None = None,
    bounds: Bounds | None = None,
    detector: Detector | None = None,
    progress: bool = False,
) -> list[Scene]:
    """Scene graphs from every ``*.png`` in ``folder`` (sorted by name; ``*.masks.png`` and their previews skipped).

    The ppm and bounds of an image come from its sidecar JSON (``scene_00000.json`` beside
    ``scene_00000.png``, as :func:`write_rendered_dataset` writes) or ``dataset.json``, else from the
    arguments (``ppm`` is then required; ``bounds`` defaults to the image centred on the origin). The
    ground truth in a sidecar is not used: objects are ``obj_0, obj_1, ...`` as the pipeline finds them.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SceneError(f"{folder}: not a folder of images")
    skip = (".masks.png", MASK_PREVIEW)  # the mask images and their coloured previews
    images = sorted(p for p in folder.glob("*.png") if not p.name.endswith(skip))
    if not images:
        raise SceneError(f"{folder}: no .png images in the folder")
    if ppm is not None:
        _check_ppm(ppm, "ppm")
    index_ppm = None
    index = folder / "dataset.json"
    if index.is_file():
        from ..scene.textfiles import loads_json, read_text

        data = loads_json(read_text(index, SceneError, "dataset index"), str(index), SceneError)
        index_ppm = data.get("ppm") if isinstance(data, dict) else None
        if index_ppm is not None:
            _check_ppm(index_ppm, f"{index}: key 'ppm'")
            if ppm is not None and not math.isclose(float(ppm), float(index_ppm), rel_tol=1e-6):
                raise SceneError(
                    f"ppm {ppm:g} disagrees with {index}, which says the images are at {index_ppm:g} px/m; "
                    "leave ppm out to use the folder's"
                )
    it: Any = images
    if progress:
        from tqdm import tqdm

        it = tqdm(images, desc="images -> graphs", unit="image")
    scenes = []
    for path in it:
        p, b = ppm, bounds
        side = path.with_suffix(".json")
        if side.is_file():
            gt = Scene.from_json(side)
            p = p or gt.meta.get("ppm") or index_ppm
            b = b or gt.bounds
        p = p or index_ppm
        if not p:
            raise SceneError(f"{path}: no ppm for the image: pass ppm (pixels per metre) or add {side.name}")
        _check_ppm(p, f"{side}: key 'meta.ppm'")
        scene = scene_from_image(path, float(p), b, encoder, detector)
        scene.meta["image"] = path.name
        scene.origin = str(path)  # errors about the scene (no objects found, ...) name the image
        scenes.append(scene)
    return scenes
