"""K energy networks at once: what batching the models of an experiment can gain, and the limit named.

    python benchmarks/bench_models_batched.py [--models 1,4,16] [--objects 10] [--threads 2] [--device cuda]

The network work of one training iteration at the defaults, for each of K models (each with its own
weights and its own pose sets): ``chain_steps`` gradients with respect to the poses of ``batch_scenes x
negatives`` pose sets (the counter-examples' Langevin steps), then one loss pass with the weights'
gradient over ``batch_scenes x candidates`` pose sets. Two ways:

- **one by one**: each model's passes in turn, as K trainings in one process run them;
- **batched**: the K models' weights stacked (``torch.func.stack_module_state``) and every pass one
  ``torch.func.vmap`` over the models.

Both run the network's plain path (``EnergyNet._pooled`` and ``readout``, no pieces or chunks), the
same arithmetic. For each K the table prints the iterations per second per model each way, the rate
the matrix-multiply work runs at each way (one model's iteration counted by the torch profiler)
against the device's own (a large float32 matrix product on the same threads), the gap to the limit
as a number, and the batched way's gain per model. Elementwise work
(activations, sums, the neighbour graph) is not in the count, so the fraction is a lower bound of the
device's use.
"""

from __future__ import annotations

import argparse
import copy
import time
from collections.abc import Callable

import torch
from torch import Tensor, nn
from torch.func import functional_call, grad, stack_module_state, vmap
from torch.profiler import ProfilerActivity, profile

from scenescore.learn import TrainConfig
from scenescore.models.network import EnergyConfig, EnergyNet
from scenescore.runtime.devices import resolve_device


class Plain(nn.Module):
    """The network's plain path: the energy of each pose set, ``(B,)``."""

    def __init__(self, net: EnergyNet):
        super().__init__()
        self.net = net

    def forward(self, poses: Tensor, feats: Tensor, sizes: Tensor) -> Tensor:
        return self.net.readout(self.net._pooled(poses, feats, sizes, None, None, None))


def workload(cfg: TrainConfig, n: int, device: torch.device, gen: torch.Generator) -> dict[str, Tensor]:
    """One model's inputs for one iteration: chain pose sets, loss pose sets, features and sizes."""
    chains = cfg.batch_scenes * cfg.negatives
    loss = cfg.batch_scenes * (cfg.negatives + cfg.perturbed + cfg.reanchored + 1)

    def rand(*shape: int) -> Tensor:
        return torch.rand(*shape, generator=gen).to(device)

    return {
        "chain": rand(chains, n, 3) * 4,
        "loss": rand(loss, n, 3) * 4,
        "feats": rand(1, n, 12),
        "sizes": 0.5 + rand(1, n, 2),
    }


def one_iteration(model: Plain, w: dict[str, Tensor], steps: int) -> None:
    """One model's iteration, as training runs it: pose gradients, then the weights' gradient."""
    for _ in range(steps):
        x = w["chain"].clone().requires_grad_(True)
        torch.autograd.grad(model(x, w["feats"], w["sizes"]).sum(), x)
    e = model(w["loss"], w["feats"], w["sizes"])
    torch.autograd.grad(e.logsumexp(0), list(model.parameters()))


def batched_iteration(base: Plain, params: dict[str, Tensor], w: dict[str, Tensor], steps: int) -> None:
    """The same for K models in one vmapped pass each: ``params`` and ``w``'s tensors have a leading K."""

    def energy(p: dict[str, Tensor], x: Tensor, f: Tensor, s: Tensor) -> Tensor:
        return functional_call(base, p, (x, f, s))

    pose_grad = vmap(grad(lambda p, x, f, s: energy(p, x, f, s).sum(), argnums=1))
    weight_grad = vmap(grad(lambda p, x, f, s: energy(p, x, f, s).logsumexp(0)))
    for _ in range(steps):
        pose_grad(params, w["chain"], w["feats"], w["sizes"])
    weight_grad(params, w["loss"], w["feats"], w["sizes"])


def seconds(fn: Callable[[], None], device: torch.device, repeat: int) -> float:
    """The fastest of ``repeat`` timed calls of ``fn``, after one warm-up."""
    fn()
    best = float("inf")
    for _ in range(repeat):
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        t = time.perf_counter()
        fn()
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        best = min(best, time.perf_counter() - t)
    return best


def peak_flops(device: torch.device, size: int = 2048) -> float:
    """The device's float32 matrix-product rate on this process's threads (FLOP/s)."""
    a, b = torch.randn(size, size, device=device), torch.randn(size, size, device=device)
    return 2 * size**3 / seconds(lambda: (a @ b, None)[1], device, 5)


def iteration_flops(model: Plain, w: dict[str, Tensor], cfg: TrainConfig) -> float:
    """The floating-point work of one model's iteration that the profiler counts (matrix products)."""
    with profile(activities=[ProfilerActivity.CPU], with_flops=True) as prof:
        one_iteration(model, w, cfg.chain_steps)
    return float(sum(e.flops for e in prof.key_averages()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default="1,4,16", help="values of K, comma-separated")
    ap.add_argument("--objects", type=int, default=10, help="objects per pose set (dense graph)")
    ap.add_argument("--threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--repeat", type=int, default=3, help="timed iterations each way (the fastest counts)")
    ap.add_argument("--device", default="cpu", help="where the networks and pose sets live (default cpu)")
    args = ap.parse_args()
    device = resolve_device(args.device, "--device")
    torch.set_num_threads(args.threads)
    cfg = TrainConfig()
    net_cfg = EnergyConfig(feat_dim=12, edge_encoder=cfg.edge_encoder, round_invariant=True)
    gen = torch.Generator().manual_seed(0)
    peak = peak_flops(device)
    work = iteration_flops(
        Plain(EnergyNet(net_cfg)).to(device), workload(cfg, args.objects, device, gen), cfg
    )
    print(
        f"{args.objects} objects, {device}, {args.threads} thread(s); one model's iteration: {work / 1e9:.2f} GFLOP"
    )
    print(f"of matrix products; the device's float32 matrix product: {peak / 1e9:.1f} GFLOP/s\n")
    print(
        "| K models | one by one (it/s per model) | its rate | batched (it/s per model) | its rate | gain |"
    )
    print("|---:|---:|---:|---:|---:|---:|")
    for k in (int(s) for s in args.models.split(",")):
        t_one, t_all = compare(k, net_cfg, cfg, args.objects, device, gen, args.repeat)
        print(
            f"| {k} | {k / t_one:.2f} | {_rate(k * work / t_one, peak)} | {k / t_all:.2f} | "
            f"{_rate(k * work / t_all, peak)} | {t_one / t_all:.2f}x |",
            flush=True,
        )


def _rate(flops: float, peak: float) -> str:
    """A rate in GFLOP/s and as a share of the device's peak."""
    return f"{flops / 1e9:.1f} GFLOP/s ({flops / peak:.0%})"


def compare(
    k: int,
    net_cfg: EnergyConfig,
    cfg: TrainConfig,
    n: int,
    device: torch.device,
    gen: torch.Generator,
    repeat: int,
) -> tuple[float, float]:
    """Seconds of one iteration of ``k`` models, one by one and batched."""
    torch.manual_seed(0)
    nets = [Plain(EnergyNet(net_cfg)).to(device) for _ in range(k)]
    loads = [workload(cfg, n, device, gen) for _ in range(k)]
    params, _ = stack_module_state(list(nets))
    params = {name: p.detach() for name, p in params.items()}
    stacked = {key: torch.stack([w[key] for w in loads]) for key in loads[0]}
    base = copy.deepcopy(nets[0]).to("meta")

    def one_by_one() -> None:
        for m, w in zip(nets, loads):
            one_iteration(m, w, cfg.chain_steps)

    def batched() -> None:
        batched_iteration(base, params, stacked, cfg.chain_steps)

    return seconds(one_by_one, device, repeat), seconds(batched, device, repeat)


if __name__ == "__main__":
    main()
