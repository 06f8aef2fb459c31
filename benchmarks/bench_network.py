"""The energy network's forward and backward, two comparisons with the same weights, interleaved runs.

    python benchmarks/bench_network.py [--scenes 256] [--repeat 5] [--population 5000]

1. The message layer as it is against the same layer with f's last linear inside the sum over
   neighbours (as it was): seconds per forward+backward (gradient with respect to the poses, as a
   Langevin step takes it) for ``--scenes`` pose sets of 12 and 28 objects, and the ratio.
2. A large population's gradient for the poses taken in pieces of about ``CACHE_EDGES`` edges, each
   forward and backward at once (what sampling gets, ``weight_grads=False``), against the path that
   also gives the weights their gradients (``weight_grads=True``: one pass, or, for a batch over one
   chunk of ``scenescore.runtime.memory.CHUNK_BYTES`` as every batch here is, chunks that run the forward pass
   twice): pose sets per second for ``--population`` pose sets of 4 to 12 objects and a fifth as many
   of 20 and 28, the ratio, and the largest difference between the two gradients.
3. The energy without a gradient (screening candidates), each message layer working in place in one
   tensor, against the same operations each writing a new tensor (as with a gradient): pose sets per
   second for 2048 pose sets of 12 and 28 objects (dense graph) and 1024 of 40 (local graph, 6
   neighbours), the ratio, and whether the energies are equal (they should be, bit for bit).

One thread.
"""

from __future__ import annotations

import argparse
import time

import torch
from torch import Tensor

from scenescore.models.graph import senders
from scenescore.models.network import EnergyConfig, EnergyNet, MessageLayer


def unfolded(
    layer: MessageLayer, v: Tensor, e: Tensor | None, pair: Tensor, index: Tensor | None = None
) -> Tensor:
    """The layer with f's last linear applied to every edge before the masked sum (the old form)."""
    m = layer.w_i(v)[:, :, None, :] + senders(layer.w_j(v), index)
    if layer.w_e is not None and e is not None:
        m = m + layer.w_e(e)
    if layer.out is not None:
        m = layer.out(layer.act(m))
    return layer.act((m * pair[..., None]).sum(dim=2))


def screening_table(repeat: int) -> None:
    """Comparison 3 of the module docstring."""
    print(
        "\n| objects | graph | pose sets | in place (sets/s) | new tensors (sets/s) | ratio | equal |"
        "\n|---:|---|---:|---:|---:|---:|---|"
    )
    in_place = MessageLayer._summed_in_place
    for n, b, neighbours in ((12, 2048, None), (28, 2048, None), (40, 1024, 6)):
        local = {} if neighbours is None else {"neighbours": neighbours, "radius": 6.0}
        net = EnergyNet(EnergyConfig(feat_dim=7, edge_encoder=32, **local))
        x, f, sz = torch.rand(b, n, 3) * 3, torch.randn(b, n, 7), torch.rand(b, n, 2)
        rate: dict[str, list[float]] = {"in place": [], "apart": []}
        energies = {}
        for _ in range(2):  # interleaved
            for name, form in (("in place", in_place), ("apart", MessageLayer._summed)):
                MessageLayer._summed_in_place = form  # type: ignore[method-assign]
                with torch.no_grad():
                    t = time.perf_counter()
                    for _ in range(repeat):
                        energies[name] = net(x, f, sz)
                    rate[name].append(b * repeat / (time.perf_counter() - t))
        MessageLayer._summed_in_place = in_place  # type: ignore[method-assign]
        fast, slow = max(rate["in place"]), max(rate["apart"])
        graph = "dense" if neighbours is None else f"local, {neighbours}"
        same = "yes" if torch.equal(energies["in place"], energies["apart"]) else "no"
        print(f"| {n} | {graph} | {b} | {fast:,.0f} | {slow:,.0f} | {fast / slow:.2f}x | {same} |")


def pose_grad(net: EnergyNet, x: Tensor, f: Tensor, sz: Tensor, weight_grads: bool) -> Tensor:
    """The gradient of the summed energies with respect to the poses ``x``."""
    xx = x.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(net(xx, f, sz, weight_grads=weight_grads).sum(), xx)
    return g


def seconds(net: EnergyNet, x: Tensor, f: Tensor, sz: Tensor, repeat: int) -> float:
    t = time.perf_counter()
    for _ in range(repeat):
        pose_grad(net, x, f, sz, weight_grads=True)
    return (time.perf_counter() - t) / repeat


def pieces_table(net: EnergyNet, population: int, repeat: int) -> None:
    """Comparison 2 of the module docstring."""
    print(
        "\n| objects | pose sets | in pieces (sets/s) | with weight gradients (sets/s) | ratio | largest gradient difference |"
        "\n|---:|---:|---:|---:|---:|---:|"
    )
    for n in (4, 8, 12, 20, 28):
        b = population if n <= 12 else max(population // 5, 1)
        x, f, sz = torch.randn(b, n, 3), torch.randn(b, n, 7), torch.rand(b, n, 2)
        rate: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(2):  # interleaved
            for whole in (False, True):
                t = time.perf_counter()
                for _ in range(repeat):
                    pose_grad(net, x, f, sz, weight_grads=whole)
                rate[whole].append(b * repeat / (time.perf_counter() - t))
        diff = (pose_grad(net, x, f, sz, False) - pose_grad(net, x, f, sz, True)).abs().max()
        pieces, whole = max(rate[False]), max(rate[True])
        print(f"| {n} | {b} | {pieces:,.0f} | {whole:,.0f} | {pieces / whole:.2f}x | {float(diff):.1e} |")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--population", type=int, default=5000, help="pose sets of 4 to 12 objects in table 2")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(0)
    net = EnergyNet(EnergyConfig(feat_dim=7))
    folded = MessageLayer.forward
    print("| objects | summed, then linear (s) | linear per edge (s) | ratio |\n|---:|---:|---:|---:|")
    for n in (12, 28):
        x, f, sz = (
            torch.randn(args.scenes, n, 3),
            torch.randn(args.scenes, n, 7),
            torch.rand(args.scenes, n, 2),
        )
        new, old = [], []
        for _ in range(2):  # interleaved, so that load on the machine falls on both
            MessageLayer.forward = folded  # type: ignore[method-assign]
            new.append(seconds(net, x, f, sz, args.repeat))
            MessageLayer.forward = unfolded  # type: ignore[method-assign,assignment]
            old.append(seconds(net, x, f, sz, args.repeat))
        MessageLayer.forward = folded  # type: ignore[method-assign]
        print(f"| {n} | {min(new):.3f} | {min(old):.3f} | {min(old) / min(new):.2f}x |")
    pieces_table(net, args.population, max(args.repeat // 2, 1))
    screening_table(args.repeat)


if __name__ == "__main__":
    main()
