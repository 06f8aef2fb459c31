"""The ``"clip"`` encoder (optional extra): CLIP image embeddings of an object's rectified crop."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..scene.scene import SceneError, SceneObject
from ..vision.crop import Crop
from ..vision.render import DEFAULT_PPM
from .image import object_crop_for

__all__ = ["ClipEncoder", "import_open_clip", "CLIP_WEIGHTS_ENV"]

CLIP_WEIGHTS_ENV = "SCENESCORE_CLIP_WEIGHTS"
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
        return self.encode_crop(object_crop_for(obj, self.ppm))

    def encode_crop(self, crop: Crop) -> np.ndarray:
        from PIL import Image

        sq = crop.square()
        x = self.preprocess(Image.fromarray(sq)).unsqueeze(0).to(self.device)
        with self._torch.no_grad():
            f = self.model.encode_image(x)[0].float()
        f = f / f.norm().clamp_min(1e-12)
        return f.cpu().numpy().astype(np.float32)
