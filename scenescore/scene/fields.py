"""The fields of a scene's JSON: each read and checked, with a one-line error naming the object and field.

Every number read is checked against the ranges below: finite in the float32 the model computes in,
and at a scale at which float32 still resolves a millimetre and a milliradian. :func:`read_object`
returns one object's fields, :func:`read_bounds` a scene's bounds; :class:`SceneError` is what they raise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "Bounds",
    "SceneError",
    "MAX_LENGTH",
    "POLYGON_REACH",
    "MIN_SIZE",
    "MAX_ANGLE",
    "MAX_FEATURE",
    "OBJECT_KEYS",
    "SCENE_KEYS",
    "location",
    "read_object",
    "read_bounds",
]

Bounds = tuple[tuple[float, float], tuple[float, float]]
MAX_LENGTH = 1e4  # metres: sizes, positions, polygon vertices and bounds (|value|)
POLYGON_REACH = 1.01  # a polygon vertex may lie this many size diagonals from its object's origin
MIN_SIZE = 1e-5  # metres: the smallest footprint side (0.01 mm)
MAX_ANGLE = 1e3  # radians: |theta| (headings are wrapped; larger values lose float32 precision)
MAX_FEATURE = 1e6  # |value| of a precomputed feature
OBJECT_KEYS = {"name", "category", "size", "pose", "color", "fixed", "shape", "features", "image"}
SCENE_KEYS = {"objects", "bounds", "meta"}


class SceneError(ValueError):
    """Malformed scene input; the message names the file, line, object and field."""


def location(source: str | None, line: int | None) -> str:
    """How errors name where a scene was read from: ``file:line``, the file, or ``scene``."""
    if source is None:
        return "scene"
    return f"{source}:{line}" if line is not None else str(source)


def _number(value: Any, what: str, limit: float | None = None, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{what}: expected a number, got {value!r}")
    if not math.isfinite(value):
        raise SceneError(f"{what}: expected a finite number, got {value!r}")
    if limit is not None and not abs(value) <= limit:
        raise SceneError(f"{what}: expected a number within +-{limit:g}{unit}, got {value!r}")
    return float(value)


def _vector(
    value: Any, n: int | None, what: str, limits: Sequence[float] | float | None = None, unit: str = ""
) -> list[float]:
    if not isinstance(value, (list, tuple)):
        raise SceneError(f"{what}: expected a list of {n if n else 'some'} numbers, got {value!r}")
    if n is not None and len(value) != n:
        raise SceneError(f"{what}: expected {n} numbers, got {len(value)}: {value!r}")
    if n is None and not value:
        raise SceneError(f"{what}: expected at least one number, got []")
    lim = [limits] * len(value) if limits is None or isinstance(limits, (int, float)) else list(limits)
    return [_number(v, f"{what}[{i}]", lim[i], unit) for i, v in enumerate(value)]


def _check_polygon(points: list[list[float]], what: str) -> None:
    """A footprint outline must be a simple polygon with an area: no crossing edges, not all on a line."""
    from shapely.geometry import Polygon

    poly = Polygon(points)
    if not poly.is_valid:
        raise SceneError(
            f"{what}: the outline self-intersects (its edges cross); expected a simple polygon, got {points}"
        )
    span = float(np.ptp(np.asarray(points), axis=0).max())
    if not poly.area > 1e-9 * span**2 or poly.area < MIN_SIZE**2:
        raise SceneError(f"{what}: the outline has no area (collinear or repeated points), got {points}")


def _check_polygon_reach(points: list[list[float]], size: Sequence[float], label: str) -> None:
    """Every vertex of a polygon footprint within the diagonal of the object's ``size`` of its origin.

    The outline is in the object's own frame (its pose is the origin) and ``size`` is the footprint's
    length and width: an outline that fits a ``length x width`` box touching its origin has no vertex
    farther than the box's diagonal. The outline need not be centred, so the rule is that distance (and
    1% more) rather than the centred box; a vertex beyond it is an outline in other units or another frame.
    """
    reach = math.hypot(size[0], size[1])
    for i, (x, y) in enumerate(points):
        far = math.hypot(x, y)
        if far > reach * POLYGON_REACH:
            raise SceneError(
                f"{label}: field 'shape.polygon[{i}]': vertex [{x:g}, {y:g}] lies {far:.3g} m from the "
                f"object's origin, farther than its size ({size[0]:g} x {size[1]:g} m, diagonal "
                f"{reach:.3g} m) allows; the outline is in the object's own frame, around its pose"
            )


def _object_label(d: Any, where: str, index: int) -> str:
    """Check an object mapping's fields, name and category; the object's label for error messages."""
    if not isinstance(d, dict):
        raise SceneError(f"{where}: objects[{index}]: expected an object (a JSON mapping), got {d!r}")
    label = f"{where}: object {d.get('name', f'#{index}')!r}"
    unknown = set(d) - OBJECT_KEYS
    if unknown:
        raise SceneError(
            f"{label}: unknown field(s) {sorted(unknown)}; expected some of {sorted(OBJECT_KEYS)}"
        )
    for key in ("name", "category", "size"):
        if key not in d:
            raise SceneError(f"{label}: missing field {key!r}")
    if not isinstance(d["name"], str) or not d["name"]:
        raise SceneError(f"{where}: objects[{index}].name: expected a non-empty string, got {d['name']!r}")
    if not isinstance(d["category"], str) or not d["category"]:
        raise SceneError(f"{label}: field 'category': expected a non-empty string, got {d['category']!r}")
    return label


def _object_size(value: Any, label: str) -> list[float]:
    """The footprint ``[length, width]`` in metres, each side at least ``MIN_SIZE``."""
    size = _vector(value, 2, f"{label}: field 'size'", MAX_LENGTH, " m")
    if not min(size) >= MIN_SIZE:
        raise SceneError(
            f"{label}: field 'size': expected two positive lengths in metres (at least {MIN_SIZE:g}), "
            f"got {size}"
        )
    return size


def _object_pose(value: Any, label: str) -> tuple[float, ...] | None:
    """``(x, y, theta)``, or ``None`` (JSON null: a pose to predict)."""
    if value is None:
        return None
    return tuple(
        _vector(value, 3, f"{label}: field 'pose' [x, y, theta]", (MAX_LENGTH, MAX_LENGTH, MAX_ANGLE))
    )


def _object_color(value: Any, label: str) -> list[float]:
    """Three integers in 0..255 (as numbers; whole floats such as ``1.0`` are accepted)."""
    color = _vector(value, 3, f"{label}: field 'color'")
    if any(c < 0 or c > 255 or c != int(c) for c in color):
        raise SceneError(f"{label}: field 'color': expected three integers in 0..255, got {value!r}")
    return color


def _object_fixed(value: Any, label: str) -> bool:
    """Whether no solver may move the object: a JSON boolean."""
    if not isinstance(value, bool):
        raise SceneError(f"{label}: field 'fixed': expected true or false, got {value!r}")
    return value


def _object_shape(shape: Any, label: str, size: Sequence[float]) -> str | dict:
    """``"box"``, ``"disk"`` or ``{"polygon": [[x, y], ...]}`` (a simple polygon with an area, within the
    reach of ``size``: :func:`_check_polygon_reach`)."""
    if isinstance(shape, str):
        if shape not in ("box", "disk"):
            raise SceneError(
                f"{label}: field 'shape': expected 'box', 'disk' or {{'polygon': [...]}}, got {shape!r}"
            )
        return shape
    if isinstance(shape, dict) and set(shape) == {"polygon"}:
        pts = shape["polygon"]
        if not isinstance(pts, list) or len(pts) < 3:
            raise SceneError(
                f"{label}: field 'shape.polygon': expected at least 3 [x, y] points, got {pts!r}"
            )
        polygon = [
            _vector(p, 2, f"{label}: field 'shape.polygon[{i}]'", MAX_LENGTH, " m") for i, p in enumerate(pts)
        ]
        _check_polygon(polygon, f"{label}: field 'shape.polygon'")
        _check_polygon_reach(polygon, size, label)
        return {"polygon": polygon}
    raise SceneError(f"{label}: field 'shape': expected 'box', 'disk' or {{'polygon': [...]}}, got {shape!r}")


def _object_features(value: Any, label: str) -> list[float] | None:
    """A precomputed semantic vector, or ``None``."""
    if value is None:
        return None
    return _vector(value, None, f"{label}: field 'features'", MAX_FEATURE)


def _object_image(value: Any, label: str) -> str | None:
    """The path of a crop to encode, or ``None``."""
    if value is not None and (not isinstance(value, str) or not value.strip()):
        raise SceneError(f"{label}: field 'image': expected a path string, got {value!r}")
    return value


def read_object(d: Any, where: str = "scene", index: int = 0) -> dict[str, Any]:
    """One object's fields, read and checked: the keyword arguments of ``SceneObject``. Errors name
    ``where``, the object (its name, else its ``index``) and the field."""
    label = _object_label(d, where, index)
    size = _object_size(d["size"], label)
    pose = _object_pose(d.get("pose"), label)
    color = _object_color(d.get("color", [128, 128, 128]), label)
    fixed = _object_fixed(d.get("fixed", False), label)
    shape = _object_shape(d.get("shape", "box"), label, size)
    features = _object_features(d.get("features"), label)
    image = _object_image(d.get("image"), label)
    if pose is None and fixed:
        raise SceneError(f"{label}: a fixed object needs a pose (got pose null and fixed true)")
    return {
        "name": d["name"],
        "category": d["category"],
        "size": (size[0], size[1]),
        "pose": pose,
        "color": tuple(int(round(c)) for c in color),
        "fixed": fixed,
        "shape": shape,
        "features": features,
        "image": image,
    }


def read_bounds(b: Any, where: str) -> Bounds:
    """A scene's ``[[xmin, ymin], [xmax, ymax]]``, in range and min < max on both axes."""
    if not isinstance(b, list) or len(b) != 2:
        raise SceneError(f"{where}: key 'bounds': expected [[xmin, ymin], [xmax, ymax]], got {b!r}")
    lo = _vector(b[0], 2, f"{where}: key 'bounds[0]'", MAX_LENGTH, " m")
    hi = _vector(b[1], 2, f"{where}: key 'bounds[1]'", MAX_LENGTH, " m")
    if not (lo[0] < hi[0] and lo[1] < hi[1]):
        raise SceneError(f"{where}: key 'bounds': expected min < max on both axes, got {b!r}")
    return (lo[0], lo[1]), (hi[0], hi[1])
