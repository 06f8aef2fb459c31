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
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, cast

import numpy as np

__all__ = [
    "Bounds",
    "SceneError",
    "WriteError",
    "SceneObject",
    "Scene",
    "read_jsonl",
    "write_jsonl",
    "atomic_write_bytes",
    "atomic_write_text",
    "wrap_angle",
    "fits_bounds",
    "check_fits",
]

Bounds = tuple[tuple[float, float], tuple[float, float]]
DEFAULT_BOUNDS: Bounds = ((-0.6, -0.6), (0.6, 0.6))
# the ranges every number read is checked against: finite in the float32 the model computes in, and a
# scale at which float32 still resolves a millimetre and a milliradian
MAX_LENGTH = 1e4  # metres: sizes, positions, polygon vertices and bounds (|value|)
POLYGON_REACH = 1.01  # a polygon vertex may lie this many size diagonals from its object's origin
MIN_SIZE = 1e-5  # metres: the smallest footprint side (0.01 mm)
MAX_ANGLE = 1e3  # radians: |theta| (headings are wrapped; larger values lose float32 precision)
MAX_FEATURE = 1e6  # |value| of a precomputed feature
_OBJECT_KEYS = {"name", "category", "size", "pose", "color", "fixed", "shape", "features", "image"}
_SCENE_KEYS = {"objects", "bounds", "meta"}


class SceneError(ValueError):
    """Malformed scene input; the message names the file, line, object and field."""


class WriteError(OSError, SceneError):
    """An output that could not be written (a file-size limit, a full disk, an I/O error): an ``OSError``
    with the cause's ``errno``, and, like every :class:`SceneError`, a one-line message (naming the file)
    that the command line prints without a traceback. The older file at that path is left as it was."""


def wrap_angle(a):
    """Wrap angles (float, ndarray or tensor) to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output_path(path: str | os.PathLike, what: str, folder: bool = False) -> None:
    """Fail early, with a one-line :class:`SceneError`, when ``path`` cannot be written: an existing
    folder where a file is meant (or a file where a folder is), a regular file among its parents, or a
    nearest existing parent that is not writable."""
    p = Path(path)
    if p.exists() and p.is_dir() != folder:
        kind = "a folder" if p.is_dir() else "a file"
        raise SceneError(f"{what} {p}: is {kind}; expected {'a folder' if folder else 'a file'} to write")
    parent = p if folder else p.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise SceneError(f"{what} {p}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise SceneError(f"{what} {p}: the folder {parent} is not writable")


@contextmanager
def _atomic_file(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """A binary file that becomes ``path`` when the block ends (written to a temporary file beside it,
    then renamed); an error or an interrupt inside the block removes it and leaves the old file. The
    file gets the usual permissions (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        # a failure of writing this file (EFBIG, ENOSPC, EIO: no file named) or of renaming it; an error
        # that names another file came from the caller's own work in the block and is left as it is
        if isinstance(e, WriteError) or e.filename not in (None, tmp):
            raise
        err = WriteError(f"{path}: could not be written ({e.strerror or e}); {_left(path)}")
        err.errno = e.errno
        raise err from e
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _left(path: Path) -> str:
    """What a failed atomic write left at ``path``."""
    return "the earlier file is unchanged" if path.exists() else "nothing was written"


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename: a failure leaves the old file."""
    with _atomic_file(path) as f:
        f.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write text atomically (see :func:`atomic_write_bytes`)."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _where(source: str | None, line: int | None) -> str:
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


def _object_label(d: Any, where: str, index: int) -> str:
    """Check an object mapping's fields, name and category; the object's label for error messages."""
    if not isinstance(d, dict):
        raise SceneError(f"{where}: objects[{index}]: expected an object (a JSON mapping), got {d!r}")
    label = f"{where}: object {d.get('name', f'#{index}')!r}"
    unknown = set(d) - _OBJECT_KEYS
    if unknown:
        raise SceneError(
            f"{label}: unknown field(s) {sorted(unknown)}; expected some of {sorted(_OBJECT_KEYS)}"
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
        label = _object_label(d, where, index)
        size = _object_size(d["size"], label)
        pose = _object_pose(d.get("pose"), label)
        color = _object_color(d.get("color", [128, 128, 128]), label)
        fixed = _object_fixed(d.get("fixed", False), label)
        shape = _object_shape(d.get("shape", "box"), label, size)
        feats = _object_features(d.get("features"), label)
        image = _object_image(d.get("image"), label)
        if pose is None and fixed:
            raise SceneError(f"{label}: a fixed object needs a pose (got pose null and fixed true)")
        return cls(
            name=d["name"],
            category=d["category"],
            size=(size[0], size[1]),
            pose=pose,  # type: ignore[arg-type]
            color=tuple(int(round(c)) for c in color),  # type: ignore[arg-type]
            fixed=fixed,
            shape=shape,
            features=feats,
            image=image,
        )


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
        where = _where(source, line)
        if not isinstance(d, dict):
            raise SceneError(f"{where}: expected a scene object with 'objects', got {type(d).__name__}")
        unknown = set(d) - _SCENE_KEYS
        if unknown:
            raise SceneError(f"{where}: unknown key(s) {sorted(unknown)}; a scene has {sorted(_SCENE_KEYS)}")
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
            b = d["bounds"]
            if not isinstance(b, list) or len(b) != 2:
                raise SceneError(f"{where}: key 'bounds': expected [[xmin, ymin], [xmax, ymax]], got {b!r}")
            lo = _vector(b[0], 2, f"{where}: key 'bounds[0]'", MAX_LENGTH, " m")
            hi = _vector(b[1], 2, f"{where}: key 'bounds[1]'", MAX_LENGTH, " m")
            if not (lo[0] < hi[0] and lo[1] < hi[1]):
                raise SceneError(f"{where}: key 'bounds': expected min < max on both axes, got {b!r}")
            bounds = ((lo[0], lo[1]), (hi[0], hi[1]))
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
    with _atomic_file(path) as f:
        for s in scenes:
            f.write((s.to_json(indent=None) + "\n").encode("utf-8"))
            count += 1
    return count
