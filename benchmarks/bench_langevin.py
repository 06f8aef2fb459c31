"""Langevin throughput (scene-steps per second) and training time, on this machine's CPU or a GPU.

    python benchmarks/bench_langevin.py [--threads 2] [--train-iterations 1200] [--device cuda]

A scene-step is one Langevin step (energy, gradient, update, projection) for one scene of N objects;
populations of 64, 512 and 5000 (Fig. 4's) particles. ``--device``: where the model, the particles
and their random numbers live (the training too).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict

import torch

from scenescore.encoders import FootprintEncoder
from scenescore.geometry.poses import uniform_init
from scenescore.learn import TrainConfig, fit
from scenescore.models import ScoreModel
from scenescore.runtime.devices import generator, resolve_device
from scenescore.scenarios import DiningScenario
from scenescore.solvers.kernel import LangevinConfig, Limits, langevin


def throughput(model: ScoreModel, n: int, b: int, steps: int = 20) -> float:
    """Scene-steps per second for ``b`` particles of ``n`` objects."""
    scene = DiningScenario(settings=(n + 3) // 4).generate(1, 0)[0]
    scene.objects = scene.objects[:n]
    fn = model.energy_fn(scene)
    dev = model.device
    gen = generator(0, dev)
    lo, hi = torch.tensor(scene.bounds[0], device=dev), torch.tensor(scene.bounds[1], device=dev)
    x0 = uniform_init((b, n), lo, hi, gen)
    movable = torch.ones(n, dtype=torch.bool, device=dev)
    limits = Limits(movable, lo, hi)
    langevin(fn, x0, limits, LangevinConfig(steps=2), gen)  # warm-up
    synchronize(dev)
    t = time.perf_counter()
    langevin(fn, x0, limits, LangevinConfig(steps=steps), gen)
    synchronize(dev)
    return b * steps / (time.perf_counter() - t)


def synchronize(device: torch.device) -> None:
    """Wait for ``device``'s queued work (a no-op on the CPU), so that wall times are the work's."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--train-iterations", type=int, default=TrainConfig().iterations)
    ap.add_argument("--device", default="cpu", help="where the model and the particles live (default cpu)")
    args = ap.parse_args()
    device = resolve_device(args.device, "--device")
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    cfg = TrainConfig(iterations=args.train_iterations)
    model = ScoreModel.create(FootprintEncoder(), **asdict(cfg.network)).to(device)
    c = model.config
    where = torch.cuda.get_device_name(device) if device.type == "cuda" else f"{args.threads} CPU thread(s)"
    print(
        f"Langevin throughput, torch {torch.__version__}, {where}, "
        f"hidden {c.hidden}, {c.layers} layers, {c.message} messages, {c.activation}"
    )
    sizes = (64, 512, 5000)
    print("| N | " + " | ".join(f"B={b} scene-steps/s" for b in sizes) + " |")
    print("|---:|" + "---:|" * len(sizes))
    for n in (4, 8, 12):
        rates = [f"{throughput(model, n, b):,.0f}" for b in sizes]
        print(f"| {n} | " + " | ".join(rates) + " |", flush=True)
    train_s, _ = DiningScenario().split(0)
    synchronize(device)
    t = time.perf_counter()
    m = fit(train_s, cfg, seed=0, progress=False, device=device)
    synchronize(device)
    dt = time.perf_counter() - t
    print(
        f"\ntraining: {len(train_s)} dining scenes (8 objects), {cfg.iterations} iterations, "
        f"{cfg.batch_scenes} scenes x {cfg.negatives} chains x {cfg.chain_steps} steps per iteration: "
        f"{dt:.1f} s ({1000 * dt / cfg.iterations:.0f} ms/iteration), final InfoNCE loss "
        f"{m.info.final_loss:.3f} (chance {m.info.chance_loss:.3f})"
    )


if __name__ == "__main__":
    main()
