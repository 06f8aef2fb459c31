"""Training and placement alone, then beside CPU-bound background processes: the slowdown under load.

    python benchmarks/bench_load.py [--iterations 20] [--busy 2] [--threads auto,2] [--all-tasks]

Each task runs alone and then beside ``--busy`` processes that spin on the CPU (started and stopped here,
also on an error or Ctrl-C), back to back; the slowdown is loaded / alone. Tasks: training on 48 dining
scenes (16 scenes x 16 chains a batch), placing one object of a scene (``place``: 64 particles), and one
object in each of 4 scenes at once (``place_many``: 256 particles in one batch).

Thread settings: ``auto`` is the default (no ``--threads``: one thread for tiny tensors, the free cores
for large batches); a number ``N`` is ``--threads N`` (large batches on N threads whatever the load).
The machine's core count shows training as it ran before threads were chosen for it; numbers run a
quarter of the training iterations and no placement (placements at 64 particles run on one thread
either way; on every thread, batched ones and the full training take minutes on a busy machine),
unless ``--all-tasks``.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import torch

import scenescore as ss
from scenescore.learn import TrainConfig, train
from scenescore.placement import place, place_many
from scenescore.threads import free_cores

# a CPU-bound process that stops by itself when the benchmark is gone (even if it was killed)
SPIN = "import os, sys\nparent = int(sys.argv[1])\nwhile os.getppid() == parent:\n    sum(range(200_000))\n"


@contextmanager
def busy(n: int) -> Iterator[None]:
    """``n`` CPU-bound background processes for the duration of the block, always stopped after."""
    procs: list[subprocess.Popen] = []
    try:
        for _ in range(n):
            procs.append(
                subprocess.Popen([sys.executable, "-c", SPIN, str(os.getpid())], start_new_session=True)
            )
        time.sleep(1.0)  # running flat out before the clock starts
        yield
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def timed(fn: Callable[[], object]) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=20, help="training iterations (default 20)")
    ap.add_argument("--busy", type=int, default=2, help="background processes (default 2)")
    ap.add_argument(
        "--threads",
        default=f"auto,{os.cpu_count() or 1}",
        help="thread settings, comma-separated: auto and/or numbers (default: auto and the core count)",
    )
    ap.add_argument("--all-tasks", action="store_true", help="every task for numeric settings too")
    args = ap.parse_args()
    settings: list[int | None] = [None if s == "auto" else int(s) for s in args.threads.split(",")]
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a kill runs the clean-up too

    scenes = ss.scenarios.get("dining").generate(48, 0)
    cfg = TrainConfig(iterations=args.iterations)
    print(
        f"load benchmark: {os.cpu_count()} cores, torch {torch.__version__} on {torch.get_num_threads()} "
        f"threads by default, {args.busy} busy background processes; load average at start "
        f"{os.getloadavg()[0]:.1f} (other users of the machine count too)",
        flush=True,
    )
    model = train(scenes[:8], TrainConfig(iterations=args.iterations), seed=0, progress=False)  # warm-up
    holes = [s.without(s.objects[1].name) for s in scenes[:4]]
    short = TrainConfig(iterations=max(1, args.iterations // 4))

    def training(c: TrainConfig) -> tuple[str, Callable[[], object]]:
        return f"train ({len(scenes)} scenes, {c.iterations} it)", lambda: train(
            scenes, c, seed=0, progress=False
        )

    tasks: list[tuple[str, Callable[[], object]]] = [
        training(cfg),
        ("place (1 scene, 64 particles)", lambda: place(model, holes[0], seed=0)),
        ("place_many (4 scenes, 256 particles)", lambda: place_many(model, holes, seed=0)),
    ]
    print("\n| task | threads | alone (s) | loaded (s) | slowdown | free cores seen: alone, loaded |")
    print("|---|---:|---:|---:|---:|---:|", flush=True)
    for n in settings:
        for name, fn in tasks if n is None or args.all_tasks else [training(short)]:
            with ss.thread_budget(n):
                alone = timed(fn)
                seen = [free_cores()]
                with busy(args.busy):
                    loaded = timed(fn)
                    seen.append(free_cores())
            print(
                f"| {name} | {'auto' if n is None else n} | {alone:.1f} | {loaded:.1f} | {loaded / alone:.1f}x | "
                f"{', '.join('-' if c is None else f'{c:.1f}' for c in seen)} |",
                flush=True,
            )
    print(f"\ntarget (issue 11): training and placement at most 3x slower beside {args.busy} busy processes")


if __name__ == "__main__":
    main()
