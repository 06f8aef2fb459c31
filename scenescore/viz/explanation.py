"""The figure of an explanation: the object, and its relations as edges as wide as their parts."""

from __future__ import annotations

import math
import os

from ..models.explain import Explanation
from ..scene.scene import Scene
from .plot import draw_scene, legend, save_figure

__all__ = ["plot_explanation"]

HOLD_COLOR = "tab:green"  # a neighbour whose part holds the object where it is
PUSH_COLOR = "tab:purple"  # a neighbour whose part pushes it off
MAX_WIDTH = 6.0  # points: the widest edge, the largest part's
LABEL_AT = 0.6  # how far along its edge, from the explained object, a part's label stands


def plot_explanation(scene: Scene, explanation: Explanation, path: str | os.PathLike) -> None:
    """``scene`` with the explained object outlined and an edge to each listed neighbour, its width the
    neighbour's part in the object's well (energy units), which its label gives; green holds, purple
    pushes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(5.4, 5.8))
    roles = draw_scene(ax, scene, [explanation.name], names="all")
    x, y, _ = explanation.pose
    top = max((abs(r.part) for r in explanation.relations), default=0.0)
    rim = 0.5 * min(scene[explanation.name].size)
    for r in explanation.relations:
        if top <= 0 or abs(r.part) < 0.02 * top:
            continue
        nx, ny, _ = scene[r.neighbour].pose or (0.0, 0.0, 0.0)
        # from the explained object's rim, so that its outline and name stay in sight
        d = max(math.hypot(nx - x, ny - y), 1e-12)
        sx, sy = x + rim * (nx - x) / d, y + rim * (ny - y) / d
        color = HOLD_COLOR if r.part > 0 else PUSH_COLOR
        ax.plot([sx, nx], [sy, ny], color=color, lw=MAX_WIDTH * abs(r.part) / top, alpha=0.6, zorder=2.5)
        ax.annotate(
            f"{r.part:+.2g}",
            (sx + LABEL_AT * (nx - sx), sy + LABEL_AT * (ny - sy)),
            fontsize=6.5,
            ha="center",
            va="center",
            color=color,
            zorder=6,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8},
        )
    extra = [
        Line2D([], [], color=HOLD_COLOR, lw=3, label="holds it (its part of the well)"),
        Line2D([], [], color=PUSH_COLOR, lw=3, label="pushes it off"),
    ]
    legend(ax, roles, extra, moved="explained")
    ax.set_title(
        f"what holds {explanation.name} where it is (well depth {explanation.depth:.3g})", fontsize=9
    )
    save_figure(fig, path)
