"""A handful of examples on the zoo: the learned energy, the examples' own relations, and their sum.

    python studies/few_examples.py [--scenarios zoo-pcb,zoo-books] [--seeds 3] [--train-scenes 5] \\
        [--weight 1.0] [--cache DIR] [--out records.json]

For every table-top scenario and seed, the zoo's protocol (``scenescore experiment zoo --train-scenes
K``): the first K training scenes of the split, 16 test scenes with one object of the scenario's
missing category removed each, placed back as ``place`` does. Three ways to place, in one run on the same
cases and seeds: ``network`` (the learned energy trained on the K scenes at the CLI's defaults, with
non-overlap: ``place``), ``examples`` (:class:`scenescore.costs.ExampleRelations` of the K scenes alone,
with the same non-overlap; it proposes the example poses as the network's guide does) and ``sum``
(``network`` plus ``--weight`` times ``examples``). One row per scenario and way, worst first by the
first way's error over the oracle's; then a line per way pooling every scenario: the median scenario's
t / oracle, the catastrophic placements (more than 25 cm and 10 oracle means off) and how many were
flagged, and the good placements (within 3 oracle means) flagged. ``--augment K`` trains the network
on K sub-scenes of each training scene beside it (each without one movable object, the relations among
the rest kept); ``--ways`` runs some of the three.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from scenescore.costs import ExampleRelations
from scenescore.experiments.zoo import zoo_cases
from scenescore.experiments.zoo_verdicts import case_records, catastrophic, good
from scenescore.learn import Run, TrainConfig, fit
from scenescore.models.layout import BOUND_TOL
from scenescore.models.trust import energy_per_object
from scenescore.planning.placement import OVERLAP_WEIGHT, PLACE, covering, non_overlap, placement_problem
from scenescore.problem.problem import Problem
from scenescore.scenarios import get
from scenescore.scenarios.zoo import ROOMS, ZOO
from scenescore.scene.outputs import atomic_write_text
from scenescore.solvers import solve
from scenescore.solvers.langevin import LangevinSolver

WAYS = ("network", "examples", "sum")


def problem_of(way: str, model: Any, scene: Any, examples: ExampleRelations, weight: float) -> Problem:
    """The placement problem of one way (see the module's description)."""
    if way == "network":
        return placement_problem(model, scene)
    if way == "sum":
        base = placement_problem(model, scene)
        return Problem(scene, base.cost + weight * examples, movable=scene.unknown, name="place")
    cost: Any = examples
    hinge = non_overlap(model, scene)
    if hinge is not None:
        cost = cost + (OVERLAP_WEIGHT / model.config.length_scale) * hinge
    return Problem(scene, cost, movable=scene.unknown, name="place")


def placed(result: Any, scene: Any) -> Any:
    """``scene`` with its unknown poses from ``result`` and their confidence, as ``place`` writes it."""
    names = scene.unknown
    out = scene.with_poses(result.poses[[scene.index(n) for n in names]], names)
    out.meta = {
        **out.meta,
        "placement": {n: result.confidence[n].to_dict() for n in names if n in result.confidence},
    }
    return out


def sub_scenes(scenes: list[Any], copies: int, seed: int) -> list[Any]:
    """``copies`` sub-scenes of each scene, each without one of its movable objects (drawn by ``seed``):
    the relations among the rest kept."""
    rng = np.random.default_rng(seed)
    out = []
    for s in scenes:
        movable = [o.name for o in s.objects if not o.fixed]
        for _ in range(copies if len(movable) > 1 else 0):
            drop = movable[int(rng.integers(len(movable)))]
            out.append(replace(s, objects=[o for o in s.objects if o.name != drop]))
    return out


def one_pair(
    name: str, seed: int, k: int, weight: float, cache: Path | None, ways: tuple[str, ...], augment: int
) -> dict[str, list[dict]]:
    """Every way's records for one scenario and seed."""
    sc = get(name)
    train_s, test_s = sc.split(seed)
    train_s = train_s[:k]
    shown = train_s + sub_scenes(train_s, augment, seed)
    model = fit(shown, TrainConfig(), seed=seed, progress=False, run=Run(cache=cache))
    examples = ExampleRelations(train_s)
    cases = zoo_cases(sc, test_s, seed)
    tol = BOUND_TOL * model.config.length_scale
    opts = covering(PLACE, model, [c.scene for c in cases])
    out: dict[str, list[dict]] = {}
    for way in ways:
        got = []
        for i, c in enumerate(cases):
            r = solve(problem_of(way, model, c.scene, examples, weight), LangevinSolver(opts), seed=seed + i)
            got.append(placed(r, c.scene))
        truths = [p.with_poses([q.truth for q in c.singles()], c.names) for c, p in zip(cases, got)]
        e = energy_per_object(model, got + truths)
        out[way] = [
            rec
            for i, (c, p) in enumerate(zip(cases, got))
            for rec in case_records(sc, c, p, e[i], e[len(cases) + i], tol, seed)[0]
        ]
    return out


def row(name: str, way: str, cases: list[dict]) -> str:
    t = np.array([c["t_cm"] for c in cases])
    o = np.array([c["oracle_t_cm"] for c in cases])
    flags = np.array([c["flagged"] for c in cases])
    cat, ok = catastrophic(cases), good(cases)
    return (
        f"| {name} | {way} | {t.mean():.2f} | {np.median(t):.2f} | {t.max():.1f} | {int(cat.sum())} "
        f"({int((cat & flags).sum())}) | {o.mean():.2f} | {t.mean() / max(o.mean(), 1e-9):.2f} | "
        f"{int((ok & flags).sum())} of {int(ok.sum())} |"
    )


def pooled(way: str, per: dict[str, dict[str, list[dict]]]) -> str:
    ratios = [
        np.mean([c["t_cm"] for c in v[way]]) / max(np.mean([c["oracle_t_cm"] for c in v[way]]), 1e-9)
        for v in per.values()
    ]
    cases = [c for v in per.values() for c in v[way]]
    flags = np.array([c["flagged"] for c in cases])
    cat, ok = catastrophic(cases), good(cases)
    return (
        f"{way}: median scenario t / oracle {np.median(ratios):.2f}, catastrophic {int(cat.sum())} of "
        f"{len(cases)} ({int((cat & flags).sum())} flagged), good flagged {int((ok & flags).sum())} of "
        f"{int(ok.sum())} ({(ok & flags).sum() / max(ok.sum(), 1):.1%})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default=",".join(s for s in ZOO if s not in ROOMS))
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--train-scenes", type=int, default=5)
    ap.add_argument("--weight", type=float, default=1.0, help="the examples' weight in the sum (default 1)")
    ap.add_argument("--cache", type=Path, default=None, help="a model cache folder")
    ap.add_argument("--out", type=Path, default=None, help="write every record here (JSON)")
    ap.add_argument("--ways", default=",".join(WAYS), help=f"comma-separated subset of {', '.join(WAYS)}")
    ap.add_argument(
        "--augment",
        type=int,
        default=0,
        help="train the network on K sub-scenes of each training scene besides it, each without one "
        "movable object (default 0)",
    )
    args = ap.parse_args()
    ways = tuple(w for w in args.ways.split(",") if w)
    if not set(ways) <= set(WAYS):
        ap.error(f"--ways: choose from {', '.join(WAYS)}")
    per: dict[str, dict[str, list[dict]]] = {}
    for name in args.scenarios.split(","):
        per[name] = {w: [] for w in ways}
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            got = one_pair(name, seed, args.train_scenes, args.weight, args.cache, ways, args.augment)
            for w in ways:
                per[name][w] += got[w]
            means = ", ".join(f"{w} {np.mean([c['t_cm'] for c in got[w]]):.2f}" for w in ways)
            print(
                f"{name} seed {seed}: mean t (cm) {means} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr
            )
        if args.out is not None:
            atomic_write_text(args.out, json.dumps(per) + "\n")

    def worst(name: str) -> float:
        v = per[name][ways[0]]
        return -np.mean([c["t_cm"] for c in v]) / max(np.mean([c["oracle_t_cm"] for c in v]), 1e-9)

    print(
        "| scenario | way | mean t (cm) | median | worst | catastrophic (flagged) | oracle t | t / oracle | good flagged |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in sorted(per, key=worst):
        for w in ways:
            print(row(name, w, per[name][w]))
    print()
    for w in ways:
        print(pooled(w, per))


if __name__ == "__main__":
    main()
