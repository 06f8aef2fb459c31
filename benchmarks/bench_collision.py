"""The hinge collision cost, forward and forward+backward: the full computation against the fast path.

    python benchmarks/bench_collision.py [--samples 5000] [--clutter 0,1,2,3,4,5,22] [--repeat 3] [--threads 1]

The television scene of Fig. 4 (``scenescore experiment compose``): the television and two speakers
moving, 0 to 5 fixed clutter boxes (N = 3 to 8 objects; 22 boxes: N = 25), every pair with a moving
object. Two populations of ``--samples`` pose sets: ``start``, the moving objects uniform in the room
(where a Langevin chain starts), and ``settled``, the scenario's own arrangements of them (where it
ends). ``old``: every pair through the kernel; ``new``: pairs screened by their bounding circles, the
gradient taken only on the overlapping pairs. Both are timed in one run, alternately; each figure is the median of ``--repeat``.
``same``: the new values and gradients equal the old bit for bit. ``near``: the share of pairs whose
bounding circles touch (computed exactly), ``overlap``: the share that overlap (carry a gradient).

The exact check (``check``, shapely; what the experiments' correctness counts call per sample) on the
first ``--check-samples`` pose sets: ``old`` builds every object's shapely core and tests every pair,
``new`` is :meth:`HingeCollision.check`, which skips pairs whose bounding circles stay apart and
computes the signed distances once per pose set; ``same``
also requires both to find the same violated pairs in every pose set.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from collections.abc import Callable

import numpy as np
import torch

from scenescore.costs import HingeCollision
from scenescore.geometry.exact import overlap_depth_exceeds, shapely_core
from scenescore.problem.problem import Problem
from scenescore.scenarios.tv import TVScenario


def timed(
    fn: Callable[[HingeCollision, torch.Tensor], object], term: HingeCollision, x: torch.Tensor
) -> float:
    """Seconds one call ``fn(term, x)`` takes."""
    t = time.perf_counter()
    fn(term, x)
    return time.perf_counter() - t


def forward(term: HingeCollision, x: torch.Tensor) -> torch.Tensor:
    with torch.no_grad():
        return term(x)


def forward_backward(term: HingeCollision, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    xr = x.clone().requires_grad_(True)
    v = term(xr)
    (g,) = torch.autograd.grad(v.sum(), xr)
    return v.detach(), g


def check_every_pair(term: HingeCollision, poses: np.ndarray, tol: float) -> set[str]:
    """The pairs the exact check flags, as the check before the skip computed them: every object's
    shapely core, every pair tested, the signed distances computed again for each overlapping pair."""
    objs = term.binding.scene.objects
    geo = [shapely_core(o, p) for o, p in zip(objs, poses)]
    out = set()
    for k, (i, j) in enumerate(term.support()):
        (ca, ra), (cb, rb) = geo[i], geo[j]
        if overlap_depth_exceeds((ca, ra), (cb, rb), tol):
            float(term.signed_distance(torch.as_tensor(poses, dtype=torch.float64)[None])[0, k])
            out.add(f"{objs[i].name} / {objs[j].name}")
        elif term.margin > tol and ca.distance(cb) - ra - rb < term.margin - tol:
            out.add(f"{objs[i].name} / {objs[j].name}")
    return out


def check_new(term: HingeCollision, poses: np.ndarray, tol: float) -> set[str]:
    return {v.label for v in term.check(poses, tol)}


def timed_checks(
    fn: Callable[[HingeCollision, np.ndarray, float], set[str]], term: HingeCollision, x: np.ndarray
):
    """Seconds for ``fn`` over every pose set of ``x``, and what it flagged in each."""
    t = time.perf_counter()
    found = [fn(term, p, 1e-4) for p in x]
    return time.perf_counter() - t, found


def populations(scenario: TVScenario, problem: Problem, samples: int, seed: int) -> dict[str, torch.Tensor]:
    """``start``: uniform draws of the moving objects; ``settled``: the scenario's arrangements of them."""
    start = problem.initial(samples, torch.Generator().manual_seed(seed))
    settled = start.clone()
    arrangements = scenario.generate(samples, seed + 1)
    settled[:, :3] = torch.as_tensor(np.array([s.poses() for s in arrangements]), dtype=torch.float64)
    return {"start": start, "settled": settled}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=5000, help="pose sets (default 5000)")
    ap.add_argument("--clutter", default="0,1,2,3,4,5,22", help="clutter boxes (default 0,1,2,3,4,5,22)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per figure, the median kept (default 3)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    ap.add_argument(
        "--check-samples", type=int, default=500, help="pose sets for the exact check (default 500)"
    )
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    scenario = TVScenario()
    _, test = scenario.split(args.seed)
    print(f"{args.samples} pose sets, {args.threads} thread(s), torch {torch.__version__}; times in ms")
    print(
        "| N | pairs | poses | near | overlap | forward old | new | old / new "
        "| fwd+bwd old | new | old / new | check old | new | old / new | same |"
    )
    print("|---:|---:|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|")
    for n in [int(v) for v in args.clutter.split(",")]:
        scene = scenario.clutter(test[0], n, seed=1000 * args.seed + 10 * n)
        problem = Problem(scene, HingeCollision(margin=0.0), movable=scene.unknown)
        new = problem.cost["collision"]
        assert isinstance(new, HingeCollision)
        old = copy.copy(new)
        old._path = "full"
        for name, x in populations(scenario, problem, args.samples, args.seed).items():
            same = torch.equal(forward(new, x), forward(old, x))
            same &= all(torch.equal(a, b) for a, b in zip(forward_backward(new, x), forward_backward(old, x)))
            times: dict[tuple[str, str], list[float]] = {}
            for _ in range(args.repeat):
                for label, term in (("old", old), ("new", new)):
                    times.setdefault((label, "f"), []).append(timed(forward, term, x))
                    times.setdefault((label, "fb"), []).append(timed(forward_backward, term, x))
            xs = x[: args.check_samples].numpy()
            for _ in range(args.repeat):
                for label, fn in (("old", check_every_pair), ("new", check_new)):
                    dt, found = timed_checks(fn, new, xs)
                    times.setdefault((label, "c"), []).append(dt)
                    if label == "old":
                        want = found
                same &= found == want
            ms = {k: 1000 * statistics.median(v) for k, v in times.items()}
            with torch.no_grad():
                near = float(new._near(x).float().mean())
                overlap = float((new.constraints(x) < 0).float().mean())
            print(
                f"| {len(scene)} | {len(new.support())} | {name} | {near:.1%} | {overlap:.1%} "
                f"| {ms['old', 'f']:.0f} | {ms['new', 'f']:.1f} | {ms['old', 'f'] / ms['new', 'f']:.1f} "
                f"| {ms['old', 'fb']:.0f} | {ms['new', 'fb']:.1f} | {ms['old', 'fb'] / ms['new', 'fb']:.1f} "
                f"| {ms['old', 'c']:.0f} | {ms['new', 'c']:.0f} | {ms['old', 'c'] / ms['new', 'c']:.1f} "
                f"| {'yes' if same else 'NO'} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
