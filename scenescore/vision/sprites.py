"""Top-down sprites: how each known category looks from above, as coloured polygons in its own frame.

A sprite is a list of parts ``(polygon, colour)`` in the object's frame (metres, ``+x`` along its
length ``l``, ``+y`` along its width ``w``), painted in order; a part whose colour is ``None`` cuts a
hole (the table shows through, e.g. between a fork's tines). Every sprite fills its footprint's
bounding box exactly: its extents are ``[-l/2, l/2] x [-w/2, w/2]``, so the box centre is the pose and
the rectified extents are the size.

The direction convention, which the moment-based pose estimate relies on: a directional sprite has
more area on its ``+x`` half (a fork's tines, a knife's blade, a spoon's bowl, a pen's grip and tip
end, a mug's body: its handle points to ``-x``; a pencil's silhouette balances, its eraser as thin
as its tip, so it is two-fold), or, when the two ``x`` halves balance, on its ``+y``
half (a television's screen, with its stand behind at ``-y``). Shades inside a sprite differ from its
base colour by little (``MAX_SHADE_STEP``), so that a colour edge means another object.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..scene.scene import SceneObject

__all__ = ["SPRITES", "DEFAULT_LOOKS", "Part", "sprite_parts", "has_sprite", "shade"]

Color = tuple[int, int, int]
Part = tuple[np.ndarray, Color | None]

# default size (l, w) in metres and colour of each category with a sprite (for tests and examples;
# a scenario's own sizes and colours always win)
DEFAULT_LOOKS: dict[str, tuple[tuple[float, float], Color]] = {
    "plate": ((0.24, 0.24), (240, 240, 232)),
    "bowl": ((0.14, 0.14), (70, 120, 200)),
    "fork": ((0.19, 0.03), (165, 165, 180)),
    "knife": ((0.22, 0.022), (205, 205, 212)),
    "spoon": ((0.17, 0.035), (185, 185, 195)),
    "television": ((0.9, 0.22), (35, 35, 40)),
    "speaker": ((0.16, 0.2), (70, 55, 50)),
    "book": ((0.24, 0.17), (170, 40, 45)),
    "pen": ((0.14, 0.012), (30, 60, 160)),
    "pencil": ((0.18, 0.009), (235, 190, 40)),
    "mug": ((0.12, 0.085), (200, 90, 60)),
}


MAX_SHADE_STEP = 14.0  # RGB distance of any shade from its base: two shades differ by at most 28


def shade(color: Color, f: float) -> Color:
    """Darker (``f < 1``: scaled) or lighter (``f > 1``: towards white) version of ``color``, at most
    ``MAX_SHADE_STEP`` away from it (so that the classical detector sees no edge inside a sprite)."""
    c = np.asarray(color, dtype=float)
    target = c * f if f <= 1 else c + (255 - c) * (f - 1)
    step = target - c
    norm = float(np.linalg.norm(step))
    if norm > MAX_SHADE_STEP:
        step *= MAX_SHADE_STEP / norm
    return tuple(int(v) for v in np.clip(np.round(c + step), 0, 255))  # type: ignore[return-value]


def _rect(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def _ellipse(
    cx: float, cy: float, rx: float, ry: float, n: int = 64, a0: float = 0.0, a1: float = 2 * math.pi
):
    k = np.linspace(a0, a1, n, endpoint=abs(a1 - a0 - 2 * math.pi) > 1e-9)
    return np.stack([cx + rx * np.cos(k), cy + ry * np.sin(k)], axis=1)


def _plate(ln: float, w: float, c: Color) -> list[Part]:
    return [(_ellipse(0, 0, ln / 2, w / 2), c), (_ellipse(0, 0, 0.34 * ln, 0.34 * w), shade(c, 0.95))]


def _bowl(ln: float, w: float, c: Color) -> list[Part]:
    return [
        (_ellipse(0, 0, ln / 2, w / 2), c),
        (_ellipse(0, 0, 0.41 * ln, 0.41 * w), shade(c, 0.92)),
        (_ellipse(0.06 * ln, 0.08 * w, 0.12 * ln, 0.08 * w), c),
    ]


def _fork(ln: float, w: float, c: Color) -> list[Part]:
    x0 = -ln / 2
    handle = _rect(x0, x0 + 0.55 * ln, -0.175 * w, 0.175 * w)
    neck = np.array(
        [
            [x0 + 0.55 * ln, -0.175 * w],
            [x0 + 0.65 * ln, -w / 2],
            [x0 + 0.65 * ln, w / 2],
            [x0 + 0.55 * ln, 0.175 * w],
        ]
    )
    head = _rect(x0 + 0.65 * ln - 1e-4, ln / 2, -w / 2, w / 2)
    parts: list[Part] = [(handle, c), (neck, c), (head, c)]
    unit = w / 7  # four tines, three gaps
    for k in (1, 3, 5):
        y = -w / 2 + k * unit
        parts.append((_rect(x0 + 0.76 * ln, ln / 2 + 1e-3, y, y + unit), None))
    return parts


def _knife(ln: float, w: float, c: Color) -> list[Part]:
    x0 = -ln / 2
    handle = np.concatenate(
        [
            _ellipse(x0 + 0.3 * w, 0, 0.3 * w, 0.3 * w, 12, math.pi / 2, 3 * math.pi / 2),
            [[x0 + 0.38 * ln, -0.3 * w]],
            [[x0 + 0.38 * ln, 0.3 * w]],
        ]
    )
    tip_len = 0.12 * ln
    xb = ln / 2 - tip_len
    blade = np.concatenate(
        [
            [[x0 + 0.38 * ln, -w / 2]],
            [[xb, -w / 2]],
            _ellipse(xb, 0, tip_len, w / 2, 24, -math.pi / 2, math.pi / 2),
            [[x0 + 0.38 * ln, w / 2]],
        ]
    )
    return [
        (handle, shade(c, 0.92)),
        (blade, c),
        (_rect(x0 + 0.37 * ln, x0 + 0.4 * ln, -0.45 * w, 0.45 * w), c),
    ]


def _spoon(ln: float, w: float, c: Color) -> list[Part]:
    x0 = -ln / 2
    bowl_len = 0.36 * ln
    handle = np.array(
        [
            [x0, -0.12 * w],
            [ln / 2 - bowl_len * 0.8, -0.09 * w],
            [ln / 2 - bowl_len * 0.8, 0.09 * w],
            [x0, 0.12 * w],
        ]
    )
    handle_end = _ellipse(x0 + 0.1 * w, 0, 0.1 * w, 0.14 * w, 16)
    return [
        (handle, c),
        (_rect(x0, x0 + 0.1 * w, -0.14 * w, 0.14 * w), c),
        (handle_end, c),
        (_ellipse(ln / 2 - bowl_len / 2, 0, bowl_len / 2, w / 2), c),
        (_ellipse(ln / 2 - bowl_len / 2 + 0.01 * ln, 0, bowl_len * 0.36, w * 0.36), shade(c, 0.93)),
    ]


def _television(ln: float, w: float, c: Color) -> list[Part]:
    screen = _rect(-ln / 2, ln / 2, w / 2 - 0.3 * w, w / 2)
    stand = np.array(
        [
            [-0.2 * ln, -w / 2],
            [0.2 * ln, -w / 2],
            [0.08 * ln, w / 2 - 0.29 * w],
            [-0.08 * ln, w / 2 - 0.29 * w],
        ]
    )
    return [
        (stand, shade(c, 1.06)),
        (screen, c),
        (_rect(-ln / 2 + 0.01, ln / 2 - 0.01, w / 2 - 0.27 * w, w / 2 - 0.03 * w), shade(c, 1.05)),
    ]


def _speaker(ln: float, w: float, c: Color) -> list[Part]:
    m = 0.08 * min(ln, w)
    return [
        (_rect(-ln / 2, ln / 2, -w / 2, w / 2), c),
        (_rect(-ln / 2 + m, ln / 2 - m, -w / 2 + m, w / 2 - m), shade(c, 1.07)),
    ]


def _book(ln: float, w: float, c: Color) -> list[Part]:
    return [
        (_rect(-ln / 2, ln / 2, -w / 2, w / 2), c),
        (_rect(-ln / 2, -ln / 2 + 0.07 * ln, -w / 2, w / 2), shade(c, 0.88)),
        (_rect(-ln / 2 + 0.2 * ln, ln / 2 - 0.12 * ln, -0.05 * w, 0.05 * w), shade(c, 1.08)),
    ]


def _pen(ln: float, w: float, c: Color) -> list[Part]:
    x0 = -ln / 2
    body = _rect(x0, x0 + 0.62 * ln, -0.3 * w, 0.3 * w)
    grip = _rect(x0 + 0.6 * ln, x0 + 0.9 * ln, -w / 2, w / 2)
    tip = np.array(
        [[x0 + 0.9 * ln, -0.42 * w], [ln / 2, -0.08 * w], [ln / 2, 0.08 * w], [x0 + 0.9 * ln, 0.42 * w]]
    )
    return [(body, c), (grip, shade(c, 0.9)), (tip, shade(c, 1.08))]


def _pencil(ln: float, w: float, c: Color) -> list[Part]:
    x0 = -ln / 2
    eraser = _rect(x0, x0 + 0.1 * ln, -0.3 * w, 0.3 * w)
    body = _rect(x0 + 0.1 * ln, x0 + 0.9 * ln, -w / 2, w / 2)
    tip = np.array([[x0 + 0.9 * ln, -w / 2], [ln / 2, -0.1 * w], [ln / 2, 0.1 * w], [x0 + 0.9 * ln, w / 2]])
    return [(eraser, shade(c, 0.9)), (body, c), (tip, shade(c, 1.08))]


def _mug(ln: float, w: float, c: Color) -> list[Part]:
    r = w / 2
    cx = ln / 2 - r
    x0 = -ln / 2
    handle_outer = _rect(x0, cx, -0.22 * w, 0.22 * w)
    hole = _rect(x0 + 0.22 * (cx - r - x0) + 0.002, cx - r, -0.1 * w, 0.1 * w)
    return [
        (handle_outer, shade(c, 0.93)),
        (hole, None),
        (_ellipse(cx, 0, r, r), c),
        (_ellipse(cx, 0, 0.82 * r, 0.82 * r), shade(c, 0.9)),
    ]


SPRITES: dict[str, Callable[[float, float, Color], list[Part]]] = {
    "plate": _plate,
    "bowl": _bowl,
    "fork": _fork,
    "knife": _knife,
    "spoon": _spoon,
    "television": _television,
    "tv": _television,
    "speaker": _speaker,
    "book": _book,
    "pen": _pen,
    "pencil": _pencil,
    "mug": _mug,
    "cup": _mug,
}


def has_sprite(obj: SceneObject) -> bool:
    """Whether ``obj`` is drawn as a sprite (a known category and no polygon footprint of its own)."""
    return obj.category.lower() in SPRITES and obj.shape_kind != "polygon"


def sprite_parts(obj: SceneObject) -> list[Part]:
    """The parts to paint for ``obj`` in its own frame: its sprite, or its footprint in its colour."""
    color: Color = tuple(int(v) for v in obj.color)  # type: ignore[assignment]
    ln, w = float(obj.size[0]), float(obj.size[1])
    if has_sprite(obj):
        return SPRITES[obj.category.lower()](ln, w, color)
    return [(obj.polygon(), color)]
