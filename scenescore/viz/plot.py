"""All drawing: scenes (footprints in their colours, an arrow for each heading), the demo figure, heatmaps."""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..evaluation.cases import case_errors
from ..scene.outputs import atomic_write_bytes
from ..scene.scene import Scene

__all__ = [
    "plot_scene",
    "plot_result",
    "plot_tidy",
    "draw_moves",
    "save_figure",
    "draw_scene",
    "legend",
    "legend_handles",
    "demo_figure",
    "draw_heatmap",
    "training_figure",
]


def save_figure(fig, path: str | os.PathLike, dpi: int = 120) -> None:
    """Save a matplotlib figure as PNG, atomically, and close it."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


# one style for every figure: what each kind of thing looks like, and its legend entry
BOUNDS_FACE = "#c8a77e"
MOVED_EDGE = "red"
TRUTH_STYLE = {"fill": False, "ls": "--", "ec": "k", "lw": 1.0}
BEFORE_STYLE = {"fill": False, "ls": "--", "ec": "0.4", "lw": 1.0}
BUFFER_STYLE = {"fill": False, "ls": ":", "ec": "tab:orange", "lw": 1.2}
MOVE_COLOR = "tab:red"
REACH_STYLE = {"fill": False, "ls": ":", "ec": "tab:blue", "lw": 1.2}
CLUTTER_FACE = "#9a9a9a"
LEGEND: dict[str, tuple[str, dict[str, Any]]] = {
    # role -> (label, matplotlib Patch keywords)
    "moved": ("placed", {"facecolor": "white", "edgecolor": MOVED_EDGE, "lw": 2.0}),
    "truth": ("truth", {"facecolor": "none", "edgecolor": "k", "ls": "--"}),
    "before": ("current pose", {"facecolor": "none", "edgecolor": "0.4", "ls": "--"}),
    "buffer": ("buffer pose", {"facecolor": "none", "edgecolor": "tab:orange", "ls": ":"}),
    "fixed": ("fixed", {"facecolor": "white", "edgecolor": "k", "hatch": "///"}),
    "clutter": ("clutter", {"facecolor": CLUTTER_FACE, "edgecolor": "k", "hatch": "xx"}),
    "bounds": ("bounds", {"facecolor": BOUNDS_FACE, "alpha": 0.35, "edgecolor": "none"}),
    "reach": ("reach", {"facecolor": "none", "edgecolor": "tab:blue", "ls": ":"}),
}


def draw_scene(
    ax,
    scene: Scene,
    highlight: Sequence[str] = (),
    ghosts: Scene | None = None,
    reach: Sequence[tuple[tuple[float, float], float]] = (),
    names: str = "highlight",
    ghost_role: str = "truth",
) -> list[str]:
    """Draw ``scene`` on a matplotlib axis in metres; returns the legend roles drawn (see :func:`legend`).

    ``highlight``: the moved objects, outlined in red and named; ``ghosts``: a scene whose poses of the
    highlighted objects are drawn dashed (``ghost_role``: ``"truth"``, or ``"before"``: the current
    poses of a tidy); ``reach``: ``((x, y), radius)`` circles; ``names``: ``"highlight"`` names the
    highlighted objects, ``"all"`` every object.
    """
    from matplotlib.patches import Circle, Polygon, Rectangle

    roles = ["bounds"]
    (x0, y0), (x1, y1) = scene.bounds
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=BOUNDS_FACE, edgecolor="none", alpha=0.35))
    if ghosts is not None:
        style = BEFORE_STYLE if ghost_role == "before" else TRUTH_STYLE
        for o in ghosts.objects:
            if o.name in highlight and o.pose is not None:
                ax.add_patch(Polygon(o.world_polygon(), closed=True, **style))
                roles.append(ghost_role)
    for o in scene.objects:
        if o.pose is None:
            continue
        hl = o.name in highlight
        clutter = o.category == "clutter"
        roles += ["moved"] * hl + ["fixed"] * bool(o.fixed) + ["clutter"] * clutter
        ax.add_patch(
            Polygon(
                o.world_polygon(),
                closed=True,
                facecolor=CLUTTER_FACE if clutter else np.array(o.color) / 255,
                edgecolor=MOVED_EDGE if hl else "k",
                lw=2.0 if hl else 0.6,
                alpha=0.95,
                hatch="///" if o.fixed else ("xx" if clutter else None),
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
        if hl or names == "all":
            # above the object; below it where the label would leave the bounds' top edge
            (_, y_lo), (_, y_hi) = scene.bounds
            below = y + 0.5 * max(o.size) + 0.05 * (y_hi - y_lo) > y_hi
            lift = 0.5 * max(o.size) * _points_per_metre(ax, scene) + 2
            ax.annotate(
                o.name,
                (x, y),
                xytext=(0, -lift if below else lift),
                textcoords="offset points",
                fontsize=6.5,
                ha="center",
                va="top" if below else "bottom",
                color="darkred" if hl else "0.2",
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
            )
    for (cx, cy), radius in reach:
        ax.add_patch(Circle((cx, cy), radius, **REACH_STYLE))
        ax.plot(cx, cy, marker="+", color="tab:blue", ms=6)
        roles.append("reach")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return list(dict.fromkeys(roles))


def _points_per_metre(ax, scene: Scene) -> float:
    """Roughly how many typographic points one metre of the scene spans on ``ax`` (for label offsets)."""
    (x0, _), (x1, _) = scene.bounds
    width_in = ax.get_position().width * ax.figure.get_figwidth()
    return 72.0 * width_in / max(x1 - x0, 1e-12)


def legend_handles(roles: Sequence[str], moved: str = "placed") -> list[Any]:
    """Legend proxies for ``roles`` (keys of :data:`LEGEND`), in its order; ``moved`` labels the
    highlighted objects ("placed", "moved", ...)."""
    from matplotlib.patches import Patch

    out = []
    for role, (label, kw) in LEGEND.items():
        if role in roles:
            out.append(Patch(label=moved if role == "moved" else label, **kw))
    return out


def legend(target, roles: Sequence[str], extra: Sequence[Any] = (), moved: str = "placed") -> None:
    """One legend row below an axis (or a figure, for grids of scenes), outside what it explains."""
    handles = legend_handles(roles, moved) + list(extra)
    if not handles:
        return
    kw = {"fontsize": 7, "frameon": False, "ncol": min(len(handles), 4), "handlelength": 1.6}
    if hasattr(target, "add_subplot"):  # a figure
        target.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0), **kw)
    else:
        target.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.13), **kw)


def plot_scene(
    scene: Scene,
    path: str | os.PathLike,
    highlight: Sequence[str] = (),
    title: str = "",
    ghosts: Scene | None = None,
    reach: Sequence[tuple[tuple[float, float], float]] = (),
    names: str = "highlight",
    moved: str = "placed",
) -> None:
    """One scene to a PNG, with its legend (see :func:`draw_scene` for the options)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 5.4))
    roles = draw_scene(ax, scene, highlight, ghosts, reach, names)
    legend(ax, roles, moved=moved)
    if title:
        ax.set_title(title, fontsize=9)
    save_figure(fig, path)


def plot_result(result: Any, path: str | os.PathLike) -> None:
    """A solver's :class:`~scenescore.solvers.result.Result`: its scene, the moving objects outlined,
    every object named, each reach limit's circle, the status and objective in the title."""
    from ..costs.reach import ReachLimit

    problem = result.problem
    moving = problem.movable if problem is not None else []
    reach = []
    if problem is not None:
        reach = [(c.base, c.radius) for _, c in problem.cost if isinstance(c, ReachLimit)]
    title = f"{result.solver}: {result.status}, objective {result.objective:.4g}"
    if not result.feasible and result.violated:
        title += f"\nviolated: {result.violated}"
    plot_scene(result.scene, path, moving, title, reach=reach, names="all", moved="moved")


def draw_moves(ax, before: Scene, steps: Sequence[Any]) -> list[str]:
    """Each pick-and-place of a plan (``object``, ``start``, ``goal``, ``buffer``) as an arrow from
    where the object is to where it goes, numbered in order; buffer poses drawn dotted. Returns roles."""
    from matplotlib.patches import Polygon

    roles: list[str] = []
    for k, s in enumerate(steps, start=1):
        if s.start is None:
            continue
        (x0, y0), (x1, y1) = s.start[:2], s.goal[:2]
        ax.annotate(
            "",
            xy=(x1, y1),
            xytext=(x0, y0),
            arrowprops={
                "arrowstyle": "-|>",
                "color": "tab:orange" if s.buffer else MOVE_COLOR,
                "lw": 1.4,
                "ls": ":" if s.buffer else "-",
                "shrinkA": 0,
                "shrinkB": 0,
            },
        )
        ax.annotate(
            str(k),
            ((x0 + x1) / 2, (y0 + y1) / 2),
            fontsize=7,
            ha="center",
            va="center",
            color="white",
            bbox={"boxstyle": "circle,pad=0.2", "fc": "tab:orange" if s.buffer else MOVE_COLOR, "ec": "none"},
        )
        if s.buffer:
            ax.add_patch(Polygon(before[s.name].world_polygon(s.goal), closed=True, **BUFFER_STYLE))
            roles.append("buffer")
    return roles


def plot_tidy(
    result: Any, path: str | os.PathLike, reach: Sequence[tuple[tuple[float, float], float]] = ()
) -> None:
    """A :class:`~scenescore.planning.tidying.TidyResult`: the tidy scene, moved objects outlined and named, their
    current poses dashed, and numbered arrows for the plan's pick-and-places (buffer moves dotted)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(5, 5.6))
    roles = draw_scene(ax, result.after, result.moved, ghosts=result.before, reach=reach, ghost_role="before")
    roles += draw_moves(ax, result.before, result.steps)
    extra = [Line2D([], [], color=MOVE_COLOR, lw=1.4, marker=">", ms=4, label="move (step number)")]
    legend(ax, list(dict.fromkeys(roles)), extra, moved="moved, at its target")
    moved = len(result.moved)
    title = (
        f"tidy (effort {result.effort:g}): {moved} object{'s' * (moved != 1)} moved, "
        f"{result.total_displacement:.2f} m in all, {len(result.steps)} step{'s' * (len(result.steps) != 1)}"
    )
    if result.buffers:
        title += f" ({result.buffers} via a buffer)"
    if not result.check.valid:
        title += "\nplan not valid: " + result.check.describe()[:80]
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
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 4 * rows + 0.6), squeeze=False)
    for ax in axes.flat[n:]:
        ax.remove()
    roles: list[str] = []
    for ax, (case, pred) in zip(axes.flat, cases):
        truth = pred.with_poses([case.truth], [case.name])
        roles += draw_scene(ax, pred, highlight=[case.name], ghosts=truth)
        ax.set_title(f"{case.name}: error {_error_cm(case, pred):.1f} cm", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.5 / (4 * rows + 0.6), 1, 1))
    legend(fig, list(dict.fromkeys(roles)))
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
    truth_label: str = "true position",
) -> None:
    """The energy grid ``e`` under the scene, ``name`` drawn at the grid's ``minimum``; ``truth`` marked
    (labelled ``truth_label``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    fig, ax = plt.subplots(figsize=(6, 5.2))
    im = ax.imshow(
        e,
        origin="lower",
        extent=(xs[0], xs[-1], ys[0], ys[-1]),
        cmap="viridis_r",
        vmax=float(np.percentile(e, 60)),
        alpha=0.9,
    )
    roles = draw_scene(ax, scene.with_poses([[minimum[0], minimum[1], 0.0]], [name]), highlight=[name])
    ax.plot(*minimum, "r+", ms=14, mew=2)
    extra = [Line2D([], [], color="r", marker="+", ms=9, mew=2, ls="none", label="energy minimum")]
    if truth is not None:
        ax.plot(*truth, "wx", ms=10, mew=2.5)
        ax.plot(*truth, "kx", ms=8, mew=1)
        extra.append(Line2D([], [], color="k", marker="x", ms=7, ls="none", label=truth_label))
    cax = make_axes_locatable(ax).append_axes("right", size="4%", pad=0.08)  # as tall as the map
    fig.colorbar(im, cax=cax, label="energy (clipped at the 60th percentile)")
    legend(ax, roles, extra, moved=f"{name} at the minimum")
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
    roles: list[str] = []
    for ax, (case, pred) in zip(axes[0, 1:], shown):
        truth = pred.with_poses([case.truth], [case.name])
        roles += draw_scene(ax, pred, highlight=[case.name], ghosts=truth)
        err = _error_cm(case, pred)
        flags = pred.meta.get("placement", {}).get(case.name, {}).get("flags")
        ax.set_title(f"held out: {case.name}, {err:.1f} cm off" + (" (flagged)" if flags else ""), fontsize=9)
    fig.tight_layout(rect=(0, 0.08 if shown else 0, 1, 1))
    if shown:
        legend(fig, list(dict.fromkeys(roles)))
    save_figure(fig, path)
