"""Composing learned relations (issue 40, Diffusion-CCSP's protocol): one energy per relation, summed.

Each relation of :data:`~scenescore.scenarios.relation_problems.PROBLEM_RELATIONS` gets one model,
trained on its own examples (``relation-<name>``: 2 or 3 objects each, the seed's training split).
The test problems are random consistent ones (:func:`~scenescore.scenarios.relation_problems.relation_problems`):
N objects, about 1.5 N relations, non-overlap and bounds, ``problems`` per N, the same for every method.
A problem is solved when some of a method's ``tries`` arrangements passes every relation's checker and
the exact non-overlap and bounds checks (:meth:`~scenescore.scenarios.relation_problems.RelationProblem.solved`).

Each relation model is trained on its own examples and kept only when its edge is sharp on examples it
never saw (:mod:`~scenescore.experiments.relation_models`). The methods, and how each solves a problem,
are :mod:`~scenescore.experiments.relation_methods`'s. Each seed and size is one task
(:mod:`scenescore.experiments.tasks`): a run's tasks share a model cache, so a seed's models are trained once.

Time per problem is the wall time of solving (and checking) one problem, training not included.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..learn import Run, TrainConfig, fit
from ..learn.cache import run_cache
from ..scenarios.relation_problems import PROBLEM_RELATIONS, relation_problems
from ..scene.scene import SceneError
from .relation_methods import (
    HEADINGS,
    LANGEVIN,
    METHODS,
    POOL,
    REFINE,
    REFINED,
    REJECTION,
    STEPS,
    WHOLE,
    best_tries,
    relation_cost_problem,
    sample_tries,
    solve_one,
    whole_scene_training,
)
from .relation_models import EXAMPLES, PERTURBED, RESTARTS, relation_training, train_config, train_relations
from .report import SeedResults, format_table, over_seeds
from .tasks import Sweep, Task, run_tasks

if TYPE_CHECKING:
    from ..models import ScoreModel

__all__ = [
    "METHODS",
    "LANGEVIN",
    "REFINED",
    "WHOLE",
    "REJECTION",
    "REFINE",
    "EXAMPLES",
    "POOL",
    "best_tries",
    "sample_tries",
    "HEADINGS",
    "PERTURBED",
    "SIZES",
    "STEPS",
    "RelationsResult",
    "train_config",
    "relation_training",
    "train_relations",
    "whole_scene_training",
    "relation_cost_problem",
    "run",
    "format_relations",
    "plot_relations",
]

SIZES: tuple[int, ...] = tuple(range(2, 11))  # objects per problem: 2 to 10


@dataclass
class RelationsResult(SeedResults):
    """Per method and seed: ``solved_<N>`` (fraction of the problems of N objects solved) and
    ``seconds_<N>`` (seconds per problem) for each N of ``sizes``; ``seconds``: each method's total
    over seeds, its share of the relation models' training included."""

    sizes: list[int] = field(default_factory=list)
    problems: int = 0
    tries: int = 0
    examples: int = 0
    restarts: int = 0
    pool: int = POOL
    relations: list[str] = field(default_factory=list)


def _models(
    chosen: list[str],
    sizes: list[int],
    seed: int,
    relations: list[str],
    examples: int,
    restarts: int,
    config: TrainConfig,
    progress: bool,
    log: Callable[[str], None],
    device: Any,
    cache: Any,
) -> tuple[dict[str, ScoreModel], ScoreModel | None, dict[str, float]]:
    """The seed's relation models (for the relation methods) and whole-scene model (for its method), and
    each method's seconds getting them (trained, or read from the model cache ``cache``)."""
    seconds = dict.fromkeys(chosen, 0.0)
    models: dict[str, ScoreModel] = {}
    if LANGEVIN in chosen or REFINED in chosen:
        t0 = time.perf_counter()
        models = train_relations(
            relations, seed, config, device, cache, examples=examples, restarts=restarts,
            log=log if progress else None,
        )  # fmt: skip
        for m in (LANGEVIN, REFINED):
            if m in chosen:
                seconds[m] += time.perf_counter() - t0
    whole = None
    if WHOLE in chosen:
        t0 = time.perf_counter()
        scenes = whole_scene_training(sizes, seed, relations)
        # no bar of its own, as for the relation models: the experiment's bar counts (seed, size) pairs
        whole = fit(scenes, config, seed=seed, progress=False, device=device, run=Run(cache=cache))
        seconds[WHOLE] += time.perf_counter() - t0
    return models, whole, seconds


def _task(
    task: Task,
    log: Callable[[str], None],
    chosen: list[str],
    sizes: list[int],
    problems: int,
    tries: int,
    pool: int,
    relations: list[str],
    examples: int,
    restarts: int,
    config: TrainConfig,
    progress: bool,
    device: Any,
    cache: Any,
) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """One seed and size of :func:`run`: per method, ``solved_<N>`` and ``seconds_<N>`` (per problem),
    and the method's seconds in all (getting its models included)."""
    seed, n = task.seed, int(json.loads(task.config)["size"])
    told = progress and n == sizes[0]  # the models' restarts are told once per seed, not once per size
    models, whole, seconds = _models(
        chosen, sizes, seed, relations, examples, restarts, config, told, log, device, cache
    )
    solved = dict.fromkeys(chosen, 0)
    spent = dict.fromkeys(chosen, 0.0)
    for k, prob in enumerate(relation_problems(n, problems, seed, relations)):
        for m, (ok, dt) in solve_one(prob, models, whole, chosen, tries, pool, 1000 * n + k).items():
            solved[m] += int(ok)
            spent[m] += dt
    figures = {m: {f"solved_{n}": solved[m] / problems, f"seconds_{n}": spent[m] / problems} for m in chosen}
    for m in chosen:
        seconds[m] += spent[m]
    if progress:
        log(f"seed {seed}, {n} objects: " + ", ".join(f"{m} {solved[m]}/{problems}" for m in chosen))
    return figures, seconds


def run(
    seeds: int = 3,
    sizes: Sequence[int] = SIZES,
    problems: int = 100,
    tries: int = 10,
    pool: int = POOL,
    methods: list[str] | None = None,
    relations: Sequence[str] = PROBLEM_RELATIONS,
    examples: int = EXAMPLES,
    restarts: int = RESTARTS,
    config: TrainConfig | None = None,
    progress: bool = True,
    log: Callable[[str], None] = print,
    device: Any = None,
    jobs: int = 1,
    cache: Any = None,
    sweep: Sweep | None = None,
) -> RelationsResult:
    """The experiment over seeds ``0 .. seeds-1``, each its own relation models and problems: the fraction
    of ``problems`` problems of each size in ``sizes`` that each method solves within ``tries``, each try
    the best of ``pool`` particles.
    ``relations``: those the problems draw from (each one model, trained on ``examples`` example
    scenes, and again at most ``restarts`` times while its edge is flat); ``config``: their training
    (default :func:`train_config`); ``jobs > 1``: the tasks (one per seed and size) in that many worker
    processes (the figures do not depend on it); ``cache``: the model cache folder (default: one for the
    run alone); ``sweep``: where each task's record is kept, to resume from (:mod:`scenescore.experiments.tasks`)."""
    chosen = methods or list(METHODS)
    unknown = [m for m in chosen if m not in METHODS]
    if unknown:
        raise SceneError(f"unknown method(s) {unknown}; choose from {METHODS}")
    if min(tries, problems, seeds, examples, pool) < 1 or restarts < 0:
        raise SceneError(
            "relations: seeds, problems, tries, pool and examples must be at least 1 and restarts at least 0, "
            f"got {seeds}, {problems}, {tries}, {pool}, {examples}, {restarts}"
        )
    res = RelationsResult(
        sizes=list(sizes),
        problems=problems,
        tries=tries,
        pool=pool,
        relations=list(relations),
        examples=examples,
        restarts=restarts,
    )
    one = partial(
        _task,
        chosen=chosen,
        sizes=list(sizes),
        problems=problems,
        tries=tries,
        pool=pool,
        relations=list(relations),
        examples=examples,
        restarts=restarts,
        config=config or train_config(),
        progress=progress,
        device=device,
    )
    settings = {
        "methods": chosen,
        "problems": problems,
        "tries": tries,
        "pool": pool,
        "relations": list(relations),
        "examples": examples,
        "restarts": restarts,
        "training": config or train_config(),
        "device": str(device),
    }  # every setting a task's record depends on
    if WHOLE in chosen:
        settings["sizes"] = list(sizes)  # the whole-scene model trains on every size's arrangements
    # one task per size and seed, the seeds of a size side by side: the workers stay busy to the end,
    # and the first tasks of a run train different seeds' models, which the later ones read from the cache
    tasks = [
        Task.of("relations", seed=seed, scenario=f"{n} objects", config={**settings, "size": n})
        for n in sizes
        for seed in range(seeds)
    ]
    res.per_seed = {m: [{} for _ in range(seeds)] for m in chosen}
    bar = "relations (seed, size)" if progress else None
    with run_cache(cache) as folder:  # every task of a seed needs its models: the first to ask trains them
        records = run_tasks(partial(one, cache=folder), tasks, jobs, log, bar, sweep)
    for task, (figures, seconds) in zip(tasks, records):
        for m in chosen:
            res.per_seed[m][task.seed].update(figures[m])  # the sizes in order: the tasks are size-major
            res.seconds[m] = res.seconds.get(m, 0.0) + seconds[m]
    return res


def format_relations(res: RelationsResult) -> str:
    """Two markdown tables: the fraction solved per N (mean ± std over seeds), the seconds per problem."""
    rows = res.rows()
    solved = [(f"solved_{n}", f"N={n}") for n in res.sizes]
    spread = {f"solved_{n}": f"solved_{n}_std" for n in res.sizes}
    timed = [(f"seconds_{n}", f"N={n}") for n in res.sizes]
    tspread = {f"seconds_{n}": f"seconds_{n}_std" for n in res.sizes}
    seeds = len(next(iter(res.per_seed.values()))) if res.per_seed else 0
    return (
        f"Fraction of {res.problems} problems solved per number of objects N (every relation's checker, "
        f"non-overlap and bounds), {res.tries} tries each; {over_seeds(seeds)}.\n\n"
        + format_table(rows, solved, spread)
        + "\n\nSeconds per problem (all tries, checks included; training not):\n\n"
        + format_table(rows, timed, tspread, digits=3)
    )


def plot_relations(res: RelationsResult, path: str | Path) -> None:
    """The fraction solved against N, one line per method (error bars: the std over seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..viz.plot import save_figure

    fig, ax = plt.subplots(figsize=(5, 3.5))
    for k, r in enumerate(res.rows()):
        y = [r.figures[f"solved_{n}"] for n in res.sizes]
        err = [r.figures.get(f"solved_{n}_std", 0.0) for n in res.sizes]
        marker, line = "os^D"[k % 4], ("-", "--", ":", "-.")[k % 4]  # lines of equal figures stay apart
        ax.errorbar(res.sizes, y, yerr=err, capsize=2, label=r.method, marker=marker, linestyle=line)
    ax.set_xlabel("objects per problem (about 1.5 relations each)")
    ax.set_ylabel(f"fraction solved (within {res.tries} tries)")
    ax.set_xticks(res.sizes)
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save_figure(fig, path)
