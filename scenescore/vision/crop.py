"""Rectify and crop: each object rotated to its canonical pose and cut out; its scale descriptor.

In a rectified crop the object's ``+x`` axis points to the right and its ``+y`` axis up, its footprint
centre is the crop's centre, and pixels that are not the object's are ``fill``. The scale descriptor
is the object's extent along ``+x`` and ``+y`` in that pose, in metres (``MomentPose.size``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from ..scene.scene import Bounds, SceneError, SceneObject
from .pose import MomentPose, pose_from_mask
from .render import DEFAULT_PPM, render_object, world_to_pixel

__all__ = ["Crop", "rectify_crop", "scale_descriptor", "object_crop", "crop_from_file", "CROP_FILL"]

CROP_FILL = (255, 255, 255)


@dataclass
class Crop:
    """One object in its canonical pose."""

    rgb: np.ndarray  # h x w x 3 uint8 RGB; pixels off the object are ``fill``
    mask: np.ndarray  # h x w bool
    ppm: float
    size: tuple[float, float]  # the scale descriptor (l, w) in metres
    symmetry: int  # as MomentPose.symmetry
    alpha: np.ndarray | None = None  # h x w float coverage (the mask before thresholding)

    def square(self) -> np.ndarray:
        """The RGB crop centred on a square of :data:`CROP_FILL` as wide as its longer side."""
        h, w = self.rgb.shape[:2]
        side = max(h, w)
        sq = np.empty((side, side, 3), np.uint8)
        sq[:] = np.asarray(CROP_FILL, np.uint8)
        r0, c0 = (side - h) // 2, (side - w) // 2
        sq[r0 : r0 + h, c0 : c0 + w] = self.rgb
        return sq


def rectify_crop(
    image: np.ndarray,
    mask: np.ndarray,
    pose: MomentPose,
    ppm: float,
    bounds: Bounds,
    margin: int = 3,
    fill: Sequence[int] = CROP_FILL,
) -> Crop:
    """Rotate ``image`` about the object's footprint centre so that its ``+x`` axis points right; crop."""
    l_px, w_px = pose.length * ppm, pose.width * ppm
    out_w, out_h = int(math.ceil(l_px)) + 2 * margin, int(math.ceil(w_px)) + 2 * margin
    sc, sr = world_to_pixel(pose.x, pose.y, bounds, ppm)
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    rot = np.array([[c, -s], [s, c]])  # maps the object's +x (cos t, -sin t in pixels) to (1, 0)
    d0 = np.array([(out_w - 1) / 2, (out_h - 1) / 2])
    m = np.concatenate([rot, (d0 - rot @ np.array([float(sc), float(sr)]))[:, None]], axis=1)
    rgb = cv2.warpAffine(image, m, (out_w, out_h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    alpha = cv2.warpAffine(
        mask.astype(np.float32), m, (out_w, out_h), flags=cv2.INTER_LINEAR, borderValue=0.0
    )
    cm = alpha >= 0.5
    rgb[~cm] = np.asarray(fill, np.uint8)
    return Crop(rgb, cm, float(ppm), pose.size, pose.symmetry, alpha)


def scale_descriptor(crop: Crop) -> tuple[float, float]:
    """The object's width and height in its canonical pose, metres: ``(l, w)``."""
    return crop.size


def object_crop(obj: SceneObject, ppm: float = DEFAULT_PPM) -> Crop:
    """The crop of ``obj`` as the pipeline would see it: rendered alone (its sprite), then rectified."""
    image, mask, bounds = render_object(obj, ppm)
    if not mask.any():
        raise SceneError(f"object {obj.name!r}: too small to draw at {ppm} px/m")
    pose = pose_from_mask(mask, ppm, bounds)
    return rectify_crop(image, mask, pose, ppm, bounds)


def crop_from_file(path: str | os.PathLike, ppm: float = DEFAULT_PPM) -> Crop:
    """A crop from an image file of one object: its alpha channel is the mask when it has one; else the
    largest instance the classical detector finds."""
    arr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if arr is None:
        raise SceneError(f"{path}: not a readable image file")
    if arr.ndim == 2:
        arr = cv2.cvtColor(arr, cv2.COLOR_GRAY2BGR)
    if arr.shape[2] == 4:
        mask = arr[..., 3] > 127
        rgb = cv2.cvtColor(arr[..., :3], cv2.COLOR_BGR2RGB)
    else:
        from .segment import ClassicalDetector

        rgb = cv2.cvtColor(arr, cv2.COLOR_BGR2RGB)
        dets = ClassicalDetector().detect(rgb)
        if not dets:
            raise SceneError(f"{path}: found no object in the image")
        mask = max(dets, key=lambda d: int(d.mask.sum())).mask
    if mask.sum() < 3:
        raise SceneError(f"{path}: the object's mask is empty")
    h, w = mask.shape
    bounds: Bounds = ((0.0, 0.0), (w / ppm, h / ppm))
    return rectify_crop(rgb, mask, pose_from_mask(mask, ppm, bounds), ppm, bounds)
