"""The real-world demo as a measurement: the energy over the mug's position, book and pen fixed.

Train SceneScore on desk scenes (book, pen, mug; the farther the pen, the farther the mug). For three
pen distances, evaluate the energy on a grid of mug positions (the mug is a disk: its heading is
irrelevant), draw it as a heatmap, and find its minimum. Quantified: the error, in cm, between the
book-to-minimum distance and the true relation's; then with a pencil (never trained on) in the pen's
place, the distance in cm between the pencil's minimum and the pen's (the issue asks <= 3 cm).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..models import ScoreModel
from ..scenarios import DeskScenario
from ..scene import Scene
from ..training import TrainConfig, train
from .report import Row, format_table

__all__ = ["energy_grid", "run", "HeatmapResult", "format_heatmap", "PEN_DISTANCES", "draw_heatmap"]

PEN_DISTANCES = (0.14, 0.21, 0.28)
BOOK = (0.0, 0.0, 0.0)


def energy_grid(
    model: ScoreModel, scene: Scene, name: str, resolution: float = 0.01, theta: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Energy with ``name`` at every grid point of the scene's bounds (heading 0), the rest as they are.
    ``theta``: the object's heading. Returns ``(xs, ys, E)`` with ``E[j, i]`` at ``(xs[i], ys[j])``."""
    (x0, y0), (x1, y1) = scene.bounds
    xs = np.arange(x0 + resolution / 2, x1, resolution)
    ys = np.arange(y0 + resolution / 2, y1, resolution)
    gx, gy = np.meshgrid(xs, ys)
    base = scene.poses()  # a null pose (the moving object's) is filled, then overwritten
    k = scene.index(name)
    poses = np.repeat(base[None], gx.size, axis=0)
    poses[:, k, 0], poses[:, k, 1], poses[:, k, 2] = gx.ravel(), gy.ravel(), theta
    fn = model.energy_fn(scene.with_poses(base))
    out = []
    with torch.no_grad():
        for chunk in range(0, len(poses), 4096):
            x = torch.as_tensor(poses[chunk : chunk + 4096], dtype=model.dtype)
            out.append(fn(x).double().numpy())
    return xs, ys, np.concatenate(out).reshape(gx.shape)


def grid_minimum(xs: np.ndarray, ys: np.ndarray, e: np.ndarray) -> tuple[float, float]:
    j, i = np.unravel_index(int(np.argmin(e)), e.shape)
    return float(xs[i]), float(ys[j])


def draw_heatmap(
    scene: Scene, name: str, xs, ys, e, minimum, path: str | Path, title: str = "", truth=None
) -> None:
    """The energy grid ``e`` under the scene, ``name`` drawn at the grid's ``minimum``; ``truth`` marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import draw_scene, save_figure

    fig, ax = plt.subplots(figsize=(6, 4.4))
    im = ax.imshow(
        e,
        origin="lower",
        extent=(xs[0], xs[-1], ys[0], ys[-1]),
        cmap="viridis_r",
        vmax=float(np.percentile(e, 60)),
        alpha=0.9,
    )
    draw_scene(ax, scene.with_poses([[minimum[0], minimum[1], 0.0]], [name]), highlight=[name])
    ax.plot(*minimum, "r+", ms=14, mew=2, label="energy minimum")
    if truth is not None:
        ax.plot(*truth, "wx", ms=10, mew=2, label="true relation")
    ax.legend(loc="lower right", fontsize=7)
    fig.colorbar(im, ax=ax, label="energy (clipped)")
    ax.set_title(title, fontsize=9)
    save_figure(fig, path)


@dataclass
class HeatmapResult:
    per_seed: list[dict[str, float]] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def rows(self) -> list[Row]:
        rows = []
        for tool in ("pen", "pencil"):
            fig: dict[str, float] = {}
            for key in self.per_seed[0]:
                if key.startswith(f"{tool}_"):
                    short = key[len(tool) + 1 :]
                    fig[short] = float(np.mean([r[key] for r in self.per_seed]))
                    fig[f"{short}_std"] = float(np.std([r[key] for r in self.per_seed]))
            fig["seconds"] = self.seconds
            rows.append(Row(f"SceneScore, {tool}", fig))
        return rows


def run(
    seeds: int = 1,
    quick: bool = False,
    progress: bool = True,
    out: str | Path | None = None,
    log: Callable[[str], None] = print,
    resolution: float = 0.01,
    n_train: int | None = None,
    iterations: int | None = None,
) -> HeatmapResult:
    """Train on desk scenes per seed, measure the minima; PNGs (seed 0) under ``out`` when given."""
    sc = DeskScenario()
    res = HeatmapResult()
    t0 = time.perf_counter()
    for seed in range(seeds):
        train_s, _ = sc.split(seed)
        if n_train is not None:
            train_s = train_s[:n_train]
        tc = TrainConfig(iterations=iterations or (60 if quick else TrainConfig().iterations))
        model = train(train_s, tc, seed=seed, progress=progress)
        figs: dict[str, float] = {}
        minima: dict[tuple[str, float], tuple[float, float]] = {}
        for tool in ("pen", "pencil"):
            errs = []
            for d in PEN_DISTANCES:
                scene = sc.arrange(BOOK, d, pen=tool)
                xs, ys, e = energy_grid(model, scene, "mug", resolution)
                mn = grid_minimum(xs, ys, e)
                minima[(tool, d)] = mn
                found = math.hypot(mn[0] - BOOK[0], mn[1] - BOOK[1])
                truth = sc.mug_distance(d)
                figs[f"{tool}_mug_distance_cm_at_{round(d * 100)}cm"] = 100 * found
                errs.append(100 * abs(found - truth))
                if out is not None and seed == 0:
                    path = Path(out) / f"heatmap_{tool}_{round(d * 100)}cm.png"
                    true_xy = (BOOK[0] - truth, BOOK[1])
                    title = f"energy over the mug's position; {tool} {d * 100:.0f} cm from the book"
                    draw_heatmap(scene, "mug", xs, ys, e, mn, path, title, truth=true_xy)
                    res.figures.append(str(path))
            figs[f"{tool}_relation_error_cm"] = float(np.mean(errs))
        shift = [100 * math.dist(minima[("pen", d)], minima[("pencil", d)]) for d in PEN_DISTANCES]
        figs["pencil_from_pen_minimum_cm"] = float(np.mean(shift))
        figs["pencil_from_pen_minimum_max_cm"] = float(np.max(shift))
        res.per_seed.append(figs)
        log(
            f"seed {seed}: relation error pen {figs['pen_relation_error_cm']:.2f} cm, pencil "
            f"{figs['pencil_relation_error_cm']:.2f} cm; pencil minimum {figs['pencil_from_pen_minimum_cm']:.2f} cm "
            "from the pen's"
        )
    res.seconds = time.perf_counter() - t0
    return res


def format_heatmap(res: HeatmapResult) -> str:
    cols = [(f"mug_distance_cm_at_{round(d * 100)}cm", f"mug at pen {d * 100:.0f} cm") for d in PEN_DISTANCES]
    cols += [("relation_error_cm", "relation error (cm)"), ("from_pen_minimum_cm", "min. from pen's (cm)")]
    cols += [("from_pen_minimum_max_cm", "worst (cm)")]
    sc = DeskScenario()
    md = "## Cost heatmap: the mug's position, book and pen (or pencil) fixed\n\n"
    md += "True book-to-mug distance: " + ", ".join(
        f"{sc.mug_distance(d) * 100:.0f} cm at pen {d * 100:.0f} cm" for d in PEN_DISTANCES
    )
    md += (
        f"; the grid's minimum's distance per pen distance, its mean error against the relation, and "
        f"(pencil) the minimum's distance from the pen's; mean ± std over {len(res.per_seed)} seed(s).\n\n"
    )
    md += format_table(res.rows(), cols, std={k: f"{k}_std" for k, _ in cols})
    if res.figures:
        md += "\n\nFigures: " + ", ".join(res.figures)
    return md
