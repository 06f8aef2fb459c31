"""Train the small dining-table energy the other examples use, and save it as a checkpoint.

    python examples/train_model.py [--iterations 300] [--out examples/dining.ckpt]

About 45 s on one CPU core for 300 iterations.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

import scenescore as ss
from scenescore.learn import NetworkConfig, TrainConfig, fit


def main(argv: list[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--out", default=str(Path(__file__).with_name("dining.ckpt")))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)  # tiny tensors: one thread is several times faster than a contended pool
    scenes = ss.scenarios.get("dining").generate(48, args.seed)
    t = time.perf_counter()
    model = fit(
        scenes,
        TrainConfig(iterations=args.iterations, members=1, network=NetworkConfig(hidden=32, layers=2)),
        progress=not args.quiet,
        seed=args.seed,
    )
    model.save(args.out)
    print(f"trained {args.iterations} iterations in {time.perf_counter() - t:.1f} s -> {args.out}")
    return Path(args.out)


if __name__ == "__main__":
    main()
