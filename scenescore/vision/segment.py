"""Instance segmentation: the :class:`Detector` protocol and a classical detector for plain tables.

A detector turns an ``HxWx3`` uint8 RGB image into :class:`Detection` s (an ``HxW`` bool mask, and
optionally a category and a score). :class:`ClassicalDetector` needs no weights: it separates the
objects from a plain table by colour, splits touching or overlapping objects along colour edges (a
blue bowl on a white plate), and splits touching objects of one colour where their shape allows (two
touching disks: a neck in the distance transform). A learned detector (Mask R-CNN, SAM) plugs in
through the same protocol: see ``docs/vision.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

from ..scene.scene import SceneError

__all__ = ["Detection", "Detector", "ClassicalDetector", "GroundTruthDetector", "as_detections"]


@dataclass
class Detection:
    """One object instance in an image."""

    mask: np.ndarray  # HxW bool
    category: str | None = None  # a detector that classifies sets it
    score: float = 1.0


@runtime_checkable
class Detector(Protocol):
    """Image (``HxWx3`` uint8 RGB) -> instances. Returning bare ``HxW`` bool masks is accepted too."""

    def detect(self, image: np.ndarray) -> Sequence[Detection | np.ndarray]: ...


def as_detections(items: Sequence[Detection | np.ndarray], shape: tuple[int, int]) -> list[Detection]:
    """Normalise a detector's output to :class:`Detection` s, checking the mask shapes."""
    out = []
    for k, it in enumerate(items):
        det = it if isinstance(it, Detection) else Detection(np.asarray(it))
        mask = np.asarray(det.mask)
        if mask.shape != shape:
            raise SceneError(f"detector: mask {k} has shape {mask.shape}; the image is {shape}")
        det.mask = mask.astype(bool, copy=False)
        out.append(det)
    return out


class GroundTruthDetector:
    """Returns given masks (e.g. the renderer's): measures the later stages without detection errors."""

    def __init__(self, masks: Sequence[np.ndarray]):
        self.masks = [np.asarray(m, bool) for m in masks]

    def detect(self, image: np.ndarray) -> list[Detection]:
        return [Detection(m) for m in self.masks if m.any()]


_NEIGHBOURS = [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]


class ClassicalDetector:
    """Colour-based instance segmentation of objects on a plain table (opencv and numpy, no weights).

    1. The table colour is ``background`` or, when ``None``, the median colour of the image border;
       a pixel farther than ``background_tol`` (RGB distance) from it is an object's.
    2. A colour edge is a step of more than ``edge_tol`` to a neighbouring pixel. The object pixels
       with no edge form connected regions (the seeds); seeds smaller than ``min_seed`` pixels are
       dropped, and an object region with no seed becomes a seed of its own.
    3. The remaining object pixels (edges, thin parts such as a fork's tines) join the adjacent seed of
       the nearest mean colour, growing outwards until none is left; adjacent regions with no colour
       edge between them (the median step across their border is within ``edge_tol``) merge.
    4. With ``split_touching``, a region that is not convex and whose distance transform has two or
       more well-separated peaks (touching disks of one colour) is split between the peaks, each
       pixel going to the peak of the least power distance ``|p - c|^2 - r^2``.
    5. Regions smaller than ``min_area`` pixels are dropped.

    Keep the shades inside one object within ``edge_tol`` of each other and distinct objects that touch
    farther apart than that: sprites are drawn so.
    """

    def __init__(
        self,
        background: Sequence[int] | None = None,
        background_tol: float = 30.0,
        edge_tol: float = 30.0,
        min_seed: int = 12,
        min_area: int = 30,
        split_touching: bool = True,
        split_min_radius: float = 8.0,
    ):
        self.background = None if background is None else np.asarray(background, np.float32)
        self.background_tol = float(background_tol)
        self.edge_tol = float(edge_tol)
        self.min_seed = int(min_seed)
        self.min_area = int(min_area)
        self.split_touching = bool(split_touching)
        self.split_min_radius = float(split_min_radius)

    def background_color(self, image: np.ndarray) -> np.ndarray:
        if self.background is not None:
            return self.background
        border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]]).astype(np.float32)
        return np.median(border, axis=0)

    def detect(self, image: np.ndarray) -> list[Detection]:
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise SceneError(f"detector: expected an HxWx3 uint8 RGB image, got {image.shape} {image.dtype}")
        labels = self.label(image)
        return [Detection(labels == k) for k in range(1, int(labels.max()) + 1) if (labels == k).any()]

    def label(self, image: np.ndarray) -> np.ndarray:
        """An ``HxW`` int32 label image: 0 for the table, ``1..K`` for the instances."""
        img = image.astype(np.float32)
        h, w = img.shape[:2]
        fg = np.linalg.norm(img - self.background_color(image), axis=2) > self.background_tol
        # largest colour step to any of the 8 neighbours
        pad = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode="edge")
        edge = np.zeros((h, w), np.float32)
        for dr, dc in _NEIGHBOURS:
            nb = pad[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
            edge = np.maximum(edge, np.linalg.norm(img - nb, axis=2))
        calm = fg & (edge <= self.edge_tol)
        n, seeds = cv2.connectedComponents(calm.astype(np.uint8), connectivity=4)
        counts = np.bincount(seeds.ravel(), minlength=n)
        small = counts < self.min_seed
        small[0] = True
        seeds[small[seeds]] = 0
        # object regions with no seed at all (a thin pen has no pixel off an edge): seed them whole
        nfg, comp = cv2.connectedComponents(fg.astype(np.uint8), connectivity=8)
        seeded = np.zeros(nfg, bool)
        seeded[np.unique(comp[seeds > 0])] = True
        seeded[0] = True
        orphan = ~seeded[comp]
        seeds[orphan] = comp[orphan] + seeds.max()
        labels = _relabel(seeds)
        labels = self._grow(img, fg, labels)
        labels = self._merge(img, labels)
        if self.split_touching:
            labels = self._split(labels)
        counts = np.bincount(labels.ravel())
        tiny = counts < self.min_area
        tiny[0] = False
        labels[tiny[labels]] = 0
        return _relabel(labels)

    def _grow(self, img: np.ndarray, fg: np.ndarray, labels: np.ndarray) -> np.ndarray:
        """Give every unlabelled object pixel the label of the adjacent region of the nearest mean colour."""
        h, w = labels.shape
        k = int(labels.max())
        if k == 0:
            return labels
        flat = labels.ravel()
        sums = np.zeros((k + 1, 3), np.float64)
        np.add.at(sums, flat, img.reshape(-1, 3))
        means = sums / np.maximum(np.bincount(flat, minlength=k + 1), 1)[:, None]
        rows, cols = np.nonzero(fg & (labels == 0))
        colors = img[rows, cols]
        for _ in range(h + w):
            if rows.size == 0:
                break
            best = np.zeros(rows.size, np.int32)
            best_d = np.full(rows.size, np.inf)
            for dr, dc in _NEIGHBOURS:
                rr, cc = rows + dr, cols + dc
                ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
                nb = np.zeros(rows.size, np.int32)
                nb[ok] = labels[rr[ok], cc[ok]]
                d = np.linalg.norm(colors - means[nb], axis=1)
                better = (nb > 0) & (d < best_d)
                best[better], best_d[better] = nb[better], d[better]
            done = best > 0
            if not done.any():
                break  # what is left touches no region
            labels[rows[done], cols[done]] = best[done]
            rows, cols, colors = rows[~done], cols[~done], colors[~done]
        return labels

    def _merge(self, img: np.ndarray, labels: np.ndarray) -> np.ndarray:
        """Merge adjacent regions with no colour edge between them (a thin part grown from two seeds)."""
        k = int(labels.max())
        if k < 2:
            return labels
        pairs, diffs = [], []
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            a = labels[: labels.shape[0] - dr, max(0, -dc) : labels.shape[1] - max(0, dc)]
            b = labels[dr:, max(0, dc) : labels.shape[1] - max(0, -dc) if dc < 0 else None]
            ia = img[: img.shape[0] - dr, max(0, -dc) : img.shape[1] - max(0, dc)]
            ib = img[dr:, max(0, dc) : img.shape[1] - max(0, -dc) if dc < 0 else None]
            sel = (a > 0) & (b > 0) & (a != b)
            if sel.any():
                lo, hi = np.minimum(a[sel], b[sel]), np.maximum(a[sel], b[sel])
                pairs.append(lo.astype(np.int64) * (k + 1) + hi)
                diffs.append(np.linalg.norm(ia[sel] - ib[sel], axis=1))
        if not pairs:
            return labels
        key, diff = np.concatenate(pairs), np.concatenate(diffs)
        parent = np.arange(k + 1)

        def find(x: int) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for u in np.unique(key):
            if np.median(diff[key == u]) <= self.edge_tol:
                ra, rb = find(int(u // (k + 1))), find(int(u % (k + 1)))
                parent[max(ra, rb)] = min(ra, rb)
        roots = np.array([find(i) for i in range(k + 1)])
        return roots[labels].astype(np.int32)

    def _split(self, labels: np.ndarray) -> np.ndarray:
        out = labels.copy()
        nxt = int(labels.max()) + 1
        for k in range(1, int(labels.max()) + 1):
            region = labels == k
            pts = cv2.findNonZero(region.astype(np.uint8))
            if pts is None or len(pts) < 4 * self.split_min_radius**2:
                continue
            hull = cv2.convexHull(pts)
            if region.sum() / max(cv2.contourArea(hull), 1.0) > 0.93:
                continue  # convex: one object
            r0, c0, hh, ww = _bbox(region)
            sub = np.pad(region[r0 : r0 + hh, c0 : c0 + ww], 1).astype(np.uint8)
            dist = cv2.distanceTransform(sub, cv2.DIST_L2, 5)
            peak_min = max(self.split_min_radius, 0.55 * float(dist.max()))
            peaks = (dist >= peak_min) & (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8)) - 1e-6)
            pr, pc = np.nonzero(peaks)
            if pr.size < 2:
                continue
            # cluster the peak pixels: peaks closer than the larger radius belong to one object
            order = np.argsort(-dist[pr, pc])
            centers: list[tuple[float, float, float]] = []
            for i in order:
                r, c, rad = float(pr[i]), float(pc[i]), float(dist[pr[i], pc[i]])
                if all(np.hypot(r - cr, c - cc) > max(rad, crad) for cr, cc, crad in centers):
                    centers.append((r, c, rad))
            if len(centers) < 2:
                continue
            rr, cc = np.nonzero(sub)
            power = np.stack(
                [(rr - cr) ** 2 + (cc - ccx) ** 2 - crad**2 for cr, ccx, crad in centers], axis=1
            )
            owner = np.argmin(power, axis=1)
            for j in range(1, len(centers)):
                sel = owner == j
                out[rr[sel] - 1 + r0, cc[sel] - 1 + c0] = nxt
                nxt += 1
        return out


def _bbox(mask: np.ndarray) -> tuple[int, int, int, int]:
    rows, cols = np.nonzero(mask)
    return (
        int(rows.min()),
        int(cols.min()),
        int(rows.max() - rows.min() + 1),
        int(cols.max() - cols.min() + 1),
    )


def _relabel(labels: np.ndarray) -> np.ndarray:
    """Consecutive labels 1..K in raster order of first appearance; 0 stays 0."""
    flat = labels.ravel()
    uniq, first = np.unique(flat, return_index=True)
    keep = uniq != 0
    uniq, first = uniq[keep], first[keep]
    order = uniq[np.argsort(first)]
    lut = np.zeros(int(labels.max()) + 1, np.int32)
    lut[order] = np.arange(1, order.size + 1, dtype=np.int32)
    return lut[labels].astype(np.int32)
