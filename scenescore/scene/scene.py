"""Scenes: objects on a plane with footprints, colours and poses; JSON and JSONL reading and writing.

The JSON contract (one scene per line in a ``.jsonl`` dataset)::

    {"objects": [{"name": "fork_0", "category": "fork", "size": [0.19, 0.025],
                  "pose": [0.12, -0.31, 1.5708], "color": [180, 180, 190]}],
     "bounds": [[-0.6, -0.6], [0.6, 0.6]]}

``pose: null`` marks a pose to predict; ``"fixed": true`` an object no solver may move. Optional per
object: ``shape`` (``"box"``, ``"disk"`` or ``{"polygon": [[x, y], ...]}``), ``features`` (a precomputed
semantic vector) and ``image`` (a crop to encode).
"""

from __future__ import annotations

import copy
import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from .fields import SCENE_KEYS, Bounds, SceneError, location, read_bounds, read_object
from .outputs import WriteError, atomic_file, atomic_write_text

__all__ = [
    "Bounds",
    "SceneError",
    "WriteError",
    "SceneObject",
    "Scene",
    "read_jsonl",
    "write_jsonl",
    "wrap_angle",
    "fits_bounds",
    "check_fits",
]

DEFAULT_BOUNDS: Bounds = ((-0.6, -0.6), (0.6, 0.6))


def wrap_angle(a):
    """Wrap angles (float, ndarray or tensor) to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def fits_bounds(obj: SceneObject, bounds: Bounds) -> bool:
    """Whether ``obj``'s footprint fits inside ``bounds`` at some heading (checked every half degree),
    with its origin inside them too: the solvers keep an object's position (its pose, the origin of its
    outline) within the bounds, so a polygon drawn far from its origin can fit nowhere."""
    (x0, y0), (x1, y1) = bounds
    pts = np.vstack([obj.polygon(), np.zeros((1, 2))])  # a box's or a disk's origin is inside already
    t = np.linspace(0.0, np.pi, 361)
    c, s = np.cos(t)[:, None], np.sin(t)[:, None]
    xs = pts[:, 0][None] * c - pts[:, 1][None] * s  # (angles, K)
    ys = pts[:, 0][None] * s + pts[:, 1][None] * c
    w, h = xs.max(1) - xs.min(1), ys.max(1) - ys.min(1)
    tol = 1e-9 * max(x1 - x0, y1 - y0)
    return bool(np.any((w <= x1 - x0 + tol) & (h <= y1 - y0 + tol)))


def check_fits(obj: SceneObject, bounds: Bounds, where: str) -> None:
    """Raise :class:`SceneError` naming ``obj`` when it cannot be placed inside ``bounds`` at any heading."""
    if not fits_bounds(obj, bounds):
        (x0, y0), (x1, y1) = bounds
        outline = ""
        if obj.shape_kind == "polygon":  # the outline, not the size, may be what cannot fit
            far = float(np.hypot(*obj.polygon().T).max())
            outline = (
                f" (its field 'shape.polygon' reaches {far:.3g} m from its pose, which stays inside them)"
            )
        raise SceneError(
            f"{where}: object {obj.name!r} ({obj.size[0]:g} x {obj.size[1]:g} m) does not fit inside its "
            f"bounds ({x1 - x0:g} x {y1 - y0:g} m) at any heading{outline}; nowhere to place it"
        )


@dataclass
class SceneObject:
    """One object: identity, footprint, appearance and pose ``(x, y, theta)`` (``None``: to predict)."""

    name: str
    category: str
    size: tuple[float, float]
    pose: tuple[float, float, float] | None = None
    color: tuple[int, int, int] = (128, 128, 128)
    fixed: bool = False
    shape: str | dict = "box"
    features: list[float] | None = None
    image: str | None = None

    @property
    def shape_kind(self) -> str:
        """``box``, ``disk`` or ``polygon``."""
        return self.shape if isinstance(self.shape, str) else "polygon"

    @property
    def kind(self) -> tuple[str, tuple[float, float]]:
        """Category and size: two objects of one kind are interchangeable (trading their places changes
        nothing)."""
        return self.category, (float(self.size[0]), float(self.size[1]))

    @property
    def round(self) -> bool:
        """A round disk: its heading means nothing (the energy ignores it, errors do not count it)."""
        return self.shape_kind == "disk" and abs(self.size[0] - self.size[1]) <= 1e-9 * max(self.size)

    def polygon(self) -> np.ndarray:
        """The footprint's outline in the object's own frame, ``(K, 2)`` counter-clockwise."""
        length, width = self.size
        if self.shape_kind == "box":
            hx, hy = length / 2, width / 2
            return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        if self.shape_kind == "disk":
            k = np.linspace(0, 2 * np.pi, 24, endpoint=False)
            return np.stack([length / 2 * np.cos(k), width / 2 * np.sin(k)], axis=1)
        return np.asarray(cast(dict, self.shape)["polygon"], dtype=float)

    def world_polygon(self, pose: Sequence[float] | None = None) -> np.ndarray:
        """The outline placed at ``pose`` (default: the object's own pose)."""
        pose = self.pose if pose is None else pose
        if pose is None:
            raise SceneError(f"object {self.name!r}: has no pose")
        x, y, t = pose
        c, s = math.cos(t), math.sin(t)
        local = self.polygon()
        return local @ np.array([[c, s], [-s, c]]) + np.array([x, y])

    def to_dict(self) -> dict[str, Any]:
        """The JSON mapping; a non-finite size, pose or feature is refused (the reader would refuse it)."""
        for key, values in (("size", self.size), ("pose", self.pose), ("features", self.features)):
            if values is not None and not all(math.isfinite(float(v)) for v in values):
                raise SceneError(
                    f"object {self.name!r}: field {key!r} is not finite ({[float(v) for v in values]}); "
                    "not written"
                )
        d: dict[str, Any] = {
            "name": self.name,
            "category": self.category,
            "size": [float(v) for v in self.size],
            "pose": None if self.pose is None else [float(v) for v in self.pose],
            "color": [int(v) for v in self.color],
        }
        if self.fixed:
            d["fixed"] = True
        if self.shape != "box":
            d["shape"] = self.shape
        if self.features is not None:
            d["features"] = [float(v) for v in self.features]
        if self.image is not None:
            d["image"] = self.image
        return d

    @classmethod
    def from_dict(cls, d: Any, where: str = "scene", index: int = 0) -> SceneObject:
        """Parse one object; errors name ``where``, the object and the field."""
        return cls(**read_object(d, where, index))


@dataclass
class Scene:
    """A set of objects inside rectangular bounds ``((xmin, ymin), (xmax, ymax))``."""

    objects: list[SceneObject]
    bounds: Bounds = DEFAULT_BOUNDS
    meta: dict[str, Any] = field(default_factory=dict)
    # where the scene was read from ("file:line"), for error messages; never written out
    origin: str | None = field(default=None, compare=False, repr=False)

    # -- access ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.objects)

    @property
    def names(self) -> list[str]:
        return [o.name for o in self.objects]

    def index(self, name: str) -> int:
        """Position of the object called ``name``; the error lists the names there are."""
        for i, o in enumerate(self.objects):
            if o.name == name:
                return i
        raise SceneError(f"no object named {name!r} in the scene; objects are {self.names}")

    def __getitem__(self, name: str) -> SceneObject:
        return self.objects[self.index(name)]

    @property
    def unknown(self) -> list[str]:
        """Names of the objects whose pose is ``null``."""
        return [o.name for o in self.objects if o.pose is None]

    def poses(self, fill: float = 0.0) -> np.ndarray:
        """Poses as ``(N, 3)``; unknown poses are filled with ``fill``."""
        return np.array(
            [o.pose if o.pose is not None else (fill, fill, fill) for o in self.objects], dtype=float
        )

    def sizes(self) -> np.ndarray:
        return np.array([o.size for o in self.objects], dtype=float)

    def with_poses(
        self, poses: np.ndarray | Sequence[Sequence[float]], names: Iterable[str] | None = None
    ) -> Scene:
        """A copy with new poses: all of them (``(N, 3)``) or those of ``names`` in that order."""
        out = self.copy()
        poses = np.asarray(poses, dtype=float)
        targets = list(range(len(out.objects))) if names is None else [out.index(n) for n in names]
        if poses.shape != (len(targets), 3):
            raise SceneError(f"with_poses: expected poses of shape ({len(targets)}, 3), got {poses.shape}")
        for i, p in zip(targets, poses):
            out.objects[i].pose = (float(p[0]), float(p[1]), float(wrap_angle(p[2])))
        return out

    def without(self, name: str) -> Scene:
        """A copy with ``name``'s pose set to ``null`` (the object stays, its pose is to predict)."""
        out = self.copy()
        out.objects[out.index(name)].pose = None
        return out

    def copy(self) -> Scene:
        return copy.deepcopy(self)

    def label(self, index: int | None = None) -> str:
        """How errors name this scene: where it was read from (``file:line``), else ``scene {index}``."""
        return self.origin or (f"scene {index}" if index is not None else "scene")

    def scaled(self, k: float) -> Scene:
        """Every length times ``k``: positions, sizes, polygon outlines and bounds (headings unchanged)."""
        out = self.copy()
        for o in out.objects:
            o.size = (o.size[0] * k, o.size[1] * k)
            if o.pose is not None:
                o.pose = (o.pose[0] * k, o.pose[1] * k, o.pose[2])
            if isinstance(o.shape, dict):
                o.shape = {"polygon": [[x * k, y * k] for x, y in o.shape["polygon"]]}
        (x0, y0), (x1, y1) = out.bounds
        out.bounds = ((x0 * k, y0 * k), (x1 * k, y1 * k))
        return out

    # -- JSON -----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "objects": [o.to_dict() for o in self.objects],
            "bounds": [list(map(float, self.bounds[0])), list(map(float, self.bounds[1]))],
        }
        if self.meta:
            d["meta"] = self.meta
        return d

    def to_json(self, path: str | os.PathLike | None = None, indent: int | None = 1) -> str:
        """Serialise; with ``path``, also write it atomically."""
        text = json.dumps(self.to_dict(), indent=indent)
        if path is not None:
            atomic_write_text(path, text + "\n")
        return text

    @classmethod
    def from_dict(cls, d: Any, source: str | None = None, line: int | None = None) -> Scene:
        """Parse and validate a scene mapping; ``source``/``line`` go into error messages."""
        where = location(source, line)
        if not isinstance(d, dict):
            raise SceneError(f"{where}: expected a scene object with 'objects', got {type(d).__name__}")
        unknown = set(d) - SCENE_KEYS
        if unknown:
            raise SceneError(f"{where}: unknown key(s) {sorted(unknown)}; a scene has {sorted(SCENE_KEYS)}")
        if "objects" not in d:
            raise SceneError(f"{where}: missing key 'objects' (a list of objects)")
        if not isinstance(d["objects"], list):
            raise SceneError(f"{where}: key 'objects': expected a list, got {type(d['objects']).__name__}")
        objects = [SceneObject.from_dict(o, where, i) for i, o in enumerate(d["objects"])]
        seen: set[str] = set()
        for o in objects:
            if o.name in seen:
                raise SceneError(f"{where}: object {o.name!r}: duplicate name; names must be unique")
            seen.add(o.name)
        bounds = DEFAULT_BOUNDS
        if d.get("bounds") is not None:
            bounds = read_bounds(d["bounds"], where)
        meta = d.get("meta") or {}
        if not isinstance(meta, dict):
            raise SceneError(f"{where}: key 'meta': expected a mapping, got {meta!r}")
        for o in objects:
            if o.pose is None:  # to be placed: it must fit somewhere
                check_fits(o, bounds, where)
        return cls(objects=objects, bounds=bounds, meta=meta, origin=None if source is None else where)

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> Scene:
        """Read one scene from a JSON file (or the first line of a ``.jsonl``)."""
        from .textfiles import loads_json, read_text

        data = loads_json(read_text(path, SceneError, "scene file"), str(path), SceneError)
        return cls.from_dict(data, source=str(path))


def read_jsonl(path: str | os.PathLike) -> list[Scene]:
    """Read a ``.jsonl`` dataset, one scene per non-empty line; errors name the file and line."""
    from .textfiles import loads_json, read_text

    scenes = []
    for lineno, line in enumerate(read_text(path, SceneError, "dataset file").splitlines(), start=1):
        if not line.strip():
            continue
        data = loads_json(line, str(path), SceneError, line=lineno)
        scenes.append(Scene.from_dict(data, source=str(path), line=lineno))
    if not scenes:
        raise SceneError(f"{path}: no scenes in the file (expected one JSON scene per line)")
    return scenes


def write_jsonl(path: str | os.PathLike, scenes: Iterable[Scene]) -> int:
    """Write scenes one per line, atomically, as they come (an iterator of scenes is never held whole);
    returns how many were written. An error while ``scenes`` is drawn leaves the old file."""
    count = 0
    with atomic_file(path) as f:
        for s in scenes:
            f.write((s.to_json(indent=None) + "\n").encode("utf-8"))
            count += 1
    return count
