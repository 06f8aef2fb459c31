"""Rooms: training and placement time against the number of objects, dense graph and local graph.

    python benchmarks/bench_rooms.py [--sizes 4,10,20,40,60,100] [--iterations 12] [--full]
    python benchmarks/bench_rooms.py --place-with classroom.ckpt
    python benchmarks/bench_rooms.py --sizes 100 --write rooms100.jsonl

Each size ``N`` is a zoo-classroom (``ClassroomScenario``) of ``N / 2`` desks, each with its chair, the
room grown with the desks so that their density stays a classroom's. For each size and graph:

- **train s/it**: seconds per training iteration at the defaults (48 scenes, 16 a batch): the time of
  ``--iterations`` iterations less that of two; **600 it (s)**: that times the default 600
  iterations (an estimate: the full run of the ``--full`` table measures it);
- **place (s)**: ``ss.place`` of a scene with three chairs missing (the default options), with the
  model of those few iterations: the time, not the placement's quality, which the zoo measures.

A third table times the aggregation alone, forward and backward: the local graph's padded sum over
each node's ``S`` neighbours against an edge-list scatter (``index_add_``, what PyTorch Geometric's
``scatter(..., reduce="sum")`` runs without the compiled ``torch-scatter``, whose PyPI release has no
wheel for this torch) of the same messages.

One thread (``thread_budget(1)``), as a laptop's worker. ``--full`` adds the issue's measure: full
default training on 48 scenes of 10 objects and of 40 (the ratio of the two), and placing three chairs
in a 40-object scene with that model. ``--place-with CKPT`` times only that placement, in five
40-object scenes, with a model you trained (``scenescore train`` on zoo-classroom data, say).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

import torch

import scenescore as ss
from scenescore.learn import TrainConfig
from scenescore.runtime.threads import thread_budget
from scenescore.scenarios.zoo.classroom import ClassroomScenario
from scenescore.scene.scene import Scene, write_jsonl

MISSING = 3


def classroom(objects: int) -> ClassroomScenario:
    """A classroom of ``objects / 2`` desks (and chairs); rows of up to 6 desks, the room grown to fit."""
    desks = max(2, objects // 2)
    cols = min(6, desks)
    rows = math.ceil(desks / cols)
    half = (max(6.0, cols + 1.0), max(5.0, 0.9 * rows + 1.5))
    return ClassroomScenario(desks=(desks, desks), columns=(cols,), max_rows=rows, half=half)


def seconds_per_iteration(
    scenes: Sequence[Scene], graph: str, timed: int
) -> tuple[float, ss.models.ScoreModel]:
    """Seconds per training iteration: the wall time of ``timed + 2`` iterations less that of 2 (the
    set-up and the trust reference cancel), over ``timed``; and the longer run's model."""
    walls = []
    model = None
    for iterations in (2, timed + 2):
        t = time.perf_counter()
        model = ss.learn.fit(
            list(scenes), TrainConfig(iterations=iterations, graph=graph), seed=0, progress=False
        )
        walls.append(time.perf_counter() - t)
    assert model is not None
    return (walls[1] - walls[0]) / timed, model


def place_seconds(model: ss.models.ScoreModel, scene: Scene) -> float:
    """Wall time of placing the scene's first ``MISSING`` chairs back (their poses removed)."""
    chairs = [o.name for o in scene.objects if o.category == "chair"][:MISSING]
    todo = scene
    for name in chairs:
        todo = todo.without(name)
    t = time.perf_counter()
    ss.place(model, todo, seed=0)
    return time.perf_counter() - t


def sweep(sizes: list[int], timed: int) -> None:
    seconds_per_iteration(classroom(4).generate(8, 0), "dense", 1)  # warm-up: first calls pay set-up
    print("| objects | graph | train s/it | 600 it (s) | place 3 (s) |")
    print("|---:|---|---:|---:|---:|")
    for n in sizes:
        scenes = classroom(n).generate(48, 0)
        for graph in ("dense", "local"):
            per_it, model = seconds_per_iteration(scenes, graph, timed)
            placing = place_seconds(model, classroom(n).generate(1, 1)[0])
            print(f"| {n} | {graph} | {per_it:.3f} | {600 * per_it:.0f} | {placing:.2f} |", flush=True)


def aggregation(rows: int = 64, objects: int = 40, slots: int = 6, hidden: int = 32) -> None:
    """The padded neighbour sum against the edge-list scatter of the same messages, forward and backward."""
    g = torch.Generator().manual_seed(0)
    m = torch.randn(rows, objects, slots, hidden, generator=g)
    w = torch.rand(rows, objects, slots, generator=g)
    receiver = torch.arange(rows * objects).repeat_interleave(slots)

    def padded() -> None:
        x = m.clone().requires_grad_(True)
        (x * w[..., None]).sum(dim=2).sum().backward()

    def scatter() -> None:
        x = m.clone().requires_grad_(True)
        msg = (x * w[..., None]).reshape(-1, hidden)
        torch.zeros(rows * objects, hidden).index_add(0, receiver, msg).sum().backward()

    print()
    print(f"| aggregation, {rows} x {objects} objects x {slots} neighbours | ms |")
    print("|---|---:|")
    for name, fn in (("padded sum", padded), ("edge-list scatter (index_add)", scatter)):
        times = []
        for _ in range(20):
            t = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t)
        print(f"| {name} | {1000 * sorted(times)[len(times) // 2]:.2f} |")


def full() -> None:
    """The issue's measure: default training on 48 scenes of 10 and of 40 objects, then placing."""
    times = {}
    models = {}
    for n in (10, 40):
        scenes = classroom(n).generate(48, 0)
        t = time.perf_counter()
        models[n] = ss.learn.fit(scenes, TrainConfig(), seed=0, progress=False)
        times[n] = time.perf_counter() - t
    scene = classroom(40).generate(1, 1)[0]
    placing = place_seconds(models[40], scene)
    print()
    print("| training, 48 scenes, defaults | 10 objects (s) | 40 objects (s) | ratio | place 3 of 40 (s) |")
    print("|---|---:|---:|---:|---:|")
    print(f"| one thread | {times[10]:.0f} | {times[40]:.0f} | {times[40] / times[10]:.2f} | {placing:.2f} |")


def placing_only(model: ss.models.ScoreModel, scenes: int = 5) -> None:
    """``place`` of 3 chairs in each of ``scenes`` 40-object classroom scenes with ``model``, as a user
    runs it (the default thread budget), after one warm-up placement."""
    rooms = classroom(40).generate(scenes + 1, 1)
    place_seconds(model, rooms[0])
    times = sorted(place_seconds(model, s) for s in rooms[1:])
    print("| place 3 of 40 objects | min (s) | median (s) | max (s) |")
    print("|---|---:|---:|---:|")
    print(f"| {scenes} scenes | {times[0]:.2f} | {times[len(times) // 2]:.2f} | {times[-1]:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="4,10,20,40,60,100", help="objects per scene, comma-separated")
    ap.add_argument("--iterations", type=int, default=12, help="timed training iterations per size")
    ap.add_argument("--full", action="store_true", help="also the full training of 10 and 40 objects")
    ap.add_argument(
        "--place-with",
        metavar="CKPT",
        help="only time placing 3 chairs of 40-object scenes with this trained classroom model (5 scenes)",
    )
    ap.add_argument(
        "--write",
        metavar="JSONL",
        help="only write 48 rooms of the first of --sizes objects (seed 0) to this file, for `scenescore train`",
    )
    args = ap.parse_args()
    if args.write:
        n = int(args.sizes.split(",")[0])
        write_jsonl(args.write, classroom(n).generate(48, 0))
        print(f"wrote 48 rooms of {n} objects to {args.write}")
        return
    if args.place_with:
        placing_only(ss.models.load(args.place_with))
        return
    with thread_budget(1):
        sweep([int(s) for s in args.sizes.split(",")], args.iterations)
        aggregation()
        if args.full:
            full()


if __name__ == "__main__":
    main()
