"""The energy network's forward and backward: the message layer as it is against the same layer with
f's last linear inside the sum over neighbours (as it was), same weights, interleaved runs.

    python benchmarks/bench_network.py [--scenes 256] [--repeat 5]

Prints seconds per forward+backward (gradient with respect to the poses, as a Langevin step takes
it) for 12 and 28 objects, one thread, and the ratio.
"""

from __future__ import annotations

import argparse
import time

import torch
from torch import Tensor

from scenescore.models.network import EnergyConfig, EnergyNet, _MessageLayer


def unfolded(layer: _MessageLayer, v: Tensor, e: Tensor | None, pair: Tensor) -> Tensor:
    """The layer with f's last linear applied to every edge before the masked sum (the old form)."""
    m = layer.w_i(v)[:, :, None, :] + layer.w_j(v)[:, None, :, :]
    if layer.w_e is not None and e is not None:
        m = m + layer.w_e(e)
    if layer.out is not None:
        m = layer.out(layer.act(m))
    return layer.act((m * pair[..., None]).sum(dim=2))


def seconds(net: EnergyNet, x: Tensor, f: Tensor, sz: Tensor, repeat: int) -> float:
    t = time.perf_counter()
    for _ in range(repeat):
        xx = x.clone().requires_grad_(True)
        torch.autograd.grad(net(xx, f, sz).sum(), xx)
    return (time.perf_counter() - t) / repeat


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(0)
    net = EnergyNet(EnergyConfig(feat_dim=7))
    folded = _MessageLayer.forward
    print("| objects | summed, then linear (s) | linear per edge (s) | ratio |\n|---:|---:|---:|---:|")
    for n in (12, 28):
        x, f, sz = (
            torch.randn(args.scenes, n, 3),
            torch.randn(args.scenes, n, 7),
            torch.rand(args.scenes, n, 2),
        )
        new, old = [], []
        for _ in range(2):  # interleaved, so that load on the machine falls on both
            _MessageLayer.forward = folded  # type: ignore[method-assign]
            new.append(seconds(net, x, f, sz, args.repeat))
            _MessageLayer.forward = unfolded  # type: ignore[method-assign,assignment]
            old.append(seconds(net, x, f, sz, args.repeat))
        _MessageLayer.forward = folded  # type: ignore[method-assign]
        print(f"| {n} | {min(new):.3f} | {min(old):.3f} | {min(old) / min(new):.2f}x |")


if __name__ == "__main__":
    main()
