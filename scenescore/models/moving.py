"""A local network's energy of a scene in which one object moves and every other stays where it is:
the nodes that the moving object cannot reach are computed once, and each pose set recomputes only the
few that it can.

A local graph's node reads its ``neighbours`` nearest objects (:func:`~scenescore.models.graph.neighbour_graph`).
Take the scene without the moving object ``o`` as the base, its states computed once, layer by layer.
Put ``o`` at a pose: the nodes whose lists change are ``o`` and those it enters (its gap to them under
their farthest neighbour's in the base), and a node's state at layer ``l`` differs from the base only
where the node, or a node it reads, differed at layer ``l - 1``. With ``L`` layers these are the nodes
within ``L`` hops of ``o``; the energy, a sum of per-node terms before the head's last linear
(:meth:`~scenescore.models.network.EnergyNet.readout`), is the base's sum with those nodes' terms
replaced. The same function as the whole network's (to float rounding: sums in another order), its
gradient in ``o``'s pose included; the lists are chosen without a gradient, as there.

Placing one object in a room of a hundred is the case it serves: a pose set then costs the few dozen
nodes near the object instead of all of them, at every step of a chain and for every candidate screened.
"""

from __future__ import annotations

from functools import partial
from typing import Any, cast

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from ..runtime import in_parallel
from .graph import fade, footprint_gaps, neighbour_graph, senders
from .network import EnergyNet, MessageLayer

__all__ = ["MovingOne", "MovingMean", "Mover", "moving_one", "PIECE_ROWS"]

PIECE_ROWS = 64  # pose sets per piece: each piece's tensors stay in cache, the pieces share the cores


class MovingOne:
    """The energy of one scene's pose sets in which only object ``o`` moves (see the module's docstring).

    Built by :meth:`of` from the scene's poses ``(N, 3)``, node embeddings ``(N, D)``, mask ``(N,)`` and
    round flags (``(N,)`` or None); called with pose sets ``(B, N, 3)`` whose other rows are the scene's
    poses, it gives their energies ``(B,)`` (:meth:`__call__`), or None for any other pose sets (the
    caller then evaluates the whole network). For placing and sampling: the gradient is the moving
    object's pose's alone, the weights get none, and the base is the weights' when it was built."""

    def __init__(
        self, net: EnergyNet, poses: Tensor, nodes: Tensor, mask: Tensor, rnd: Tensor | None, o: int
    ):
        cfg = net.cfg
        assert cfg.neighbours is not None and cfg.radius is not None  # a local graph: see of
        self.neighbours, self.radius = cfg.neighbours, cfg.radius
        self.layers = [cast(MessageLayer, layer) for layer in net.layers]
        self.net, self.o, self.poses = net, o, poses
        self.nodes, self.rnd = nodes, rnd
        self.reach = net.reach(nodes)  # (N,)
        n = poses.shape[0]
        self.mask = mask
        self.base_mask = mask & (torch.arange(n, device=poses.device) != o)  # the scene without o
        with torch.no_grad():
            pos = (poses[:, :2] / cfg.length_scale)[None]
            index, pair = neighbour_graph(
                pos, self.reach[None], self.base_mask[None], None, cfg.neighbours, cfg.radius
            )
            e = net.edges(poses[None], None if rnd is None else rnd[None], None, index)
            states = [nodes[None]]
            assert index is not None  # more objects than a list holds: see of
            for layer in self.layers:
                states.append(layer(states[-1], e, pair, index))
            terms = net.node_terms(states[-1])[0]  # (N, H): each node's term
            # what each layer's senders send, w_j of their states
            self.sent = [layer.w_j(s[0]) for layer, s in zip(self.layers, states)]
        self.index = index[0]  # (N, S): the base's lists, nearest first
        self.farthest = footprint_gaps(pos, self.reach[None], index)[0, :, -1]  # (N,)
        self.states = [s[0] for s in states]  # (N, H) at each layer
        self.terms = terms * self.base_mask[:, None].to(terms.dtype)  # o's and padding's count none
        self.pooled = self.terms.sum(dim=0)  # (H,)

    @classmethod
    def of(
        cls, net: Any, poses: Tensor, nodes: Tensor, mask: Tensor, rnd: Tensor | None, o: int
    ) -> MovingOne | None:
        """The evaluator for ``net`` and one scene, or None where it does not apply: a dense or absolute
        network, one with walls, or a scene where some object has fewer candidates than its list holds
        without ``o`` (a small scene, which the whole network evaluates quickly); an ensemble's is
        :func:`moving_one`'s."""
        if not isinstance(net, EnergyNet) or poses.device.type != "cpu":
            return None  # a device where reading the sets' sizes back would wait on it
        cfg = net.cfg
        if cfg.neighbours is None or not cfg.local or cfg.walls or cfg.absolute:
            return None
        if int(mask.sum()) - 2 < cfg.neighbours:
            return None
        return cls(net, poses, nodes, mask, rnd, o)

    def applies(self, poses: Tensor) -> bool:
        """Whether every object of ``poses (B, N, 3)`` but ``o`` is at the scene's pose."""
        o = self.o
        if poses.dim() != 3 or poses.shape[1:] != self.poses.shape:
            return False
        fixed = self.poses.to(poses.dtype)
        return bool(torch.equal(poses[:, :o], fixed[None, :o].expand(poses.shape[0], -1, -1))) and bool(
            torch.equal(poses[:, o + 1 :], fixed[None, o + 1 :].expand(poses.shape[0], -1, -1))
        )

    def __call__(self, poses: Tensor) -> Tensor | None:
        """The energies ``(B,)`` of ``poses (B, N, 3)``, or None where other objects than ``o`` move. A
        large batch goes in pieces of :data:`PIECE_ROWS`, side by side, each forward and backward at
        once when the poses need a gradient."""
        return self.energies(poses) if self.applies(poses) else None

    def energies(self, poses: Tensor) -> Tensor:
        """As :meth:`__call__`, for pose sets that :meth:`applies` accepts (not checked here)."""
        x = poses[:, self.o].to(self.poses.dtype)
        if not (torch.is_grad_enabled() and poses.requires_grad):
            pieces = [partial(self._energy_only, x[a : a + PIECE_ROWS]) for a in range(0, len(x), PIECE_ROWS)]
            return torch.cat(in_parallel(pieces)).to(poses.dtype)
        return _PoseGrad.apply(self, poses)

    def _energy_only(self, x: Tensor) -> Tensor:
        with torch.no_grad():  # grad mode is per thread: set in the worker's
            return self.energy(x)

    def energy(self, x: Tensor) -> Tensor:
        """The energies ``(B,)`` with ``o`` at ``x (B, 3)``, differentiable in ``x``."""
        cfg, net, o = self.net.cfg, self.net, self.o
        b, n = x.shape[0], self.poses.shape[0]
        poses = torch.cat(
            [self.poses[None, :o].expand(b, -1, -1), x[:, None], self.poses[None, o + 1 :].expand(b, -1, -1)],
            1,
        )
        pos = poses[..., :2] / cfg.length_scale
        reach = self.reach[None].expand(b, n)
        rec, lists, enters, widths = self._graph(pos, reach)
        valid = rec < n  # (B, M): a node, not padding
        safe = rec.clamp(max=n - 1)
        pair = fade(footprint_gaps(pos, reach, lists, safe), self.radius) * valid[..., None].to(pos.dtype)
        rnd = None if self.rnd is None else self.rnd[None].expand(b, n)
        e = net.edges(poses, rnd, None, lists, safe)
        new, start = self.nodes[safe[:, : widths[0]]], 0  # layer 0: the embeddings, moved or not
        for k, (layer, m) in enumerate(zip(self.layers, widths)):
            # the receivers' states: new for the first ``start`` (those that differed already), the
            # base's for the rest; the senders': the base's with the new ones in place
            v_i = torch.cat([new[:, :start], self.states[k][safe[:, start:m]]], dim=1) if k else new
            if k:
                sent = _scatter(self.sent[k], rec[:, :start], layer.w_j(new[:, :start]))
            else:
                sent = self.sent[0][None].expand(b, n, -1)
            new = layer.received(v_i, sent, e[:, :m], pair[:, :m], lists[:, :m])  # (B, m, H)
            start = m
        kept = valid.to(pos.dtype)[..., None]
        old = self.terms[safe] * kept
        pooled = self.pooled + (net.node_terms(new) * kept - old).sum(dim=1)
        return net.readout(pooled)

    def _graph(self, pos: Tensor, reach: Tensor) -> tuple[Tensor, Tensor, Tensor, list[int]]:
        """The nodes whose states differ from the base's, ``rec (B, M)`` (padding: ``N``), ordered by the
        layer from which they differ, and the lists ``(B, M, S)`` they read; ``enters (B, N)``, the nodes
        whose lists ``o`` enters; ``widths``: how many of ``rec``'s columns each layer recomputes."""
        o, n, layers = self.o, pos.shape[1], len(self.layers)
        with torch.no_grad():
            to_o = torch.full((pos.shape[0], n, 1), o, dtype=torch.long, device=pos.device)
            gap = footprint_gaps(pos, reach, to_o)[..., 0]  # (B, N): each node's gap to o
            enters = self.base_mask & (gap < self.farthest)  # (B, N)
            own = gap.masked_fill(~self.base_mask, float("inf")).topk(self.neighbours, largest=False)[1]
            changed = enters.clone()
            changed[:, o] = True
            first = torch.where(changed, 1, layers + 1)  # the layer from which each node differs
            base_lists = self.index[None].expand(pos.shape[0], -1, -1)
            for layer in range(2, layers + 1):
                changed = changed | senders(changed[..., None], base_lists)[..., 0].any(dim=-1)
                changed = changed & self.mask
                first = torch.where(changed & (first > layer), layer, first)
            counts = [int((first <= layer).sum(dim=1).max()) for layer in range(1, layers + 1)]
            order = first.argsort(dim=1, stable=True)[:, : counts[-1]]
            rec = torch.where(first.gather(1, order) <= layers, order, n)
            safe = rec.clamp(max=n - 1)
            lists = self.index[safe]  # (B, M, S)
            into = enters.gather(1, safe)[..., None] & (
                torch.arange(lists.shape[-1], device=pos.device) == lists.shape[-1] - 1
            )
            lists = torch.where(into, o, lists)  # o takes the farthest neighbour's place
            lists = torch.where((safe == o)[..., None], own[:, None, :], lists)
        return rec, lists, enters, counts


def _scatter(base: Tensor, rec: Tensor, new: Tensor) -> Tensor:
    """The base's states ``(N, H)`` for each pose set, with the rows ``rec (B, M)`` replaced by ``new (B,
    M, H)`` (padding, ``rec == N``, lands in a spare row that nothing reads)."""
    b, n, h = rec.shape[0], base.shape[0], base.shape[1]
    full = torch.cat([base, base.new_zeros(1, h)])[None].expand(b, n + 1, h)
    return full.scatter(1, rec[..., None].expand(-1, -1, h), new)[:, :n]


class _PoseGrad(torch.autograd.Function):
    """:meth:`MovingOne.energy` of a batch and its gradient in ``o``'s pose, in pieces side by side (as
    :class:`~scenescore.models.chunks.PoseGradInPieces`); the other rows get a zero gradient."""

    @staticmethod
    def forward(ctx: Any, mover: MovingOne, poses: Tensor) -> Tensor:
        x = poses[:, mover.o].detach().to(mover.poses.dtype)

        def piece(a: int) -> tuple[Tensor, Tensor]:
            with torch.enable_grad():
                part = x[a : a + PIECE_ROWS].requires_grad_(True)
                e = mover.energy(part)
                (g,) = torch.autograd.grad(e.sum(), part)
            return e.detach(), g

        done = in_parallel([partial(piece, a) for a in range(0, len(x), PIECE_ROWS)])
        ctx.o, ctx.shape = mover.o, poses.shape
        ctx.save_for_backward(torch.cat([g for _, g in done]).to(poses.dtype))
        return torch.cat([e for e, _ in done]).to(poses.dtype)

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        (g,) = ctx.saved_tensors
        out = g.new_zeros(ctx.shape)
        out[:, ctx.o] = grad[:, None] * g
        return None, out


class MovingMean:
    """An ensemble's mean energy where one object moves: each member's :class:`MovingOne`, their mean
    taken as :meth:`~scenescore.models.ensemble.EnsembleNet.forward` takes it."""

    def __init__(self, movers: list[MovingOne]):
        self.movers = movers

    def __call__(self, poses: Tensor) -> Tensor | None:
        """The mean energies ``(B,)``, or None where other objects than the moving one move."""
        if not self.movers[0].applies(poses):  # the members share the scene: one check serves all
            return None
        return torch.stack([m.energies(poses) for m in self.movers]).mean(dim=0)


Mover = MovingOne | MovingMean


def moving_one(
    nets: list[EnergyNet], poses: Tensor, nodes: Tensor, mask: Tensor, rnd: Tensor | None, o: int
) -> Mover | None:
    """The evaluator of one scene's pose sets in which only ``o`` moves, for a network (``nets`` of one)
    or an ensemble's members (``nodes (N, members * D)`` their embeddings side by side, as
    :meth:`~scenescore.models.ensemble.EnsembleNet.node_embedding` gives them); None where
    :meth:`MovingOne.of` does not apply."""
    parts = nodes.chunk(len(nets), dim=-1)
    movers = [MovingOne.of(net, poses, part, mask, rnd, o) for net, part in zip(nets, parts, strict=True)]
    if any(m is None for m in movers):
        return None
    ones = cast(list[MovingOne], movers)
    return ones[0] if len(ones) == 1 else MovingMean(ones)
