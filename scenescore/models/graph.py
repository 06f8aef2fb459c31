"""The graph the energy network reads: each edge's features (the relative pose, with the walls' and
round objects' own forms) and, for rooms, the local graph of each object's nearest neighbours.

Per-node tensors ``(B, N, ...)`` are seen along the edges into each node by :func:`senders`: a dense
graph broadcasts them over the receivers, ``(B, 1, N, ...)``; a local graph gathers each node's
neighbours, ``(B, N, S, ...)`` for the lists ``index (B, N, S)`` of :func:`neighbour_graph`.
"""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = [
    "WALLS",
    "wall_nodes",
    "senders",
    "receiving",
    "edge_features",
    "fade",
    "footprint_gaps",
    "neighbour_graph",
]

WALLS = 4  # the bounds' sides that a model with walls appends after each scene's objects


def wall_nodes(mask: Tensor, count: int = WALLS) -> Tensor:
    """``(B, N)`` bool: the last ``count`` real nodes of each row, where batching puts the walls."""
    after = mask.flip(-1).cumsum(-1).flip(-1)  # real nodes at or after each index
    return mask & (after <= count)


def senders(t: Tensor, index: Tensor | None) -> Tensor:
    """Per-node ``t (B, N, ...)`` seen along the edges into each node: ``(B, N, S, ...)`` with ``t[b,
    index[b, i, s]]`` for a local graph (``index (B, N, S)``), or ``(B, 1, N, ...)`` broadcast over the
    receivers for a dense one (``index`` None)."""
    if index is None:
        return t[:, None]
    b, n = t.shape[:2]
    flat = (index + (torch.arange(b, device=t.device) * n)[:, None, None]).reshape(-1)
    return t.reshape(b * n, *t.shape[2:]).index_select(0, flat).reshape(*index.shape, *t.shape[2:])


def receiving(t: Tensor, receivers: Tensor | None) -> Tensor:
    """Per-node ``t (B, N, ...)`` at the receiving end of the edges: ``t`` itself, or, for the edges into
    the nodes ``receivers (B, M)`` alone, those nodes' rows ``(B, M, ...)``."""
    return t if receivers is None else senders(t, receivers[..., None])[:, :, 0]


def edge_features(
    poses: Tensor,
    length_scale: float,
    edge_range: float | None = None,
    round: Tensor | None = None,
    walls: Tensor | None = None,
    wall_range: float | None = None,
    wall_lines: bool = False,
    index: Tensor | None = None,
    receivers: Tensor | None = None,
) -> Tensor:
    """``e[b, i, j]``: pose of ``i`` in the frame of ``j``, ``(B, N, N, 4)``; positions in length scales,
    saturating beyond ``edge_range`` of them (the network never extrapolates to offsets far beyond the
    data's: they all look alike, as far). With ``index (B, N, S)`` (a local graph) only the edges into
    each ``i`` from ``index[b, i, s]``: ``(B, N, S, 4)``; with ``receivers (B, M)`` as well, only the edges
    into those nodes, ``index (B, M, S)`` their senders: ``(B, M, S, 4)``.

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
    d = receiving(p, receivers)[:, :, None, :] - senders(p, index)  # (B, N_i, N_j or S, 2): p_i - p_j
    c, s = senders(torch.cos(th), index), senders(torch.sin(th), index)  # theta_j
    rx = c * d[..., 0] + s * d[..., 1]
    ry = -s * d[..., 0] + c * d[..., 1]
    # made here, after the offsets: autograd sums the poses' gradient in the order its operations were
    # made, and a seed's trained model depends on that order
    th_i = receiving(th, receivers)[:, :, None]  # (B, N_i, 1)
    dth = th_i - senders(th, index)
    ux, uy = rx / length_scale, ry / length_scale
    cd, sd = torch.cos(dth), torch.sin(dth)
    if walls is not None and wall_lines:
        wi, wj = (
            receiving(walls, receivers)[:, :, None],
            senders(walls, index),
        )  # (B, N_i, 1), (B, 1 or N_i, N_j or S)
        # [b, i, j]: how far j stands from i's line, were i a wall: j's y in the frame of i (the
        # transposed edge of a dense graph; worked out along a local graph's edges)
        if index is None:
            h = uy.transpose(1, 2)
        else:
            c_i, s_i = torch.cos(th_i), torch.sin(th_i)
            h = (s_i * d[..., 0] - c_i * d[..., 1]) / length_scale
        ux, uy = (
            torch.where(wj, torch.zeros_like(ux), torch.where(wi, sd * h, ux)),
            torch.where(wi & ~wj, -cd * h, uy),
        )
    if round is not None:
        rj = senders(round, index)  # (B, 1 or N_i, N_j or S)
        dist = torch.sqrt(ux * ux + uy * uy + 1e-12)  # the constant keeps the gradient finite at i == j
        ux, uy = torch.where(rj, dist, ux), uy.masked_fill(rj, 0.0)
        either = rj | receiving(round, receivers)[:, :, None]
        cd, sd = cd.masked_fill(either, 0.0), sd.masked_fill(either, 0.0)
    if walls is not None and wall_range is not None:
        touch = receiving(walls, receivers)[:, :, None] | senders(walls, index)  # (B, N_i, N_j or S)
        ux = torch.where(touch, ux * torch.rsqrt(1 + (ux / wall_range) ** 2), ux)
        uy = torch.where(touch, uy * torch.rsqrt(1 + (uy / wall_range) ** 2), uy)
    if edge_range is not None:
        f = torch.rsqrt(1 + (ux * ux + uy * uy) / edge_range**2)
        ux, uy = ux * f, uy * f
    return torch.stack([ux, uy, cd, sd], dim=-1)


def fade(gap: Tensor, radius: float) -> Tensor:
    """An edge's weight in a local graph: ``(1 - (gap / radius)^2)^2`` up to ``radius``, zero beyond;
    one at touching, with zero slope there and at ``radius``."""
    x = (gap / radius).clamp(max=1.0)
    return (1 - x * x) ** 2


def footprint_gaps(
    pos: Tensor, reach: Tensor, index: Tensor | None = None, receivers: Tensor | None = None
) -> Tensor:
    """The gap between objects' circles: centre distance less both ``reach`` (half the longer side),
    at least zero; ``pos (B, N, 2)``, ``reach (B, N)`` -> ``(B, N, N)``, or ``(B, N, S)`` along the local
    graph ``index`` (``(B, M, S)`` into the nodes ``receivers (B, M)``, as in :func:`edge_features`). A
    pair at one spot (an object and itself) gets a finite gradient."""
    d = receiving(pos, receivers)[:, :, None, :] - senders(pos, index)
    dist = torch.sqrt((d * d).sum(-1) + 1e-12)
    return (dist - receiving(reach, receivers)[:, :, None] - senders(reach, index)).clamp(min=0.0)


def neighbour_graph(
    pos: Tensor,
    reach: Tensor,
    mask: Tensor,
    walls: Tensor | None,
    neighbours: int,
    radius: float,
) -> tuple[Tensor | None, Tensor]:
    """The local graph of a batch: each node's ``neighbours`` nearest objects by :func:`footprint_gaps`
    (walls never among them), then the walls, ``index (B, N, S)``, and each edge's weight ``(B, N, S)``:
    :func:`fade` of the gap; one from a wall; zero for padding, a node itself and gaps beyond ``radius``.
    Walls are read by every node and read only each other. When every object fits in the list the graph
    is dense: ``(None, weight (B, N, N))``, the same energy without the gathering. The choice of
    neighbours has no gradient; the weights do. Nothing here reads a tensor's values back (a chain
    builds the graph at every step)."""
    b, n = mask.shape
    objects = mask if walls is None else mask & ~walls
    eye = torch.eye(n, dtype=torch.bool, device=pos.device)
    from_object = objects[:, :, None] & objects[:, None, :] & ~eye  # (B, N, N): object j read by object i
    if neighbours >= n - 1:
        weight = fade(footprint_gaps(pos, reach), radius) * from_object
        if walls is not None:
            weight = weight + (mask[:, :, None] & walls[:, None, :] & ~eye).to(weight.dtype)
        return None, weight
    with torch.no_grad():
        gap = footprint_gaps(pos, reach).masked_fill(~from_object, float("inf"))
        near, index = gap.topk(neighbours, dim=-1, largest=False)
        ok = torch.isfinite(near)
    weight = fade(footprint_gaps(pos, reach, index), radius) * ok
    if walls is not None:
        # the walls are each row's last WALLS real nodes (wall_nodes), real nodes come first; a row of
        # padding alone reads nothing (its weights are zero) from indices that stay in the row
        first = (mask.sum(dim=1, keepdim=True) - WALLS).clamp(min=0)
        w_index = (first + torch.arange(WALLS, device=pos.device))[:, None, :].expand(b, n, WALLS)
        w_ok = mask[:, :, None] & (w_index != torch.arange(n, device=pos.device)[None, :, None])
        index = torch.cat([index, w_index], dim=2)
        weight = torch.cat([weight, w_ok.to(weight.dtype)], dim=2)
    return index, weight
