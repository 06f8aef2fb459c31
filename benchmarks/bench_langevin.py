"""Langevin throughput (scene-steps per second) and training time, on this machine's CPU.

    python benchmarks/bench_langevin.py [--threads 2] [--train-iterations 1200]

A scene-step is one Langevin step (energy, gradient, update, projection) for one scene of N objects.
"""

from __future__ import annotations

import argparse
import time

import torch

from scenescore.encoders import FootprintEncoder
from scenescore.models import ScoreModel
from scenescore.sampling import LangevinConfig, langevin, uniform_init
from scenescore.scenarios import DiningScenario
from scenescore.training import TrainConfig, train


def throughput(model: ScoreModel, n: int, b: int, steps: int = 20) -> float:
    """Scene-steps per second for ``b`` particles of ``n`` objects."""
    scene = DiningScenario(settings=(n + 3) // 4).generate(1, 0)[0]
    scene.objects = scene.objects[:n]
    fn = model.energy_fn(scene)
    gen = torch.Generator().manual_seed(0)
    lo, hi = torch.tensor(scene.bounds[0]), torch.tensor(scene.bounds[1])
    x0 = uniform_init((b, n), lo, hi, gen)
    movable = torch.ones(n, dtype=torch.bool)
    langevin(fn, x0, movable, lo, hi, LangevinConfig(steps=2), gen)  # warm-up
    t = time.perf_counter()
    langevin(fn, x0, movable, lo, hi, LangevinConfig(steps=steps), gen)
    return b * steps / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--train-iterations", type=int, default=TrainConfig().iterations)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    cfg = TrainConfig(iterations=args.train_iterations)
    model = ScoreModel.create(FootprintEncoder(), **cfg.model)
    c = model.config
    print(
        f"Langevin throughput, torch {torch.__version__}, {args.threads} thread(s), "
        f"hidden {c.hidden}, {c.layers} layers, {c.message} messages, {c.activation}"
    )
    print("| N | B=64 scene-steps/s | B=512 scene-steps/s |")
    print("|---:|---:|---:|")
    for n in (4, 8, 12):
        print(f"| {n} | {throughput(model, n, 64):,.0f} | {throughput(model, n, 512):,.0f} |", flush=True)
    train_s, _ = DiningScenario().split(0)
    t = time.perf_counter()
    m = train(train_s, cfg, seed=0, progress=False)
    dt = time.perf_counter() - t
    print(
        f"\ntraining: {len(train_s)} dining scenes (8 objects), {cfg.iterations} iterations, "
        f"{cfg.batch_scenes} scenes x {cfg.negatives} chains x {cfg.chain_steps} steps per iteration: "
        f"{dt:.1f} s ({1000 * dt / cfg.iterations:.0f} ms/iteration), final InfoNCE loss "
        f"{m.info['final_loss']:.3f} (chance {m.info['chance_loss']:.3f})"
    )


if __name__ == "__main__":
    main()
