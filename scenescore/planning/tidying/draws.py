"""The starting draws of the selection's re-placement chains that are not uniform: a share of them
near where the objects are now, and a share with two objects of the set in each other's places."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from ...runtime.devices import draw
from ...scene.scene import Scene

__all__ = ["NEAR", "near_draws", "exchanges", "pair_rows", "swap_draws"]

#: the spread (length scales; radians for the heading) of the re-placement draws started near an
#: object's current pose (:func:`near_draws`; 0: none)
NEAR = 1.0


def near_draws(x: Tensor, scene: Scene, rows: list[int], length: float, gen: torch.Generator) -> None:
    """In the eighth of the draws ``x (D, N, 3)`` before their last quarter, the objects ``rows`` near
    where they are now: their poses in ``scene`` plus Gaussian noise of :data:`NEAR` length scales
    ``length`` (and radians): an object nudged a little is found by a short chain, not left to uniform
    draws over the whole bounds."""
    if NEAR <= 0 or not rows:
        return
    d = x.shape[0]
    a, z = d - d // 4 - d // 8, d - d // 4
    if z <= a:
        return
    now = torch.as_tensor(scene.poses()[rows], dtype=x.dtype, device=x.device)  # (R, 3)
    noise = draw("randn", (z - a, len(rows), 3), gen, x.device, x.dtype)
    noise[..., :2] *= NEAR * length
    noise[..., 2] *= NEAR
    x[a:z, rows] = now + noise


def exchanges(x: np.ndarray, pairs: Sequence[tuple[int, int]]) -> np.ndarray:
    """The poses ``x (N, 3)`` with each pair of rows ``pairs`` exchanged, two ways: ``(2P, N, 3)``, first
    each object at the other's pose, then (rows ``P..2P``) at the other's position with its own heading."""
    x = np.asarray(x, dtype=float)
    out = np.repeat(x[None], 2 * len(pairs), axis=0)
    for j, (a, b) in enumerate(pairs):
        out[j, a], out[j, b] = x[b], x[a]
        out[len(pairs) + j, a, :2], out[len(pairs) + j, b, :2] = x[b, :2], x[a, :2]
    return out


def pair_rows(scene: Scene, names: Sequence[str]) -> list[tuple[int, int]]:
    """Rows of every pair of the objects ``names`` of ``scene``."""
    rows = [scene.index(m) for m in names]
    return [(a, b) for i, a in enumerate(rows) for b in rows[i + 1 :]]


def swap_draws(x: Tensor, scene: Scene, names: list[str]) -> None:
    """In the last quarter of the draws ``x (D, N, 3)``, each pair of the set ``names`` in turn trades
    places (:func:`exchanges`: with the other's heading, and in every other round with its own), the
    set's other objects as drawn: two objects in each other's places are found at once, not left to
    uniform draws."""
    pairs = pair_rows(scene, names)
    if not pairs:
        return
    swapped = torch.as_tensor(exchanges(scene.poses(), pairs), dtype=x.dtype, device=x.device)  # (2P, N, 3)
    p, start = len(pairs), x.shape[0] - x.shape[0] // 4
    k = torch.arange(x.shape[0] - start, device=x.device)  # the last quarter's draws: k // p is the round
    # each draw's row of ``swapped``: its pair, in every other round with its own heading
    src = k % p + p * ((k // p) % 2)
    for i, (a, b) in enumerate(pairs):
        mine = k[k % p == i]  # (M,)
        rows = torch.tensor([a, b], device=x.device)
        x[start + mine[:, None], rows] = swapped[src[mine]][:, rows]
