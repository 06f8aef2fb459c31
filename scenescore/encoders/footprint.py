"""The default encoder: what a top-down image shows of an object, read from its footprint."""

from __future__ import annotations

import colorsys
import math
from typing import Any

import numpy as np

from ..scene import SceneObject

__all__ = ["FootprintEncoder"]


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
