"""The vision pipeline: top-down images of scenes and scene graphs from images.

render (sprites, ground-truth masks) -> segment (a :class:`Detector`) -> pose from image moments ->
rectify and crop -> encode (the built-in ``"image"`` encoder, or CLIP) + scale descriptor -> Scene.
See ``docs/vision.md``.
"""

from __future__ import annotations

import importlib
from typing import Any

from .crop import Crop, object_crop, rectify_crop, scale_descriptor
from .pose import MomentPose, angle_error, pose_from_mask
from .render import (
    DEFAULT_PPM,
    TABLE_COLOR,
    read_image,
    render_object,
    render_scene,
    write_image,
    write_rendered_dataset,
)
from .segment import ClassicalDetector, Detection, Detector, GroundTruthDetector
from .sprites import DEFAULT_LOOKS, SPRITES

__all__ = [
    "DEFAULT_PPM",
    "TABLE_COLOR",
    "DEFAULT_LOOKS",
    "SPRITES",
    "render_scene",
    "render_object",
    "write_rendered_dataset",
    "read_image",
    "write_image",
    "Detection",
    "Detector",
    "ClassicalDetector",
    "GroundTruthDetector",
    "MomentPose",
    "pose_from_mask",
    "angle_error",
    "Crop",
    "rectify_crop",
    "scale_descriptor",
    "object_crop",
    "scene_from_image",
    "graphs_from_renders",
    "scenes_from_image_folder",
    "match_objects",
]

# Scene graphs from images need the encoders, which sit above these imaging primitives (the image
# encoders crop with them): the graph functions are imported on first use, so importing a primitive
# never pulls in the encoders.
_LAZY = {
    "scene_from_image": "graph",
    "graphs_from_renders": "graph",
    "scenes_from_image_folder": "graph",
    "match_objects": "graph",
}
__all__ += list(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
