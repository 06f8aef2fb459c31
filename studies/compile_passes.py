"""Study: can ``torch.compile`` (inductor, CPU) make a training iteration faster than eager?

A training iteration (``scenescore.learn.loop._iterate``, the training defaults ``TrainConfig()``) is
timed eager and with compiled parts, interleaved in one process (one trainer per variant, all from the
same seed, so every round draws the same batches and shapes), on one torch thread:

- ``eager``: the library as it is.
- ``frozen``: no compiling; the weights' ``requires_grad`` off while the chains run (eager), the cheap
  fix that compiling is measured against.
- ``chain``: the chains' pose gradient ``(poses, ...) -> (energy, dE/dposes)`` compiled as one function
  (``torch.func.grad_and_value`` over the message layers and the head), the library's pieces kept.
- ``chain-pooled``: the chains' energy compiled, its pose gradient by ``autograd.grad`` through the
  AOT-compiled backward (the weights' ``requires_grad`` off while the chains run, so that the compiled
  backward does not compute weight gradients nobody reads).
- ``loss``: the energies that the loss takes weight gradients of (true scenes, chains, re-anchored)
  compiled (forward and AOT backward); the chains eager.
- ``chain+loss``: both.
- ``step``: a whole Langevin step (energy, pose gradient, noise, clip, projection into the bounds,
  angle wrap) compiled as one function per size group; noise drawn outside, from the same generator in
  the same order as the library's kernel.
- ``step+loss``: both.

A suffix changes a variant: ``:max`` compiles with ``mode="max-autotune-no-cudagraphs"``, ``:func``
takes the pose gradient with ``torch.func.grad_and_value`` (else ``torch.autograd.grad`` traced into the
graph), ``:lean`` skips the chains' final energies, which ``ChainBuffer.advance`` drops (``eager:lean``,
``frozen:lean``: the same without compiling), ``:contig`` makes the compiled functions' inputs contiguous
(a size group cropped to fewer objects is a strided view: a second graph otherwise).

The compiled functions read the network through ``pooled_resolved``, the library's ``_pooled`` with its
one data-dependent branch (does any scene have a round object?) decided by the caller: compiled as it is,
``bool(round.any())`` breaks the graph (``--mode explain``).

Modes (``--mode``): ``time`` (the iteration-time table), ``numerics`` (compiled vs eager energies,
gradients, a chain's poses), ``cost`` (cold compile and warm start: child processes with a fresh
``TORCHINDUCTOR_CACHE_DIR``, then the same one again), ``threads`` (compiled functions called from
several Python threads at once; bitwise reproducibility in one process), ``explain`` (graph breaks),
``profile`` (aten calls per iteration, eager vs compiled), ``passes`` (single network passes on one
size group: the chains' pose gradient, the loss's forward and backward, a forward without gradient),
``all``.

Run pinned to one core: ``OMP_NUM_THREADS=1 taskset -c 1 python studies/compile_passes.py --mode time``.
Results: ``studies/compile_passes.md``.
"""

from __future__ import annotations

import argparse
import copy
import functools
import hashlib
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

import scenescore as ss
from scenescore.learn import TrainConfig, derive
from scenescore.learn import negatives as negatives_module
from scenescore.learn.loop import _iterate
from scenescore.learn.negatives import ChainBuffer
from scenescore.learn.size_groups import SizeGroups, cropped
from scenescore.learn.training_state import Progress, Trainer
from scenescore.models import EnergyNet, ScoreModel
from scenescore.models import network as network_module
from scenescore.models.graph import neighbour_graph, wall_nodes
from scenescore.models.network import round_flags
from scenescore.runtime import in_parallel
from scenescore.runtime.devices import draw, generator
from scenescore.solvers.kernel import langevin as library_langevin

# how a compiled function takes the pose gradient: "autograd" (torch.autograd.grad, traced into the graph
# with trace_autograd_ops: one graph for every batch and object count) or "func"
# (torch.func.grad_and_value: dynamo specialises every size under it, a graph per shape; --grad)
GRAD = "autograd"
MODE: str | None = None  # torch.compile's mode (--compile-mode)
VARIANTS = ("eager", "frozen", "chain", "chain-pooled", "loss", "chain+loss", "step", "step+loss")
SCENARIOS = ("dining", "zoo-classroom")
CPU = torch.device("cpu")

torch._dynamo.config.recompile_limit = 64  # one process holds a network per variant (see Study)
torch._dynamo.config.accumulated_recompile_limit = 4096


# ---- the network with its one data-dependent branch decided outside ------------------------------------


def resolve_round(net: EnergyNet, round: torch.Tensor | None, b: int, n: int) -> torch.Tensor | None:
    """``_pooled``'s branch taken outside the compiled region: the round flags ``(B, N)`` when the network
    ignores round disks' headings and some scene has one, else None (the plain path, the same numbers)."""
    rnd = round_flags(net.cfg, round)
    return None if rnd is None else rnd.expand(b, n)


def pooled_resolved(
    net: EnergyNet,
    poses: torch.Tensor,
    feats: torch.Tensor,
    sizes: torch.Tensor,
    mask: torch.Tensor,
    rnd: torch.Tensor | None,
) -> torch.Tensor:
    """``EnergyNet._pooled(poses, feats, sizes, mask, None, round)`` with ``rnd = resolve_round(...)``
    given: the same operations in the same order, without the ``bool(round.any())`` that breaks a
    compiled graph (checked bitwise against ``_pooled`` by ``--mode numerics``)."""
    cfg = net.cfg
    assert not cfg.absolute and not cfg.walls, "the study covers the networks of its two scenarios"
    b, n, _ = poses.shape
    v = net.node_embedding(feats, sizes)
    v = v.expand(b, n, v.shape[-1])
    maskf = mask.to(poses.dtype).expand(b, n)
    walls = wall_nodes(mask).expand(b, n) if cfg.walls else None
    index = None
    if cfg.local:
        reach = 0.5 * v[..., -2:].amax(dim=-1)
        pos = poses[..., :2] / cfg.length_scale
        index, pair = neighbour_graph(pos, reach, mask.expand(b, n), walls, cfg.neighbours, cfg.radius)
    else:
        eye = torch.eye(n, dtype=poses.dtype, device=poses.device)
        pair = maskf[:, :, None] * maskf[:, None, :] * (1 - eye)
    e = net.edges(poses, rnd, walls if net.reads_walls else None, index)
    for layer in net.layers:
        v = layer(v, e, pair, index)
    if cfg.local:
        v = net.head[1](net.head[0](v))
    return (v * maskf[..., None]).sum(dim=1)


def energy_resolved(net, poses, feats, sizes, mask, rnd):
    return net.readout(pooled_resolved(net, poses, feats, sizes, mask, rnd))


def mark(dynamic: str, *tensors: torch.Tensor | None, dims: tuple[int, ...] = (0, 1)) -> None:
    """Mark the batch (and object) dimensions dynamic (``--dynamic mark``), so that size groups and pieces
    of other sizes reuse the compiled graph."""
    if dynamic != "mark":
        return
    for t in tensors:
        if t is not None:
            for d in dims:
                if t.dim() > d:
                    (
                        torch._dynamo.mark_dynamic
                        if os.environ.get("STRICT")
                        else torch._dynamo.maybe_mark_dynamic
                    )(t, d)


def compile_fn(fn, dynamic: str, fullgraph: bool = True, mode: str | None = None):
    kw: dict[str, Any] = {"fullgraph": fullgraph}
    if mode or MODE:
        kw["mode"] = mode or MODE
    if dynamic == "true":
        kw["dynamic"] = True
    elif dynamic == "static":
        kw["dynamic"] = False
    return torch.compile(fn, **kw)


# ---- the compiled pieces of one network ----------------------------------------------------------------


class Study:
    """The compiled functions of one network for one variant, reached through its patched ``forward``
    (chains and loss) and the patched Langevin kernel (``step``)."""

    def __init__(self, net: EnergyNet, variant: str, dynamic: str = "mark", fullgraph: bool = True):
        self.net, self.variant, self.dynamic = net, variant, dynamic
        name, *flags = variant.split(":")
        mode = "max-autotune-no-cudagraphs" if "max" in flags else None
        grad = "func" if "func" in flags else GRAD
        self.lean = "lean" in flags  # the chains skip their final energies (advance drops them)
        # the compiled functions' inputs made contiguous: a size group cropped to fewer objects than the
        # batch's widest is a strided view, and its strides are guarded on (a second graph otherwise)
        self.contig = "contig" in flags
        parts = set(name.split("+"))
        modes = {"chain": "grad", "chain-pooled": "pooled", "frozen": "frozen"}
        self.chain_mode = next((modes[p] for p in parts if p in modes), None)
        self.loss = "loss" in parts
        self.step = "step" in parts

        def pose_grad_func(poses, feats, sizes, mask, rnd):
            def total(p):
                e = energy_resolved(net, p, feats, sizes, mask, rnd)
                return e.sum(), e

            g, (_, e) = torch.func.grad_and_value(total, has_aux=True)(poses)
            return e, g

        def pose_grad_autograd(poses, feats, sizes, mask, rnd):
            # traced into the graph with torch._dynamo.config.trace_autograd_ops (see GRAD)
            with torch.enable_grad():
                x = poses.detach().requires_grad_(True)
                e = energy_resolved(net, x, feats, sizes, mask, rnd)
                (g,) = torch.autograd.grad(e.sum(), x)
            return e.detach(), g.detach()

        pose_grad = pose_grad_func if grad == "func" else pose_grad_autograd

        def energy(poses, feats, sizes, mask, rnd):
            return energy_resolved(net, poses, feats, sizes, mask, rnd)

        def step(x, w, lam, clip, scale, lo, hi, move_b, feats, sizes, mask, rnd):
            """One step of ``scenescore.solvers.kernel.langevin`` (its ``step``), the same operations."""
            _, g = pose_grad(x, feats, sizes, mask, rnd)
            gn = g * scale
            delta = torch.maximum(torch.minimum(lam * (gn + w), clip), -clip)
            moved = x - delta * scale
            moved = torch.cat(
                [
                    torch.minimum(torch.maximum(moved[..., :2], lo), hi),
                    torch.remainder(moved[..., 2:] + math.pi, 2 * math.pi) - math.pi,
                ],
                dim=-1,
            )
            return torch.where(move_b, moved, x), torch.isfinite(g).all()

        self.pose_grad_c = (
            compile_fn(pose_grad, dynamic, fullgraph, mode) if self.chain_mode == "grad" else None
        )
        self.chain_energy_c = (
            compile_fn(energy, dynamic, fullgraph, mode) if self.chain_mode == "pooled" else None
        )
        self.loss_energy_c = compile_fn(energy, dynamic, fullgraph, mode) if self.loss else None
        self.step_c = compile_fn(step, dynamic, fullgraph, mode) if self.step else None

    def c(self, t: torch.Tensor | None) -> torch.Tensor | None:
        return t.contiguous() if self.contig and t is not None else t

    # -- the chains' pose gradient, in the library's pieces (EnergyNet.forward's rule)
    def pieces(self, b: int, n: int, itemsize: int) -> int:
        net = self.net
        rows = net.chunk_rows(n, True, itemsize)
        per_row = n * net.reads(n)
        piece = min(rows, max(1, network_module.CACHE_EDGES // per_row))
        edges = b * per_row
        if edges >= 2 * network_module.PIECE_EDGES:
            cores = network_module.usable_cores()
            piece = min(piece, -(-b // min(cores, edges // network_module.PIECE_EDGES)))
        return piece

    def pose_grad(self, poses, feats, sizes, mask, rnd, piece: int | None = None):
        """``(energy (B,), dE/dposes (B, N, 3))``, the batch in the library's pieces side by side."""
        b, n, _ = poses.shape
        piece = piece or self.pieces(b, n, poses.element_size())

        def one(a: int):
            args = [
                self.c(t if t is None or t.shape[0] != b else t[a : a + piece])
                for t in (poses, feats, sizes, mask, rnd)
            ]
            args[0] = args[0].detach()
            mark(self.dynamic, *args)
            # under no_grad (grad_and_value takes its own gradient): with grad mode on and the weights
            # requiring grad, AOTAutograd builds a graph differentiable once more in the weights and
            # the compiled function ran no faster than eager (--mode explain's note)
            with torch.no_grad():
                return self.pose_grad_c(*args)

        done = in_parallel([functools.partial(one, a) for a in range(0, b, piece)])
        if len(done) == 1:
            return done[0]
        return torch.cat([e for e, _ in done]), torch.cat([g for _, g in done])


class PoseGradFn(torch.autograd.Function):
    """As ``scenescore.models.chunks.PoseGradInPieces``: the energy, its pose gradient kept for backward."""

    @staticmethod
    def forward(ctx, study: Study, poses, feats, sizes, mask, rnd):
        e, g = study.pose_grad(poses, feats, sizes, mask, rnd)
        ctx.save_for_backward(g)
        return e.detach()

    @staticmethod
    def backward(ctx, grad):
        (g,) = ctx.saved_tensors
        return None, grad[:, None, None] * g, None, None, None, None


@contextmanager
def frozen_weights(net: EnergyNet):
    params = [p for p in net.parameters() if p.requires_grad]
    for p in params:
        p.requires_grad_(False)
    try:
        yield
    finally:
        for p in params:
            p.requires_grad_(True)


_library_forward = EnergyNet.forward


def study_forward(self, poses, feats, sizes, mask=None, nodes=None, round=None, weight_grads=True):
    """``EnergyNet.forward`` with the variant's compiled functions where they apply (else the library's)."""
    s: Study | None = getattr(self, "_study", None)
    if s is None or nodes is not None or feats is None or mask is None or not torch.is_grad_enabled():
        return _library_forward(self, poses, feats, sizes, mask, nodes, round, weight_grads)
    b, n, _ = poses.shape
    if not weight_grads and poses.requires_grad and s.chain_mode is not None:
        if s.chain_mode == "frozen":  # eager, the weights' requires_grad off while the chains run
            with frozen_weights(self):
                return _library_forward(self, poses, feats, sizes, mask, nodes, round, weight_grads)
        rnd = resolve_round(self, round, b, n)
        if s.chain_mode == "grad":
            return PoseGradFn.apply(s, poses, feats, sizes, mask, rnd)
        poses, feats, sizes, mask, rnd = (s.c(t) for t in (poses, feats, sizes, mask, rnd))
        mark(s.dynamic, poses, feats, sizes, mask, rnd)
        with frozen_weights(self):
            return s.chain_energy_c(poses, feats, sizes, mask, rnd)
    if weight_grads and s.loss:
        assert b <= self.chunk_rows(n, True, poses.element_size()), "a chunked batch: not in the study"
        rnd = resolve_round(self, round, b, n)
        poses, feats, sizes, mask, rnd = (s.c(t) for t in (poses, feats, sizes, mask, rnd))
        mark(s.dynamic, poses, feats, sizes, mask, rnd)
        return s.loss_energy_c(poses, feats, sizes, mask, rnd)
    return _library_forward(self, poses, feats, sizes, mask, nodes, round, weight_grads)


# the size groups' energy callable, carrying its groups for the compiled step
_library_bound = SizeGroups.bound


class Bound:
    def __init__(self, fn, groups: SizeGroups, model: ScoreModel, st, k: int):
        self.fn, self.groups, self.model, self.st, self.k = fn, groups, model, st, k
        self._parts = None

    def __call__(self, poses):
        return self.fn(poses)

    def parts(self):
        """``[(rows or None, n, cropped tensors)]`` as ``SizeGroups.bound`` cuts them."""
        if self._parts is None:
            st, k = self.st, self.k
            if len(self.groups.groups) == 1:
                self._parts = [(None, st.poses.shape[1], st)]
            else:
                self._parts = []
                for scenes, n in self.groups.groups:
                    r = torch.tensor([i * k + j for i in scenes for j in range(k)], device=st.poses.device)
                    self._parts.append((r, n, cropped(st.index(r), n)))
        return self._parts


def study_bound(self, model, st, k=1, weight_grads=True):
    return Bound(_library_bound(self, model, st, k, weight_grads), self, model, st, k)


def _without_final_energies(energy_fn):
    """``energy_fn`` whose calls without gradient (the kernel's final energies, which
    ``ChainBuffer.advance`` drops; training's chains resample never) return zeros instead."""

    def fn(poses):
        if torch.is_grad_enabled():
            return energy_fn(poses)
        return torch.zeros(poses.shape[0], dtype=poses.dtype)

    return fn


def study_langevin(
    energy_fn,
    init,
    movable,
    lo,
    hi,
    cfg=None,
    generator=None,
    project=None,
    age=None,
    run_steps=None,
    groups=1,
):
    """``langevin`` for training's chains with each step compiled (the library's otherwise)."""
    model = getattr(energy_fn, "model", None)
    s: Study | None = getattr(model.net, "_study", None) if model is not None else None
    plain = cfg is None or project is not None or cfg.resample or cfg.heading_sweep or cfg.final_descent
    if s is not None and s.lean and not s.step and not plain:  # eager chains without their final energies
        energy_fn = _without_final_energies(energy_fn)
    if s is None or not s.step or plain or age is None:
        return library_langevin(
            energy_fn, init, movable, lo, hi, cfg, generator, project, age, run_steps, groups
        )
    net = model.net
    x = init.detach().clone()
    b, n, _ = x.shape
    dtype = x.dtype
    lo = lo.to(dtype).reshape(-1, 1, 2).expand(b, 1, 2)
    hi = hi.to(dtype).reshape(-1, 1, 2).expand(b, 1, 2)
    half = (hi - lo) / 2
    pi = torch.full((b, 1, 1), math.pi, dtype=dtype, device=x.device)
    scale = torch.cat([half, pi], dim=-1)
    move_b = movable.reshape(-1, n).expand(b, n)[..., None].bool()
    # each size group's chains on their own (a group's gradient reads its own rows alone)
    groups_ = []
    for r, m, sub in energy_fn.parts():
        sel = (lambda t: t) if r is None else (lambda t, r=r: t[r])
        feats, sizes, mask = s.c(sub.feats), s.c(sub.sizes), s.c(sub.mask)
        rnd = s.c(resolve_round(net, sub.round, feats.shape[0], m))
        groups_.append(
            [
                r,
                m,
                sel(x)[:, :m].contiguous(),
                sel(scale),
                sel(lo).contiguous(),
                sel(hi).contiguous(),
                sel(move_b)[:, :m].contiguous(),
                feats,
                sizes,
                mask,
                rnd,
            ]
        )
    total = cfg.steps if run_steps is None else run_steps
    for t in range(total):
        lam = torch.as_tensor(cfg.step_size((age + t).to(dtype))).reshape(b, 1, 1)
        w = draw("randn", tuple(x.shape), generator, x.device, dtype) * cfg.noise
        clip = torch.as_tensor(cfg.clip(lam), dtype=dtype, device=x.device)
        for gr in groups_:
            r, m, xg, sc, lo_g, hi_g, mv, feats, sizes, mask, rnd = gr
            sel = (lambda t_: t_) if r is None else (lambda t_, r=r: t_[r])
            wg, lam_g, clip_g = sel(w)[:, :m].contiguous(), sel(lam), sel(clip)
            mark(s.dynamic, xg, wg, mv, feats, sizes, mask, rnd)
            mark(s.dynamic, lam_g, clip_g, sc, lo_g, hi_g, dims=(0,))
            with torch.no_grad():
                xg, ok = s.step_c(xg, wg, lam_g, clip_g, sc, lo_g, hi_g, mv, feats, sizes, mask, rnd)
            if not bool(ok):
                raise FloatingPointError("Langevin: the energy's gradient is not finite")
            gr[2] = xg
    for r, m, xg, *_ in groups_:
        if r is None:
            x[:, :m] = xg
        else:
            x[r, :m] = xg
    if s.lean:
        return x.detach(), None
    with torch.no_grad():
        e = energy_fn(x)  # as the library's kernel (ChainBuffer.advance drops it)
    return x.detach(), e.detach()


def install() -> None:
    """The study's patches: per-network forward (a no-op for networks without a ``_study``), the size
    groups' callable carrying its groups, the chains' kernel. The library's code is not changed."""
    EnergyNet.forward = study_forward
    SizeGroups.bound = study_bound
    negatives_module.langevin = study_langevin


install()


# ---- trainers ------------------------------------------------------------------------------------------


@dataclass
class Run:
    variant: str
    t: Trainer
    cfg: TrainConfig
    d: Any
    data: Any
    progress: Progress = field(default_factory=Progress)
    it: int = 0
    times: list[float] = field(default_factory=list)
    warm: list[float] = field(default_factory=list)
    graphs_warm: int = 0
    graphs_timed: int = 0

    def iterate(self) -> float:
        t0 = time.perf_counter()
        _iterate(self.t, self.cfg, self.d, self.data, self.progress, None, self.it)
        self.it += 1
        return time.perf_counter() - t0


_scenes: dict[str, list] = {}


def scenes_of(name: str):
    if name not in _scenes:
        _scenes[name] = ss.scenarios.get(name).generate(48, 0)
    return _scenes[name]


def make_run(scenario: str, variant: str, dynamic: str, seed: int = 0, fullgraph: bool = True) -> Run:
    """A trainer as ``fit`` builds it (same seed: the same weights, chains and batches for every variant)."""
    scenes = scenes_of(scenario)
    cfg = TrainConfig()
    torch.manual_seed(seed)
    gen = generator(seed, CPU)
    d = derive(cfg, scenes)
    model = ScoreModel(EnergyNet(d.energy), d.encoder)
    data = model.tensors(scenes)
    buf = ChainBuffer(data, cfg.negatives, cfg, gen)
    opt = torch.optim.AdamW(model.net.parameters(), lr=d.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(
        opt, T_max=max(cfg.iterations, 1), eta_min=cfg.lr_final
    )
    if variant != "eager":
        model.net._study = Study(model.net, variant, dynamic, fullgraph)
    return Run(variant, Trainer(model, opt, sched, buf, gen), cfg, d, data)


def graphs() -> int:
    return int(torch._dynamo.utils.counters["stats"]["unique_graphs"])


def median(xs):
    return statistics.median(xs) if xs else float("nan")


# ---- mode: time ----------------------------------------------------------------------------------------


def mode_time(args) -> dict:
    out = {}
    for scenario in args.scenarios:
        runs = [make_run(scenario, v, args.dynamic) for v in args.variants]
        for r in runs:  # warm-up, compiles included
            for _ in range(args.warmup):
                g0 = graphs()
                r.warm.append(r.iterate())
                r.graphs_warm += graphs() - g0
        for k in range(args.iterations):  # interleaved, order rotated each round
            order = runs[k % len(runs) :] + runs[: k % len(runs)]
            for r in order:
                g0 = graphs()
                r.times.append(r.iterate())
                r.graphs_timed += graphs() - g0
        eager = next((r for r in runs if r.variant == "eager"), None)
        rows = []
        print(
            f"\n{scenario}: median of {args.iterations} interleaved iterations after {args.warmup} warm-up"
            f" (dynamic={args.dynamic})"
        )
        print(
            f"{'variant':<12} {'median ms':>10} {'speedup':>8} {'paired':>7} {'warm-up s':>10} "
            f"{'graphs warm/timed':>18} {'loss after':>11}"
        )
        for r in runs:
            med = median(r.times)
            sp = median(eager.times) / med if eager else float("nan")
            paired = median([a / b for a, b in zip(eager.times, r.times)]) if eager else float("nan")
            rows.append(
                {
                    "variant": r.variant,
                    "median_s": med,
                    "speedup": sp,
                    "paired": paired,
                    "warmup_s": sum(r.warm),
                    "graphs_warm": r.graphs_warm,
                    "graphs_timed": r.graphs_timed,
                    "loss": r.progress.history[-1],
                }
            )
            print(
                f"{r.variant:<12} {med * 1e3:>10.1f} {sp:>8.2f} {paired:>7.2f} {sum(r.warm):>10.1f} "
                f"{r.graphs_warm:>8d}/{r.graphs_timed:<9d} {r.progress.history[-1]:>11.5f}"
            )
        out[scenario] = rows
    return out


# ---- mode: numerics ------------------------------------------------------------------------------------


def rel(a: torch.Tensor, b: torch.Tensor) -> tuple[float, float]:
    """``(max |a - b|, max |a - b| / max |b|)``."""
    d = (a.detach().double() - b.detach().double()).abs().max().item()
    return d, d / max(b.detach().double().abs().max().item(), 1e-30)


class Recorder:
    """The network calls of one iteration: ``(kind, poses, feats, sizes, mask, round)``."""

    def __init__(self):
        self.calls: list[tuple] = []
        self.on = False

    def __call__(self, net, poses, feats, sizes, mask, round, weight_grads):
        if self.on and torch.is_grad_enabled() and feats is not None:
            kind = "loss" if weight_grads else "chain"
            self.calls.append((kind, poses.detach().clone(), feats, sizes, mask, round))


def mode_numerics(args) -> dict:
    return {scenario: _numerics(args, scenario) for scenario in args.scenarios}


def _numerics(args, scenario: str) -> dict:
    print(f"\n{scenario}: compiled vs eager, float32 (max abs diff, and relative to the largest value)")
    base = make_run(scenario, "eager", args.dynamic)
    for _ in range(args.warmup):
        base.iterate()
    rec = Recorder()
    forward = EnergyNet.forward

    def recording(self, poses, feats, sizes, mask=None, nodes=None, round=None, weight_grads=True):
        rec(self, poses, feats, sizes, mask, round, weight_grads)
        return forward(self, poses, feats, sizes, mask, nodes, round, weight_grads)

    state = snapshot(base)
    EnergyNet.forward = recording
    rec.on = True
    base.iterate()
    rec.on = False
    EnergyNet.forward = forward
    net = base.t.model.net
    chain_calls = [c for c in rec.calls if c[0] == "chain"]
    loss_calls = [c for c in rec.calls if c[0] == "loss"]
    res: dict[str, Any] = {"chain_calls": len(chain_calls), "loss_calls": len(loss_calls)}
    print(
        f"  one iteration: {len(chain_calls)} chain calls (energy + pose gradient), "
        f"{len(loss_calls)} loss calls (weight gradients)"
    )
    study = Study(net, "chain+loss", args.dynamic)
    # _pooled vs pooled_resolved, eager: bitwise
    same = True
    for _, poses, feats, sizes, mask, round in rec.calls[:8]:
        b, n, _ = poses.shape
        with torch.no_grad():
            a = net._pooled(poses, feats, sizes, mask, None, round)
            c = pooled_resolved(net, poses, feats, sizes, mask, resolve_round(net, round, b, n))
        same &= bool(torch.equal(a, c))
    res["resolved_bitwise"] = same
    print(f"  pooled_resolved == _pooled bitwise (eager): {same}")
    # chains: energy and pose gradient
    de = dg = re_ = rg = 0.0
    for _, poses, feats, sizes, mask, round in chain_calls:
        x = poses.clone().requires_grad_(True)
        e_ref = _library_forward(net, x, feats, sizes, mask, None, round, False)
        (g_ref,) = torch.autograd.grad(e_ref.sum(), x)
        b, n, _ = poses.shape
        e_c, g_c = study.pose_grad(poses, feats, sizes, mask, resolve_round(net, round, b, n))
        a1, r1 = rel(e_c, e_ref)
        a2, r2 = rel(g_c, g_ref)
        de, re_, dg, rg = max(de, a1), max(re_, r1), max(dg, a2), max(rg, r2)
    res["chain"] = {"energy_abs": de, "energy_rel": re_, "grad_abs": dg, "grad_rel": rg}
    print(f"  chain energy      abs {de:.2e} rel {re_:.2e}   pose grad abs {dg:.2e} rel {rg:.2e}")
    # loss: energies and weight gradients (a random weighting of the energies backpropagated)
    de = dw = re_ = rw = 0.0
    net.train()
    params = list(net.parameters())
    for _, poses, feats, sizes, mask, round in loss_calls:
        b, n, _ = poses.shape
        wts = torch.randn(b, generator=torch.Generator().manual_seed(1))
        e_ref = _library_forward(net, poses, feats, sizes, mask, None, round, True)
        g_ref = torch.autograd.grad((e_ref * wts).sum(), params)
        rnd = resolve_round(net, round, b, n)
        mark(args.dynamic, poses, feats, sizes, mask, rnd)
        e_c = study.loss_energy_c(poses, feats, sizes, mask, rnd)
        g_c = torch.autograd.grad((e_c * wts).sum(), params)
        a1, r1 = rel(e_c, e_ref)
        de, re_ = max(de, a1), max(re_, r1)
        for p, q in zip(g_c, g_ref):
            a2, r2 = rel(p, q)
            dw, rw = max(dw, a2), max(rw, r2)
    res["loss"] = {"energy_abs": de, "energy_rel": re_, "wgrad_abs": dw, "wgrad_rel": rw}
    print(
        f"  loss energy       abs {de:.2e} rel {re_:.2e}   weight grads abs {dw:.2e} rel {rw:.2e} "
        "(per tensor, worst)"
    )
    # whole chains (6 steps) and one iteration's loss, from the same state: eager vs compiled step
    runs = {}
    for v in ("eager", "step"):
        r = make_run(scenario, v, args.dynamic)
        restore(r, state)
        runs[v] = r
    neg = {}
    for v, r in runs.items():
        neg[v] = advance_once(r, steps=1), advance_once(r, steps=5)
    for v in ("step",):
        a1, r1 = rel(neg[v][0], neg["eager"][0])
        a6, r6 = rel(neg[v][1], neg["eager"][1])
        res["step_poses"] = {"after_1_abs": a1, "after_1_rel": r1, "after_6_abs": a6, "after_6_rel": r6}
        print(
            f"  chain poses, compiled step vs library kernel: after 1 step abs {a1:.2e} rel {r1:.2e};"
            f" after 6 steps abs {a6:.2e} rel {r6:.2e}"
        )
    losses = {}
    for v in ("eager", "chain+loss", "step+loss"):
        r = make_run(scenario, v, args.dynamic)
        restore(r, state)
        hist = []
        for _ in range(args.iterations):
            r.iterate()
            hist.append(r.progress.history[-1])
        losses[v] = hist
    for v in ("chain+loss", "step+loss"):
        d1 = abs(losses[v][0] - losses["eager"][0])
        dn = max(abs(a - b) for a, b in zip(losses[v], losses["eager"]))
        res[f"loss_{v}"] = {"first_abs": d1, "max_abs": dn, "iterations": args.iterations}
        print(
            f"  training loss, {v} vs eager from the same state: first iteration abs {d1:.2e}; "
            f"worst over {args.iterations} iterations abs {dn:.2e} (eager loss {losses['eager'][0]:.4f})"
        )
    return res


def snapshot(r: Run) -> dict:
    t = r.t
    return {
        "model": copy.deepcopy(t.model.net.state_dict()),
        "opt": copy.deepcopy(t.opt.state_dict()),
        "sched": copy.deepcopy(t.sched.state_dict()),
        "poses": t.buf.poses.clone(),
        "movable": t.buf.movable.clone(),
        "age": t.buf.age.clone(),
        "gen": t.gen.get_state(),
        "torch": torch.get_rng_state(),
        "it": r.it,
    }


def restore(r: Run, s: dict) -> None:
    t = r.t
    t.model.net.load_state_dict(s["model"])
    t.opt.load_state_dict(copy.deepcopy(s["opt"]))
    t.sched.load_state_dict(s["sched"])
    t.buf.poses.copy_(s["poses"])
    t.buf.movable.copy_(s["movable"])
    t.buf.age.copy_(s["age"])
    t.gen.set_state(s["gen"])
    torch.set_rng_state(s["torch"])
    r.it = s["it"]


def advance_once(r: Run, steps: int) -> torch.Tensor:
    """The chains of the scenes of rows 0..15 advanced ``steps`` steps, as ``_loss`` does it."""
    model, cfg, data, buf = r.t.model, r.cfg, r.data, r.t.buf
    rows = torch.arange(r.d.batch_scenes)
    batch = data.index(rows)
    rep = batch.repeat(cfg.negatives)
    sizes = SizeGroups(batch.mask.sum(dim=1), cfg.group_sizes)
    model.net.eval()
    neg = buf.advance(rows, sizes.bound(model, rep, cfg.negatives, weight_grads=False), rep, r.d.chain, steps)
    model.net.train()
    return neg.clone()


# ---- mode: cost (cold compile, warm start) --------------------------------------------------------------


def child_cost(args) -> dict:
    """In a fresh process (``TORCHINDUCTOR_CACHE_DIR`` set by the parent): the first iterations of one
    compiled variant, then eager iterations; compile seconds = first iterations less eager ones."""
    from torch._dynamo.utils import counters

    t_start = float(os.environ.get("STUDY_T0", time.time()))
    scenario, variant = args.scenarios[0], args.variants[0]
    comp = make_run(scenario, variant, args.dynamic)
    eager = make_run(scenario, "eager", args.dynamic)
    first = [comp.iterate() for _ in range(args.warmup)]
    late = []
    ref = []
    for _ in range(args.iterations):
        late.append(comp.iterate())
        ref.append(eager.iterate())
    digest = hashlib.sha256(json.dumps(comp.progress.history).encode()).hexdigest()[:16]
    wdig = hashlib.sha256(
        b"".join(p.detach().numpy().tobytes() for p in comp.t.model.net.parameters())
    ).hexdigest()[:16]
    return {
        "scenario": scenario,
        "variant": variant,
        "first_s": first,
        "compiled_median_s": median(late),
        "eager_median_s": median(ref),
        "compile_overhead_s": sum(first) - args.warmup * median(late),
        "process_s": time.time() - t_start,
        "graphs": graphs(),
        "inductor": dict(counters["inductor"]),
        "aot": dict(counters["aot_autograd"]),
        "loss_digest": digest,
        "weights_digest": wdig,
        "phases": phases(),
        "fx_graph_cache": torch._inductor.config.fx_graph_cache,
        "autograd_cache": torch._functorch.config.enable_autograd_cache,
    }


def phases() -> dict[str, float]:
    """Seconds spent in the main compile phases (dynamo's ``compile_times``, summed)."""
    from torch._dynamo.utils import compilation_time_metrics

    keep = (
        "_compile.compile_inner",
        "OutputGraph.call_user_compiler",
        "create_aot_dispatcher_function",
        "compile_fx_inner",
        "fx_codegen_and_compile",
        "async_compile.wait",
        "PyCodeCache.load_by_key_path",
        "build_guards",
        "bytecode_tracing",
        "backend_compile",
        "aot_collect_metadata",
        "compile_file",
        "load_by_key_path",
    )
    return {k: round(sum(v), 2) for k, v in compilation_time_metrics.items() if any(q in k for q in keep)}


def mode_cost(args) -> dict:
    out = {}
    for scenario in args.scenarios:
        for variant in [v for v in args.variants if v != "eager"]:
            with tempfile.TemporaryDirectory(prefix="inductor-") as cache:
                res = []
                for label in ("cold", "warm"):
                    env = dict(os.environ, TORCHINDUCTOR_CACHE_DIR=cache, STUDY_T0=repr(time.time()))
                    if args.precompile:
                        env["TORCH_CACHING_PRECOMPILE"] = "1"
                    cmd = [
                        sys.executable,
                        __file__,
                        "--child",
                        "cost",
                        "--scenario",
                        scenario,
                        "--variants",
                        variant,
                        "--iterations",
                        str(args.iterations),
                        "--warmup",
                        str(args.warmup),
                        "--dynamic",
                        args.dynamic,
                        "--grad",
                        args.grad,
                        "--compile-mode",
                        args.compile_mode,
                    ]
                    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
                    if p.returncode:
                        print(p.stderr[-4000:], file=sys.stderr)
                        raise SystemExit(f"child failed: {cmd}")
                    r = json.loads(p.stdout.strip().splitlines()[-1])
                    r["label"] = label
                    res.append(r)
            out[f"{scenario}/{variant}"] = res
    print(
        f"\ncold compile and warm start (first {args.warmup} iterations of a fresh process, less "
        f"{args.warmup} x the compiled median; process: start to the end of {args.warmup + args.iterations} "
        "compiled and as many eager iterations)"
    )
    print(
        f"{'scenario/variant':<26} {'':<5} {'1st it s':>9} {'overhead s':>11} {'process s':>10} "
        f"{'graphs':>7} {'fx hit/miss':>12} {'aot hit/miss':>13} {'same losses':>12}"
    )
    for key, (cold, warm) in out.items():
        for r in (cold, warm):
            ind, aot = r["inductor"], r["aot"]
            same = (
                cold["loss_digest"] == warm["loss_digest"]
                and cold["weights_digest"] == warm["weights_digest"]
            )
            print(
                f"{key:<26} {r['label']:<5} {r['first_s'][0]:>9.1f} {r['compile_overhead_s']:>11.1f} "
                f"{r['process_s']:>10.1f} {r['graphs']:>7d} "
                f"{ind.get('fxgraph_cache_hit', 0):>5}/{ind.get('fxgraph_cache_miss', 0):<6} "
                f"{aot.get('autograd_cache_hit', 0):>6}/{aot.get('autograd_cache_miss', 0):<6} "
                f"{str(same) if r is warm else '':>12}"
            )
            print(f"{'':<32} phases {r['phases']}")
    return out


# ---- mode: threads, reproducibility --------------------------------------------------------------------


def config_in_thread() -> dict:
    """torch's config as a new thread sees it, after the main thread set it (``install``/``main``)."""
    seen = {}

    def look():
        seen["trace_autograd_ops"] = torch._dynamo.config.trace_autograd_ops
        seen["recompile_limit"] = torch._dynamo.config.recompile_limit

    th = threading.Thread(target=look)
    th.start()
    th.join()
    return seen


def mode_threads(args) -> dict:
    return {scenario: _threads(args, scenario) for scenario in args.scenarios}


def _threads(args, scenario: str) -> dict:
    base = make_run(scenario, "eager", args.dynamic)
    for _ in range(2):
        base.iterate()
    net = base.t.model.net
    data = base.data
    rep = data.index(torch.arange(16)).repeat(16)
    sub = cropped(rep, int(rep.mask.sum(1).max()))
    n = sub.poses.shape[1]
    poses = base.t.buf.poses[:16].reshape(256, *base.t.buf.poses.shape[2:])[:, :n].contiguous()
    rnd = resolve_round(net, sub.round, 256, n)
    args_ = (poses, sub.feats, sub.sizes, sub.mask, rnd)
    main_cfg = {
        "trace_autograd_ops": torch._dynamo.config.trace_autograd_ops,
        "recompile_limit": torch._dynamo.config.recompile_limit,
    }
    res: dict[str, Any] = {"config_main": main_cfg, "config_new_thread": config_in_thread()}

    def race(study: Study, carry: bool) -> tuple[bool, bool, list[str]]:
        """A fresh compiled function called first from 4 threads at once (compiling under the race);
        ``carry``: each thread runs in a copy of the caller's context (its torch config)."""
        import contextvars

        errors: list[str] = []

        def call():
            try:
                return study.pose_grad(*args_, piece=64)
            except Exception as exc:  # noqa: BLE001
                errors.append(type(exc).__name__ + ": " + str(exc).splitlines()[0][:120])
                return None

        ctxs = [contextvars.copy_context() for _ in range(4)]
        with ThreadPoolExecutor(4) as ex:
            futs = [ex.submit(c.run, call) if carry else ex.submit(call) for c in ctxs]
            got = [f.result() for f in futs]
        ok = not errors and all(g is not None for g in got)
        same = ok and all(torch.equal(g[0], got[0][0]) and torch.equal(g[1], got[0][1]) for g in got)
        return ok, same, errors

    torch._dynamo.reset()
    ok, same, errs = race(Study(net, "chain", args.dynamic), carry=False)
    res["cold_race_plain_threads"] = {"ok": ok, "same": same, "errors": sorted(set(errs))}
    torch._dynamo.reset()
    study = Study(net, "chain", args.dynamic)
    g0 = graphs()
    ok, same, errs = race(study, carry=True)
    res["cold_race_context_copied"] = {
        "ok": ok,
        "same": same,
        "errors": sorted(set(errs)),
        "graphs": graphs() - g0,
    }
    # warm: serial reference, then 4 threads x 10 calls at once, plain threads (nothing to compile)
    serial = study.pose_grad(*args_, piece=64)
    again = study.pose_grad(*args_, piece=64)
    res["bitwise_repeat_serial"] = torch.equal(serial[0], again[0]) and torch.equal(serial[1], again[1])
    g0 = graphs()
    with ThreadPoolExecutor(4) as ex:
        many = list(ex.map(lambda _: study.pose_grad(*args_, piece=64), range(40)))
    res["warm_4_threads_x10_bitwise"] = all(
        torch.equal(m[1], serial[1]) and torch.equal(m[0], serial[0]) for m in many
    )
    # the library's own workers: pieces of 64 rows side by side on 4 threads (in_parallel, budget 4)
    with ss.thread_budget(4):
        par = study.pose_grad(*args_, piece=64)
    res["in_parallel_budget_4_bitwise"] = torch.equal(par[1], serial[1]) and torch.equal(par[0], serial[0])
    res["graphs_compiled_while_warm"] = graphs() - g0
    # compiled pieces of another size (another batch size for the same dynamic kernels)
    whole = study.pose_grad(*args_, piece=256)
    res["pieces_256_vs_64_rel"] = rel(whole[1], serial[1])[1]
    # whole training runs twice in one process: bitwise?
    for v in ("eager", "chain+loss", "step+loss"):
        hs = []
        for _ in range(2):
            r = make_run(scenario, v, args.dynamic)
            for _ in range(4):
                r.iterate()
            hs.append((r.progress.history, [p.detach().clone() for p in r.t.model.net.parameters()]))
        res[f"4_iterations_twice_bitwise_{v}"] = hs[0][0] == hs[1][0] and all(
            torch.equal(p, q) for p, q in zip(hs[0][1], hs[1][1])
        )
    print(f"\n{scenario}: threads and reproducibility (chain pose gradient, 256 rows in pieces of 64)")
    for k, v in res.items():
        print(f"  {k}: {v}")
    return res


# ---- mode: explain, profile ----------------------------------------------------------------------------


def mode_explain(args) -> dict:
    return {scenario: _explain(args, scenario) for scenario in args.scenarios}


def _explain(args, scenario: str) -> dict:
    base = make_run(scenario, "eager", args.dynamic)
    base.iterate()
    net = base.t.model.net
    data = base.data
    st = data.index(torch.arange(16))
    sub = cropped(st, int(st.mask.sum(1).max()))
    args_ = (sub.poses, sub.feats, sub.sizes, sub.mask, None, sub.round)
    res = {}
    for label, fn, a in (
        ("EnergyNet._pooled as it is", lambda *z: net._pooled(*z), args_),
        (
            "pooled_resolved",
            lambda *z: pooled_resolved(net, *z),
            (
                sub.poses,
                sub.feats,
                sub.sizes,
                sub.mask,
                resolve_round(net, sub.round, 16, sub.poses.shape[1]),
            ),
        ),
    ):
        torch._dynamo.reset()
        ex = torch._dynamo.explain(fn)(*a)
        reasons = sorted({str(b.reason).splitlines()[0][:110] for b in ex.break_reasons})
        res[label] = {
            "graphs": ex.graph_count,
            "breaks": ex.graph_break_count,
            "ops": ex.op_count,
            "reasons": reasons,
        }
        print(
            f"{scenario}: {label}: {ex.graph_count} graphs, {ex.graph_break_count} breaks, "
            f"{ex.op_count} ops; {reasons}"
        )
    # the pose-gradient function with fullgraph=True on the library's _pooled: does it compile?
    torch._dynamo.reset()

    def pg(poses, feats, sizes, mask, round):
        def total(p):
            e = net.readout(net._pooled(p, feats, sizes, mask, None, round))
            return e.sum(), e

        return torch.func.grad_and_value(total, has_aux=True)(poses)

    try:
        torch.compile(pg, fullgraph=True)(sub.poses, sub.feats, sub.sizes, sub.mask, sub.round)
        res["grad_fullgraph_library"] = "compiles"
    except Exception as exc:  # noqa: BLE001
        res["grad_fullgraph_library"] = type(exc).__name__ + ": " + str(exc).splitlines()[0][:160]
    print(
        f"{scenario}: grad_and_value over the library's _pooled, fullgraph=True: {res['grad_fullgraph_library']}"
    )
    return res


def mode_passes(args) -> dict:
    return {scenario: _passes(args, scenario) for scenario in args.scenarios}


def _passes(args, scenario: str) -> dict:
    """Single passes of the network on one size group of a training batch (its chains' rows), eager and
    compiled interleaved: the chains' pose gradient, the loss's forward and backward with weight
    gradients, a forward without gradient."""
    base = make_run(scenario, "eager", args.dynamic)
    for _ in range(2):
        base.iterate()
    net, data, k = base.t.model.net, base.data, base.cfg.negatives
    rows = torch.arange(base.d.batch_scenes)
    batch = data.index(rows)
    groups = SizeGroups(batch.mask.sum(dim=1), base.cfg.group_sizes)
    scenes, n = max(groups.groups, key=lambda g: len(g[0]) * g[1])  # the group with the most nodes
    r = torch.tensor([i * k + j for i in scenes for j in range(k)])
    sub = cropped(batch.repeat(k).index(r), n)
    poses = base.t.buf.poses[rows].reshape(len(rows) * k, *base.t.buf.poses.shape[2:])[r, :n]
    b = poses.shape[0]
    rnd = resolve_round(net, sub.round, b, n)
    a5 = (poses, sub.feats, sub.sizes, sub.mask, rnd)
    wts = torch.randn(b, generator=torch.Generator().manual_seed(1))
    params = list(net.parameters())
    chain = Study(net, "chain", args.dynamic)
    func = Study(net, "chain:func", args.dynamic)
    pooled = Study(net, "chain-pooled+loss", args.dynamic)

    def pose_eager():
        x = poses.clone().requires_grad_(True)
        e = _library_forward(net, x, sub.feats, sub.sizes, sub.mask, None, sub.round, False)
        return torch.autograd.grad(e.sum(), x)[0]

    def pose_frozen():
        with frozen_weights(net):
            return pose_eager()

    def pose_compiled_one_graph():
        return chain.pose_grad(*a5)[1]

    def pose_func_no_grad():
        with torch.no_grad():
            return func.pose_grad_c(*a5)[1]

    def pose_func_grad_on():  # grad mode on, the weights requiring grad: (e, g) differentiable in them
        return func.pose_grad_c(*a5)[1].detach()

    def pose_compiled_energy():
        x = poses.clone().requires_grad_(True)
        mark(args.dynamic, x, *a5[1:])
        with frozen_weights(net):
            e = pooled.chain_energy_c(x, *a5[1:])
        return torch.autograd.grad(e.sum(), x)[0]

    def loss_eager():
        e = _library_forward(net, poses, sub.feats, sub.sizes, sub.mask, None, sub.round, True)
        return torch.autograd.grad((e * wts).sum(), params)

    def loss_compiled():
        mark(args.dynamic, *a5)
        e = pooled.loss_energy_c(*a5)
        return torch.autograd.grad((e * wts).sum(), params)

    def fwd_eager():
        with torch.no_grad():
            return _library_forward(net, poses, sub.feats, sub.sizes, sub.mask, None, sub.round, True)

    def fwd_compiled():
        with torch.no_grad():
            mark(args.dynamic, *a5)
            return pooled.loss_energy_c(*a5)

    fns = {
        "pose grad, eager (library)": pose_eager,
        "pose grad, eager, weights frozen": pose_frozen,
        "pose grad, compiled one graph": pose_compiled_one_graph,
        "pose grad, compiled energy + autograd": pose_compiled_energy,
        "pose grad, compiled func.grad, no_grad": pose_func_no_grad,
        "pose grad, compiled func.grad, grad on": pose_func_grad_on,
        "loss fwd+bwd, eager": loss_eager,
        "loss fwd+bwd, compiled": loss_compiled,
        "forward no grad, eager": fwd_eager,
        "forward no grad, compiled": fwd_compiled,
    }
    first = {}
    for name, fn in fns.items():  # compiles
        t0 = time.perf_counter()
        fn()
        first[name] = time.perf_counter() - t0
    # numbers: compiled vs eager
    diff = {
        "pose one graph": rel(pose_compiled_one_graph(), pose_eager())[1],
        "pose energy+autograd": rel(pose_compiled_energy(), pose_eager())[1],
        "pose func.grad": rel(pose_func_no_grad(), pose_eager())[1],
        "loss weight grads": max(rel(a, q)[1] for a, q in zip(loss_compiled(), loss_eager())),
        "forward": rel(fwd_compiled(), fwd_eager())[1],
    }
    times: dict[str, list[float]] = {name: [] for name in fns}
    names = list(fns)
    for i in range(args.iterations):
        for name in names[i % len(names) :] + names[: i % len(names)]:
            t0 = time.perf_counter()
            fns[name]()
            times[name].append(time.perf_counter() - t0)
    med = {name: median(v) for name, v in times.items()}
    ref = {
        "pose": med["pose grad, eager (library)"],
        "loss": med["loss fwd+bwd, eager"],
        "forward": med["forward no grad, eager"],
    }
    print(
        f"\n{scenario}: one size group, {b} pose sets of {n} objects; median of {args.iterations}, interleaved"
    )
    print(f"{'pass':<40} {'median ms':>10} {'vs eager':>9} {'first call s':>13}")
    res: dict[str, Any] = {"rows": b, "objects": n, "rel_diff": diff}
    for name in names:
        kind = "pose" if name.startswith("pose") else "loss" if name.startswith("loss") else "forward"
        res[name] = {"median_s": med[name], "speedup": ref[kind] / med[name], "first_s": first[name]}
        print(f"{name:<40} {med[name] * 1e3:>10.2f} {ref[kind] / med[name]:>9.2f} {first[name]:>13.1f}")
    print("  relative differences, compiled vs eager: " + ", ".join(f"{k} {v:.1e}" for k, v in diff.items()))
    return res


def mode_profile(args) -> dict:
    from torch.profiler import ProfilerActivity, profile

    out = {}
    for scenario in args.scenarios:
        res = {}
        for v in args.variants:
            r = make_run(scenario, v, args.dynamic)
            for _ in range(args.warmup):
                r.iterate()
            with profile(activities=[ProfilerActivity.CPU]) as prof:
                r.iterate()
            ev = prof.key_averages()
            aten = sum(e.count for e in ev if e.key.startswith("aten::"))
            total_us = sum(e.self_cpu_time_total for e in ev)
            groups: dict[str, float] = {}
            for e in ev:
                k = e.key
                if (
                    "Compiled" in k
                    or "Torch-Compiled" in k
                    or k.startswith("cpp_fused")
                    or "inductor" in k.lower()
                ):
                    g = "compiled regions"
                elif k.startswith("aten::") and any(
                    s in k for s in ("mm", "addmm", "linear", "bmm", "matmul")
                ):
                    g = "aten matmul"
                elif k.startswith("aten::"):
                    g = "aten other"
                else:
                    g = "other (autograd, python)"
                groups[g] = groups.get(g, 0.0) + e.self_cpu_time_total
            top = sorted(ev, key=lambda e: -e.self_cpu_time_total)[:8]
            res[v] = {
                "aten_calls": aten,
                "self_ms": total_us / 1e3,
                "share": {k: round(x / total_us, 3) for k, x in groups.items()},
                "top": [(e.key[:48], e.count, round(e.self_cpu_time_total / 1e3, 1)) for e in top],
            }
            print(
                f"\n{scenario} {v}: {aten} aten calls, {total_us / 1e3:.0f} ms self CPU (profiled); "
                f"shares {res[v]['share']}"
            )
            for row in res[v]["top"]:
                print(f"    {row[0]:<48} x{row[1]:<6} {row[2]:>8.1f} ms")
        out[scenario] = res
    return out


# ---- main ----------------------------------------------------------------------------------------------


def main() -> None:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__,
    )
    p.add_argument("--scenario", choices=(*SCENARIOS, "both"), default="both")
    p.add_argument(
        "--mode",
        choices=("time", "passes", "numerics", "cost", "threads", "explain", "profile", "all"),
        default="time",
    )
    p.add_argument(
        "--variants",
        default=",".join(VARIANTS),
        help=f"comma-separated, of {', '.join(VARIANTS)} (default all); a compiled one with "
        "':max' appended compiles with mode='max-autotune-no-cudagraphs', with ':func' takes its "
        "pose gradient with torch.func.grad_and_value; any with ':lean' (eager:lean too) skips the chains' "
        "final energies, which ChainBuffer.advance drops; with ':contig' the compiled functions' inputs "
        "are made contiguous",
    )
    p.add_argument("--iterations", type=int, default=10, help="timed iterations per variant (default 10)")
    p.add_argument("--warmup", type=int, default=3, help="iterations before timing, compiles included")
    p.add_argument(
        "--dynamic",
        choices=("mark", "auto", "true", "static"),
        default="mark",
        help="mark: batch and object dims marked dynamic (maybe_mark_dynamic); auto: torch's "
        "default (static, then dynamic after a recompile); true: dynamic=True; static: dynamic=False",
    )
    p.add_argument(
        "--grad",
        choices=("autograd", "func"),
        default="autograd",
        help="the pose gradient inside compiled functions: torch.autograd.grad traced into the graph "
        "(trace_autograd_ops) or torch.func.grad_and_value (a graph per shape)",
    )
    p.add_argument(
        "--compile-mode",
        choices=("default", "max-autotune-no-cudagraphs", "reduce-overhead"),
        default="default",
        help="torch.compile's mode (default: its default)",
    )
    p.add_argument(
        "--precompile",
        action="store_true",
        help="--mode cost: the children with TORCH_CACHING_PRECOMPILE=1 (dynamo's own cache, experimental)",
    )
    p.add_argument("--json", type=Path, help="also write the results here")
    p.add_argument("--child", choices=("cost",), help=argparse.SUPPRESS)
    args = p.parse_args()
    args.scenarios = list(SCENARIOS) if args.scenario == "both" else [args.scenario]
    args.variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    for v in args.variants:
        if v.split(":")[0] not in VARIANTS or not set(v.split(":")[1:]) <= {"max", "func", "lean", "contig"}:
            p.error(f"unknown variant {v!r}")
    torch.set_num_threads(1)
    global GRAD
    GRAD = args.grad
    global MODE
    MODE = None if args.compile_mode == "default" else args.compile_mode
    torch._dynamo.config.trace_autograd_ops = args.grad == "autograd"
    if args.dynamic == "static":
        torch._dynamo.config.automatic_dynamic_shapes = False
    if args.child == "cost":
        print(json.dumps(child_cost(args)))
        return
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} thread, affinity {sorted(os.sched_getaffinity(0))},"
        f" fx_graph_cache {torch._inductor.config.fx_graph_cache}, autograd cache "
        f"{torch._functorch.config.enable_autograd_cache}, cache dir {os.environ.get('TORCHINDUCTOR_CACHE_DIR', 'default')}"
    )
    modes = (
        ("explain", "passes", "numerics", "time", "threads", "profile", "cost")
        if args.mode == "all"
        else (args.mode,)
    )
    results = {}
    for m in modes:
        results[m] = globals()[f"mode_{m}"](args)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
