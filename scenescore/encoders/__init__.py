"""Semantic encoders: object -> pose-invariant vector.

An :class:`Encoder` turns one :class:`~scenescore.scene.scene.SceneObject` into a fixed-length vector. The
energy model passes that vector through a trained 2-layer MLP and appends the scale descriptor
(the footprint's length and width). Encoders are registered by name so that a checkpoint can
rebuild the one it was trained with (:func:`make_encoder`).

Built in: ``footprint`` (the default: shape, size and colour read from the footprint), ``image``
(shape and colour descriptors of the rectified crop, no weights), ``efficientnet`` (ImageNet
EfficientNet-Lite0 features of the crop; the ``pretrained`` extra) and ``clip`` (CLIP embeddings of
the crop; the ``clip`` extra and local weights).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..scene.scene import Scene, SceneError, SceneObject
from .footprint import FootprintEncoder

__all__ = [
    "Encoder",
    "FootprintEncoder",
    "register_encoder",
    "make_encoder",
    "available_encoders",
    "encode_scene",
    "warn_unused_images",
]


@runtime_checkable
class Encoder(Protocol):
    """Object -> vector of length ``dim``, independent of the object's pose. An encoder that never reads
    an object's ``image`` may say so with ``reads_images = False`` (then a named image is warned unused)."""

    name: str
    dim: int

    def encode(self, obj: SceneObject) -> np.ndarray: ...

    def config(self) -> dict[str, Any]: ...


_REGISTRY: dict[str, Callable[..., Encoder]] = {"footprint": FootprintEncoder}
# name -> module, imported on first use
_BUILTIN = {"image": ".image", "clip": ".clip", "efficientnet": ".efficientnet"}


def register_encoder(name: str, factory: Callable[..., Encoder]) -> None:
    """Make an encoder constructible by name (checkpoints store the name and ``config()``)."""
    _REGISTRY[name] = factory


def available_encoders() -> list[str]:
    """Every encoder name: the built-in ones and those registered."""
    return sorted({*_REGISTRY, *_BUILTIN})


def _factory(name: str) -> Callable[..., Encoder] | None:
    """The factory registered under ``name``; built-in encoders are imported on first use."""
    if name not in _REGISTRY and name in _BUILTIN:
        mod = importlib.import_module(_BUILTIN[name], __name__)
        cls = {"image": "ImageEncoder", "clip": "ClipEncoder", "efficientnet": "EfficientNetEncoder"}[name]
        _REGISTRY[name] = getattr(mod, cls)
    return _REGISTRY.get(name)


def make_encoder(name: str, config: dict[str, Any] | None = None) -> Encoder:
    """Build a registered encoder; an unknown name lists the valid ones."""
    factory = _factory(name)
    if factory is None:
        raise SceneError(f"unknown encoder {name!r}; available: {available_encoders()}")
    return factory(**(config or {}))


_warned: set[tuple[str, str]] = set()  # (encoder, file) whose unused images were named in this process


def warn_unused_images(scene: Scene, encoder: Encoder) -> None:
    """Say on stderr that a scene's objects' ``image`` files are not read by ``encoder`` (one that declares
    ``reads_images = False``, such as ``footprint``), naming the objects and the files and whether they
    exist: a crop named in a scene otherwise changes nothing, without a word. Said for the first such
    scene of each file (a dataset of image scenes gives one line, not one per scene) and encoder."""
    named = [o for o in scene.objects if o.image is not None and o.features is None]
    if not named:
        return
    listed = ", ".join(
        f"object {o.name!r} ({o.image}{'' if Path(str(o.image)).is_file() else ': no such file'})"
        for o in named
    )
    msg = (
        f"warning: {scene.label()}: the {encoder.name} encoder reads no images; unused: the image of {listed}"
    )
    source = scene.label()
    head, _, line = source.rpartition(":")
    key = (encoder.name, head if head and line.isdigit() else source)  # file:line -> the file
    if key not in _warned:
        _warned.add(key)
        print(msg, file=sys.stderr)


def encode_scene(scene: Scene, encoder: Encoder, names: Sequence[str] | None = None) -> np.ndarray:
    """Vectors for every object, ``(N, dim)``; an object's own ``features`` win over the encoder."""
    objs = scene.objects if names is None else [scene[n] for n in names]
    if not getattr(encoder, "reads_images", True):
        warn_unused_images(scene, encoder)
    out = np.zeros((len(objs), encoder.dim), dtype=np.float32)
    for i, o in enumerate(objs):
        if o.features is not None:
            if len(o.features) != encoder.dim:
                raise SceneError(
                    f"{scene.label()}: object {o.name!r}: field 'features' has {len(o.features)} numbers; "
                    f"the encoder {encoder.name!r} makes vectors of {encoder.dim}"
                )
            out[i] = np.asarray(o.features, dtype=np.float32)
        else:
            try:
                out[i] = encoder.encode(o)
            except SceneError as e:  # e.g. an image that cannot be read: say which scene
                if scene.origin is None or str(e).startswith(scene.origin):
                    raise
                raise SceneError(f"{scene.origin}: {e}") from None
    return out
