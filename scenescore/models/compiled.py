"""The energy network's passes compiled (torch.compile, inductor): fewer, fused kernels for each training
iteration, the same function to float rounding.

Two functions per network, both of :meth:`~scenescore.models.network.EnergyNet.pooled` (the network
once its data's branches are settled) and its head:

- ``pose_grad``: a batch's energies and their gradient with respect to the poses, the gradient taken
  inside the graph (the counter-examples' Langevin steps). It is called with grad mode off, so that the
  compiler never prepares it to be differentiated again in the weights;
- ``energy``: the energies with their graph for the weights' gradient (the loss's passes), forward and
  backward both compiled (together, so that pieces differentiated side by side share one backward
  graph).

A large batch goes through either in pieces, one for each core, side by side (:class:`CompiledPoseGrad`,
:class:`CompiledEnergy`); training calls the loss's passes as one batch (its true scenes and every kind
of counter-example, :func:`scenescore.learn.loop._pass_energies`), so that the pieces are few and large.
The batch and object dimensions vary from the first call, so pieces and size groups of any size share
a graph. A network is compiled while it trains (:func:`compiling`) and is eager again after, so that
placing and evaluating a model is the same whatever trained it; Tables 1 and 2, which place many
scenes with networks of a shape they trained compiled, place with the compiled ``pose_grad`` alone
(``compiling(..., loss=False)``, :meth:`scenescore.models.ScoreModel.compiled_chains`). Compiled
networks are kept beside the network, not in it: a model pickles and copies as it always does.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from functools import partial, reduce
from itertools import accumulate
from typing import Any, TypeVar

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from ..runtime import (
    backward_with_forward,
    compile_fn,
    first_compile,
    in_parallel,
    mark_batch,
    traced_autograd,
)
from .chunks import rows_of

T = TypeVar("T")
# ``net`` below is the EnergyNet (typed Any: this module sits under network.py, which imports it)
EnergyNet = Any

__all__ = ["Compiled", "compiling", "compiled_of", "CompiledPoseGrad", "CompiledEnergy"]


class Compiled:
    """The compiled ``pose_grad`` and ``energy`` of one network (see the module's docstring)."""

    def __init__(self, net: EnergyNet, device_type: str, loss: bool = True):
        def pose_grad(*resolved: Any) -> tuple[Tensor, Tensor]:
            with torch.enable_grad():
                x = resolved[0].detach().requires_grad_(True)
                e = net.readout(net.pooled(x, *resolved[1:]))
                (g,) = torch.autograd.grad(e.sum(), x)
            return e.detach(), g.detach()

        def energy(*resolved: Any) -> Tensor:
            return net.readout(net.pooled(*resolved))

        self._pose_grad = compile_fn(pose_grad, device_type)
        self._energy = compile_fn(energy, device_type)
        self.net, self.device_type = net, device_type
        self.loss = loss  # whether passes with the weights' gradient go through ``energy`` (else eager)
        self.traced = False  # whether pose_grad has run once (its graph compiled, or read from the cache)
        self.energy_traced = False  # the same of energy

    def pose_grad(self, resolved: Sequence[Any]) -> tuple[Tensor, Tensor]:
        """``(energies (B,), their gradient in the poses (B, N, 3))`` of one batch's resolved inputs."""
        args = _contiguous(resolved)
        mark_batch(*[a for a in args if isinstance(a, Tensor)])
        with torch.no_grad(), traced_autograd():
            return self._pose_grad(*args)

    def energy(self, resolved: Sequence[Any]) -> Tensor:
        """The energies ``(B,)`` of one batch's resolved inputs, differentiable in the weights."""
        args = _contiguous(resolved)
        mark_batch(*[a for a in args if isinstance(a, Tensor)])
        with backward_with_forward():
            return self._energy(*args)


def graph_key(kind: str, c: Compiled, args: Sequence[Any]) -> str:
    """What decides the graph that ``c``'s ``kind`` pass compiles for ``args`` (the network's settings,
    which inputs are given and their kinds), naming it for :func:`~scenescore.runtime.first_compile`."""
    kinds = [
        f"{a.dtype}/{a.dim()}" if isinstance(a, Tensor) else ("-" if a is None else repr(a)) for a in args
    ]
    return f"{kind} {c.device_type} {c.net.cfg!r} {kinds}"


def _contiguous(resolved: Sequence[Any]) -> list[Any]:
    """The inputs laid out densely from the start of their own storage: a size group cropped to fewer
    objects is a strided view, and a piece of a batch starts inside the batch's storage; the compiler
    keeps one graph per layout, and another for a start at 0."""
    return [_dense(a) if isinstance(a, Tensor) else a for a in resolved]


def _dense(t: Tensor) -> Tensor:
    """``t`` contiguous, copied where it starts inside a larger storage."""
    return t.clone(memory_format=torch.contiguous_format) if t.storage_offset() else t.contiguous()


_COMPILED: weakref.WeakKeyDictionary[Any, Compiled] = weakref.WeakKeyDictionary()


def compiled_of(net: EnergyNet) -> Compiled | None:
    """``net``'s compiled passes while it is :func:`compiling`, else None."""
    return _COMPILED.get(net)


@contextmanager
def compiling(net: EnergyNet, device_type: str, on: bool = True, loss: bool = True) -> Iterator[None]:
    """Within the block ``net``'s chains (and its loss's passes, with ``loss``) run compiled (``on``),
    eager after it."""
    if not on:
        yield
        return
    _COMPILED[net] = Compiled(net, device_type, loss)
    try:
        yield
    finally:
        _COMPILED.pop(net, None)


def _first(c: Compiled, kind: str, inputs: Sequence[Any], call: Callable[[], T]) -> T:
    """A pass's first call in this process: within :func:`~scenescore.runtime.first_compile` of its
    graph, so that processes starting alike compile it once between them."""
    with first_compile(graph_key(kind, c, inputs)):
        return call()


class CompiledPoseGrad(torch.autograd.Function):
    """The energies of a batch and their gradient in the poses, ``rows`` pose sets at a time through the
    compiled ``pose_grad``, the pieces side by side (the first call's first piece alone in the calling
    thread, which traces the graph that the others then share); the backward pass scales the kept
    gradient. The other inputs and the weights get no gradient."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, c: Compiled, rows: int, *inputs: Tensor | None) -> Tensor:
        b = inputs[0].shape[0]  # type: ignore[union-attr]

        def piece(a: int) -> tuple[Tensor, Tensor]:
            part = [None if t is None else t.detach() for t in rows_of(inputs, b, a, a + rows)]
            return c.pose_grad(net.resolve(*part))

        starts = list(range(0, b, rows))
        first = [] if c.traced else [_first(c, "pose_grad", inputs, partial(piece, starts.pop(0)))]
        c.traced = True
        done = [*first, *in_parallel([partial(piece, a) for a in starts])]
        ctx.save_for_backward(torch.cat([g for _, g in done]))
        return torch.cat([e for e, _ in done])

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        (g,) = ctx.saved_tensors
        return (None, None, None, grad[:, None, None] * g, None, None, None, None, None)


class CompiledEnergy(torch.autograd.Function):
    """The energies of a batch through the compiled ``energy``, ``rows`` pose sets at a time, the pieces
    side by side, each keeping its own graph (the first call's first piece alone, as in
    :class:`CompiledPoseGrad`); the backward pass differentiates the pieces side by side and sums their
    weight gradients in the pieces' order, so the sum depends on the batch and the machine's core count,
    never on the load. ``inputs``: the six inputs of the network's forward pass, then its weights, the
    only inputs that get a gradient."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, c: Compiled, rows: int, *inputs: Tensor | None) -> Tensor:
        args = inputs[:6]
        b = args[0].shape[0]  # type: ignore[union-attr]

        def piece(a: int) -> Tensor:
            part = [None if t is None else t.detach() for t in rows_of(args, b, a, a + rows)]
            with torch.enable_grad():
                return c.energy(net.resolve(*part))

        starts = list(range(0, b, rows))
        first = [] if c.energy_traced else [_first(c, "energy", args, partial(piece, starts.pop(0)))]
        c.energy_traced = True
        ctx.pieces = [*first, *in_parallel([partial(piece, a) for a in starts])]
        ctx.weights = inputs[6:]
        return torch.cat([e.detach() for e in ctx.pieces])

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        pieces, weights = ctx.pieces, ctx.weights
        del ctx.pieces
        starts = [0, *accumulate(len(e) for e in pieces)]

        def piece(k: int) -> tuple[Tensor | None, ...]:
            with torch.enable_grad():
                out = grad[starts[k] : starts[k + 1]]
                return torch.autograd.grad(pieces[k], weights, out, allow_unused=True)

        done = in_parallel([partial(piece, k) for k in range(len(pieces))])
        summed: list[Tensor | None] = []
        for k in range(len(weights)):
            parts = [g for d in done if (g := d[k]) is not None]
            summed.append(reduce(torch.add, parts) if parts else None)
        return (None, None, None, *([None] * 6), *summed)
