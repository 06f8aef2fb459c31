"""The built-in ``"image"`` encoder: pose-invariant descriptors of an object's rectified crop.

Both turn a rectified :class:`~scenescore.vision.crop.Crop` into a vector (``encode_crop``) and, as
:class:`~scenescore.encoders.Encoder` s, any :class:`~scenescore.scene.scene.SceneObject` (``encode``): the
crop file named by its ``image`` field, or else its sprite rendered alone, rectified and cropped by
the same pipeline as an object detected in a scene image.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..scene.scene import SceneError, SceneObject
from ..vision.crop import Crop, crop_from_file, object_crop
from ..vision.render import DEFAULT_PPM

__all__ = ["ImageEncoder", "object_crop_for"]


def object_crop_for(obj: SceneObject, ppm: float) -> Crop:
    """The crop an encoder sees: the object's ``image`` file, or its sprite rendered alone and cropped."""
    if obj.image is not None:
        if not Path(obj.image).is_file():
            raise SceneError(f"object {obj.name!r}: field 'image': {obj.image}: no such image file")
        try:
            return crop_from_file(obj.image, ppm)
        except SceneError as e:
            raise SceneError(f"object {obj.name!r}: field 'image': {e}") from None
    return object_crop(obj, ppm)


def _profile(counts: np.ndarray, bins: int) -> np.ndarray:
    """Resample a 1-D profile to ``bins`` means."""
    edges = np.linspace(0, counts.size, bins + 1)
    out = np.empty(bins)
    for i in range(bins):
        a, b = int(math.floor(edges[i])), max(int(math.ceil(edges[i + 1])), int(math.floor(edges[i])) + 1)
        out[i] = counts[a:b].mean()
    return out


class ImageEncoder:
    """Pose-invariant shape and colour descriptors of the rectified crop; offline, no weights.

    Layout (29 numbers): size (log l, log w, w/l, log area) | fill of the box, solidity | width profile
    along ``+x`` (8 bins) | length profile along ``+y`` (4 bins) | mean colour (L, a, b), lightness
    spread | lightness profile along ``+x`` (4 bins, relative to the mean) and from the centre out
    (centre minus rim) | Hu's first moment (log, relative to a disk's) and eccentricity
    (sqrt(h2) / h1). Profiles of an object whose direction is ambiguous
    (two-fold, four-fold or round) are symmetrised, so that the arbitrary choice does not show.
    """

    name = "image"
    dim = 29

    def __init__(self, ppm: float = DEFAULT_PPM):
        if isinstance(ppm, bool) or not isinstance(ppm, (int, float)) or not (math.isfinite(ppm) and ppm > 0):
            raise SceneError(f"ImageEncoder: ppm: expected pixels per metre, a number > 0, got {ppm!r}")
        self.ppm = float(ppm)

    def config(self) -> dict[str, Any]:
        return {"ppm": self.ppm}

    def encode(self, obj: SceneObject) -> np.ndarray:
        return self.encode_crop(object_crop_for(obj, self.ppm))

    def encode_crop(self, crop: Crop) -> np.ndarray:
        mask = crop.mask
        if mask.sum() < 3:
            raise SceneError("ImageEncoder: the crop's mask is empty")
        rows = np.nonzero(mask.any(axis=1))[0]
        cols = np.nonzero(mask.any(axis=0))[0]
        m = mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        rgb = crop.rgb[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        ln, w = crop.size
        area = float(mask.sum()) / crop.ppm**2
        size = [math.log(ln / 0.1), math.log(w / 0.1), min(w, ln) / max(w, ln), 0.5 * math.log(area / 0.01)]
        pts = cv2.findNonZero(m.astype(np.uint8))
        hull = cv2.contourArea(cv2.convexHull(pts)) if pts is not None else 0.0
        npx = float(m.sum())
        fill = [npx / m.size, min(npx / max(hull, 1.0), 1.0)]
        a = (
            m.astype(np.float32)
            if crop.alpha is None
            else crop.alpha[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        )
        wprof = _profile(a.sum(axis=0) / a.shape[0], 8)
        # rows run downwards, +y is up: reverse so that the profile runs along +y
        lprof = _profile(a.sum(axis=1)[::-1] / a.shape[1], 4)
        lab = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)
        px = lab[m]
        mean = px.mean(axis=0)
        color = [mean[0] / 50.0, mean[1] / 25.0, mean[2] / 25.0, px[:, 0].std() / 10.0]
        lum = np.where(m, lab[..., 0], np.nan)
        with np.errstate(invalid="ignore"):
            colmean = np.nanmean(lum, axis=0)
        colmean = np.where(np.isnan(colmean), mean[0], colmean)
        lumprof = (_profile(colmean, 4) - mean[0]) / 10.0
        yy, xx = np.nonzero(m)
        cy, cx = (m.shape[0] - 1) / 2, (m.shape[1] - 1) / 2
        rr = np.hypot((yy - cy) / max(m.shape[0], 1), (xx - cx) / max(m.shape[1], 1))
        inner = rr < 0.25
        radial = [
            (lab[m][inner, 0].mean() - lab[m][~inner, 0].mean()) / 10.0
            if inner.any() and (~inner).any()
            else 0.0
        ]
        h1, h2 = cv2.HuMoments(cv2.moments(a)).ravel()[:2]
        hu = [math.log(max(h1, 1e-9) / (0.5 / math.pi)), math.sqrt(max(h2, 0.0)) / max(h1, 1e-9)]
        if crop.symmetry != 1:
            wprof, lprof, lumprof = ((p + p[::-1]) / 2 for p in (wprof, lprof, lumprof))
        vec = np.concatenate([size, fill, 2 * wprof, lprof, color, lumprof, radial, hu])
        return vec.astype(np.float32)
