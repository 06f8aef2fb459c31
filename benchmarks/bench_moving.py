"""One object moving in a room: the whole local network against the nodes it reaches alone.

    python benchmarks/bench_moving.py [--sizes 40,100,200] [--sets 512] [--threads 1]

Placing one object (``scenescore place`` of a missing chair, ``train``'s and ``evaluate``'s held-out
placements) evaluates pose sets in which every other object stays put.
:class:`scenescore.models.moving.MovingOne` computes the rest of the scene once and, per pose set, only
the nodes within the network's layers of the moving object. For each room size (a zoo-classroom
grown as ``bench_rooms.py`` grows it, a model of the training defaults' shape with random weights):
pose sets per second without a gradient (screening candidates) and with the pose gradient (a chain's
step), both ways, the best of ``--repeat`` runs, and the largest difference of the energies.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import torch

import scenescore as ss
from scenescore.learn.data import local_radius
from scenescore.runtime.threads import thread_budget

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench_rooms' classrooms of N objects
from bench_rooms import classroom  # noqa: E402

LENGTH = 0.225  # a classroom's length scale at the training defaults (its chairs')


def best(fn: Callable[[], object], repeat: int) -> float:
    """The fastest of ``repeat`` runs of ``fn``, after one untimed."""
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def row(objects: int, sets: int, repeat: int) -> dict[str, float]:
    scene = classroom(objects).generate(1, 0)[0]
    torch.manual_seed(0)
    radius = local_radius([scene], LENGTH, 6)
    model = ss.models.ScoreModel.create(
        ss.FootprintEncoder(), neighbours=6, radius=radius, length_scale=LENGTH, edge_encoder=32
    )
    st = model.tensors([scene])
    o = next(k for k, ob in enumerate(scene.objects) if ob.category == "chair")
    mover = model.moving_one(st, o)
    assert mover is not None, "a local network on a room: the moving evaluator applies"
    whole_fn = model.energy_fn_for(st)
    g = torch.Generator().manual_seed(0)
    lo, hi = (torch.as_tensor(b, dtype=torch.float32) for b in scene.bounds)
    poses = st.poses.expand(sets, -1, -1).clone()
    poses[:, o, :2] = lo + (hi - lo) * torch.rand(sets, 2, generator=g)
    poses[:, o, 2] = 6.283 * torch.rand(sets, generator=g)

    def no_grad(fn: Callable[[torch.Tensor], torch.Tensor | None]) -> Callable[[], object]:
        def run() -> object:
            with torch.no_grad():
                return fn(poses)

        return run

    def with_grad(fn: Callable[[torch.Tensor], torch.Tensor | None]) -> Callable[[], object]:
        def run() -> object:
            x = poses.clone().requires_grad_(True)
            e = fn(x)
            assert e is not None
            return torch.autograd.grad(e.sum(), x)[0]

        return run

    with torch.no_grad():
        e_whole, e_mine = whole_fn(poses), mover(poses)
    assert e_mine is not None
    return {
        "whole": sets / best(no_grad(whole_fn), repeat),
        "mine": sets / best(no_grad(mover), repeat),
        "whole_g": sets / best(with_grad(whole_fn), repeat),
        "mine_g": sets / best(with_grad(mover), repeat),
        "diff": float((e_whole - e_mine).abs().max()),
        "scale": float(e_whole.abs().max()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="40,100,200", help="objects per room, comma-separated")
    ap.add_argument("--sets", type=int, default=512, help="pose sets per evaluation")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per figure (the best is kept)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (and worker threads)")
    args = ap.parse_args()
    print(f"pose sets per second, {args.sets} a batch, one object moving, {args.threads} thread(s)\n")
    print(
        "| objects | whole, no gradient | moving, no gradient | ratio | whole, gradient | moving, gradient | ratio | max energy difference |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    with thread_budget(args.threads):
        for n in (int(s) for s in args.sizes.split(",")):
            r = row(n, args.sets, args.repeat)
            print(
                f"| {n} | {r['whole']:,.0f} | {r['mine']:,.0f} | {r['mine'] / r['whole']:.2f}x | "
                f"{r['whole_g']:,.0f} | {r['mine_g']:,.0f} | {r['mine_g'] / r['whole_g']:.2f}x | "
                f"{r['diff']:.1e} (of {r['scale']:.2g}) |",
                flush=True,
            )


if __name__ == "__main__":
    main()
