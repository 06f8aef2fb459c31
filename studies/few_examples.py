"""A handful of examples on the zoo: the learned energy, the examples' own relations, their sum, a prior.

    python studies/few_examples.py [--scenarios zoo-pcb,zoo-books] [--seeds 3] [--train-scenes 5] \\
        [--weight 1.0] [--cache DIR] [--out records.json]

For every table-top scenario and seed, the zoo's protocol (``scenescore experiment zoo --train-scenes
K``): the first K training scenes of the split, 16 test scenes with one object of the scenario's
missing category removed each, placed back as ``place`` does. Ways to place, in one run on the same
cases and seeds: ``network`` (the learned energy trained on the K scenes at the CLI's defaults, with
non-overlap: ``place``), ``examples`` (:class:`scenescore.costs.ExampleRelations` of the K scenes alone,
with the same non-overlap; it proposes the example poses as the network's guide does) and ``sum``
(``network`` plus ``--weight`` times ``examples``); a fourth, ``prior``, is the network fine-tuned on the
K scenes from a prior (:func:`prior_of`: one network trained at the defaults on every other bundled
table top's training scenes, each dataset at unit length scale, the scenario tested held out of
it), and ``prior_sum`` that network plus ``--weight`` times ``examples``. One row per scenario and
way, worst first by the first way's error over the oracle's; then a line per way pooling every
scenario: the median scenario's t / oracle, the catastrophic placements (more than 25 cm and 10 of the
scenario's oracle means off) and how many were flagged, and the good placements (within 3 of the
scenario's oracle means) flagged; last, per way, how many catastrophic and good placements each kind of
flag fired on, and for an ensemble the counts with its ``members`` flag needing more members to doubt,
or only where they split. ``--mirror`` trains the networks on each training scene's mirror image
beside it (:func:`mirrored`); ``--mirror-fit`` prints how well they fit the other scenes' relations
(:func:`mirror_fit`), training nothing. ``--augment K`` trains the network
on K sub-scenes of each training scene beside it (each without one movable object, the relations among
the rest kept); ``--ways`` runs some of the five. ``--priors DIR`` keeps each prior there by name,
``--tune JSON`` sets the fine-tuning's TrainConfig fields, ``--first-seed`` starts the seeds elsewhere
than 0, and ``--from A.json B.json`` prints the table of earlier ``--out`` files pooled.
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
import torch
from zoo_configs import flag_kinds, members_rules  # a sibling study: studies/ is the script's own folder

from scenescore.costs import ExampleRelations
from scenescore.experiments.prior import train_prior
from scenescore.experiments.zoo import zoo_cases
from scenescore.experiments.zoo_verdicts import case_records, catastrophic, good
from scenescore.learn import ONE_NETWORK, Run, TrainConfig, fit
from scenescore.models import load
from scenescore.models.layout import BOUND_TOL
from scenescore.models.trust import energy_per_object
from scenescore.planning.placement import OVERLAP_WEIGHT, PLACE, covering, non_overlap, placement_problem
from scenescore.problem.problem import Problem
from scenescore.scenarios import get
from scenescore.scenarios.zoo import ROOMS, ZOO
from scenescore.scene import wrap_angle
from scenescore.scene.outputs import atomic_write_text
from scenescore.solvers import solve
from scenescore.solvers.langevin import LangevinSolver

WAYS = ("network", "examples", "sum", "prior", "prior_sum")
TUNED = ("prior", "prior_sum")


def prior_of(held_out: str, cache: Path | None, priors: Path | None = None) -> Any:
    """The prior that ``held_out`` is tested with (:func:`scenescore.experiments.prior.train_prior`, seed
    0): one network at the CLI's defaults on the training scenes of every bundled table top but
    ``held_out``, each dataset at unit length scale. ``priors``: a folder where
    each is kept by name (``prior-without-<name>.ckpt``) and read from when there, whatever code wrote
    it (the model cache keys on the code, so an edit to the package trains them again)."""
    path = None if priors is None else priors / f"prior-without-{held_out}.ckpt"
    if path is not None and path.exists():
        return load(path)
    model = train_prior([held_out], seed=0, progress=False, run=Run(cache=cache))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
    return model


def problem_of(way: str, model: Any, scene: Any, examples: ExampleRelations, weight: float) -> Problem:
    """The placement problem of one way (see the module's description)."""
    if way in ("network", "prior"):
        return placement_problem(model, scene)
    if way in ("sum", "prior_sum"):
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


def mirrored(scene: Any) -> Any:
    """``scene`` reflected in the vertical line through its bounds' centre: ``x`` to ``x0 + x1 - x``,
    headings ``t`` to ``pi - t``, each outline mirrored in its own frame (``v`` to ``-v``), so that every
    footprint lands where the reflection puts it."""
    out = scene.copy()
    (x0, _), (x1, _) = out.bounds
    for o in out.objects:
        if o.pose is not None:
            o.pose = (x0 + x1 - o.pose[0], o.pose[1], float(wrap_angle(np.pi - o.pose[2])))
        if isinstance(o.shape, dict):
            o.shape = {"polygon": [[u, -v] for u, v in reversed(o.shape["polygon"])]}
    return out


def mirror_fit(scenes: list[Any]) -> tuple[float, float]:
    """How well each scene, and its mirror image, fits the relations of the others
    (:class:`~scenescore.costs.ExampleRelations` of them, every object moving): the mean energy per object
    of the scenes as they are and of their mirror images. Where the two are alike, the data shows its
    relations mirrored too."""
    own, mirror = [], []
    for i, s in enumerate(scenes):
        rest = ExampleRelations([t for j, t in enumerate(scenes) if j != i])
        for shown, out in ((s, own), (mirrored(s), mirror)):
            cost = rest.bind(shown, movable=np.ones(len(shown), dtype=bool))
            poses = torch.as_tensor(shown.poses(), dtype=torch.float32)[None]
            out.append(float(cost.evaluate(poses)[0]) / len(shown))
    return float(np.mean(own)), float(np.mean(mirror))


def one_pair(
    name: str,
    seed: int,
    k: int,
    weight: float,
    cache: Path | None,
    ways: tuple[str, ...],
    augment: int,
    priors: Path | None = None,
    tune: TrainConfig | None = None,
    mirror: bool = False,
) -> dict[str, list[dict]]:
    """Every way's records for one scenario and seed (``priors``: as :func:`prior_of`; ``tune``: the
    fine-tuning's settings, default the CLI's; ``mirror``: the networks trained on each scene's mirror
    image too)."""
    sc = get(name)
    train_s, test_s = sc.split(seed)
    train_s = train_s[:k]
    shown = train_s + sub_scenes(train_s, augment, seed)
    shown += [mirrored(s) for s in shown] if mirror else []
    model = tuned = None
    if set(ways) - set(TUNED):
        model = fit(shown, TrainConfig(**ONE_NETWORK), seed=seed, progress=False, run=Run(cache=cache))
    if set(TUNED) & set(ways):
        prior = prior_of(name, cache, priors)
        tuned = fit(
            shown,
            tune or TrainConfig(**ONE_NETWORK),
            seed=seed,
            progress=False,
            run=Run(cache=cache, init=prior),
        )
    ref = model if model is not None else tuned
    examples = ExampleRelations(train_s)
    cases = zoo_cases(sc, test_s, seed)
    tol = BOUND_TOL * ref.config.length_scale
    opts = covering(PLACE, ref, [c.scene for c in cases])
    out: dict[str, list[dict]] = {}
    for way in ways:
        got = []
        for i, c in enumerate(cases):
            m = tuned if way in TUNED else model
            r = solve(problem_of(way, m, c.scene, examples, weight), LangevinSolver(opts), seed=seed + i)
            got.append(placed(r, c.scene))
        truths = [p.with_poses([q.truth for q in c.singles()], c.names) for c, p in zip(cases, got)]
        e = energy_per_object(tuned if way in TUNED else model, got + truths)
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
    # catastrophic and good are each scenario's verdicts (against its own oracle's mean), added up
    cases = [c for v in per.values() for c in v[way]]
    flags = np.array([c["flagged"] for c in cases], dtype=bool)
    cat = np.concatenate([catastrophic(v[way]) for v in per.values()])
    ok = np.concatenate([good(v[way]) for v in per.values()])
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
    ap.add_argument(
        "--mirror",
        action="store_true",
        help="train the networks on each training scene's mirror image too (reflected in the vertical "
        "line through the bounds' centre)",
    )
    ap.add_argument(
        "--mirror-fit",
        action="store_true",
        help="print how well each scenario's training scenes and their mirror images fit the other "
        "scenes' relations (mirror_fit), running nothing else",
    )
    ap.add_argument("--first-seed", type=int, default=0, help="the first seed (default 0)")
    ap.add_argument("--priors", type=Path, default=None, help="a folder the priors are kept in by name")
    ap.add_argument(
        "--tune",
        default=None,
        help='the prior way\'s fine-tuning settings, a JSON object of TrainConfig fields ({"lr": 5e-4}; '
        "default the CLI's)",
    )
    ap.add_argument(
        "--from",
        dest="records",
        type=Path,
        nargs="+",
        default=None,
        help="print the table of these --out files' records pooled (seeds of one scenario added up), "
        "running nothing",
    )
    args = ap.parse_args()
    ways = tuple(w for w in args.ways.split(",") if w)
    if not set(ways) <= set(WAYS):
        ap.error(f"--ways: choose from {', '.join(WAYS)}")
    tune = TrainConfig(**{**ONE_NETWORK, **json.loads(args.tune)}) if args.tune else None
    if args.records:
        report(merged(args.records, ways), ways)
        return
    if args.mirror_fit:
        print("| scenario | seed | own (per object) | mirrored | mirrored - own |\n|---|---:|---:|---:|---:|")
        for name in args.scenarios.split(","):
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                own, mirror = mirror_fit(get(name).split(seed)[0][: args.train_scenes])
                print(f"| {name} | {seed} | {own:.2f} | {mirror:.2f} | {mirror - own:+.2f} |")
        return
    per: dict[str, dict[str, list[dict]]] = {}
    for name in args.scenarios.split(","):
        per[name] = {w: [] for w in ways}
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            t0 = time.perf_counter()
            got = one_pair(
                name,
                seed,
                args.train_scenes,
                args.weight,
                args.cache,
                ways,
                args.augment,
                args.priors,
                tune,
                args.mirror,
            )
            for w in ways:
                per[name][w] += got[w]
            means = ", ".join(f"{w} {np.mean([c['t_cm'] for c in got[w]]):.2f}" for w in ways)
            print(
                f"{name} seed {seed}: mean t (cm) {means} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr
            )
        if args.out is not None:
            atomic_write_text(args.out, json.dumps(per) + "\n")
    report(per, ways)


def merged(paths: list[Path], ways: tuple[str, ...]) -> dict[str, dict[str, list[dict]]]:
    """The records of several ``--out`` files, each scenario's and way's added up in the files' order."""
    per: dict[str, dict[str, list[dict]]] = {}
    for path in paths:
        for name, by_way in json.loads(path.read_text(encoding="utf-8")).items():
            for w in ways:
                if w not in by_way:
                    sys.exit(f"{path}: {name} has no records of the way {w!r}")
                per.setdefault(name, {v: [] for v in ways})[w] += by_way[w]
    return per


def report(per: dict[str, dict[str, list[dict]]], ways: tuple[str, ...]) -> None:
    """The table, worst first by the first way's t / oracle, and each way's pooled line."""

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
    for w in ways:
        by_scenario = {name: v[w] for name, v in per.items()}
        print(f"{w}: {flag_kinds(by_scenario)}")
        if line := members_rules(by_scenario):
            print(f"{w}: {line}")


if __name__ == "__main__":
    main()
