"""The real-world demo as a measurement: the energy over the mug's position, book and pen fixed.

Train SceneScore on desk scenes (book, pen, mug; the farther the pen, the farther the mug). For three
pen distances, evaluate the energy on a grid of mug positions (the mug is a disk: its heading is
irrelevant), draw it as a heatmap, and find its minimum. Quantified: the error, in cm, between the
book-to-minimum distance and the true relation's; then with a pencil (never trained on) in the pen's
place, the distance in cm between the pencil's minimum and the pen's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..planning.heatmap import energy_grid, grid_minimum
from ..scenarios import DeskScenario
from ..viz.plot import draw_heatmap
from .execution import Execution
from .report import Row, format_table, over_seeds
from .tasks import Task, run_tasks

__all__ = ["run", "HeatmapResult", "format_heatmap", "PEN_DISTANCES"]

PEN_DISTANCES = (0.14, 0.21, 0.28)
BOOK = (0.0, 0.0, 0.0)


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
                    if len(self.per_seed) > 1:  # no spread from one seed
                        fig[f"{short}_std"] = float(np.std([r[key] for r in self.per_seed]))
            fig["seconds"] = self.seconds
            rows.append(Row(f"SceneScore, {tool}", fig))
        return rows


def run(
    seeds: int = 1,
    quick: bool = False,
    out: str | Path | None = None,
    resolution: float = 0.01,
    n_train: int | None = None,
    iterations: int | None = None,
    *,
    execution: Execution | None = None,
) -> HeatmapResult:
    """Train on desk scenes per seed, measure the minima; PNGs (seed 0) under ``out`` when given. Each
    seed is a task; ``seconds`` sums the tasks'. ``execution``: where and how (default
    :class:`Execution`'s): the models train on its ``device``, with its model ``cache``; ``jobs``:
    worker processes; its ``sweep`` keeps each seed's record, to resume from, and runs it
    (:mod:`scenescore.experiments.tasks`)."""
    ex = execution or Execution()
    config = {
        "quick": quick,
        "resolution": resolution,
        "n_train": n_train,
        "iterations": iterations or (60 if quick else TrainConfig().iterations),
        "device": str(ex.device),
        "out": None if out is None else str(out),
    }  # every setting a seed's record depends on
    progress = ex.progress and ex.jobs == 1
    one = partial(_seed, config=config, progress=progress, device=ex.device, cache=ex.cache)
    tasks = [Task.of("heatmap", seed=seed, config=config) for seed in range(seeds)]
    res = HeatmapResult()
    bar = "heatmap seeds" if ex.progress else None
    for record in run_tasks(one, tasks, ex.jobs, ex.log, bar, ex.sweep):
        res.per_seed.append(record["figures"])
        res.figures += record["files"]
        res.seconds += record["seconds"]
    return res


def _seed(
    task: Task, log: Callable[[str], None], config: dict[str, Any], progress: bool, device: Any, cache: Any
) -> dict[str, Any]:
    """One seed: train, find the minima over the grid, draw them (seed 0, under ``config["out"]``); its
    figures, the files drawn and the seconds taken."""
    t0 = time.perf_counter()
    sc = DeskScenario()
    seed = task.seed
    train_s, _ = sc.split(seed)
    if config["n_train"] is not None:
        train_s = train_s[: config["n_train"]]
    tc = TrainConfig(iterations=config["iterations"], **ONE_NETWORK)
    model = fit(train_s, tc, seed=seed, progress=progress, device=device, run=Run(cache=cache))
    figs: dict[str, float] = {}
    files: list[str] = []
    minima: dict[tuple[str, float], tuple[float, float]] = {}
    for tool in ("pen", "pencil"):
        errs = []
        for d in PEN_DISTANCES:
            scene = sc.arrange(BOOK, d, pen=tool)
            xs, ys, e = energy_grid(model, scene, "mug", config["resolution"])
            mn = grid_minimum(xs, ys, e)
            minima[(tool, d)] = mn
            found = math.hypot(mn[0] - BOOK[0], mn[1] - BOOK[1])
            truth = sc.mug_distance(d)
            figs[f"{tool}_mug_distance_cm_at_{round(d * 100)}cm"] = 100 * found
            errs.append(100 * abs(found - truth))
            if config["out"] is not None and seed == 0:
                path = Path(config["out"]) / f"heatmap_{tool}_{round(d * 100)}cm.png"
                true_xy = (BOOK[0] - truth, BOOK[1])
                title = f"energy over the mug's position; {tool} {d * 100:.0f} cm from the book"
                draw_heatmap(scene, "mug", xs, ys, e, mn, path, title, truth=true_xy)
                files.append(str(path))
        figs[f"{tool}_relation_error_cm"] = float(np.mean(errs))
    shift = [100 * math.dist(minima[("pen", d)], minima[("pencil", d)]) for d in PEN_DISTANCES]
    figs["pencil_from_pen_minimum_cm"] = float(np.mean(shift))
    figs["pencil_from_pen_minimum_max_cm"] = float(np.max(shift))
    log(
        f"seed {seed}: relation error pen {figs['pen_relation_error_cm']:.2f} cm, pencil "
        f"{figs['pencil_relation_error_cm']:.2f} cm; pencil minimum {figs['pencil_from_pen_minimum_cm']:.2f} cm "
        "from the pen's"
    )
    return {"figures": figs, "files": files, "seconds": time.perf_counter() - t0}


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
        f"(pencil) the minimum's distance from the pen's; {over_seeds(len(res.per_seed))}.\n\n"
    )
    md += format_table(res.rows(), cols, std={k: f"{k}_std" for k, _ in cols})
    if res.figures:
        md += "\n\nFigures: " + ", ".join(res.figures)
    return md
