"""How each method of the relations experiment (:mod:`~scenescore.experiments.relations`) solves one
problem, and what it counts as its tries.

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
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ..costs import Bounds, Cost, HingeCollision, LearnedEnergy, Relation
from ..problem.problem import FEASIBILITY_TOL, Problem
from ..scenarios.relation_problems import RelationProblem, relation_problems
from ..scene.scene import Scene, SceneError
from ..solvers import get as get_solver
from ..solvers import solve
from ..solvers.result import best_first

if TYPE_CHECKING:
    from ..models import ScoreModel

__all__ = [
    "METHODS",
    "LANGEVIN",
    "REFINED",
    "WHOLE",
    "REJECTION",
    "REFINE",
    "POOL",
    "STEPS",
    "HEADINGS",
    "best_tries",
    "rejection",
    "sample_tries",
    "solve_one",
    "whole_scene_training",
    "whole_scene_problem",
    "relation_cost_problem",
]

LANGEVIN = "Relations (langevin)"
REFINED = "Relations (langevin>alm)"
WHOLE = "Whole scenes (langevin>alm)"
REJECTION = "Rejection (uniform)"
METHODS = [LANGEVIN, REFINED, WHOLE, REJECTION]
WHOLE_SCENES = 48  # training arrangements of each size for the whole-scene energy
WHOLE_STREAM = 10_000  # their generator's seed is this plus the seed: never a test problem's
STEPS = 100  # Langevin steps per particle (the rejection budget is tries * pool * STEPS draws)
POOL = 16  # Langevin particles per try by default: the tries are the best tries of tries * pool particles
HEADINGS = 24  # the chain's heading sweep: each object turned to the best of 24 headings (15 degrees apart)
COLLISION_WEIGHT = 10.0  # the hinge collision and bounds penalties' weight beside the relation energies
#: the refinement's ``alm`` options: descend until feasible and the objective nearly flat
REFINE: dict[str, Any] = {"tol_grad": 1.0}


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


def solve_one(
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
