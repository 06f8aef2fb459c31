"""A batch of pose sets through :class:`~scenescore.models.network.EnergyNet` in pieces: chunks whose
graphs are recomputed in the backward pass (bounded memory), and pieces whose pose gradients are taken
at once while their tensors are in cache."""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from ..runtime import in_parallel

# ``net`` below is the EnergyNet (typed Any: this module sits under network.py, which imports it)
EnergyNet = Any

__all__ = ["ChunkedPooled", "PoseGradInPieces", "even_piece", "pooled_in_chunks", "rows_of"]


class ChunkedPooled(torch.autograd.Function):
    """:meth:`EnergyNet._pooled` over a batch in chunks of ``rows``: the forward pass keeps no graph; the
    backward pass recomputes one chunk at a time with its graph and backpropagates through it."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, rows: int, *inputs: Tensor | None) -> Tensor:
        args = inputs[:6]
        b = _first(args).shape[0]
        ctx.net, ctx.rows, ctx.b = net, rows, b
        ctx.save_for_backward(*args)
        with torch.no_grad():
            return pooled_in_chunks(net, rows, args)

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        net, rows, b = ctx.net, ctx.rows, ctx.b
        args = ctx.saved_tensors
        want = ctx.needs_input_grad[2:]
        params = list(
            net.parameters()
        )[
            : len(want) - 6
        ]  # the weights given as inputs (or none)  # the inputs after net and rows: the six arguments, the weights
        arg_grads: list[list[Tensor]] = [[] for _ in args]
        param_grads: list[Tensor | None] = [None] * len(params)
        for a in range(0, b, rows):
            with torch.enable_grad():
                part = rows_of(args, b, a, a + rows)
                part = [
                    t.detach().requires_grad_(True) if t is not None and want[k] else t
                    for k, t in enumerate(part)
                ]
                leaves = [t for k, t in enumerate(part) if t is not None and want[k]]
                leaves += [p for k, p in enumerate(params) if want[6 + k]]
                if not leaves:
                    continue
                out = _pooled_of(net, part)
                got = list(torch.autograd.grad(out, leaves, grad[a : a + rows], allow_unused=True))
            for k, t in enumerate(part):
                if t is not None and want[k]:
                    g = got.pop(0)
                    arg_grads[k].append(torch.zeros_like(t) if g is None else g)
            for k in range(len(params)):
                if want[6 + k]:
                    g, prev = got.pop(0), param_grads[k]
                    if g is not None:
                        param_grads[k] = g if prev is None else prev + g
        out_args: list[Tensor | None] = []
        for k, t in enumerate(args):
            if t is None or not want[k]:
                out_args.append(None)
            elif t.shape[0] == b:
                out_args.append(torch.cat(arg_grads[k]))
            else:  # broadcast over the batch: its gradient is the sum over the chunks
                out_args.append(torch.stack(arg_grads[k]).sum(0))
        return (None, None, *out_args, *param_grads)


class PoseGradInPieces(torch.autograd.Function):
    """The energy of a batch and its gradient with respect to the poses, ``rows`` pose sets at a time: each
    piece runs forward and backward at once, while its tensors are in cache, and keeps only the gradient
    ``(rows, N, 3)``; the backward pass scales it. The energies come from the head over the whole batch,
    as in one pass. The other inputs and the weights get no gradient."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, rows: int, *inputs: Tensor | None) -> Tensor:
        b = _first(inputs).shape[0]

        def piece(a: int) -> tuple[Tensor, Tensor]:
            part = [None if t is None else t.detach() for t in rows_of(inputs, b, a, a + rows)]
            with torch.enable_grad():
                poses = _first(part).requires_grad_(True)
                p = _pooled_of(net, [poses, *part[1:]])
                (g,) = torch.autograd.grad(net.readout(p).sum(), poses)
            return p.detach(), g

        done = in_parallel([partial(piece, a) for a in range(0, b, rows)])
        pooled, grads = [p for p, _ in done], [g for _, g in done]
        ctx.save_for_backward(torch.cat(grads))
        with torch.no_grad():
            return net.readout(torch.cat(pooled))

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        (g,) = ctx.saved_tensors
        return (None, None, grad[:, None, None] * g, None, None, None, None, None)


def _first(args: Sequence[Tensor | None]) -> Tensor:
    poses = args[0]
    assert poses is not None
    return poses


def _pooled_of(net: EnergyNet, args: Sequence[Tensor | None]) -> Tensor:
    """``net._pooled`` of the six arguments of :meth:`EnergyNet.forward` (``poses`` first, never None)."""
    return net._pooled(_first(args), *args[1:])


def pooled_in_chunks(net: EnergyNet, rows: int, args: Sequence[Tensor | None]) -> Tensor:
    """:func:`_pooled_of` of a batch's six inputs, ``rows`` pose sets at a time, concatenated."""
    b = _first(args).shape[0]

    def piece(a: int) -> Tensor:
        with torch.no_grad():
            return _pooled_of(net, rows_of(args, b, a, a + rows))

    work = [partial(piece, a) for a in range(0, b, rows)]
    return torch.cat(in_parallel(work, _first(args).device.type == "cpu"))


def even_piece(b: int, most: int, lanes: int) -> int:
    """Rows per piece for a batch of ``b`` rows cut into pieces of at most ``most`` rows that ``lanes``
    threads share: as many pieces as ``most`` needs, rounded up to a multiple of ``lanes``, and all of
    one size but the last (one lane: ``most``). :func:`~scenescore.runtime.threads.in_parallel` hands
    each lane every ``lanes``-th piece, so pieces of ``most`` rows and a short last one would leave a
    lane idle while another finishes its extra piece."""
    if lanes <= 1 or b <= 1:
        return most
    rounds = _ceil_div(_ceil_div(b, max(1, most)), lanes)
    return _ceil_div(b, rounds * lanes)


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def rows_of(args: Sequence[Tensor | None], b: int, a: int, z: int) -> list[Tensor | None]:
    """Rows ``a:z`` of each of a batch's inputs (see :func:`_rows`)."""
    return [_rows(t, b, a, z) for t in args]


def _rows(t: Tensor | None, b: int, a: int, z: int) -> Tensor | None:
    """Rows ``a:z`` of a per-row input of a batch of ``b`` (inputs of one row broadcast: kept whole)."""
    if t is None or t.shape[0] != b:
        return t
    return t[a:z]
