"""The hinge collision cost, forward and forward+backward: the full computation against the fast path.

    python benchmarks/bench_collision.py [--samples 5000] [--clutter 0,1,2,3,4,5,22] [--repeat 3] [--threads 1]

The television scene of Fig. 4 (``scenescore experiment compose``): the television and two speakers
moving, 0 to 5 fixed clutter boxes (N = 3 to 8 objects; 22 boxes: N = 25), every pair with a moving
object. Two populations of ``--samples`` pose sets: ``start``, the moving objects uniform in the room
(where a Langevin chain starts), and ``settled``, the scenario's own arrangements of them (where it
ends). ``old``: every pair through the plain kernel (the computation before the fast path); ``new``:
pairs screened by their bounding circles, the split-coordinate kernel, the gradient taken only on the
overlapping pairs. Both are timed in one run, alternately; each figure is the median of ``--repeat``.
``same``: the new values and gradients equal the old bit for bit. ``near``: the share of pairs whose
bounding circles touch (computed exactly), ``overlap``: the share that overlap (carry a gradient).
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
from scenescore.problem import Problem
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
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    scenario = TVScenario()
    _, test = scenario.split(args.seed)
    print(f"{args.samples} pose sets, {args.threads} thread(s), torch {torch.__version__}; times in ms")
    print(
        "| N | pairs | poses | near | overlap | forward old | new | old / new "
        "| fwd+bwd old | new | old / new | same |"
    )
    print("|---:|---:|:---|---:|---:|---:|---:|---:|---:|---:|---:|:---|")
    for n in [int(v) for v in args.clutter.split(",")]:
        scene = scenario.clutter(test[0], n, seed=1000 * args.seed + 10 * n)
        problem = Problem(scene, HingeCollision(margin=0.0), movable=scene.unknown)
        new = problem.cost["collision"]
        assert isinstance(new, HingeCollision)
        old = copy.copy(new)
        old._path = "reference"
        for name, x in populations(scenario, problem, args.samples, args.seed).items():
            same = torch.equal(forward(new, x), forward(old, x))
            same &= all(torch.equal(a, b) for a, b in zip(forward_backward(new, x), forward_backward(old, x)))
            times: dict[tuple[str, str], list[float]] = {}
            for _ in range(args.repeat):
                for label, term in (("old", old), ("new", new)):
                    times.setdefault((label, "f"), []).append(timed(forward, term, x))
                    times.setdefault((label, "fb"), []).append(timed(forward_backward, term, x))
            ms = {k: 1000 * statistics.median(v) for k, v in times.items()}
            with torch.no_grad():
                near = float(new._near(x).float().mean())
                overlap = float((new.constraints(x) < 0).float().mean())
            print(
                f"| {len(scene)} | {len(new.support())} | {name} | {near:.1%} | {overlap:.1%} "
                f"| {ms['old', 'f']:.0f} | {ms['new', 'f']:.1f} | {ms['old', 'f'] / ms['new', 'f']:.1f} "
                f"| {ms['old', 'fb']:.0f} | {ms['new', 'fb']:.1f} | {ms['old', 'fb'] / ms['new', 'fb']:.1f} "
                f"| {'yes' if same else 'NO'} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
