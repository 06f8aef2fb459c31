"""Composing learned relations (issue 40, Diffusion-CCSP's protocol): one energy per relation, summed.

Each relation of :data:`~scenescore.scenarios.relation_problems.PROBLEM_RELATIONS` gets one model,
trained on its own examples (``relation-<name>``: 2 or 3 objects each, the seed's training split).
The test problems are random consistent ones (:func:`~scenescore.scenarios.relation_problems.relation_problems`):
N objects, about 1.5 N relations, non-overlap and bounds, ``problems`` per N, the same for every method.
A problem is solved when some of a method's ``tries`` arrangements passes every relation's checker and
the exact non-overlap and bounds checks (:meth:`~scenescore.scenarios.relation_problems.RelationProblem.solved`).

Each relation model is trained on its own examples and kept only when its edge is sharp on examples it
never saw (:mod:`~scenescore.experiments.relation_models`).

- Relations (langevin): the relation models bound to the problem's objects (one
  :class:`~scenescore.costs.Relation` term per relation, its instances batched) + 10 * hinge
  collision + 10 * bounds, sampled by ``langevin`` with ``tries * pool`` particles from uniform
  starts, each object's heading swept (:data:`HEADINGS`) before the chain's final descent, since a
  relation such as ``facing`` has a narrow basin in the heading; the tries are the ``tries`` best
  particles by the method's own judgement (within the collision and bounds tolerance first, then the
  lowest cost), never by the checkers.
- Relations (langevin>alm): the same particles, each refined at once by the batched augmented
  Lagrangian (``alm``, :data:`REFINE`) under the collision and bounds constraints, the tries the
  ``tries`` best refined ones; its time includes the Langevin stage.
- Whole scenes (langevin>alm): one SceneScore energy trained on whole arrangements of the same process
  (:func:`whole_scene_training`: the generator's arrangements, :data:`WHOLE_SCENES` of each size, drawn
  from another stream than the test problems), + 10 * hinge collision + 10 * bounds, sampled and refined
  as the row above. It sees the objects, never the relations a problem asks for: the baseline that tells
  what knowing the relations buys.
- Rejection (uniform): arrangements drawn uniformly (positions in the bounds, headings in a full
  turn) until one solves the problem, at most ``tries * pool * STEPS`` of them: as many as the
  Langevin stage evaluates the cost at.

Time per problem is the wall time of solving (and checking) one problem, training not included.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ..costs import Bounds, Cost, HingeCollision, LearnedEnergy, Relation
from ..learn import TrainConfig, train
from ..problem import FEASIBILITY_TOL, Problem
from ..scenarios.relation_problems import PROBLEM_RELATIONS, RelationProblem, relation_problems
from ..scene import Scene, SceneError
from ..solvers import get as get_solver
from ..solvers import solve
from ..solvers.result import best_first
from ..tasks import Sweep, Task, run_tasks
from .relation_models import EXAMPLES, PERTURBED, RESTARTS, relation_training, train_config, train_relations
from .report import SeedResults, format_table, over_seeds

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

LANGEVIN = "Relations (langevin)"
REFINED = "Relations (langevin>alm)"
WHOLE = "Whole scenes (langevin>alm)"
REJECTION = "Rejection (uniform)"
METHODS = [LANGEVIN, REFINED, WHOLE, REJECTION]
WHOLE_SCENES = 48  # training arrangements of each size for the whole-scene energy
WHOLE_STREAM = 10_000  # their generator's seed is this plus the seed: never a test problem's
SIZES: tuple[int, ...] = tuple(range(2, 11))  # objects per problem: 2 to 10
STEPS = 100  # Langevin steps per particle (the rejection budget is tries * pool * STEPS draws)
POOL = 16  # Langevin particles per try by default: the tries are the best tries of tries * pool particles
HEADINGS = 24  # the chain's heading sweep: each object turned to the best of 24 headings (15 degrees apart)
COLLISION_WEIGHT = 10.0  # the hinge collision and bounds penalties' weight beside the relation energies
#: the refinement's ``alm`` options: descend until feasible and the objective nearly flat
REFINE: dict[str, Any] = {"tol_grad": 1.0}


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


def whole_scene_training(sizes: Sequence[int], seed: int, relations: Sequence[str]) -> list[Scene]:
    """The whole-scene energy's training arrangements: :data:`WHOLE_SCENES` of each size in ``sizes``,
    the problem generator's own arrangements (solutions of its problems) from the stream
    ``WHOLE_STREAM + seed``, so that no test problem's arrangement is among them."""
    return [
        p.scene
        for n in sizes
        for p in relation_problems(n, WHOLE_SCENES, WHOLE_STREAM + seed, list(relations))
    ]


def whole_scene_problem(problem: RelationProblem, model: ScoreModel) -> Problem:
    """The whole-scene energy over the problem's objects + 10 * hinge collision + 10 * bounds, every
    object moving: the relations themselves are not in it."""
    cost = LearnedEnergy(model) + COLLISION_WEIGHT * HingeCollision() + COLLISION_WEIGHT * Bounds()
    return Problem(problem.unposed, cost)


def relation_cost_problem(problem: RelationProblem, models: dict[str, ScoreModel]) -> Problem:
    """The problem's summed relation energies (one :class:`~scenescore.costs.Relation` term per relation,
    its instances in one call) + 10 * hinge collision + 10 * bounds, every object moving."""
    if not problem.relations:
        raise SceneError("relation problem: it names no relation, so there is no relation energy to sum")
    terms = []
    for rel, instances in problem.by_relation().items():
        if rel not in models:
            raise SceneError(f"relation problem: no model for the relation {rel!r}; models: {sorted(models)}")
        terms.append(Relation(models[rel], objects=instances, name=rel))
    cost: Cost = terms[0]
    for t in terms[1:]:
        cost = cost + t
    cost = cost + COLLISION_WEIGHT * HingeCollision() + COLLISION_WEIGHT * Bounds()
    return Problem(problem.unposed, cost)


def _any_solved(problem: RelationProblem, samples: np.ndarray) -> bool:
    return any(problem.solved(p) for p in np.asarray(samples, dtype=float))


def best_tries(prob: Problem, samples: np.ndarray | torch.Tensor, tries: int) -> np.ndarray:
    """The ``tries`` best of ``samples``: those within the collision and bounds tolerance first, then
    by cost (the relation energies' judgement; the checkers are never asked)."""
    x = torch.as_tensor(np.asarray(samples, dtype=float))
    with torch.no_grad():
        order = best_first(prob.violation(x) <= FEASIBILITY_TOL, prob.evaluate(x))
    return x[order[:tries]].numpy()


def rejection(problem: RelationProblem, budget: int, seed: int) -> bool:
    """Whether one of ``budget`` uniform arrangements (positions in the bounds, headings in a full turn)
    solves ``problem``; draws stop at the first that does."""
    rng = np.random.default_rng(seed)
    (x0, y0), (x1, y1) = problem.scene.bounds
    n = len(problem.scene)
    for _ in range(budget):
        poses = np.column_stack(
            [rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), rng.uniform(-np.pi, np.pi, n)]
        )
        if problem.solved(poses):
            return True
    return False


def sample_tries(
    prob: Problem, tries: int, seed: int, refine: bool, pool: int = POOL
) -> list[tuple[np.ndarray, float]]:
    """How the experiment samples ``prob``: ``langevin`` with ``tries * pool`` particles (the heading
    sweep on), then (``refine``) ``alm`` from every particle; for each stage its ``tries`` best
    (:func:`best_tries`) and the seconds so far (the refinement's include the sampling's)."""
    t0 = time.perf_counter()
    options = {"particles": tries * pool, "steps": STEPS, "heading_sweep": HEADINGS}
    r = solve(prob, "langevin", seed=seed, options={"langevin": options})
    assert r.samples is not None
    stages = [(best_tries(prob, r.samples, tries), time.perf_counter() - t0)]
    if refine:
        rr = get_solver("alm", **REFINE).solve(prob, init=torch.as_tensor(r.samples))
        assert rr.samples is not None
        stages.append((best_tries(prob, rr.samples, tries), time.perf_counter() - t0))
    return stages


def _sample_refine(
    problem: RelationProblem, prob: Problem, tries: int, seed: int, refine: bool, pool: int
) -> tuple[tuple[bool, float], tuple[bool, float] | None]:
    """:func:`sample_tries`: whether one of each stage's tries solves ``problem``, and its seconds."""
    stages = [
        (_any_solved(problem, chosen), t) for chosen, t in sample_tries(prob, tries, seed, refine, pool)
    ]
    return stages[0], stages[1] if refine else None


def _solve_one(
    problem: RelationProblem,
    models: dict[str, ScoreModel],
    whole: ScoreModel | None,
    chosen: list[str],
    tries: int,
    pool: int,
    seed: int,
) -> dict[str, tuple[bool, float]]:
    """Whether each chosen method solves ``problem`` within ``tries`` (each the best of ``pool`` particles),
    and its seconds."""
    out: dict[str, tuple[bool, float]] = {}
    if LANGEVIN in chosen or REFINED in chosen:
        sampled, refined = _sample_refine(
            problem, relation_cost_problem(problem, models), tries, seed, REFINED in chosen, pool
        )
        if LANGEVIN in chosen:
            out[LANGEVIN] = sampled
        if refined is not None:
            out[REFINED] = refined
    if WHOLE in chosen:
        assert whole is not None
        _, refined = _sample_refine(problem, whole_scene_problem(problem, whole), tries, seed, True, pool)
        assert refined is not None
        out[WHOLE] = refined
    if REJECTION in chosen:
        t0 = time.perf_counter()
        out[REJECTION] = (rejection(problem, tries * pool * STEPS, seed), time.perf_counter() - t0)
    return out


def _seed(
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
    """One seed of :func:`run`: per method, ``solved_<N>`` and ``seconds_<N>`` (per problem), and the
    method's seconds in all (its models' training included)."""
    seed = task.seed
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
        whole = train(
            whole_scene_training(sizes, seed, relations), config, seed=seed, device=device, cache=cache
        )
        seconds[WHOLE] += time.perf_counter() - t0
    figures: dict[str, dict[str, float]] = {m: {} for m in chosen}
    for n in sizes:
        solved = dict.fromkeys(chosen, 0)
        spent = dict.fromkeys(chosen, 0.0)
        for k, prob in enumerate(relation_problems(n, problems, seed, relations)):
            for m, (ok, dt) in _solve_one(prob, models, whole, chosen, tries, pool, 1000 * n + k).items():
                solved[m] += int(ok)
                spent[m] += dt
        for m in chosen:
            figures[m][f"solved_{n}"] = solved[m] / problems
            figures[m][f"seconds_{n}"] = spent[m] / problems
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
    (default :func:`train_config`); ``jobs > 1``: the seeds in that many worker processes (the figures do not
    depend on it); ``sweep``: where each seed's record is kept, to resume from (:mod:`scenescore.tasks`)."""
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
        _seed,
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
        cache=cache,
    )
    settings = {
        "methods": chosen,
        "sizes": list(sizes),
        "problems": problems,
        "tries": tries,
        "pool": pool,
        "relations": list(relations),
        "examples": examples,
        "restarts": restarts,
        "training": config or train_config(),
        "device": str(device),
    }  # every setting a seed's record depends on
    tasks = [Task.of("relations", seed=seed, config=settings) for seed in range(seeds)]
    for figures, seconds in run_tasks(one, tasks, jobs, log, "relations seeds" if progress else None, sweep):
        for m in chosen:
            res.per_seed.setdefault(m, []).append(figures[m])
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

    from ..plot import save_figure

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
