"""Training iterations eager and compiled, beside the work each iteration does and the machine's rate.

    python benchmarks/bench_training.py [--scenarios dining,zoo-classroom,rooms-100] [--iterations 8]
        [--warmup 2] [--threads 1] [--device cpu] [--whole [--block 100]]

For each scenario (48 scenes of it at the training defaults; ``rooms-100``: classrooms of 100 objects,
half desks, half chairs, as ``benchmarks/bench_rooms.py`` builds them) two trainings from the same seed,
one eager (``compile="off"``) and one compiled (``compile="on"``), their iterations interleaved so that
the machine's speed drifts alike for both:

- **eager / compiled (s/it)**: the median seconds per iteration after ``--warmup`` iterations each (the
  compiled one's first iterations compile its passes: **compile (s)** is their time less the median's,
  in this process, with the compiled-kernel cache this machine already has), and their ratio;
  **600 it (s)**: the default training's iterations at those medians, the compiled one's compile added;
- **GFLOP/it**: the floating-point work of one eager iteration (torch's FLOP counter: matrix products
  and convolutions, the bulk), **calls/it**: the aten operations it dispatches;
- **GFLOP/s** eager and compiled: that work over each median, against the machine's own rate for it,
  **mm GFLOP/s**: float32 matrix products of the network's shapes (its width, a large batch of rows),
  on the same threads. The gap to the limit is their ratio.

``--whole`` checks the 600-iteration column against a whole training instead: one compiled training of
each scenario for the training default's iterations, the seconds of each block of ``--block``
iterations (the first block's include the compile) and their sum.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import torch
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils.flop_counter import flop_registry

import scenescore as ss
from scenescore.learn import TrainConfig
from scenescore.learn.loop import Training
from scenescore.runtime.devices import resolve_device
from scenescore.runtime.threads import thread_budget

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench_rooms' classrooms of N objects
from bench_rooms import classroom  # noqa: E402


class Work(TorchDispatchMode):
    """Counts the aten operations dispatched inside the block (this thread's), and their floating-point
    operations where torch's FLOP counter knows the operation (matrix products, the bulk)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: Counter[str] = Counter()
        self.flops = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):  # noqa: ANN001
        kwargs = kwargs or {}
        out = func(*args, **kwargs)
        self.calls[str(func.overloadpacket)] += 1
        count = flop_registry.get(func.overloadpacket)
        if count is not None:
            self.flops += count(*args, **kwargs, out_val=out)
        return out


def scenes_of(name: str) -> list[ss.Scene]:
    if name.startswith("rooms-"):
        return classroom(int(name.split("-")[1])).generate(48, 0)
    return ss.scenarios.get(name).generate(48, 0)


def matmul_rate(width: int, device: torch.device, rows: int = 65536, repeat: int = 20) -> float:
    """GFLOP/s of ``(rows, width) @ (width, width)`` float32 products here."""
    a = torch.randn(rows, width, device=device)
    w = torch.randn(width, width, device=device)
    for _ in range(3):
        a @ w
    t = time.perf_counter()
    for _ in range(repeat):
        a @ w
    if device.type == "cuda":
        torch.cuda.synchronize()
    return 2 * rows * width * width * repeat / (time.perf_counter() - t) / 1e9


def timed_step(tr: Training) -> float:
    """One iteration's seconds, inside the training's session (held open by the caller, as ``fit``
    holds it for the whole run)."""
    t = time.perf_counter()
    tr.step()
    if tr.device.type == "cuda":
        torch.cuda.synchronize()
    return time.perf_counter() - t


def work_of(scenes: list[ss.Scene], device: torch.device) -> tuple[float, int]:
    """GFLOP and aten calls of one eager iteration (after a first one, so that the chains are warm), on
    one thread: a dispatch mode counts its own thread's operations, so every piece runs in it."""
    tr = Training(scenes, TrainConfig(compile="off"), None, 0, device)
    with thread_budget(1), tr.session():
        timed_step(tr)
        work = Work()
        with work:
            timed_step(tr)
    return work.flops / 1e9, sum(work.calls.values())


def row(name: str, args: argparse.Namespace, device: torch.device) -> str:
    scenes = scenes_of(name)
    eager = Training(scenes, TrainConfig(compile="off"), None, 0, device)
    compiled = Training(scenes, TrainConfig(compile="on"), None, 0, device)
    first: dict[str, list[float]] = {"eager": [], "compiled": []}
    times: dict[str, list[float]] = {"eager": [], "compiled": []}
    with eager.session(), compiled.session():
        for _ in range(args.warmup):
            first["compiled"].append(timed_step(compiled))
            first["eager"].append(timed_step(eager))
        for k in range(args.iterations):
            order = (
                (("eager", eager), ("compiled", compiled))
                if k % 2
                else (("compiled", compiled), ("eager", eager))
            )
            for label, tr in order:
                times[label].append(timed_step(tr))
    e, c = statistics.median(times["eager"]), statistics.median(times["compiled"])
    compile_s = sum(first["compiled"]) - args.warmup * c
    gflop, calls = work_of(scenes, device)
    mm = matmul_rate(eager.derived.energy.hidden, device)
    n = sum(len(s) for s in scenes) / len(scenes)
    graph = "local" if eager.derived.energy.local else "dense"
    return (
        f"| {name} | {n:.0f} | {graph} | {e:.3f} | {c:.3f} | {e / c:.2f}x | {600 * e:.0f} | "
        f"{600 * c + compile_s:.0f} | {compile_s:.0f} | {gflop:.2f} | {calls:,} | {gflop / e:.1f} | "
        f"{gflop / c:.1f} | {mm:.1f} | {100 * gflop / c / mm:.0f}% |"
    )


def whole(name: str, block: int, device: torch.device) -> str:
    """One compiled training of ``name`` at the defaults, timed block by block: a table row."""
    cfg = TrainConfig(compile="on")
    tr = Training(scenes_of(name), cfg, None, 0, device)
    blocks: list[tuple[float, int]] = []  # (seconds, iterations) of each block
    with tr.session():
        for first in range(0, cfg.iterations, block):
            its = min(block, cfg.iterations - first)
            t = time.perf_counter()
            for _ in range(its):
                tr.step()
            if device.type == "cuda":
                torch.cuda.synchronize()
            blocks.append((time.perf_counter() - t, its))
    per = " | ".join(f"{sec / its:.3f}" for sec, its in blocks)
    return f"| {name} | {cfg.iterations} | {per} | {sum(sec for sec, _ in blocks):.0f} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", default="dining,zoo-classroom,rooms-100", help="comma-separated")
    ap.add_argument("--iterations", type=int, default=8, help="timed iterations of each (default 8)")
    ap.add_argument("--warmup", type=int, default=2, help="iterations first, not timed (default 2)")
    ap.add_argument("--threads", type=int, default=1, help="the thread budget (default 1)")
    ap.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    ap.add_argument(
        "--whole", action="store_true", help="one whole compiled training of each, block by block"
    )
    ap.add_argument("--block", type=int, default=100, help="iterations a block with --whole (default 100)")
    args = ap.parse_args()
    device = resolve_device(args.device, "--device")
    print(f"torch {torch.__version__}, {args.threads} thread(s), {device}; times in seconds")
    if args.whole:
        blocks = -(-TrainConfig().iterations // args.block)
        print(
            "| scenario | iterations | "
            + " | ".join(f"s/it, block {k + 1}" for k in range(blocks))
            + " | total (s) |"
        )
        print("|---|---:|" + "---:|" * (blocks + 1))
        with thread_budget(args.threads):
            for name in args.scenarios.split(","):
                print(whole(name.strip(), args.block, device), flush=True)
        return
    print(
        "| scenario | objects | graph | eager s/it | compiled s/it | speedup | 600 it eager | 600 it compiled "
        "| compile (s) | GFLOP/it | calls/it | GFLOP/s eager | GFLOP/s compiled | mm GFLOP/s | of mm |"
    )
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    with thread_budget(args.threads):
        for name in args.scenarios.split(","):
            print(row(name.strip(), args, device), flush=True)


if __name__ == "__main__":
    main()
