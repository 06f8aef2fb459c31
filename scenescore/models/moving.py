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

from collections.abc import Sequence
from dataclasses import dataclass, fields
from functools import partial
from typing import Any, NamedTuple, cast

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from ..runtime import in_parallel
from .graph import fade, footprint_gaps, neighbour_graph, senders
from .network import EnergyNet, MessageLayer

__all__ = ["MovingOne", "MovingMean", "Mover", "moving_one", "stack_movers", "PIECE_ROWS"]

#: pose sets per piece: the pieces share the cores, and a piece is large enough that its several hundred
#: operations' dispatch does not outweigh their work, small enough that its tensors stay in cache
PIECE_ROWS = 128


@dataclass(frozen=True)
class _Base:
    """The scenes without their moving objects, each computed once: per scene (the leading ``P``) its
    poses ``(P, N, 3)``, embeddings, mask, round flags and moving object ``o (P,)``; the base graph's
    lists ``(P, N, S)`` and each node's farthest neighbour's gap; each layer's states and what its
    senders send ``(P, N, H)``; each node's term and their sum."""

    poses: Tensor
    nodes: Tensor
    mask: Tensor
    rnd: Tensor | None
    o: Tensor
    reach: Tensor
    base_mask: Tensor
    index: Tensor
    farthest: Tensor
    states: list[Tensor]
    sent: list[Tensor]
    terms: Tensor
    pooled: Tensor

    @staticmethod
    def cat(bases: Sequence[_Base]) -> _Base:
        """The bases of several scenes of one width, side by side."""
        out: dict[str, Any] = {}
        for f in fields(_Base):
            vals = [getattr(b, f.name) for b in bases]
            if isinstance(vals[0], list):
                out[f.name] = [torch.cat(layer) for layer in zip(*vals)]
            else:
                out[f.name] = None if vals[0] is None else torch.cat(vals)
        return _Base(**out)


def _rows(t: Tensor, pid: Tensor) -> Tensor:
    """Per-scene ``t (P, ...)`` for each pose set of scene ``pid (B,)``: ``(B, ...)`` (one scene: a view)."""
    return t.expand(len(pid), *t.shape[1:]) if t.shape[0] == 1 else t[pid]


def _at(t: Tensor, pid: Tensor, idx: Tensor) -> Tensor:
    """Per-node ``t (P, N, ...)`` at the nodes ``idx (B, M)`` of each pose set's scene ``pid (B,)``."""
    return t[0][idx] if t.shape[0] == 1 else t[pid[:, None], idx]


class _Reach(NamedTuple):
    """What a moving object changes, per pose set: ``first (B, N)``, the layer from which each node's
    state differs from the base's (beyond the last layer: never); ``enters (B, N)``, the nodes whose
    lists the moving object enters; ``own (B, S)``, the moving object's own list."""

    first: Tensor
    enters: Tensor
    own: Tensor

    def take(self, rows: Tensor | slice) -> _Reach:
        """The pose sets ``rows`` (an order, or a piece)."""
        return _Reach(*(t[rows] for t in self))


class MovingOne:
    """The energy of pose sets in which only one object moves (see the module's docstring).

    Built by :meth:`of` from a scene's poses ``(N, 3)``, node embeddings ``(N, D)``, mask ``(N,)`` and
    round flags (``(N,)`` or None); called with pose sets ``(B, N, 3)`` whose other rows are the scene's
    poses, it gives their energies ``(B,)`` (:meth:`__call__`), or None for any other pose sets (the
    caller then evaluates the whole network). :meth:`stack` puts several scenes of one width side by
    side, each for its own contiguous rows of the pose sets, so that a batch of placement problems takes
    one call per step. For placing and sampling: the gradient is the moving object's pose's alone, the
    weights get none, and the base is the weights' when it was built."""

    def __init__(self, net: EnergyNet, base: _Base, pid: Tensor | None = None):
        cfg = net.cfg
        assert cfg.neighbours is not None and cfg.radius is not None  # a local graph: see of
        self.neighbours, self.radius = cfg.neighbours, cfg.radius
        self.layers = [cast(MessageLayer, layer) for layer in net.layers]
        self.net, self.base, self.pid = net, base, pid

    @staticmethod
    def _base(
        net: EnergyNet, poses: Tensor, nodes: Tensor, mask: Tensor, rnd: Tensor | None, o: int
    ) -> _Base:
        """One scene's :class:`_Base`, ``o`` left out."""
        cfg, n = net.cfg, poses.shape[0]
        assert cfg.neighbours is not None and cfg.radius is not None  # a local graph: see of
        reach = net.reach(nodes)  # (N,)
        base_mask = mask & (torch.arange(n, device=poses.device) != o)  # the scene without o
        with torch.no_grad():
            pos = (poses[:, :2] / cfg.length_scale)[None]
            index, pair = neighbour_graph(pos, reach[None], base_mask[None], None, cfg.neighbours, cfg.radius)
            assert index is not None  # more objects than a list holds: see of
            e = net.edges(poses[None], None if rnd is None else rnd[None], None, index)
            states = [nodes[None]]
            layers = [cast(MessageLayer, layer) for layer in net.layers]
            for layer in layers:
                states.append(layer(states[-1], e, pair, index))
            terms = net.node_terms(states[-1])  # (1, N, H): each node's term
            terms = terms * base_mask[None, :, None].to(terms.dtype)  # o's and padding's count none
            # what each layer's senders send, w_j of their states, with a spare row for padding to land in
            sent = [layer.w_j(s) for layer, s in zip(layers, states)]
            sent = [torch.cat([s, s.new_zeros(1, 1, s.shape[-1])], 1) for s in sent]
        return _Base(
            poses=poses[None],
            nodes=nodes[None],
            mask=mask[None],
            rnd=None if rnd is None else rnd[None],
            o=torch.tensor([o], device=poses.device),
            reach=reach[None],
            base_mask=base_mask[None],
            index=index,
            farthest=footprint_gaps(pos, reach[None], index)[:, :, -1],
            states=states,
            sent=sent,
            terms=terms,
            pooled=terms.sum(dim=1),
        )

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
        return cls(net, cls._base(net, poses, nodes, mask, rnd, o))

    @classmethod
    def stack(cls, movers: Sequence[MovingOne], sizes: Sequence[int]) -> MovingOne | None:
        """One evaluator for several scenes' movers, mover ``k`` for the next ``sizes[k]`` pose sets; None
        where they do not share the network, the width and whether round flags are given."""
        first = movers[0]
        if any(
            m.net is not first.net
            or m.width != first.width
            or (m.base.rnd is None) != (first.base.rnd is None)
            or m.pid is not None
            for m in movers
        ):
            return None
        base = _Base.cat([m.base for m in movers])
        reps = torch.as_tensor(list(sizes), device=base.o.device)
        return cls(first.net, base, torch.arange(len(movers), device=base.o.device).repeat_interleave(reps))

    @property
    def width(self) -> int:
        """The number of objects of the scenes (the pose sets' ``N``)."""
        return int(self.base.poses.shape[1])

    def _pids(self, b: int) -> Tensor:
        return torch.zeros(b, dtype=torch.long, device=self.base.o.device) if self.pid is None else self.pid

    def applies(self, poses: Tensor) -> bool:
        """Whether ``poses (B, N, 3)`` are this evaluator's: its scenes' width and rows (stacked), and
        every object but the moving one where the scene has it."""
        if poses.shape[1] != self.width or (self.pid is not None and poses.shape[0] != len(self.pid)):
            return False
        base = self.base
        if self.pid is None:  # one scene: compare the slices either side of o
            o, fixed = int(base.o[0]), base.poses[0].to(poses.dtype)
            return bool(torch.equal(poses[:, :o], fixed[None, :o].expand(poses.shape[0], -1, -1))) and bool(
                torch.equal(poses[:, o + 1 :], fixed[None, o + 1 :].expand(poses.shape[0], -1, -1))
            )
        pid = self.pid
        other = torch.arange(self.width, device=pid.device) != base.o[pid][:, None]  # (B, N)
        return not bool(((poses != base.poses[pid].to(poses.dtype)).any(-1) & other).any())

    def __call__(self, poses: Tensor) -> Tensor | None:
        """The energies ``(B,)`` of ``poses (B, N, 3)``, or None where other objects than the moving ones
        move. A large batch goes in pieces of :data:`PIECE_ROWS`, side by side, each forward and backward
        at once when the poses need a gradient."""
        return self.energies(poses) if self.applies(poses) else None

    def moving(self, poses: Tensor) -> Tensor:
        """The moving objects' poses ``(B, 3)`` of ``poses (B, N, 3)``, in the base's dtype."""
        pid = self._pids(poses.shape[0])
        rows = torch.arange(poses.shape[0], device=pid.device)
        return poses.detach()[rows, self.base.o[pid]].to(self.base.poses.dtype)

    def energies(self, poses: Tensor) -> Tensor:
        """As :meth:`__call__`, for pose sets that :meth:`applies` accepts (not checked here)."""
        if not (torch.is_grad_enabled() and poses.requires_grad):
            x, pid, reach, order = self.sorted(poses)
            pieces = [
                partial(
                    self._energy_only,
                    x[a : a + PIECE_ROWS],
                    pid[a : a + PIECE_ROWS],
                    reach.take(slice(a, a + PIECE_ROWS)),
                )
                for a in range(0, len(x), PIECE_ROWS)
            ]
            return _unsorted(torch.cat(in_parallel(pieces)), order).to(poses.dtype)
        return _PoseGrad.apply(self, poses)

    def sorted(self, poses: Tensor) -> tuple[Tensor, Tensor, _Reach, Tensor | None]:
        """The moving objects' poses ``(B, 3)`` of ``poses (B, N, 3)``, their scenes ``(B,)`` and what
        each changes (:class:`_Reach`), in the order of how many nodes each changes, and that order: a
        piece recomputes as many nodes for every pose set as its widest one needs, so pose sets of like
        reach go in one piece. A batch of one piece keeps its order (None)."""
        x, pid = self.moving(poses), self._pids(poses.shape[0])
        reach = self._reach(self._poses(x, pid)[..., :2] / self.net.cfg.length_scale, pid)
        if len(x) <= PIECE_ROWS:
            return x, pid, reach, None
        order = (reach.first <= len(self.layers)).sum(dim=1).argsort(stable=True)
        return x[order], pid[order], reach.take(order), order

    def _energy_only(self, x: Tensor, pid: Tensor, reach: _Reach) -> Tensor:
        with torch.no_grad():  # grad mode is per thread: set in the worker's
            return self.energy(x, pid, reach)

    def energy(self, x: Tensor, pid: Tensor | None = None, reach: _Reach | None = None) -> Tensor:
        """The energies ``(B,)`` with each pose set's moving object at ``x (B, 3)``, differentiable in
        ``x``; ``pid (B,)``: each pose set's scene (default: the first); ``reach``: what each changes,
        where the caller has it (:meth:`sorted`)."""
        net, base, n = self.net, self.base, self.width
        pid = torch.zeros(x.shape[0], dtype=torch.long, device=x.device) if pid is None else pid
        poses = self._poses(x, pid)
        pos = poses[..., :2] / net.cfg.length_scale
        rec, lists, widths = self._graph(self._reach(pos.detach(), pid) if reach is None else reach, pid)
        valid = rec < n  # (B, M): a node, not padding
        safe = rec.clamp(max=n - 1)
        pair = fade(footprint_gaps(pos, _rows(base.reach, pid), lists, safe), self.radius)
        pair = pair * valid[..., None].to(pos.dtype)
        rnd = None if base.rnd is None else _rows(base.rnd, pid)
        e = net.edges(poses, rnd, None, lists, safe)
        new, start = _at(base.nodes, pid, safe[:, : widths[0]]), 0  # layer 0: the embeddings, moved or not
        for k, (layer, m) in enumerate(zip(self.layers, widths)):
            # the receivers' states: new for the first ``start`` (those that differed already), the
            # base's for the rest; the senders': the base's with the new ones in place
            if k:
                v_i = torch.cat([new[:, :start], _at(base.states[k], pid, safe[:, start:m])], dim=1)
                sent = _scatter(_rows(base.sent[k], pid), rec[:, :start], layer.w_j(new[:, :start]))
            else:
                v_i, sent = new, _rows(base.sent[0], pid)[:, :n]
            new = layer.received(v_i, sent, e[:, :m], pair[:, :m], lists[:, :m])  # (B, m, H)
            start = m
        kept = valid.to(pos.dtype)[..., None]
        old = _at(base.terms, pid, safe) * kept
        pooled = _rows(base.pooled, pid) + (net.node_terms(new) * kept - old).sum(dim=1)
        return net.readout(pooled)

    def _poses(self, x: Tensor, pid: Tensor) -> Tensor:
        """The pose sets ``(B, N, 3)``: each scene's ``pid (B,)`` base with its moving object at ``x (B, 3)``."""
        o = _rows(self.base.o, pid)  # (B,)
        at_o = (torch.arange(self.width, device=x.device) == o[:, None])[..., None]  # (B, N, 1)
        return torch.where(at_o, x[:, None], _rows(self.base.poses, pid))

    def _reach(self, pos: Tensor, pid: Tensor) -> _Reach:
        """What the moving object changes at positions ``pos (B, N, 2)`` (in length scales) of scenes
        ``pid (B,)``: :class:`_Reach`."""
        base, n, layers, b = self.base, pos.shape[1], len(self.layers), pos.shape[0]
        with torch.no_grad():
            o = _rows(base.o, pid)  # (B,)
            reach = _rows(base.reach, pid)
            gap = footprint_gaps(pos, reach, o[:, None, None].expand(b, n, 1))[..., 0]  # each node's gap to o
            base_mask = _rows(base.base_mask, pid)
            enters = base_mask & (gap < _rows(base.farthest, pid))  # (B, N)
            own = gap.masked_fill(~base_mask, float("inf")).topk(self.neighbours, largest=False)[1]
            changed = enters | (torch.arange(n, device=pos.device) == o[:, None])
            first = torch.where(changed, 1, layers + 1)
            base_lists, mask = _rows(base.index, pid), _rows(base.mask, pid)
            for layer in range(2, layers + 1):
                changed = changed | senders(changed[..., None], base_lists)[..., 0].any(dim=-1)
                changed = changed & mask
                first = torch.where(changed & (first > layer), layer, first)
        return _Reach(first, enters, own)

    def _graph(self, reach: _Reach, pid: Tensor) -> tuple[Tensor, Tensor, list[int]]:
        """The nodes whose states differ from the base's, ``rec (B, M)`` (padding: ``N``), ordered by the
        layer from which they differ, and the lists ``(B, M, S)`` they read; ``widths``: how many of
        ``rec``'s columns each layer recomputes. ``pid (B,)``: each pose set's scene."""
        base, layers = self.base, len(self.layers)
        first, enters, own = reach.first, reach.enters, reach.own
        n = first.shape[1]
        with torch.no_grad():
            o = _rows(base.o, pid)
            counts = [int((first <= layer).sum(dim=1).max()) for layer in range(1, layers + 1)]
            order = first.argsort(dim=1, stable=True)[:, : counts[-1]]
            rec = torch.where(first.gather(1, order) <= layers, order, n)
            safe = rec.clamp(max=n - 1)
            lists = _at(base.index, pid, safe)  # (B, M, S)
            into = enters.gather(1, safe)[..., None] & (
                torch.arange(lists.shape[-1], device=first.device) == lists.shape[-1] - 1
            )
            lists = torch.where(into, o[:, None, None], lists)  # o takes the farthest neighbour's place
            lists = torch.where((safe == o[:, None])[..., None], own[:, None, :], lists)
        return rec, lists, counts


def _unsorted(values: Tensor, order: Tensor | None) -> Tensor:
    """``values`` computed for the rows ``order`` of a batch (None: in its order), put back in the
    batch's order."""
    if order is None:
        return values
    out = torch.empty_like(values)
    out[order] = values
    return out


def _scatter(full: Tensor, rec: Tensor, new: Tensor) -> Tensor:
    """Each pose set's base states ``full (B, N + 1, H)`` (a spare last row) with the rows ``rec (B, M)``
    replaced by ``new (B, M, H)`` (padding, ``rec == N``, lands in the spare row, which nothing reads)."""
    h = full.shape[-1]
    return full.scatter(1, rec[..., None].expand(-1, -1, h), new)[:, :-1]


class _PoseGrad(torch.autograd.Function):
    """:meth:`MovingOne.energy` of a batch and its gradient in the moving objects' poses, in pieces side
    by side (as :class:`~scenescore.models.chunks.PoseGradInPieces`); the other objects get a zero
    gradient."""

    @staticmethod
    def forward(ctx: Any, mover: MovingOne, poses: Tensor) -> Tensor:
        x, pid, reach, order = mover.sorted(poses)

        def piece(a: int) -> tuple[Tensor, Tensor]:
            with torch.enable_grad():
                part = x[a : a + PIECE_ROWS].requires_grad_(True)
                e = mover.energy(part, pid[a : a + PIECE_ROWS], reach.take(slice(a, a + PIECE_ROWS)))
                (g,) = torch.autograd.grad(e.sum(), part)
            return e.detach(), g

        done = in_parallel([partial(piece, a) for a in range(0, len(x), PIECE_ROWS)])
        g = _unsorted(torch.cat([g for _, g in done]), order)
        ctx.shape = poses.shape
        ctx.save_for_backward(g.to(poses.dtype), mover.base.o[mover._pids(poses.shape[0])])
        return _unsorted(torch.cat([e for e, _ in done]), order).to(poses.dtype)

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        g, o = ctx.saved_tensors
        out = g.new_zeros(ctx.shape)
        out[torch.arange(len(o), device=o.device), o] = grad[:, None] * g
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


def stack_movers(movers: Sequence[Mover], sizes: Sequence[int]) -> Mover | None:
    """One evaluator for several scenes' movers side by side, mover ``k`` for the next ``sizes[k]`` pose
    sets (:meth:`MovingOne.stack`, member by member for an ensemble's); None where they do not stack."""
    if all(isinstance(m, MovingOne) for m in movers):
        return MovingOne.stack(cast(list[MovingOne], movers), sizes)
    if not all(isinstance(m, MovingMean) for m in movers):
        return None
    means = cast(list[MovingMean], movers)
    if len({len(m.movers) for m in means}) != 1:
        return None
    members = [MovingOne.stack([m.movers[i] for m in means], sizes) for i in range(len(means[0].movers))]
    return None if any(m is None for m in members) else MovingMean(cast(list[MovingOne], members))


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
