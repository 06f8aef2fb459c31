"""Top-down rendering of scenes with ground-truth instance masks, and rendered data sets on disk.

Pixel geometry (used by every stage of the vision pipeline): an image of a scene with bounds
``((xmin, ymin), (xmax, ymax))`` at ``ppm`` pixels per metre is ``round((ymax - ymin) * ppm)`` rows by
``round((xmax - xmin) * ppm)`` columns; world ``+x`` is to the right, world ``+y`` is up (towards row
0); the centre of pixel ``(row, col)`` is at ``x = xmin + (col + 0.5) / ppm``,
``y = ymax - (row + 0.5) / ppm``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import cast

import cv2
import numpy as np

from ..runtime import check_memory
from ..scene.outputs import atomic_write_bytes, atomic_write_text
from ..scene.scene import Bounds, Scene, SceneError, SceneObject
from .sprites import sprite_parts

__all__ = [
    "DEFAULT_PPM",
    "TABLE_COLOR",
    "image_shape",
    "world_to_pixel",
    "pixel_to_world",
    "render_scene",
    "render_object",
    "write_rendered_dataset",
    "read_image",
    "write_image",
]

DEFAULT_PPM = 500.0  # pixels per metre: a 1.2 m table is 600 x 600 px, a fork 95 x 15 px
TABLE_COLOR = (152, 118, 84)  # a plain wooden table
_SHIFT = 4  # sub-pixel bits for cv2.fillPoly
_SUPERSAMPLE = 4  # sub-pixels per pixel side: a pixel belongs to an object when half of it is covered


def image_shape(bounds: Bounds, ppm: float) -> tuple[int, int]:
    """``(rows, cols)`` of an image of ``bounds`` at ``ppm``."""
    (xmin, ymin), (xmax, ymax) = bounds
    return int(round((ymax - ymin) * ppm)), int(round((xmax - xmin) * ppm))


def world_to_pixel(x, y, bounds: Bounds, ppm: float):
    """World metres -> continuous pixel-index coordinates ``(col, row)`` (pixel centres are integers)."""
    (xmin, _), (_, ymax) = bounds
    return (np.asarray(x) - xmin) * ppm - 0.5, (ymax - np.asarray(y)) * ppm - 0.5


def pixel_to_world(col, row, bounds: Bounds, ppm: float):
    """Continuous pixel-index coordinates ``(col, row)`` -> world metres ``(x, y)``."""
    (xmin, _), (_, ymax) = bounds
    return xmin + (np.asarray(col, dtype=float) + 0.5) / ppm, ymax - (
        np.asarray(row, dtype=float) + 0.5
    ) / ppm


def _paint_object(
    obj: SceneObject, pose: Sequence[float], bounds: Bounds, ppm: float, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, tuple[slice, slice]]:
    """Rasterise one object: (layer colours, layer mask) inside a window of the image, and that window."""
    x, y, t = (float(v) for v in pose)
    c, s = math.cos(t), math.sin(t)
    rot = np.array([[c, s], [-s, c]])
    parts = [(poly @ rot + np.array([x, y]), col) for poly, col in sprite_parts(obj)]
    allpts = np.concatenate([p for p, _ in parts])
    cols, rows = world_to_pixel(allpts[:, 0], allpts[:, 1], bounds, ppm)
    r0 = max(int(math.floor(rows.min())) - 2, 0)
    r1 = min(int(math.ceil(rows.max())) + 3, shape[0])
    c0 = max(int(math.floor(cols.min())) - 2, 0)
    c1 = min(int(math.ceil(cols.max())) + 3, shape[1])
    if r1 <= r0 or c1 <= c0:
        z = np.zeros((0, 0), bool)
        return np.zeros((0, 0, 3), np.uint8), z, (slice(0, 0), slice(0, 0))
    h, w = r1 - r0, c1 - c0
    k = _SUPERSAMPLE
    layer = np.zeros((h * k, w * k, 3), np.uint8)
    mask = np.zeros((h * k, w * k), np.uint8)
    for poly, col in parts:
        pc, pr = world_to_pixel(poly[:, 0], poly[:, 1], bounds, ppm)
        # supersampled pixel-index coordinates: sub-pixel j of pixel i has its centre at i + (j + 0.5) / k - 0.5
        sc, sr = (pc - c0 + 0.5) * k - 0.5, (pr - r0 + 0.5) * k - 0.5
        pts = np.round(np.stack([sc, sr], axis=1) * (1 << _SHIFT)).astype(np.int32)
        if col is None:
            cv2.fillPoly(mask, [pts], 0, lineType=cv2.LINE_8, shift=_SHIFT)
        else:
            cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=_SHIFT)
            cv2.fillPoly(layer, [pts], tuple(int(v) for v in col), lineType=cv2.LINE_8, shift=_SHIFT)
    # coverage of each pixel, and the mean colour of its covered sub-pixels
    cover = mask.reshape(h, k, w, k).mean(axis=(1, 3))
    colsum = (layer.astype(np.float32) * mask[..., None]).reshape(h, k, w, k, 3).sum(axis=(1, 3))
    layer = np.round(colsum / np.maximum(cover * k * k, 1)[..., None]).astype(np.uint8)
    mask = cover >= 0.5
    return layer, mask, (slice(r0, r1), slice(c0, c1))


MAX_PIXELS = 64_000_000  # one image: 8000 x 8000, about 200 MB with its masks
# bytes per pixel: the RGB image and the owner labels (4), plus one mask byte per object; per pixel of
# an object's window, painted at _SUPERSAMPLE^2 sub-pixels: colours, mask, float sums and coverage
_IMAGE_BYTES = 3 + 4
_WINDOW_BYTES = _SUPERSAMPLE**2 * (3 + 1 + 12 + 8)
# the vision pipeline's working set per pixel of an image it reads (segmentation's float maps and labels)
PIPELINE_BYTES = 64


def check_image_memory(scene: Scene, ppm: float, shape: tuple[int, int]) -> None:
    """Raise :class:`~scenescore.runtime.memory.MemoryBudgetError` before drawing ``scene`` at ``ppm`` would
    exceed the memory budget (the image, one mask per object, the largest object's supersampled window)."""
    pixels = shape[0] * shape[1]
    reach = max((math.hypot(*o.size) for o in scene.objects if o.pose is not None), default=0.0)
    window = min((reach * ppm + 5) ** 2, float(pixels))
    check_memory(
        pixels * (_IMAGE_BYTES + len(scene)) + window * _WINDOW_BYTES,
        f"render: ppm {ppm:g} gives a {shape[1]} x {shape[0]} image of {len(scene)} objects",
        "the ppm (pixels per metre)",
    )


def render_scene(
    scene: Scene,
    ppm: float = DEFAULT_PPM,
    background: Sequence[int] = TABLE_COLOR,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Draw ``scene`` from above: ``(image HxWx3 uint8 RGB, masks)``.

    Known categories are drawn as sprites (:mod:`scenescore.vision.sprites`) whose footprint is
    ``size`` and whose ``+x`` axis points along ``theta``; any other category as its footprint (box,
    disk or polygon) in its colour. Objects are painted in scene order, later ones on top. ``masks``
    holds one ``HxW`` bool array per object, in scene order: the pixels where that object is visible
    (so the masks never overlap); an object without a pose, or outside the image, has an empty mask.
    """
    if not (math.isfinite(ppm) and ppm > 0):
        raise SceneError(f"render_scene: ppm must be a positive number, got {ppm}")
    shape = image_shape(scene.bounds, ppm)
    if shape[0] * shape[1] > MAX_PIXELS:
        raise SceneError(
            f"render_scene: ppm {ppm:g} gives a {shape[1]} x {shape[0]} image for bounds {scene.bounds}; "
            f"at most {MAX_PIXELS:,} pixels (lower the ppm)"
        )
    check_image_memory(scene, ppm, shape)
    image = np.empty((*shape, 3), np.uint8)
    image[:] = np.asarray(background, dtype=np.uint8)
    owner = np.full(shape, -1, dtype=np.int32)
    for i, obj in enumerate(scene.objects):
        if obj.pose is None:
            continue
        layer, m, win = _paint_object(obj, obj.pose, scene.bounds, ppm, shape)
        if not m.any():
            continue
        image[win][m] = layer[m]
        owner[win][m] = i
    masks = [owner == i for i in range(len(scene.objects))]
    return image, masks


def render_object(
    obj: SceneObject,
    ppm: float = DEFAULT_PPM,
    theta: float = 0.0,
    margin: float = 0.02,
    background: Sequence[int] = TABLE_COLOR,
    center: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, Bounds]:
    """``obj`` alone at ``(center, theta)`` in a window just large enough: ``(image, mask, bounds)``."""
    r = 0.5 * math.hypot(*obj.size) + margin
    bounds: Bounds = ((center[0] - r, center[1] - r), (center[0] + r, center[1] + r))
    alone = SceneObject(
        obj.name,
        obj.category,
        cast(tuple[float, float], tuple(obj.size)),
        (center[0], center[1], theta),
        cast(tuple[int, int, int], tuple(obj.color)),
        shape=obj.shape,
    )
    image, masks = render_scene(Scene([alone], bounds), ppm, background)
    return image, masks[0], bounds


def write_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an RGB (or single-channel) image as PNG, atomically."""
    arr = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", arr)
    if not ok:
        raise SceneError(f"{path}: could not encode the image as PNG")
    atomic_write_bytes(path, buf.tobytes())


def png_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG file's header, without decoding it; None for other files."""
    try:
        with open(path, "rb") as f:
            head = f.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as ``HxWx3`` uint8 RGB (an alpha channel is dropped). A PNG's size is checked
    against the memory budget from its header, before it is decoded; any image's once decoded."""
    size = png_size(path)
    if size is not None:
        _check_read(path, *size)
    arr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if arr is None:
        raise SceneError(f"{path}: not a readable image file")
    _check_read(path, arr.shape[1], arr.shape[0])
    return cv2.cvtColor(arr, cv2.COLOR_BGR2RGB)


def _check_read(path: str | os.PathLike, w: int, h: int) -> None:
    check_memory(
        w * h * PIPELINE_BYTES,
        f"{path}: a {w} x {h} image through the vision pipeline",
        "the image's size (scale it down, and the ppm with it)",
    )


MASK_PREVIEW = ".masks-preview.png"  # the coloured view of a 16-bit mask image: not a scene image


def mask_preview(labels: np.ndarray, image: np.ndarray) -> np.ndarray:
    """A 16-bit label image as colours (one per label, the table left grey) over ``image``, RGB uint8."""
    rng = np.random.default_rng(0)  # fixed colours: the same label looks the same in every preview
    palette = rng.integers(40, 256, size=(int(labels.max()) + 1, 3)).astype(np.uint8)
    grey = image.mean(axis=2, keepdims=True).astype(np.uint8).repeat(3, axis=2)
    out = np.where(labels[..., None] > 0, palette[labels], grey // 2 + 64)
    return out.astype(np.uint8)


def write_rendered_dataset(
    scenes: Sequence[Scene],
    out_dir: str | os.PathLike,
    ppm: float = DEFAULT_PPM,
    masks: bool = True,
    progress: bool = False,
) -> list[Path]:
    """Render ``scenes`` into ``out_dir``: per scene ``scene_00000.png`` and ``scene_00000.json``.

    The JSON is the ground-truth scene with ``meta.image`` (the PNG's file name) and ``meta.ppm``.
    With ``masks``, ``scene_00000.masks.png`` holds the instance masks as a 16-bit label image
    (0: table, ``k``: the scene's object ``k - 1``; it looks black in an image viewer), and
    ``scene_00000.masks-preview.png`` the same labels in colours over the image, to look at. ``dataset.json`` lists the images and the ppm.
    Returns the paths of the images written. ``progress``: a progress bar.
    """
    from tqdm.auto import tqdm

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for k, scene in enumerate(tqdm(scenes, desc="render", unit="image", disable=not progress)):
        stem = f"scene_{k:05d}"
        image, ms = render_scene(scene, ppm)
        write_image(out / f"{stem}.png", image)
        if masks:
            labels = np.zeros(image.shape[:2], np.uint16)
            for i, m in enumerate(ms):
                labels[m] = i + 1
            ok, buf = cv2.imencode(".png", labels)
            if not ok:
                raise SceneError(f"{out / stem}.masks.png: could not encode the masks")
            atomic_write_bytes(out / f"{stem}.masks.png", buf.tobytes())
            write_image(out / f"{stem}{MASK_PREVIEW}", mask_preview(labels, image))
        gt = scene.copy()
        gt.meta = {**gt.meta, "image": f"{stem}.png", "ppm": float(ppm)}
        gt.to_json(out / f"{stem}.json")
        written.append(out / f"{stem}.png")
    index = {
        "format": "scenescore-rendered",
        "version": 1,
        "ppm": float(ppm),
        "images": [p.name for p in written],
    }
    atomic_write_text(out / "dataset.json", json.dumps(index, indent=1) + "\n")
    return written
