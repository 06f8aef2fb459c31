"""How often one relation model alone gives an arrangement its checker accepts, and how sharp its edge is.

    python studies/relation_models.py [--seed 0] [--problems 20] [--relations left_of,facing]
        [--edge 100] [--restarts 3] [--set KEY=VALUE ...]

The relations experiment sums one energy per relation; a problem of N objects asks for about 1.5 N of
them, so its solved fraction is bounded by how often each energy alone is satisfied. Here each relation
model is trained as `scenescore experiment relations` trains it: on 2048 example scenes for the seed,
and trained again with the next member seed, at most ``--restarts`` times, while its edge on 100
further examples of its training stream is flat (each restart is printed). It is bound to problems that
ask for that relation only (2 objects, 3 for ``between``: the problem generator's own, restricted to
the relation), with non-overlap and bounds, and sampled as the experiment's ``Relations
(langevin>alm)`` row samples (160 particles with the heading sweep, each refined, the 10 best by the cost
kept). The first table gives, per relation, the fraction of the kept samples that solve their problem
(every checker, non-overlap, bounds) and the fraction of problems with at least one; a relation with
few samples accepted limits every problem that names it. ``--set`` changes the models' training
settings (``TrainConfig`` fields, as for ``scenescore train --set``), to compare them on these tables.

The second table is the edge: ``--edge`` held-out examples of each relation (its scenario's test
stream for the seed), the subject moved 1.5 and 3 cm in 16 directions; of the moves the checker
rejects, the fraction the energy ranks above the example itself, and the mean energy rise, beside the
seed the kept model was trained with. In a sum of many energies a relation whose broken arrangements
cost no more than its true ones is the first to give way; alone, sampling many particles and keeping
the best hides it.
"""

from __future__ import annotations

import argparse
import time

from scenescore.cli.train_settings import overridden, parse_overrides
from scenescore.errors import ConfigError
from scenescore.experiments import relations as R
from scenescore.experiments.relation_models import DIRECTIONS, edge
from scenescore.models import ScoreModel
from scenescore.scenarios import get
from scenescore.scenarios.relation_problems import PROBLEM_RELATIONS, relation_problems

TRIES = 10
MOVES = (0.015, 0.03)  # metres the subject moves off a held-out example


def samples(models: dict[str, ScoreModel], rels: list[str], seed: int, problems: int) -> None:
    """The first table: per relation, the kept samples accepted and the problems solved."""
    print("| relation | problems | samples accepted | problems solved (any of 10) |")
    print("|---|---:|---:|---:|")
    for rel in rels:
        n = 3 if rel == "between" else 2
        # the generator names only relations that hold in its arrangement: some draws name none
        probs = [p for p in relation_problems(n, problems, seed, [rel]) if p.relations]
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


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--problems", type=int, default=20, help="problems drawn per relation (default 20; 0: the edge alone)"
    )
    ap.add_argument("--relations", default=",".join(PROBLEM_RELATIONS))
    ap.add_argument(
        "--edge", type=int, default=100, help="held-out examples per relation for the edge (0: none)"
    )
    ap.add_argument(
        "--restarts", type=int, default=R.RESTARTS, help="trainings again of a flat model at most (default 3)"
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
    models = R.train_relations(rels, args.seed, config, cache=args.cache, log=print, restarts=args.restarts)
    print(f"trained {len(rels)} relation models in {time.perf_counter() - t0:.0f} s (seed {args.seed})")
    print("settings:", ", ".join(args.set) or "the experiment's", "\n")
    if args.problems:
        samples(models, rels, args.seed, args.problems)
    if args.edge:
        cols = " | ".join(f"broken at {d * 100:g} cm | ranked worse | mean rise" for d in MOVES)
        print(f"\nThe edge: {args.edge} held-out examples, the subject moved in {DIRECTIONS} directions\n")
        print(f"| relation | trained with seed | {cols} |")
        print("|---|---:|" + "---:|" * (3 * len(MOVES)))
        for rel in rels:
            held = get(f"relation-{rel}", n_test=args.edge).split(args.seed)[1]
            figs = edge(models[rel], rel, held, MOVES)
            cells = " | ".join(f"{f.broken} | {f.worse:.2f} | {f.rise:.3f}" for f in figs)
            print(f"| {rel} | {models[rel].info.seed} | {cells} |")
    print(f"\n{time.perf_counter() - t0:.0f} s in all")


if __name__ == "__main__":
    main()
