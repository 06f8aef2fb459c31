"""The vision pipeline: top-down images of scenes and scene graphs from images.

render (sprites, ground-truth masks) -> segment (a :class:`Detector`) -> pose from image moments ->
rectify and crop -> encode (the built-in ``"image"`` encoder, or CLIP) + scale descriptor -> Scene.
This package's face holds the imaging primitives; the last step, which encodes crops and so sits above
the encoders, is :mod:`scenescore.vision.graph` (``scene_from_image``, ``graphs_from_renders``,
``scenes_from_image_folder``), imported from there. See ``docs/vision.md``.
"""

from __future__ import annotations

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
]
