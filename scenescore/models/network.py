"""The SceneScore energy network: a batched graph neural network over object poses.

Nodes carry semantic embeddings (encoder vector -> trained 2-layer MLP, scale descriptor appended).
The edge feature ``e_ji`` is the pose of object ``i`` in the frame of object ``j``:
``R(-theta_j)(p_i - p_j), cos(theta_i - theta_j), sin(theta_i - theta_j)``, so the energy is invariant
to any rigid motion of the whole scene. Each layer is ``v_i' = act(sum_j f(v_i, v_j, e_ji))``. The graph
(:mod:`scenescore.models.graph`) is dense, ``(B, N, N, H)`` edge tensors with a padding mask, global add
pooling and an MLP head giving one scalar per scene; or, for rooms, local: each object reads its
nearest neighbours, ``(B, N, S, H)``, and the energy is a sum of per-object terms.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from ..runtime import check_memory, chunk_rows, return_freed_memory, usable_cores
from .architecture import EnergyConfig, parameter_count
from .chunks import ChunkedPooled, PoseGradInPieces, even_piece, pooled_in_chunks
from .compiled import CompiledEnergy, CompiledPoseGrad, compiled_of
from .graph import WALLS, edge_features, neighbour_graph, senders, wall_nodes

__all__ = [
    "WALLS",
    "EnergyConfig",
    "EnergyNet",
    "MessageLayer",
    "edge_features",
    "make_activation",
    "parameter_count",
    "round_flags",
    "wall_nodes",
]

# on the CPU, one pass over more edges than this (pose sets x N x N) runs slower per pose set than the
# same pass in pieces: its (B, N, N, H) tensors leave the cache and fresh large allocations fault in their
# pages. Energies without a gradient, and a gradient for the poses alone (sampling, refinement), are then
# taken piece by piece, each piece forward and backward at once (``benchmarks/bench_network.py`` times it)
CACHE_EDGES = 49152
# a batch of two pieces of this many edges or more (pose sets x N x the nodes each reads) is cut into as
# many pieces of at least this many as the machine has usable cores, which run side by side on the cores
# other processes leave free (:func:`scenescore.runtime.threads.in_parallel`), each on one torch thread: the
# numbers never depend on the load; smaller pieces would spend more time in Python than in torch
PIECE_EDGES = 4096

# floats per edge (i, j) of one pose set that evaluating the energy holds at its peak (CPU, float32,
# rounded up): the edge features, then per message layer its (N, N, inner) tensors; with a gradient
# every layer's are kept for the backward pass
_EDGE_FLOATS = 32
_LAYER_FLOATS = 16


def round_flags(cfg: EnergyConfig, round: Tensor | None) -> Tensor | None:
    """``round`` where a network of ``cfg`` reads round objects and one of them is, else None: scenes
    without a round object take the plain path (the same numbers, less work). It reads the device once:
    made once per batch of scenes (a problem, a size group), not at each step of a chain."""
    if round is None or not cfg.round_invariant or not bool(round.any()):
        return None
    return round


def make_activation(name: str) -> nn.Module:
    """The activation module called ``name``."""
    if name == "silu":
        return nn.SiLU()
    if name == "softplus":
        return nn.Softplus()
    if name == "leaky_relu":
        return nn.LeakyReLU(0.1)
    raise ValueError(f"unknown activation {name!r}; expected 'silu', 'softplus' or 'leaky_relu'")


def _act_in_place(act: nn.Module, t: Tensor) -> Tensor:
    """``act(t)`` written into ``t`` where the activation has an in-place form (the same numbers)."""
    if isinstance(act, nn.SiLU):
        return F.silu(t, inplace=True)
    if isinstance(act, nn.LeakyReLU):
        return F.leaky_relu(t, act.negative_slope, inplace=True)
    return act(t)


class MessageLayer(nn.Module):
    """``v_i' = act(sum_{j != i} f(v_i, v_j, e_ji))`` with the first linear of ``f`` split per part."""

    def __init__(self, d_in: int, d_edge: int, hidden: int, message: str, act: nn.Module, edge_hidden: int):
        super().__init__()
        inner = edge_hidden if message == "mlp" else hidden
        self.w_i = nn.Linear(d_in, inner)
        self.w_j = nn.Linear(d_in, inner, bias=False)
        self.w_e = nn.Linear(d_edge, inner, bias=False) if d_edge else None
        self.out = nn.Linear(inner, hidden) if message == "mlp" else None
        self.act = act

    def forward(self, v: Tensor, e: Tensor | None, pair_mask: Tensor, index: Tensor | None = None) -> Tensor:
        """``pair_mask``: each edge's weight, ``(B, N, N)`` (dense) or ``(B, N, S)`` for the local graph
        ``index (B, N, S)`` (see :func:`senders`)."""
        return self.received(v, self.w_j(v), e, pair_mask, index)

    def received(
        self, v_i: Tensor, sent: Tensor, e: Tensor | None, pair_mask: Tensor, index: Tensor | None
    ) -> Tensor:
        """The new states of the receiving nodes ``v_i (B, M, D)`` from the senders' ``w_j`` of their
        states, ``sent (B, N, H)``, along the edges ``e``, ``pair_mask`` and ``index`` into them (``(B, M,
        N or S, ...)``): :meth:`forward` with ``v_i = v``, or a few nodes' alone
        (:class:`~scenescore.models.moving.MovingOne`)."""
        # f's last linear is moved out of the sum over j (it is linear): sum_j p_ij (W a_ij + b) =
        # W (sum_j p_ij a_ij) + b deg_i, so the (B, N, N, H) tensors are the first layer's and its
        # activation only
        summed = self._summed if torch.is_grad_enabled() else self._summed_in_place
        return self.act(summed(v_i, sent, e, pair_mask, index))

    def _summed(
        self, v_i: Tensor, sent: Tensor, e: Tensor | None, pair_mask: Tensor, index: Tensor | None
    ) -> Tensor:
        """:meth:`received`'s sum before its activation, each operation writing a new tensor (autograd
        keeps them for the backward pass)."""
        m = self.w_i(v_i)[:, :, None, :] + senders(sent, index)  # (B, M, N or S, H)
        if self.w_e is not None and e is not None:
            m = m + self.w_e(e)
        if self.out is not None:
            m = self.act(m)
        return self._out((m * pair_mask[..., None]).sum(dim=2), pair_mask)  # sum_j p_ij m_ij

    def _summed_in_place(
        self, v_i: Tensor, sent: Tensor, e: Tensor | None, pair_mask: Tensor, index: Tensor | None
    ) -> Tensor:
        """:meth:`_summed` without a gradient: the same operations in the same order (the same numbers),
        each written into the one ``(B, M, N or S, H)`` tensor, which saves writing and reading several
        (``benchmarks/bench_network.py`` times both). With a gradient the tensors stay apart, which is
        the faster there."""
        w_i, m = self.w_i(v_i)[:, :, None, :], senders(sent, index)
        m = w_i + m if index is None else m.add_(w_i)  # a dense graph's senders are a broadcast view
        if self.w_e is not None and e is not None:
            m.add_(self.w_e(e))
        if self.out is not None:
            m = _act_in_place(self.act, m)
        return self._out(m.mul_(pair_mask[..., None]).sum(dim=2), pair_mask)

    def _out(self, s: Tensor, pair_mask: Tensor) -> Tensor:
        """``f``'s last linear applied to the weighted sum ``s`` (its bias once per unit of edge weight)."""
        if self.out is None:
            return s
        return F.linear(s, self.out.weight) + pair_mask.sum(dim=2, keepdim=True) * self.out.bias


class EnergyNet(nn.Module):
    """E(x | s): poses ``(B, N, 3)``, features ``(B, N, F)``, sizes ``(B, N, 2)``, mask ``(B, N)`` -> ``(B,)``."""

    def __init__(self, cfg: EnergyConfig):
        super().__init__()
        self.cfg = cfg
        act = make_activation(cfg.activation)
        self.embed = nn.Sequential(
            nn.Linear(cfg.feat_dim, cfg.hidden),
            make_activation(cfg.activation),
            nn.Linear(cfg.hidden, cfg.embed_dim),
        )
        d_node = cfg.embed_dim + 2 + (4 if cfg.absolute else 0)
        d_edge = 0 if cfg.absolute else 4
        if cfg.edge_encoder and not cfg.absolute:
            self.edge_enc: nn.Module | None = nn.Sequential(
                nn.Linear(4, cfg.edge_encoder), make_activation(cfg.activation)
            )
            d_edge = cfg.edge_encoder
        else:
            self.edge_enc = None
        dims = [d_node] + [cfg.hidden] * cfg.layers
        self.layers = nn.ModuleList(
            MessageLayer(dims[k], d_edge, cfg.hidden, cfg.message, act, cfg.edge_hidden or cfg.hidden)
            for k in range(cfg.layers)
        )
        self.head = nn.Sequential(
            nn.Linear(cfg.hidden, cfg.hidden), make_activation(cfg.activation), nn.Linear(cfg.hidden, 1)
        )

        check_memory(
            4 * parameter_count(cfg) * torch.empty(0).element_size(),
            f"energy network: {parameter_count(cfg):,} weights ({cfg.describe()}) with their gradients "
            "and optimiser state",
            "hidden, edge_hidden or layers",
        )

    def row_bytes(self, n: int, grad: bool, itemsize: int = 4) -> int:
        """Estimated peak bytes of evaluating the energy of one pose set of ``n`` objects (``grad``: with
        the graph kept for a backward pass); the ``(N, N, inner)`` message tensors dominate."""
        cfg = self.cfg
        inner = (cfg.edge_hidden or cfg.hidden) if cfg.message == "mlp" else cfg.hidden
        per_edge = _EDGE_FLOATS + (cfg.layers * (_LAYER_FLOATS + inner) + 3 * inner if grad else 4 * inner)
        per_edge += 2 * (cfg.edge_encoder or 0)
        per_node = cfg.feat_dim + 2 * cfg.embed_dim + 8 * cfg.hidden * cfg.layers
        return itemsize * (n * self.reads(n) * per_edge + n * per_node)

    def reads(self, n: int) -> int:
        """:meth:`EnergyConfig.reads` of this network's graph."""
        return self.cfg.reads(n)

    def chunk_rows(self, n: int, grad: bool, itemsize: int = 4, roomy: bool | None = None) -> int:
        """Pose sets of ``n`` objects evaluated at once (see :func:`scenescore.runtime.memory.chunk_rows`). With a
        gradient a local graph's batch is cut only as the memory budget needs (its rows grow with ``n``,
        not ``n^2``, and cutting a training batch into chunks runs its forward pass twice); ``roomy``
        overrides that choice."""
        return chunk_rows(
            self.row_bytes(n, grad, itemsize),
            f"energy network: one pose set of {n} objects ({self.cfg.describe()}"
            f"{', with its gradient' if grad else ''})",
            "the number of objects in the scene",
            roomy=grad and self.cfg.local if roomy is None else roomy,
        )

    def loss_rows(self, n: int, itemsize: int = 4) -> int:
        """Pose sets of ``n`` objects that training's compiled loss differentiates in one call, graphs kept
        (its passes merged, :func:`scenescore.learn.loop._pass_energies`): as many as an eighth of the
        memory budget holds. Eager training keeps every pass's graph until the loss's backward pass too;
        one chunk's :meth:`chunk_rows` would send the merged passes to the chunked path, which runs their
        forward pass twice."""
        return self.chunk_rows(n, True, itemsize, roomy=True)

    @staticmethod
    def reach(nodes: Tensor) -> Tensor:
        """Each object's half longer side in length scales, ``(..., N)``, from its
        :meth:`node_embedding` ``(..., N, D)`` (whose last two columns are its sizes): the circle a local
        graph's gaps are measured between."""
        return 0.5 * nodes[..., -2:].amax(dim=-1)

    def node_embedding(self, feats: Tensor, sizes: Tensor) -> Tensor:
        """Pose-independent node features ``(B, N, embed_dim + 2)``."""
        return torch.cat([self.embed(feats), sizes / self.cfg.length_scale], dim=-1)

    def forward(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None = None,
        nodes: Tensor | None = None,
        round: Tensor | None = None,
        weight_grads: bool = True,
    ) -> Tensor:
        """Energy per scene. ``nodes`` may carry a precomputed :meth:`node_embedding` (broadcast over B);
        ``round (B or 1, N)``: the round objects, whose headings a ``round_invariant`` network ignores
        (None where none is: :func:`round_flags`).

        A batch larger than :meth:`chunk_rows` goes through the message layers in chunks of rows (with a
        gradient, each chunk is recomputed in the backward pass instead of kept), and the head sees the
        whole batch: the same numbers as one pass, in bounded memory. The chunked path has first
        derivatives only (no ``create_graph``); with ``weight_grads=False`` (sampling, which needs the
        gradient with respect to the poses alone) it gives the weights none.

        On the CPU a batch of more than :data:`CACHE_EDGES` edges (or more rows than one chunk) is taken
        in pieces of at most that many when it needs no gradient, or (with ``weight_grads=False``) a
        gradient for the poses alone, each piece forward and backward at once, without the chunked
        path's second forward pass (:class:`~scenescore.models.chunks.PoseGradInPieces`); the head sees the whole batch. The same
        energies, the same gradients to float rounding, faster."""
        b, n, _ = poses.shape
        grad = torch.is_grad_enabled()
        rows = self.chunk_rows(n, grad, poses.element_size())
        args = (poses, feats, sizes, mask, nodes, round)
        per_row = n * self.reads(n)  # edges of one pose set
        piece = min(rows, max(1, CACHE_EDGES // per_row))
        shares = min(usable_cores(), b * per_row // PIECE_EDGES)  # a piece for each core, none too small
        piece = even_piece(b, piece, shares)  # enough work to share: a multiple of ``shares`` pieces
        c = compiled_of(self)
        if c is not None and grad:  # the compiled passes (compiled.compiling)
            if not weight_grads and poses.requires_grad:  # a chain's pose gradient
                return CompiledPoseGrad.apply(self, c, piece, *args)
            if weight_grads and c.loss and b <= self.loss_rows(n, poses.element_size()):  # the loss's passes
                if shares > 1 and not any(t is not None and t.requires_grad for t in args):
                    return CompiledEnergy.apply(self, c, -(-b // shares), *args, *self.parameters())
                return c.energy(self.resolve(*args))
        if poses.device.type == "cpu" and b > piece:
            if not grad:
                return self.readout(pooled_in_chunks(self, piece, args))
            if not weight_grads and poses.requires_grad:
                return PoseGradInPieces.apply(self, piece, *args)
        if b <= rows:
            pooled = self._pooled(*args)
        else:
            return_freed_memory()
            weights = list(self.parameters()) if weight_grads else []
            pooled = ChunkedPooled.apply(self, rows, *args, *weights)
        return self.readout(pooled)

    def _pooled(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None,
        nodes: Tensor | None,
        round: Tensor | None,
    ) -> Tensor:
        """The message layers and the global add pooling: ``(B, hidden)``: :meth:`pooled` of
        :meth:`resolve`'s inputs."""
        return self.pooled(*self.resolve(poses, feats, sizes, mask, nodes, round))

    def resolve(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None,
        nodes: Tensor | None,
        round: Tensor | None,
    ) -> tuple[Tensor, Tensor | None, Tensor | None, Tensor, Tensor | None, Tensor | None, Tensor | None]:
        """:meth:`pooled`'s inputs: the mask, the round flags and the wall nodes laid out here, so that
        :meth:`pooled` has no branch but on the network's settings and which inputs are given."""
        b, n, _ = poses.shape
        if mask is None:
            mask = torch.ones(b, n, dtype=torch.bool, device=poses.device)
        # nothing here reads a tensor's values, which would wait on the device at every step of a chain:
        # a caller gives ``round`` only where some object is round (:func:`round_flags`, once per batch
        # of scenes), and a network with walls has them in every row that has an object
        rnd = round.expand(b, n) if round is not None and self.cfg.round_invariant else None
        walls = wall_nodes(mask).expand(b, n) if self.cfg.walls else None
        return poses, feats, sizes, mask, nodes, rnd, walls

    def pooled(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor,
        nodes: Tensor | None,
        rnd: Tensor | None,
        walls: Tensor | None,
        tap: Callable[[Tensor, Tensor, Tensor | None], None] | None = None,
    ) -> Tensor:
        """:meth:`_pooled` once the data's branches are settled: ``mask (B, N)``; ``rnd (B, N)`` the round
        objects, or None for none; ``walls (B, N)`` the wall nodes (a network with walls), or None.
        The same operations for any values of the tensors:
        what :mod:`~scenescore.models.compiled` compiles. ``tap``: called with the edges the message
        layers read, their weights (``(B, N, N or S, ...)``, ``(B, N, N or S)``) and the local graph's
        ``index`` (None: dense), the tensors through which alone the poses act on the energy (:mod:`~scenescore.models.explain` splits the energy
        by edge through their gradients)."""
        b, n, _ = poses.shape
        if nodes is None:
            assert feats is not None and sizes is not None, "EnergyNet: give feats and sizes, or nodes"
            v = self.node_embedding(feats, sizes)
        else:
            v = nodes
        v = v.expand(b, n, v.shape[-1])
        maskf = mask.to(poses.dtype).expand(b, n)
        index = None
        if self.cfg.local:
            assert self.cfg.neighbours is not None and self.cfg.radius is not None
            reach = self.reach(v)
            pos = poses[..., :2] / self.cfg.length_scale
            index, pair = neighbour_graph(
                pos, reach, mask.expand(b, n), walls, self.cfg.neighbours, self.cfg.radius
            )
        else:
            eye = torch.eye(n, dtype=poses.dtype, device=poses.device)
            pair = maskf[:, :, None] * maskf[:, None, :] * (1 - eye)  # (B, N, N), no self-edges, no padding
        if self.cfg.absolute:
            th = poses[..., 2:3]
            heading = torch.cat([torch.cos(th), torch.sin(th)], dim=-1)
            if rnd is not None:
                heading = heading * (~rnd)[..., None].to(heading.dtype)
            absf = torch.cat([poses[..., :2] / self.cfg.length_scale, heading], dim=-1)
            v = torch.cat([v, absf], dim=-1)
            e = None
        else:
            e = self.edges(poses, rnd, walls if self.reads_walls else None, index)
            if tap is not None:
                tap(e, pair, index)
        for layer in self.layers:
            v = layer(v, e, pair, index)
        if self.cfg.local:  # each object's own term, summed
            v = self.node_terms(v)
        return (v * maskf[..., None]).sum(dim=1)  # global add pooling

    def node_terms(self, v: Tensor) -> Tensor:
        """A local network's per-object terms up to the head's last linear, ``act(W1 v_i + b1)``, from the
        last layer's states ``v (..., N, H)`` (their sum is what :meth:`readout` reads)."""
        return self.head[1](self.head[0](v))

    def readout(self, pooled: Tensor) -> Tensor:
        """The energy per scene from :meth:`_pooled`'s sum: the head (dense), or the head's last linear
        (local: the energy is a sum of per-object terms ``W2 act(W1 v_i + b1)``, plus one bias, so one
        object's terms weigh as much among forty objects as among four, and far objects add their own
        terms instead of changing how the head reads the sum)."""
        return (self.head[2](pooled) if self.cfg.local else self.head(pooled)).squeeze(-1)

    @property
    def reads_walls(self) -> bool:
        """Whether edges touching a wall are read as such (:attr:`EnergyConfig.wall_range`, ``wall_lines``)."""
        return self.cfg.walls and (self.cfg.wall_range is not None or self.cfg.wall_lines)

    def edges(
        self,
        poses: Tensor,
        round: Tensor | None,
        walls: Tensor | None = None,
        index: Tensor | None = None,
        receivers: Tensor | None = None,
    ) -> Tensor:
        """What the message layers read of each edge: :func:`edge_features`, through the edge encoder
        when the network has one; ``(B, N, N or S, 4 or edge_encoder)``. ``walls (B, N)``: which nodes
        are walls (see :func:`wall_nodes`), for a network that :attr:`reads_walls`; ``index``: a local
        graph (:func:`neighbour_graph`), the edges into ``receivers`` alone where given."""
        cfg = self.cfg
        e = edge_features(
            poses,
            cfg.length_scale,
            cfg.edge_range,
            round,
            walls,
            cfg.wall_range,
            cfg.wall_lines,
            index,
            receivers,
        )
        return e if self.edge_enc is None else self.edge_enc(e)
