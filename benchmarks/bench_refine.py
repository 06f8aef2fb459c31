"""Refining every Langevin sample at once: the ``alm`` stage's time against the ``langevin`` stage's.

    python benchmarks/bench_refine.py [--samples 5000] [--quick] [--model tv.ckpt] [--threads 2] [--device cuda]

The television scene of Fig. 4 (``scenescore experiment compose``: its energy, its cost, its Langevin
options) with 0 to 5 fixed clutter boxes: the Langevin stage draws ``--samples`` arrangements, then the
``alm`` stage refines all of them in one batch, twice: polishing (the default: each sample minimises
the energy until stationary) and as a repair (``polish: false``: each sample stops once feasible).
Printed per clutter level: the stages' wall times, the ratio to Langevin's, and the fraction of
samples feasible by the exact check (``Problem.check``: shapely for collisions and bounds) before and
after. ``--quick``: 300 samples and a briefly trained energy.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import torch

from scenescore.experiments.compose import langevin_options, train_energy, tv_problem
from scenescore.models import ScoreModel, load
from scenescore.problem.problem import Problem
from scenescore.scenarios.tv import TVScenario
from scenescore.solvers import Result, Solver, get


def feasible_fraction(problem: Problem, samples: np.ndarray) -> float:
    """The share of ``samples (S, N, 3)`` that pass the exact check."""
    return float(np.mean([problem.check(x).feasible for x in samples]))


def energy(path: str | None, seed: int, quick: bool, device: str = "cpu") -> ScoreModel:
    """The compose experiment's energy on ``device``: loaded from ``path`` when it exists, else trained
    (and saved there)."""
    if path and Path(path).exists():
        return load(path, device=device)
    train_scenes, _ = TVScenario().split(seed)
    model = train_energy(train_scenes, seed, quick, device=device)
    if path:
        model.save(path)
    return model


def timed(solver: Solver, problem: Problem, **kwargs: Any) -> tuple[Result, float]:
    """``solver.solve(problem, **kwargs)`` and its wall time in seconds."""
    t = time.perf_counter()
    r = solver.solve(problem, **kwargs)
    return r, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=None, help="Langevin samples per level (default 5000)")
    ap.add_argument("--quick", action="store_true", help="300 samples and a briefly trained energy")
    ap.add_argument("--levels", default="0,1,2,3,4,5", help="clutter levels (default 0,1,2,3,4,5)")
    ap.add_argument("--model", help="checkpoint of the energy: loaded if it exists, else trained and saved")
    ap.add_argument(
        "--threads", type=int, default=None, help="torch threads of both stages (default: theirs)"
    )
    ap.add_argument("--device", default="cpu", help="where the energy and both stages run (default cpu)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    samples = args.samples or (300 if args.quick else 5000)
    levels = [int(v) for v in args.levels.split(",")]
    scenario = TVScenario()
    t = time.perf_counter()
    model = energy(args.model, args.seed, args.quick, args.device)
    print(f"energy ready in {time.perf_counter() - t:.1f} s")
    _, test_scenes = scenario.split(args.seed)
    threads = {} if args.threads is None else {"threads": args.threads}
    langevin = get("langevin", **langevin_options(samples), **threads)
    alm = get("alm", **threads)
    repair = get("alm", polish=False, **threads)
    where = torch.cuda.get_device_name(model.device) if model.device.type == "cuda" else "cpu"
    print(f"\n{samples} samples per level, torch {torch.__version__}, {where}")
    print(
        "| clutter | langevin s | alm s | alm / langevin | repair s | repair / langevin | feasible before "
        "| after alm | after repair | alm statuses |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|")
    for n in levels:
        scene = scenario.clutter(test_scenes[0], n, seed=1000 * args.seed + 10 * n)
        problem = tv_problem(scene, model)
        lan, t_lan = timed(langevin, problem, seed=args.seed)
        assert lan.samples is not None
        ref, t_alm = timed(alm, problem, init=torch.as_tensor(lan.samples))
        rep, t_rep = timed(repair, problem, init=torch.as_tensor(lan.samples))
        assert ref.samples is not None and ref.sample_status is not None and rep.samples is not None
        before = feasible_fraction(problem, lan.samples)
        after = feasible_fraction(problem, ref.samples)
        after_rep = feasible_fraction(problem, rep.samples)
        statuses = ", ".join(f"{k} {v}" for k, v in sorted(Counter(ref.sample_status.tolist()).items()))
        print(
            f"| {n} | {t_lan:.2f} | {t_alm:.2f} | {t_alm / t_lan:.2f} | {t_rep:.2f} | {t_rep / t_lan:.2f} | "
            f"{before:.2%} | {after:.2%} | {after_rep:.2%} | {statuses} |",
            flush=True,
        )
    print(f"\nthreads: langevin {lan.threads}, alm {ref.threads}")


if __name__ == "__main__":
    main()
