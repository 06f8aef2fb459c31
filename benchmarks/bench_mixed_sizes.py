"""Training on scenes of mixed sizes: batches evaluated in groups of similar object counts against one
padded pass (``TrainConfig.group_sizes``), paired on this machine.

    python benchmarks/bench_mixed_sizes.py [--scenario zoo-books] [--iterations 20] [--repeats 3]

Both settings train the same scenes with the same seed, in turn (A B A B ...), so a machine whose
speed drifts slows both alike; the table gives each one's median and the ratio of the medians. The
energies of the two are the same to float rounding (``tests/test_training.py``); so are the losses.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from scenescore.learn import TrainConfig, fit
from scenescore.scenarios import get


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="zoo-books")
    ap.add_argument("--iterations", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    scenes, _ = get(args.scenario).split(0)
    counts = sorted(len(s) for s in scenes)
    times: dict[bool, list[float]] = {True: [], False: []}
    loss: dict[bool, float] = {}
    for _ in range(args.repeats):
        for grouped in (True, False):
            t = time.perf_counter()
            m = fit(
                scenes, TrainConfig(iterations=args.iterations, group_sizes=grouped), seed=0, progress=False
            )
            times[grouped].append(time.perf_counter() - t)
            loss[grouped] = m.info.final_loss
    print(
        f"{args.scenario}: {len(scenes)} scenes of {counts[0]} to {counts[-1]} objects, {args.iterations} "
        f"iterations, {args.repeats} runs each, {args.threads} thread(s)\n"
    )
    print("| batches | median s | min s | max s | final loss |")
    print("|---|---:|---:|---:|---:|")
    for grouped, label in ((False, "one padded pass"), (True, "grouped by size")):
        t = times[grouped]
        print(f"| {label} | {statistics.median(t):.1f} | {min(t):.1f} | {max(t):.1f} | {loss[grouped]:.3f} |")
    ratio = statistics.median(times[False]) / statistics.median(times[True])
    print(f"\ngrouped by size: {ratio:.2f}x faster (ratio of the medians)")


if __name__ == "__main__":
    main()
