"""Training and placement alone, then beside CPU-bound background processes: the slowdown under load.

    python benchmarks/bench_load.py [--iterations 20] [--busy 2] [--threads auto,2] [--all-tasks]

Each task runs alone and then beside ``--busy`` processes that spin on the CPU (started and stopped here,
also on an error or Ctrl-C), back to back; the slowdown is loaded / alone, and "same result" says
whether the two runs gave the same weights (training) or the same poses (placement), bit for bit.
Tasks: training on 48 dining scenes (16 scenes x 16 chains a batch), placing one object of a scene
(``place``: 64 particles), one object in each of 4 scenes at once (``place_many``: 256 particles in one
batch), and a room: training on zoo-classroom's 48 scenes of 25 to 40 objects (``--room-iterations``,
the local graph) and placing three chairs in each of 2 test scenes.

Thread settings: ``auto`` is the default (no ``--threads``: large batches in pieces on the cores other
processes leave free); a number ``N`` is ``--threads N`` (up to N pieces at once whatever the load).
Numbers run the dining training only, unless ``--all-tasks``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import torch

import scenescore as ss
from scenescore.experiments.zoo import zoo_cases
from scenescore.learn import TrainConfig, fit
from scenescore.models import ScoreModel
from scenescore.planning.placement import place, place_many
from scenescore.runtime.cores import free_cores

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


def timed(fn: Callable[[], object]) -> tuple[float, str]:
    """Seconds ``fn`` took, and a fingerprint of what it returned (weights or poses)."""
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, fingerprint(out)


def fingerprint(out: object) -> str:
    """A hash of a model's weights, or of the poses of a scene or of a list of scenes."""
    h = hashlib.sha256()
    if isinstance(out, ScoreModel):
        for v in out.net.state_dict().values():
            h.update(v.detach().cpu().numpy().tobytes())
    else:
        for s in out if isinstance(out, list) else [out]:
            h.update(np.asarray([o.pose for o in s.objects], dtype=np.float64).tobytes())
    return h.hexdigest()[:12]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=20, help="training iterations (default 20)")
    ap.add_argument(
        "--room-iterations", type=int, default=10, help="the room's training iterations (default 10)"
    )
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

    print(
        f"load benchmark: {os.cpu_count()} cores, torch {torch.__version__} on {torch.get_num_threads()} "
        f"threads by default, {args.busy} busy background processes; load average at start "
        f"{os.getloadavg()[0]:.1f} (other users of the machine count too)",
        flush=True,
    )
    tasks = _tasks(args.iterations, args.room_iterations)
    print(
        "\n| task | threads | alone (s) | loaded (s) | slowdown | same result | free cores seen: alone, loaded |"
    )
    print("|---|---:|---:|---:|---:|---|---:|", flush=True)
    for n in settings:
        for name, fn in tasks if n is None or args.all_tasks else tasks[:1]:
            with ss.thread_budget(n):
                alone, a = timed(fn)
                seen = [free_cores()]
                with busy(args.busy):
                    loaded, b = timed(fn)
                    seen.append(free_cores())
            print(
                f"| {name} | {'auto' if n is None else n} | {alone:.1f} | {loaded:.1f} | {loaded / alone:.1f}x | "
                f"{'yes' if a == b else 'NO'} | {', '.join('-' if c is None else f'{c:.1f}' for c in seen)} |",
                flush=True,
            )
    print(f"\ntarget (issue 11): training and placement at most 3x slower beside {args.busy} busy processes")
    print("target (issue 44): the same result alone and loaded, in every row")


def _tasks(iterations: int, room_iterations: int) -> list[tuple[str, Callable[[], object]]]:
    """The benchmark's tasks, their models trained first (which warms up too)."""
    scenes = ss.scenarios.get("dining").generate(48, 0)
    model = fit(scenes[:8], TrainConfig(iterations=iterations), seed=0, progress=False)
    holes = [s.without(s.objects[1].name) for s in scenes[:4]]
    room = ss.scenarios.get("zoo-classroom")
    room_train, room_test = room.split(0)
    room_cfg = TrainConfig(iterations=room_iterations)
    room_model = fit(room_train, room_cfg, seed=0, progress=False)
    rooms = [c.scene for c in zoo_cases(room, room_test, 0)[:2]]
    cfg = TrainConfig(iterations=iterations)
    return [
        (
            f"train ({len(scenes)} scenes, {iterations} it)",
            lambda: fit(scenes, cfg, seed=0, progress=False),
        ),
        ("place (1 scene, 64 particles)", lambda: place(model, holes[0], seed=0)),
        ("place_many (4 scenes, 256 particles)", lambda: place_many(model, holes, seed=0)),
        (
            f"train a room ({len(room_train)} classroom scenes, {room_iterations} it)",
            lambda: fit(room_train, room_cfg, seed=0, progress=False),
        ),
        ("place in a room (3 chairs x 2 scenes)", lambda: place_many(room_model, rooms, seed=0)),
    ]


if __name__ == "__main__":
    main()
