"""The learned energy over one object's position, the rest fixed: a grid and its minimum."""

from __future__ import annotations

import numpy as np
import torch

from ..errors import ConfigError, check_number
from ..models import ScoreModel
from ..runtime.memory import check as check_memory
from ..scene.scene import Scene

__all__ = ["energy_grid", "grid_minimum", "MAX_CELLS"]

MAX_CELLS = 4_000_000  # grid points of one heatmap (2000 x 2000)
CHUNK = 4096  # grid points whose poses are built and evaluated at once (the network chunks further)


def energy_grid(
    model: ScoreModel, scene: Scene, name: str, resolution: float = 0.01, theta: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Energy with ``name`` at every grid point of the scene's bounds (heading 0), the rest as they are.
    ``theta``: the object's heading. Returns ``(xs, ys, E)`` with ``E[j, i]`` at ``(xs[i], ys[j])``."""
    (x0, y0), (x1, y1) = scene.bounds
    check_number("heatmap", "resolution", resolution, 0, open_lo=True)
    cells = ((x1 - x0) / resolution) * ((y1 - y0) / resolution)
    if cells > MAX_CELLS:
        raise ConfigError(
            f"heatmap: resolution {resolution:g} m gives {cells:.3g} grid cells over the bounds "
            f"{scene.bounds}; at most {MAX_CELLS:,} (a coarser resolution)"
        )
    # float64 per grid point: the meshgrid's x and y, their flat copies, the energies (and the image drawn
    # from them); the poses are built a chunk at a time
    check_memory(
        8 * 8 * cells + 8 * 3 * CHUNK * len(scene),
        f"heatmap: resolution {resolution:g} m gives {cells:.3g} grid cells over the bounds {scene.bounds}",
        "the resolution (a larger --resolution, fewer cells)",
    )
    xs = np.arange(x0 + resolution / 2, x1, resolution)
    ys = np.arange(y0 + resolution / 2, y1, resolution)
    gx, gy = np.meshgrid(xs, ys)
    fx, fy = gx.ravel(), gy.ravel()
    base = scene.poses()  # a null pose (the moving object's) is filled, then overwritten
    k = scene.index(name)
    fn = model.energy_fn(scene.with_poses(base))
    out = []
    with torch.no_grad():
        for a in range(0, fx.size, CHUNK):
            poses = np.repeat(base[None], len(fx[a : a + CHUNK]), axis=0)
            poses[:, k, 0], poses[:, k, 1], poses[:, k, 2] = fx[a : a + CHUNK], fy[a : a + CHUNK], theta
            x = torch.as_tensor(poses, dtype=model.dtype, device=model.device)
            out.append(fn(x).double().cpu().numpy())
    return xs, ys, np.concatenate(out).reshape(gx.shape)


def grid_minimum(xs: np.ndarray, ys: np.ndarray, e: np.ndarray) -> tuple[float, float]:
    """The grid point of lowest energy ``(x, y)``."""
    j, i = np.unravel_index(int(np.argmin(e)), e.shape)
    return float(xs[i]), float(ys[j])
