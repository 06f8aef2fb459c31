"""The SceneScore energy network: a dense, batched graph neural network over object poses.

Nodes carry semantic embeddings (encoder vector -> trained 2-layer MLP, scale descriptor appended).
The edge feature ``e_ji`` is the pose of object ``i`` in the frame of object ``j``:
``R(-theta_j)(p_i - p_j), cos(theta_i - theta_j), sin(theta_i - theta_j)``, so the energy is invariant
to any rigid motion of the whole scene. Each layer is ``v_i' = act(sum_j f(v_i, v_j, e_ji))``; global add
pooling and an MLP head give one scalar per scene. Graphs are fully connected and dense: ``(B, N, N, H)``
edge tensors with a padding mask.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch.autograd.function import once_differentiable

from ..errors import ConfigError, check_number
from ..memory import check as check_memory
from ..memory import chunk_rows, return_freed_memory

__all__ = [
    "WALLS",
    "EnergyConfig",
    "EnergyNet",
    "edge_features",
    "make_activation",
    "parameter_count",
    "wall_nodes",
]

Activation = Literal["silu", "softplus", "leaky_relu"]


MAX_WIDTH = 8192  # the widest layer a checkpoint may declare (the defaults are 32)
MAX_LAYERS = 64
WALLS = 4  # the bounds' sides that a model with walls appends after each scene's objects


@dataclass
class EnergyConfig:
    """Architecture of :class:`EnergyNet` (stored in checkpoints)."""

    feat_dim: int
    embed_dim: int = 32
    hidden: int = 32
    edge_hidden: int | None = None  # width inside the message MLP f (default: hidden)
    layers: int = 3
    message: Literal["mlp", "linear"] = "mlp"  # "linear": the paper's single linear layer
    activation: Activation = "silu"  # the paper's is "leaky_relu"; smooth helps second-order solvers
    absolute: bool = False  # the "Abs" ablation: absolute poses in the nodes, no edge features
    length_scale: float = 0.1  # metres that map to one unit inside the network (training derives it)
    # offsets (in length scales) beyond which edge positions saturate smoothly: u / sqrt(1 + |u|^2 / R^2);
    # None: linear (checkpoints before it). Training derives it from the data's largest offset.
    edge_range: float | None = None
    walls: bool = False  # the bounds' four sides are fixed objects in every graph (training decides)
    # round disks' headings ignored: an edge from a round object carries only the distance, and an edge
    # touching one no relative heading (False: checkpoints before it; training turns it on)
    round_invariant: bool = False
    # width of the edge encoder ``act(W e + b)`` that each message layer reads instead of the four raw
    # edge features, so a message is a two-layer function of the relative pose and can form a well at
    # one offset, not only a ramp; None: the raw features (checkpoints before it)
    edge_encoder: int | None = None
    # offsets (in length scales) beyond which the positions on an edge touching a wall saturate, each
    # axis on its own: a wall is read near it (how far, how turned, which corner) and not as a ramp across
    # the room, whose sum over four walls pulled objects off their places far from every wall; None:
    # linear (checkpoints before it). Used only with ``walls``
    wall_range: float | None = None
    # walls as lines: seen from a wall an object is only how far it stands from it (its offset along the
    # wall is dropped), and a wall seen from an object is the foot of the perpendicular from the object
    # to it, so no edge reads where along a wall something stands (False: checkpoints before it)
    wall_lines: bool = False

    def __post_init__(self) -> None:
        own = "EnergyConfig"
        for name in ("feat_dim", "embed_dim", "hidden", "layers"):
            check_number(own, name, getattr(self, name), 1, MAX_WIDTH, integer=True)
        if self.edge_hidden is not None:
            check_number(own, "edge_hidden", self.edge_hidden, 1, MAX_WIDTH, integer=True)
        check_number(own, "layers", self.layers, 1, MAX_LAYERS, integer=True)
        check_number(own, "length_scale", self.length_scale, 0, open_lo=True)
        if self.edge_range is not None:
            check_number(own, "edge_range", self.edge_range, 0, open_lo=True)
        if self.edge_encoder is not None:
            check_number(own, "edge_encoder", self.edge_encoder, 1, MAX_WIDTH, integer=True)
        if self.wall_range is not None:
            check_number(own, "wall_range", self.wall_range, 0, open_lo=True)
        if self.message not in ("mlp", "linear"):
            raise ConfigError(f"{own}: message: expected 'mlp' or 'linear', got {self.message!r}")
        if self.activation not in ("silu", "softplus", "leaky_relu"):
            raise ConfigError(
                f"{own}: activation: expected 'silu', 'softplus' or 'leaky_relu', got {self.activation!r}"
            )
        for name in ("absolute", "walls", "round_invariant", "wall_lines"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{own}: {name}: expected true or false, got {getattr(self, name)!r}")

    def to_dict(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        """The widths that memory grows with, for messages."""
        inner = f", edge_hidden {self.edge_hidden}" if self.edge_hidden is not None else ""
        return f"hidden {self.hidden}{inner}, {self.layers} layers, embed_dim {self.embed_dim}"


def parameter_count(cfg: EnergyConfig) -> int:
    """The number of weights :class:`EnergyNet` has for ``cfg``, counted without building it."""
    h, inner = cfg.hidden, (cfg.edge_hidden or cfg.hidden) if cfg.message == "mlp" else cfg.hidden
    total = cfg.feat_dim * h + h + h * cfg.embed_dim + cfg.embed_dim  # embed
    d_edge = 0 if cfg.absolute else 4
    if cfg.edge_encoder and not cfg.absolute:
        total += 4 * cfg.edge_encoder + cfg.edge_encoder
        d_edge = cfg.edge_encoder
    for k in range(cfg.layers):
        d_in = cfg.embed_dim + 2 + (4 if cfg.absolute else 0) if k == 0 else h
        total += 2 * d_in * inner + inner + d_edge * inner  # w_i (with bias), w_j, w_e
        if cfg.message == "mlp":
            total += inner * h + h  # out
    return total + h * h + h + h + 1  # head


# on the CPU, one pass over more edges than this (pose sets x N x N) runs slower per pose set than the
# same pass in pieces: its (B, N, N, H) tensors leave the cache and fresh large allocations fault in their
# pages. Energies without a gradient, and a gradient for the poses alone (sampling, refinement), are then
# taken piece by piece, each piece forward and backward at once (``python benchmarks/bench_network.py``:
# 1.4 to 1.8 times the pose sets per second of the chunked path, 5000 pose sets of 4 to 12 objects and
# 1000 of 20 and 28, one thread)
CACHE_EDGES = 49152

# floats per edge (i, j) of one pose set that evaluating the energy holds at its peak, measured (CPU,
# float32) and rounded up: the edge features, then per message layer its (N, N, inner) tensors; with a
# gradient every layer's are kept for the backward pass
_EDGE_FLOATS = 32
_LAYER_FLOATS = 16


def make_activation(name: str) -> nn.Module:
    """The activation module called ``name``."""
    if name == "silu":
        return nn.SiLU()
    if name == "softplus":
        return nn.Softplus()
    if name == "leaky_relu":
        return nn.LeakyReLU(0.1)
    raise ValueError(f"unknown activation {name!r}; expected 'silu', 'softplus' or 'leaky_relu'")


def wall_nodes(mask: Tensor, count: int = WALLS) -> Tensor:
    """``(B, N)`` bool: the last ``count`` real nodes of each row, where batching puts the walls."""
    after = mask.flip(-1).cumsum(-1).flip(-1)  # real nodes at or after each index
    return mask & (after <= count)


def edge_features(
    poses: Tensor,
    length_scale: float,
    edge_range: float | None = None,
    round: Tensor | None = None,
    walls: Tensor | None = None,
    wall_range: float | None = None,
    wall_lines: bool = False,
) -> Tensor:
    """``e[b, i, j]``: pose of ``i`` in the frame of ``j``, ``(B, N, N, 4)``; positions in length scales,
    saturating beyond ``edge_range`` of them (the network never extrapolates to offsets far beyond the
    data's: they all look alike, as far).

    ``round (B, N)`` marks objects without a heading (round disks): seen from a round ``j`` the offset
    is ``(|u|, 0)``, the distance alone, and an edge touching one has relative heading ``(0, 0)``; the
    features then do not change when a round object turns.

    ``walls (B, N)`` marks the walls. With ``wall_lines`` an object seen from a wall is at ``(0, h)``, its
    height ``h`` above the wall's line (along the wall's own ``+y``), and a wall seen from an object is
    at the foot of the perpendicular, ``R(theta_wall - theta_j) (0, -h)``. With ``wall_range``, on an
    edge touching a wall each offset axis saturates on its own beyond that many length scales,
    ``u / sqrt(1 + (u / R)^2)``."""
    p = poses[..., :2]  # (B, N, 2)
    th = poses[..., 2]  # (B, N)
    d = p[:, :, None, :] - p[:, None, :, :]  # (B, N_i, N_j, 2): p_i - p_j
    c, s = torch.cos(th)[:, None, :], torch.sin(th)[:, None, :]  # theta_j, broadcast over i
    rx = c * d[..., 0] + s * d[..., 1]
    ry = -s * d[..., 0] + c * d[..., 1]
    dth = th[:, :, None] - th[:, None, :]
    ux, uy = rx / length_scale, ry / length_scale
    cd, sd = torch.cos(dth), torch.sin(dth)
    if walls is not None and wall_lines:
        wi, wj = walls[:, :, None], walls[:, None, :]  # (B, N_i, 1), (B, 1, N_j)
        h = uy.transpose(1, 2)  # [b, i, j]: how far j stands from i's line, were i a wall
        ux, uy = (
            torch.where(wj, torch.zeros_like(ux), torch.where(wi, sd * h, ux)),
            torch.where(wi & ~wj, -cd * h, uy),
        )
    if round is not None:
        rj = round[:, None, :]  # (B, 1, N_j)
        dist = torch.sqrt(ux * ux + uy * uy + 1e-12)  # the constant keeps the gradient finite at i == j
        ux, uy = torch.where(rj, dist, ux), uy.masked_fill(rj, 0.0)
        either = rj | round[:, :, None]
        cd, sd = cd.masked_fill(either, 0.0), sd.masked_fill(either, 0.0)
    if walls is not None and wall_range is not None:
        touch = walls[:, :, None] | walls[:, None, :]  # (B, N_i, N_j)
        ux = torch.where(touch, ux * torch.rsqrt(1 + (ux / wall_range) ** 2), ux)
        uy = torch.where(touch, uy * torch.rsqrt(1 + (uy / wall_range) ** 2), uy)
    if edge_range is not None:
        f = torch.rsqrt(1 + (ux * ux + uy * uy) / edge_range**2)
        ux, uy = ux * f, uy * f
    return torch.stack([ux, uy, cd, sd], dim=-1)


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

    def forward(self, v: Tensor, e: Tensor | None, pair_mask: Tensor) -> Tensor:
        # f's last linear is moved out of the sum over j (it is linear): sum_j p_ij (W a_ij + b) =
        # W (sum_j p_ij a_ij) + b deg_i, so the (B, N, N, H) tensors are the first layer's and its
        # activation only
        m = self.w_i(v)[:, :, None, :] + self.w_j(v)[:, None, :, :]  # (B, N, N, H)
        if self.w_e is not None and e is not None:
            m = m + self.w_e(e)
        if self.out is not None:
            m = self.act(m)
        s = (m * pair_mask[..., None]).sum(dim=2)  # (B, N, H): sum_j p_ij m_ij
        if self.out is not None:
            s = F.linear(s, self.out.weight) + pair_mask.sum(dim=2, keepdim=True) * self.out.bias
        return self.act(s)


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
        return itemsize * (n * n * per_edge + n * per_node)

    def chunk_rows(self, n: int, grad: bool, itemsize: int = 4) -> int:
        """Pose sets of ``n`` objects evaluated at once (see :func:`scenescore.memory.chunk_rows`)."""
        return chunk_rows(
            self.row_bytes(n, grad, itemsize),
            f"energy network: one pose set of {n} objects ({self.cfg.describe()}"
            f"{', with its gradient' if grad else ''})",
            "the number of objects in the scene",
        )

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
        ``round (B or 1, N)``: the round objects, whose headings a ``round_invariant`` network ignores.

        A batch larger than :meth:`chunk_rows` goes through the message layers in chunks of rows (with a
        gradient, each chunk is recomputed in the backward pass instead of kept), and the head sees the
        whole batch: the same numbers as one pass, in bounded memory. The chunked path has first
        derivatives only (no ``create_graph``); with ``weight_grads=False`` (sampling, which needs the
        gradient with respect to the poses alone) it gives the weights none.

        On the CPU a batch of more than :data:`CACHE_EDGES` edges (or more rows than one chunk) is taken
        in pieces of at most that many when it needs no gradient, or (with ``weight_grads=False``) a
        gradient for the poses alone, each piece forward and backward at once, without the chunked
        path's second forward pass (:class:`_PoseGradInPieces`); the head sees the whole batch. The same
        energies, the same gradients to float rounding, faster."""
        b, n, _ = poses.shape
        grad = torch.is_grad_enabled()
        rows = self.chunk_rows(n, grad, poses.element_size())
        args = (poses, feats, sizes, mask, nodes, round)
        piece = min(rows, max(1, CACHE_EDGES // (n * n)))
        if poses.device.type == "cpu" and b > piece:
            if not grad:
                return self.head(_pooled_in_chunks(self, piece, args)).squeeze(-1)
            if not weight_grads and poses.requires_grad:
                return _PoseGradInPieces.apply(self, piece, *args)
        if b <= rows:
            pooled = self._pooled(*args)
        else:
            return_freed_memory()
            weights = list(self.parameters()) if weight_grads else []
            pooled = _ChunkedPooled.apply(self, rows, *args, *weights)
        return self.head(pooled).squeeze(-1)

    def _pooled(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None,
        nodes: Tensor | None,
        round: Tensor | None,
    ) -> Tensor:
        """The message layers and the global add pooling: ``(B, hidden)``."""
        b, n, _ = poses.shape
        if mask is None:
            mask = torch.ones(b, n, dtype=torch.bool, device=poses.device)
        if nodes is None:
            assert feats is not None and sizes is not None, "EnergyNet: give feats and sizes, or nodes"
            v = self.node_embedding(feats, sizes)
        else:
            v = nodes
        v = v.expand(b, n, v.shape[-1])
        maskf = mask.to(poses.dtype).expand(b, n)
        eye = torch.eye(n, dtype=poses.dtype, device=poses.device)
        pair = maskf[:, :, None] * maskf[:, None, :] * (1 - eye)  # (B, N, N), no self-edges, no padding
        # scenes without a round object take the plain path (the same numbers, less work)
        rnd = None
        if round is not None and self.cfg.round_invariant and bool(round.any()):
            rnd = round.expand(b, n)
        if self.cfg.absolute:
            th = poses[..., 2:3]
            heading = torch.cat([torch.cos(th), torch.sin(th)], dim=-1)
            if rnd is not None:
                heading = heading * (~rnd)[..., None].to(heading.dtype)
            absf = torch.cat([poses[..., :2] / self.cfg.length_scale, heading], dim=-1)
            v = torch.cat([v, absf], dim=-1)
            e = None
        else:
            e = self.edges(poses, rnd, wall_nodes(mask).expand(b, n) if self.reads_walls else None)
        for layer in self.layers:
            v = layer(v, e, pair)
        return (v * maskf[..., None]).sum(dim=1)  # global add pooling

    @property
    def reads_walls(self) -> bool:
        """Whether edges touching a wall are read as such (:attr:`EnergyConfig.wall_range`, ``wall_lines``)."""
        return self.cfg.walls and (self.cfg.wall_range is not None or self.cfg.wall_lines)

    def edges(self, poses: Tensor, round: Tensor | None, walls: Tensor | None = None) -> Tensor:
        """What the message layers read of each edge: :func:`edge_features`, through the edge encoder
        when the network has one; ``(B, N, N, 4 or edge_encoder)``. ``walls (B, N)``: which nodes are
        walls (see :func:`wall_nodes`), for a network that :attr:`reads_walls`."""
        cfg = self.cfg
        e = edge_features(
            poses, cfg.length_scale, cfg.edge_range, round, walls, cfg.wall_range, cfg.wall_lines
        )
        return e if self.edge_enc is None else self.edge_enc(e)


class _ChunkedPooled(torch.autograd.Function):
    """:meth:`EnergyNet._pooled` over a batch in chunks of ``rows``: the forward pass keeps no graph; the
    backward pass recomputes one chunk at a time with its graph and backpropagates through it."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, rows: int, *inputs: Tensor | None) -> Tensor:
        args = inputs[:6]
        b = _first(args).shape[0]
        ctx.net, ctx.rows, ctx.b = net, rows, b
        ctx.save_for_backward(*args)
        with torch.no_grad():
            return _pooled_in_chunks(net, rows, args)

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
                part = _rows_of(args, b, a, a + rows)
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


class _PoseGradInPieces(torch.autograd.Function):
    """The energy of a batch and its gradient with respect to the poses, ``rows`` pose sets at a time: each
    piece runs forward and backward at once, while its tensors are in cache, and keeps only the gradient
    ``(rows, N, 3)``; the backward pass scales it. The energies come from the head over the whole batch,
    as in one pass. The other inputs and the weights get no gradient."""

    @staticmethod
    def forward(ctx: Any, net: EnergyNet, rows: int, *inputs: Tensor | None) -> Tensor:
        b = _first(inputs).shape[0]
        pooled, grads = [], []
        for a in range(0, b, rows):
            part = [None if t is None else t.detach() for t in _rows_of(inputs, b, a, a + rows)]
            with torch.enable_grad():
                poses = _first(part).requires_grad_(True)
                p = _pooled_of(net, [poses, *part[1:]])
                (g,) = torch.autograd.grad(net.head(p).sum(), poses)
            pooled.append(p.detach())
            grads.append(g)
        ctx.save_for_backward(torch.cat(grads))
        with torch.no_grad():
            return net.head(torch.cat(pooled)).squeeze(-1)

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


def _pooled_in_chunks(net: EnergyNet, rows: int, args: Sequence[Tensor | None]) -> Tensor:
    """:func:`_pooled_of` of a batch's six inputs, ``rows`` pose sets at a time, concatenated."""
    b = _first(args).shape[0]
    return torch.cat([_pooled_of(net, _rows_of(args, b, a, a + rows)) for a in range(0, b, rows)])


def _rows_of(args: Sequence[Tensor | None], b: int, a: int, z: int) -> list[Tensor | None]:
    """Rows ``a:z`` of each of a batch's inputs (see :func:`_rows`)."""
    return [_rows(t, b, a, z) for t in args]


def _rows(t: Tensor | None, b: int, a: int, z: int) -> Tensor | None:
    """Rows ``a:z`` of a per-row input of a batch of ``b`` (inputs of one row broadcast: kept whole)."""
    if t is None or t.shape[0] != b:
        return t
    return t[a:z]
