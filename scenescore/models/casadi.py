"""The energy network as a CasADi expression, rebuilt from its weights (exact derivatives for IPOPT)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import torch

__all__ = ["energy_mx"]


def _act(name: str, x):
    if name == "silu":
        return x / (1 + ca.exp(-x))
    if name == "softplus":
        return ca.log1p(ca.exp(x))
    if name == "leaky_relu":
        return ca.fmax(x, 0.1 * x)
    raise ValueError(f"activation {name!r} has no CasADi form")


def energy_mx(model, scene, poses):
    """The model's energy as a CasADi expression of ``poses`` (an ``N x 3`` MX/SX/DM), rebuilt from its weights."""
    net = model.net
    cfg = net.cfg
    st = model.tensors([scene])
    with torch.no_grad():
        nodes = net.node_embedding(st.feats, st.sizes)[0].double().cpu().numpy().T  # (D, N)
    sd = {k: v.detach().double().cpu().numpy() for k, v in net.state_dict().items()}
    walls = st.poses[0, len(scene) :].double().cpu().numpy()  # the objects the model adds (walls): constants
    rnd = st.round[0].tolist() if cfg.round_invariant else [False] * st.poses.shape[1]
    if len(walls):
        poses = ca.vertcat(poses, ca.DM(walls))
    n = len(scene) + len(walls)
    ls = cfg.length_scale
    reads_walls = net.reads_walls
    x, y, th = poses[:, 0], poses[:, 1], poses[:, 2]
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    si = np.zeros((n, len(pairs)))
    sj = np.zeros((n, len(pairs)))
    for p, (i, j) in enumerate(pairs):
        si[i, p] = 1.0
        sj[j, p] = 1.0
    if cfg.absolute:
        keep = ca.DM([[0.0 if r else 1.0 for r in rnd]])  # (1, N): round objects show no heading
        v = ca.vertcat(ca.DM(nodes), (x / ls).T, (y / ls).T, ca.cos(th).T * keep, ca.sin(th).T * keep)
        e = None
    else:
        v = ca.DM(nodes)
        cols = []
        for i, j in pairs:
            dx, dy = x[i] - x[j], y[i] - y[j]
            c, s = ca.cos(th[j]), ca.sin(th[j])
            ux, uy = (c * dx + s * dy) / ls, (-s * dx + c * dy) / ls
            hc, hs = ca.cos(th[i] - th[j]), ca.sin(th[i] - th[j])
            if reads_walls and cfg.wall_lines and j >= len(scene):  # seen from a wall: the height alone
                ux = 0
            elif reads_walls and cfg.wall_lines and i >= len(scene):  # a wall: the perpendicular's foot
                h = (-ca.sin(th[i]) * (x[j] - x[i]) + ca.cos(th[i]) * (y[j] - y[i])) / ls
                ux, uy = hs * h, -hc * h
            if rnd[j]:  # seen from a round object: the distance alone (see edge_features)
                ux, uy = ca.sqrt(ux * ux + uy * uy + 1e-12), 0
            if rnd[i] or rnd[j]:
                hc, hs = 0, 0
            if reads_walls and cfg.wall_range is not None and max(i, j) >= len(scene):  # see edge_features
                r = cfg.wall_range
                ux, uy = ux / ca.sqrt(1 + (ux / r) ** 2), uy / ca.sqrt(1 + (uy / r) ** 2)
            if cfg.edge_range is not None:
                f = 1 / ca.sqrt(1 + (ux * ux + uy * uy) / cfg.edge_range**2)
                ux, uy = ux * f, uy * f
            cols.append(ca.vertcat(ux, uy, hc, hs))
        e = ca.horzcat(*cols)  # (4, P)
        if cfg.edge_encoder:
            e = _act(cfg.activation, ca.mtimes(sd["edge_enc.0.weight"], e) + sd["edge_enc.0.bias"])
    for k in range(cfg.layers):
        pre = f"layers.{k}."
        a = ca.mtimes(sd[pre + "w_i.weight"], v) + sd[pre + "w_i.bias"]
        c = ca.mtimes(sd[pre + "w_j.weight"], v)
        m = ca.mtimes(a, si) + ca.mtimes(c, sj)
        if e is not None:
            m = m + ca.mtimes(sd[pre + "w_e.weight"], e)
        if cfg.message == "mlp":
            m = ca.mtimes(sd[pre + "out.weight"], _act(cfg.activation, m)) + sd[pre + "out.bias"]
        v = _act(cfg.activation, ca.mtimes(m, si.T))
    pooled = ca.sum2(v)
    h = _act(cfg.activation, ca.mtimes(sd["head.0.weight"], pooled) + sd["head.0.bias"])
    return ca.mtimes(sd["head.2.weight"], h) + sd["head.2.bias"]
