"""Composing learned relations (after Diffusion-CCSP's protocol): one energy per relation, summed.

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
from .execution import Execution
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
from .tasks import Task, run_tasks

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
    "RelationSettings",
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


@dataclass(frozen=True)
class RelationSettings:
    """The experiment's problems, methods and relation models: every setting its figures depend on.

    ``sizes``: the numbers of objects per problem, one column each; ``problems``: how many problems of
    each size, the same for every method; ``tries``: arrangements per problem and method (a problem is
    solved when one of them passes every check); ``pool``: Langevin particles per try, each try the best
    of them; ``methods``: the rows (default :data:`METHODS`); ``relations``: those the problems draw
    from, each one model; ``examples``: the example scenes each relation model trains on;
    ``restarts``: how many times at most a model is trained again while its edge is flat; ``config``:
    the models' training (default :func:`train_config`)."""

    sizes: Sequence[int] = SIZES
    problems: int = 100
    tries: int = 10
    pool: int = POOL
    methods: list[str] | None = None
    relations: Sequence[str] = PROBLEM_RELATIONS
    examples: int = EXAMPLES
    restarts: int = RESTARTS
    config: TrainConfig | None = None

    def chosen(self) -> list[str]:
        """The methods run: ``methods``, or every one of :data:`METHODS`."""
        return self.methods or list(METHODS)

    def training(self) -> TrainConfig:
        """The models' training settings: ``config``, or :func:`train_config`'s."""
        return self.config or train_config()

    def record_config(self, device: Any) -> dict[str, Any]:
        """Every setting a task's record depends on beyond its seed and size (the task adds its size):
        these settings, and the ``device`` the models train on."""
        chosen = self.chosen()
        config = {
            "methods": chosen,
            "problems": self.problems,
            "tries": self.tries,
            "pool": self.pool,
            "relations": list(self.relations),
            "examples": self.examples,
            "restarts": self.restarts,
            "training": self.training(),
            "device": str(device),
        }
        if WHOLE in chosen:
            config["sizes"] = list(self.sizes)  # the whole-scene model trains on every size's arrangements
        return config


@dataclass
class RelationsResult(SeedResults):
    """Per method and seed: ``solved_<N>`` (fraction of the problems of N objects solved) and
    ``seconds_<N>`` (seconds per problem) for each N of ``sizes``; ``seconds``: each method's total
    over seeds, its share of the relation models' training included. The other fields: the
    :class:`RelationSettings` it was run with."""

    sizes: list[int] = field(default_factory=list)
    problems: int = 0
    tries: int = 0
    examples: int = 0
    restarts: int = 0
    pool: int = POOL
    relations: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, settings: RelationSettings) -> RelationsResult:
        """An empty result of a run with ``settings``."""
        return cls(
            sizes=list(settings.sizes),
            problems=settings.problems,
            tries=settings.tries,
            pool=settings.pool,
            relations=list(settings.relations),
            examples=settings.examples,
            restarts=settings.restarts,
        )


def _models(
    settings: RelationSettings,
    seed: int,
    progress: bool,
    log: Callable[[str], None],
    device: Any,
    cache: Any,
) -> tuple[dict[str, ScoreModel], ScoreModel | None, dict[str, float]]:
    """The seed's relation models (for the relation methods) and whole-scene model (for its method), and
    each method's seconds getting them (trained, or read from the model cache ``cache``)."""
    chosen, config, relations = settings.chosen(), settings.training(), list(settings.relations)
    seconds = dict.fromkeys(chosen, 0.0)
    models: dict[str, ScoreModel] = {}
    if LANGEVIN in chosen or REFINED in chosen:
        t0 = time.perf_counter()
        models = train_relations(
            relations, seed, config, device, cache, examples=settings.examples, restarts=settings.restarts,
            log=log if progress else None,
        )  # fmt: skip
        for m in (LANGEVIN, REFINED):
            if m in chosen:
                seconds[m] += time.perf_counter() - t0
    whole = None
    if WHOLE in chosen:
        t0 = time.perf_counter()
        scenes = whole_scene_training(list(settings.sizes), seed, relations)
        # no bar of its own, as for the relation models: the experiment's bar counts (seed, size) pairs
        whole = fit(scenes, config, seed=seed, progress=False, device=device, run=Run(cache=cache))
        seconds[WHOLE] += time.perf_counter() - t0
    return models, whole, seconds


def _task(
    task: Task,
    log: Callable[[str], None],
    settings: RelationSettings,
    progress: bool,
    device: Any,
    cache: Any,
) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """One seed and size of :func:`run`: per method, ``solved_<N>`` and ``seconds_<N>`` (per problem),
    and the method's seconds in all (getting its models included)."""
    seed, n = task.seed, int(json.loads(task.config)["size"])
    chosen, problems = settings.chosen(), settings.problems
    # the models' restarts are told once per seed, not once per size
    told = progress and n == list(settings.sizes)[0]
    models, whole, seconds = _models(settings, seed, told, log, device, cache)
    solved = dict.fromkeys(chosen, 0)
    spent = dict.fromkeys(chosen, 0.0)
    relations, tries, pool = list(settings.relations), settings.tries, settings.pool
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


def _check(seeds: int, settings: RelationSettings) -> None:
    """Refuse an unknown method and a count out of range, before any task starts."""
    unknown = [m for m in settings.chosen() if m not in METHODS]
    if unknown:
        raise SceneError(f"unknown method(s) {unknown}; choose from {METHODS}")
    s = settings
    if min(s.tries, s.problems, seeds, s.examples, s.pool) < 1 or s.restarts < 0:
        raise SceneError(
            "relations: seeds, problems, tries, pool and examples must be at least 1 and restarts at least 0, "
            f"got {seeds}, {s.problems}, {s.tries}, {s.pool}, {s.examples}, {s.restarts}"
        )


def run(
    seeds: int = 3,
    settings: RelationSettings | None = None,
    *,
    execution: Execution | None = None,
) -> RelationsResult:
    """The experiment over seeds ``0 .. seeds-1``, each its own relation models and problems: the fraction
    of ``settings.problems`` problems of each size in ``settings.sizes`` that each method solves within
    ``settings.tries``, each try the best of ``settings.pool`` particles (default
    :class:`RelationSettings`'s). ``execution``: where and how (default :class:`Execution`'s); its
    ``jobs > 1``: the tasks (one per seed and size) in that many worker processes (the figures do not
    depend on it); its ``cache``: the model cache folder (default: one for the run alone); its
    ``sweep``: where each task's record is kept, to resume from (:mod:`scenescore.experiments.tasks`)."""
    s = settings or RelationSettings()
    ex = execution or Execution()
    _check(seeds, s)
    chosen = s.chosen()
    res = RelationsResult.of(s)
    one = partial(_task, settings=s, progress=ex.progress, device=ex.device)
    config = s.record_config(ex.device)  # every setting a task's record depends on
    # one task per size and seed, the seeds of a size side by side: the workers stay busy to the end,
    # and the first tasks of a run train different seeds' models, which the later ones read from the cache
    tasks = [
        Task.of("relations", seed=seed, scenario=f"{n} objects", config={**config, "size": n})
        for n in s.sizes
        for seed in range(seeds)
    ]
    res.per_seed = {m: [{} for _ in range(seeds)] for m in chosen}
    bar = "relations (seed, size)" if ex.progress else None
    with run_cache(ex.cache) as folder:  # every task of a seed needs its models: the first to ask trains them
        records = run_tasks(partial(one, cache=folder), tasks, ex.jobs, ex.log, bar, ex.sweep)
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
