"""Encoders of rectified crops: the built-in ``"image"`` encoder and CLIP (``"clip"``, optional).

Both turn a rectified :class:`~scenescore.vision.crop.Crop` into a vector (``encode_crop``) and, as
:class:`~scenescore.encoders.Encoder` s, any :class:`~scenescore.scene.SceneObject` (``encode``): the
crop file named by its ``image`` field, or else its sprite rendered alone, rectified and cropped by
the same pipeline as an object detected in a scene image.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..encoders import register_encoder
from ..scene import SceneError, SceneObject
from .crop import CROP_FILL, Crop, crop_from_file, object_crop
from .render import DEFAULT_PPM

__all__ = ["ImageEncoder", "ClipEncoder", "import_open_clip", "CLIP_WEIGHTS_ENV"]

CLIP_WEIGHTS_ENV = "SCENESCORE_CLIP_WEIGHTS"


def _object_crop(obj: SceneObject, ppm: float) -> Crop:
    if obj.image is not None:
        return crop_from_file(obj.image, ppm)
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
        self.ppm = float(ppm)

    def config(self) -> dict[str, Any]:
        return {"ppm": self.ppm}

    def encode(self, obj: SceneObject) -> np.ndarray:
        return self.encode_crop(_object_crop(obj, self.ppm))

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


# -- CLIP (optional: the ``clip`` extra) ----------------------------------------------------------------
_TV_SHIM: Any = None


def import_open_clip():
    """Import ``open_clip``; a clear error when the ``clip`` extra is not installed.

    The torchvision wheels on PyPI are CUDA builds: with a CPU torch their compiled ops cannot load, and
    torchvision (0.28) then fails on import registering fake kernels for ``torchvision::nms``. CLIP uses
    none of those ops, so when that happens the two op schemas are declared (with no kernels: calling
    them still fails) and the import is retried; the transforms are pure Python and work.
    """
    global _TV_SHIM
    try:
        import open_clip
    except ImportError as e:
        raise SceneError(
            "the CLIP encoder needs open_clip: install the 'clip' extra (see .ci/install_clip.sh for a CPU "
            f"torch: pip install open-clip-torch torchvision matching your torch) ({e})"
        ) from None
    except RuntimeError as e:
        if "torchvision::" not in str(e):
            raise
        import torch

        for k in [k for k in sys.modules if k.split(".")[0] in ("torchvision", "open_clip", "timm")]:
            del sys.modules[k]
        if _TV_SHIM is None:
            _TV_SHIM = torch.library.Library("torchvision", "FRAGMENT")
            for op in ("nms", "qnms"):
                if not hasattr(torch.ops.torchvision, op):
                    _TV_SHIM.define(f"{op}(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")
        import open_clip
    return open_clip


class ClipEncoder:
    """CLIP image embeddings of the rectified crop (open_clip), L2-normalised.

    ``weights``: a local checkpoint file (what open_clip saves, ``.pt``/``.bin``/``.safetensors``), or an
    open_clip pretrained tag (``"openai"``, ``"laion2b_s34b_b79k"``, ...) that is already in the open_clip
    cache (``cache_dir``); nothing is downloaded. When unset, the environment variable
    ``SCENESCORE_CLIP_WEIGHTS`` is read. ``model_config``: a JSON model config for a ``model_name``
    open_clip does not know (it is registered under the file's stem). Crops are padded to a square of
    white before open_clip's own preprocessing.
    """

    name = "clip"

    def __init__(
        self,
        model_name: str = "ViT-B-32",
        weights: str | None = None,
        model_config: str | None = None,
        cache_dir: str | None = None,
        device: str = "cpu",
        ppm: float = DEFAULT_PPM,
    ):
        weights = weights or os.environ.get(CLIP_WEIGHTS_ENV) or None
        if weights is None:
            raise SceneError(
                f"ClipEncoder: no CLIP weights for {model_name!r}. Set the encoder option 'weights' to a local "
                f"checkpoint file (or an open_clip pretrained tag already in the open_clip cache), or set the "
                f"environment variable {CLIP_WEIGHTS_ENV}; weights cannot be downloaded on these machines"
            )
        open_clip = import_open_clip()
        import torch

        if model_config is not None:
            if not Path(model_config).is_file():
                raise SceneError(f"ClipEncoder: model_config {model_config!r}: no such file")
            open_clip.add_model_config(model_config)
        if model_name not in open_clip.list_models():
            raise SceneError(
                f"ClipEncoder: unknown model_name {model_name!r} (set 'model_config' to its JSON config); "
                f"open_clip knows e.g. {open_clip.list_models()[:8]}"
            )
        is_file = Path(weights).is_file()
        if not is_file and (
            os.sep in weights or Path(weights).suffix in (".pt", ".bin", ".safetensors", ".pth")
        ):
            raise SceneError(f"ClipEncoder: weights {weights!r}: no such file (set the option 'weights')")
        old = os.environ.get("HF_HUB_OFFLINE")
        os.environ["HF_HUB_OFFLINE"] = "1"
        try:
            model, _, preprocess = open_clip.create_model_and_transforms(
                model_name, pretrained=str(weights), device=device, cache_dir=cache_dir
            )
        except Exception as e:  # noqa: BLE001 - open_clip raises many kinds for missing weights
            raise SceneError(
                f"ClipEncoder: could not load weights {weights!r} for {model_name!r}: {type(e).__name__}: {e}. "
                f"Set the option 'weights' (or {CLIP_WEIGHTS_ENV}) to a local checkpoint file"
            ) from None
        finally:
            if old is None:
                os.environ.pop("HF_HUB_OFFLINE", None)
            else:
                os.environ["HF_HUB_OFFLINE"] = old
        model.eval()
        self._torch = torch
        self.model, self.preprocess, self.device = model, preprocess, device
        self.model_name, self.weights, self.model_config, self.cache_dir = (
            model_name,
            str(weights),
            model_config,
            cache_dir,
        )
        self.ppm = float(ppm)
        with torch.no_grad():
            size = preprocess.transforms[0].size if hasattr(preprocess, "transforms") else 224
            size = size if isinstance(size, int) else size[0]
            self.dim = int(model.encode_image(torch.zeros(1, 3, size, size, device=device)).shape[-1])

    def config(self) -> dict[str, Any]:
        return {
            "model_name": self.model_name,
            "weights": self.weights,
            "model_config": self.model_config,
            "cache_dir": self.cache_dir,
            "ppm": self.ppm,
        }

    def encode(self, obj: SceneObject) -> np.ndarray:
        return self.encode_crop(_object_crop(obj, self.ppm))

    def encode_crop(self, crop: Crop) -> np.ndarray:
        from PIL import Image

        h, w = crop.rgb.shape[:2]
        side = max(h, w)
        sq = np.empty((side, side, 3), np.uint8)
        sq[:] = np.asarray(CROP_FILL, np.uint8)
        r0, c0 = (side - h) // 2, (side - w) // 2
        sq[r0 : r0 + h, c0 : c0 + w] = crop.rgb
        x = self.preprocess(Image.fromarray(sq)).unsqueeze(0).to(self.device)
        with self._torch.no_grad():
            f = self.model.encode_image(x)[0].float()
        f = f / f.norm().clamp_min(1e-12)
        return f.cpu().numpy().astype(np.float32)


register_encoder("image", ImageEncoder)
register_encoder("clip", ClipEncoder)
