"""The default encoder: what a top-down image shows of an object, read from its footprint."""

from __future__ import annotations

import colorsys
import math
from typing import Any

import numpy as np

from ..scene.scene import SceneObject

__all__ = ["FootprintEncoder"]


class FootprintEncoder:
    """What a top-down image shows of an object, read from its footprint: shape, size and colour.

    Works for any category, seen or not: two objects that look alike get nearby vectors. Sizes are
    read in units of ``length_scale`` (training sets it to the data's), so scaling a dataset leaves
    its vectors unchanged.
    Layout: shape one-hot (box, disk, polygon) | log length, log width, aspect, area |
    colour RGB | hue (cos, sin) weighted by saturation.
    """

    name = "footprint"
    dim = 12
    reads_images = False  # an object's ``image`` is not read (encode_scene warns that it is unused)

    def __init__(self, length_scale: float | None = None):
        if length_scale is not None and not (isinstance(length_scale, (int, float)) and length_scale > 0):
            raise ValueError(
                f"FootprintEncoder: length_scale: expected a length > 0 in metres, got {length_scale!r}"
            )
        self.length_scale = None if length_scale is None else float(length_scale)

    @property
    def unit(self) -> float:
        """Sizes are read in this unit (metres): the data's length scale, or 0.1 m when none was set."""
        return 0.1 if self.length_scale is None else self.length_scale

    def scaled(self, length_scale: float) -> FootprintEncoder:
        """This encoder reading sizes in units of ``length_scale`` (training sets the data's), unless set."""
        return self if self.length_scale is not None else FootprintEncoder(length_scale)

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
            math.log(length / self.unit),
            math.log(width / self.unit),
            min(length, width) / max(length, width),
            area / self.unit**2,
            r,
            g,
            b,
            s * math.cos(2 * math.pi * h),
            s * math.sin(2 * math.pi * h),
        ]
        return np.asarray(vec, dtype=np.float32)

    def config(self) -> dict[str, Any]:
        return {} if self.length_scale is None else {"length_scale": self.length_scale}
