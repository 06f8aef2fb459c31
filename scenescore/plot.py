"""All drawing: scenes (footprints in their colours, an arrow for each heading), the demo figure, heatmaps."""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from .evaluation import case_errors
from .scene import Scene, atomic_write_bytes

__all__ = ["plot_scene", "save_figure", "draw_scene", "demo_figure", "draw_heatmap", "training_figure"]


def save_figure(fig, path: str | os.PathLike, dpi: int = 120) -> None:
    """Save a matplotlib figure as PNG, atomically, and close it."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def draw_scene(ax, scene: Scene, highlight: Sequence[str] = (), ghosts: Scene | None = None) -> None:
    """Draw ``scene`` on a matplotlib axis; ``highlight`` names get a red outline; ``ghosts``: true poses dashed."""
    from matplotlib.patches import Polygon, Rectangle

    (x0, y0), (x1, y1) = scene.bounds
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="#c8a77e", edgecolor="none", alpha=0.35))
    if ghosts is not None:
        for o in ghosts.objects:
            if o.name in highlight and o.pose is not None:
                ax.add_patch(Polygon(o.world_polygon(), closed=True, fill=False, ls="--", ec="k", lw=1))
    for o in scene.objects:
        if o.pose is None:
            continue
        hl = o.name in highlight
        poly = o.world_polygon()
        ax.add_patch(
            Polygon(
                poly,
                closed=True,
                facecolor=np.array(o.color) / 255,
                edgecolor="red" if hl else "k",
                lw=2.0 if hl else 0.6,
                alpha=0.95,
                hatch="///" if o.fixed else None,
            )
        )
        x, y, t = o.pose
        r = 0.35 * max(o.size)
        if o.shape_kind != "disk":
            ax.annotate(
                "",
                xy=(x + r * np.cos(t), y + r * np.sin(t)),
                xytext=(x, y),
                arrowprops={"arrowstyle": "->", "color": "k", "lw": 0.8},
            )
        if hl:
            ax.text(x, y, o.name, fontsize=7, ha="center", va="bottom", color="darkred")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def plot_scene(
    scene: Scene,
    path: str | os.PathLike,
    highlight: Sequence[str] = (),
    title: str = "",
    ghosts: Scene | None = None,
) -> None:
    """One scene to a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 5))
    draw_scene(ax, scene, highlight, ghosts)
    if title:
        ax.set_title(title, fontsize=9)
    save_figure(fig, path)


def _error_cm(case: Any, pred: Scene) -> float:
    """How far ``pred`` placed the case's object from its true position, in cm."""
    pose = pred[case.name].pose
    if pose is None:
        raise ValueError(f"{case.name!r} was not placed")
    return case_errors(case, pose, True)[0]


def demo_figure(
    cases: Sequence[tuple[Any, Scene]],
    path: str | os.PathLike,
    title: str = "SceneScore: missing objects placed by Langevin on the learned energy (truth dashed)",
) -> None:
    """A grid of placed scenes: each ``(case, predicted scene)`` with the true pose dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(cases)
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 4 * rows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.axis("off")
    for ax, (case, pred) in zip(axes.flat, cases):
        truth = pred.with_poses([case.truth], [case.name])
        draw_scene(ax, pred, highlight=[case.name], ghosts=truth)
        ax.set_title(f"{case.name}: error {_error_cm(case, pred):.1f} cm", fontsize=9)
    fig.suptitle(title)
    save_figure(fig, path)


def draw_heatmap(
    scene: Scene,
    name: str,
    xs: np.ndarray,
    ys: np.ndarray,
    e: np.ndarray,
    minimum: tuple[float, float],
    path: str | os.PathLike,
    title: str = "",
    truth: tuple[float, float] | None = None,
) -> None:
    """The energy grid ``e`` under the scene, ``name`` drawn at the grid's ``minimum``; ``truth`` marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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


def training_figure(
    history: Sequence[float], chance: float, examples: Sequence[tuple[Any, Scene]], path: str | os.PathLike
) -> None:
    """The learning curve (mean InfoNCE loss per 10 iterations, chance dashed) beside up to three
    held-out placements (placed object outlined in red, truth dashed, flagged ones named so)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = list(examples)[:3]
    fig, axes = plt.subplots(1, 1 + len(shown), figsize=(4.2 * (1 + len(shown)), 4), squeeze=False)
    ax = axes[0, 0]
    its = 10 * np.arange(len(history)) + 5
    ax.plot(its, history, color="C0", label="training loss")
    ax.axhline(chance, color="grey", ls="--", label=f"chance ({chance:.2f})")
    ax.set_xlabel("iteration")
    ax.set_ylabel("InfoNCE loss")
    ax.set_title("learning curve", fontsize=9)
    ax.legend(fontsize=7)
    for ax, (case, pred) in zip(axes[0, 1:], shown):
        truth = pred.with_poses([case.truth], [case.name])
        draw_scene(ax, pred, highlight=[case.name], ghosts=truth)
        err = _error_cm(case, pred)
        flags = pred.meta.get("placement", {}).get(case.name, {}).get("flags")
        ax.set_title(f"held out: {case.name}, {err:.1f} cm off" + (" (flagged)" if flags else ""), fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)
