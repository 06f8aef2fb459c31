"""Semantic encoders: object -> pose-invariant vector.

An :class:`Encoder` turns one :class:`~scenescore.scene.SceneObject` into a fixed-length vector. The
energy model passes that vector through a trained 2-layer MLP and appends the scale descriptor
(the footprint's length and width). Encoders are registered by name so that a checkpoint can
rebuild the one it was trained with (:func:`make_encoder`).
"""

from __future__ import annotations

import colorsys
import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .scene import Scene, SceneError, SceneObject

__all__ = [
    "Encoder",
    "FootprintEncoder",
    "register_encoder",
    "make_encoder",
    "available_encoders",
    "encode_scene",
]


@runtime_checkable
class Encoder(Protocol):
    """Object -> vector of length ``dim``, independent of the object's pose."""

    name: str
    dim: int

    def encode(self, obj: SceneObject) -> np.ndarray: ...

    def config(self) -> dict[str, Any]: ...


class FootprintEncoder:
    """What a top-down image shows of an object, read from its footprint: shape, size and colour.

    Works for any category, seen or not: two objects that look alike get nearby vectors.
    Layout: shape one-hot (box, disk, polygon) | log length, log width, aspect, area |
    colour RGB | hue (cos, sin) weighted by saturation.
    """

    name = "footprint"
    dim = 12

    def encode(self, obj: SceneObject) -> np.ndarray:
        length, width = obj.size
        kind = obj.shape_kind
        onehot = [kind == "box", kind == "disk", kind == "polygon"]
        if kind == "polygon":
            pts = obj.polygon()
            x, y = pts[:, 0], pts[:, 1]
            area = 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))
        elif kind == "disk":
            area = math.pi * length * width / 4
        else:
            area = length * width
        r, g, b = (c / 255.0 for c in obj.color)
        h, s, v = colorsys.rgb_to_hsv(r, g, b)
        vec = [
            *map(float, onehot),
            math.log(length / 0.1),
            math.log(width / 0.1),
            min(length, width) / max(length, width),
            area / 0.01,
            r,
            g,
            b,
            s * math.cos(2 * math.pi * h),
            s * math.sin(2 * math.pi * h),
        ]
        return np.asarray(vec, dtype=np.float32)

    def config(self) -> dict[str, Any]:
        return {}


_REGISTRY: dict[str, Callable[..., Encoder]] = {"footprint": FootprintEncoder}


def register_encoder(name: str, factory: Callable[..., Encoder]) -> None:
    """Make an encoder constructible by name (checkpoints store the name and ``config()``)."""
    _REGISTRY[name] = factory


def available_encoders() -> list[str]:
    _load_optional()
    return sorted(_REGISTRY)


def _load_optional() -> None:
    """Import modules that register further encoders (the vision pipeline), if present."""
    try:
        import scenescore.vision.encoders  # noqa: F401
    except ImportError:
        pass


def make_encoder(name: str, config: dict[str, Any] | None = None) -> Encoder:
    """Build a registered encoder; an unknown name lists the valid ones."""
    if name not in _REGISTRY:
        _load_optional()
    if name not in _REGISTRY:
        raise SceneError(f"unknown encoder {name!r}; available: {sorted(_REGISTRY)}")
    return _REGISTRY[name](**(config or {}))


def encode_scene(scene: Scene, encoder: Encoder, names: Sequence[str] | None = None) -> np.ndarray:
    """Vectors for every object, ``(N, dim)``; an object's own ``features`` win over the encoder."""
    objs = scene.objects if names is None else [scene[n] for n in names]
    out = np.zeros((len(objs), encoder.dim), dtype=np.float32)
    for i, o in enumerate(objs):
        if o.features is not None:
            if len(o.features) != encoder.dim:
                raise SceneError(
                    f"object {o.name!r}: field 'features' has {len(o.features)} numbers; "
                    f"the encoder {encoder.name!r} makes vectors of {encoder.dim}"
                )
            out[i] = np.asarray(o.features, dtype=np.float32)
        else:
            out[i] = encoder.encode(o)
    return out
