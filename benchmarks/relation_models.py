"""How often one relation model alone gives an arrangement its checker accepts, and how sharp its edge is.

    python benchmarks/relation_models.py [--seed 0] [--problems 20] [--relations left_of,facing]
        [--edge 100] [--set KEY=VALUE ...]

The relations experiment sums one energy per relation; a problem of N objects asks for about 1.5 N of
them, so its solved fraction is bounded by how often each energy alone is satisfied. Here each relation
model (trained as `scenescore experiment relations` trains it, on 2048 example scenes for the seed) is
bound to problems that ask for that relation only (2 objects, 3 for ``between``: the problem
generator's own, restricted to the relation), with non-overlap and bounds, and sampled as the
experiment's ``Relations (langevin>alm)`` row samples (80 particles with the heading sweep, each refined,
the 10 best by the cost kept). The table gives, per relation, the fraction of the kept samples that
solve their problem (every checker, non-overlap, bounds) and the fraction of problems with at least
one; a relation with few samples accepted limits every problem that names it. ``--set`` changes the
models' training settings (``TrainConfig`` fields, as for ``scenescore train --set``), to compare them
on these tables.

The second table is the edge: ``--edge`` held-out examples of each relation (its scenario's test
stream for the seed), the subject moved 1.5 and 3 cm in 16 directions; of the moves the checker
rejects, the fraction the energy ranks above the example itself, and the mean energy rise. In a sum of
many energies a relation whose broken arrangements cost no more than its true ones is the first to give
way; alone, sampling many particles and keeping the best hides it.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from scenescore.cli.train_settings import overridden, parse_overrides
from scenescore.costs import Relation
from scenescore.errors import ConfigError
from scenescore.experiments import relations as R
from scenescore.models import ScoreModel
from scenescore.problem import Problem
from scenescore.scenarios import get
from scenescore.scenarios.relation_problems import PROBLEM_RELATIONS, relation_problems
from scenescore.scene import Scene

TRIES = 10
MOVES = (0.015, 0.03)  # metres the subject moves off a held-out example
DIRECTIONS = 16


def edge(model: ScoreModel, rel: str, seed: int, examples: int) -> list[tuple[int, float, float]]:
    """Per move of :data:`MOVES`: (moves the checker rejects, the fraction of them the energy ranks above
    the example, their mean energy rise over it)."""
    scenario = get(f"relation-{rel}", n_test=examples)
    angles = np.arange(DIRECTIONS) * (2 * math.pi / DIRECTIONS)
    dist = np.repeat(MOVES, DIRECTIONS)  # each move's length, the 16 directions of each in turn
    shift = dist[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])[np.tile(range(DIRECTIONS), 2)]
    rises: dict[float, list[float]] = {d: [] for d in MOVES}
    for ex in scenario.split(seed)[1]:
        scene = Scene([ex[n] for n in scenario.roles], ex.bounds)  # the term adds the axes marker itself
        prob = Problem(scene, Relation(model, objects=[scenario.roles]))
        poses = np.repeat(np.array([o.pose for o in scene.objects], dtype=float)[None], len(dist) + 1, 0)
        poses[1:, 0, :2] += shift  # row 0: the example; then the subject moved
        with torch.no_grad():
            e = prob.evaluate(torch.as_tensor(poses)).numpy()
        for d, p, ek in zip(dist, poses[1:], e[1:]):
            if not scenario.check(scene.with_poses(p)):
                rises[float(d)].append(float(ek - e[0]))
    return [
        (len(r), float(np.mean(np.array(r) > 0)) if r else math.nan, float(np.mean(r)) if r else math.nan)
        for r in rises.values()
    ]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--problems", type=int, default=20, help="problems drawn per relation (default 20)")
    ap.add_argument("--relations", default=",".join(PROBLEM_RELATIONS))
    ap.add_argument(
        "--edge", type=int, default=100, help="held-out examples per relation for the edge (0: none)"
    )
    ap.add_argument("--cache", default=None, help="a model cache folder (the models are trained once)")
    ap.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a training setting, e.g. perturbed=8"
    )
    args = ap.parse_args(argv)
    rels = [r.strip() for r in args.relations.split(",") if r.strip()]
    unknown = sorted(set(rels) - set(PROBLEM_RELATIONS))
    if unknown:
        ap.error(f"--relations: unknown {unknown}; choose from {list(PROBLEM_RELATIONS)}")
    t0 = time.perf_counter()
    try:
        config = overridden(R.train_config(), parse_overrides(args.set))
    except ConfigError as e:
        ap.error(str(e))
    models = R.train_relations(rels, args.seed, config, cache=args.cache)
    print(f"trained {len(rels)} relation models in {time.perf_counter() - t0:.0f} s (seed {args.seed})")
    print("settings:", ", ".join(args.set) or "the experiment's", "\n")
    print("| relation | problems | samples accepted | problems solved (any of 10) |")
    print("|---|---:|---:|---:|")
    for rel in rels:
        n = 3 if rel == "between" else 2
        # the generator names only relations that hold in its arrangement: some draws name none
        probs = [p for p in relation_problems(n, args.problems, args.seed, [rel]) if p.relations]
        accepted = solved = 0
        for k, prob in enumerate(probs):
            chosen, _ = R.sample_tries(R.relation_cost_problem(prob, models), TRIES, k, refine=True)[-1]
            ok = [prob.solved(p) for p in chosen]
            accepted += sum(ok)
            solved += any(ok)
        if probs:
            frac = accepted / (TRIES * len(probs))
            print(f"| {rel} | {len(probs)} | {frac:.2f} | {solved / len(probs):.2f} |")
        else:
            print(f"| {rel} | 0 | - | - |")
    if args.edge:
        cols = " | ".join(f"broken at {d * 100:g} cm | ranked worse | mean rise" for d in MOVES)
        print(f"\nThe edge: {args.edge} held-out examples, the subject moved in {DIRECTIONS} directions\n")
        print(f"| relation | {cols} |")
        print("|---|" + "---:|" * (3 * len(MOVES)))
        for rel in rels:
            figs = edge(models[rel], rel, args.seed, args.edge)
            print(f"| {rel} | " + " | ".join(f"{n} | {w:.2f} | {m:.3f}" for n, w, m in figs) + " |")
    print(f"\n{time.perf_counter() - t0:.0f} s in all")


if __name__ == "__main__":
    main()
