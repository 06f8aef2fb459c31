"""The ``casadi`` solver: IPOPT refinement through CasADi.

The learned energy enters CasADi as a symbolic MX rebuild of the network from its weights
(``energy="mx"``, the default: exact Hessians), or as a ``casadi.Callback`` that evaluates the network and
its gradient in torch (``energy="callback"``, with IPOPT's limited-memory Hessian). The MX rebuild is
kept as the default because it measured faster and more reliable here (``benchmarks/bench_solvers.py``).
Other terms without a symbolic form (a user's :class:`~scenescore.costs.CostFn`) always go through a
Callback. Non-overlap is exact for convex footprints: one separating line per pair (angle ``phi``,
offset ``b`` as extra variables) with every core vertex of one object on its side, grown by the radius
and half the margin. Bounds hold every footprint vertex inside; reach is ``|p - base|^2 <= r^2``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
import torch
from torch import Tensor

from ..costs import Bounds, HingeCollision, LearnedEnergy, PoseTarget, ReachLimit
from ..costs.geometry import footprint_core
from ..problem import Problem
from .result import Result, StageSolver, Status, make_result
from .sqp import _start

__all__ = ["CasadiOptions", "CasadiSolver", "energy_mx"]


@dataclass
class CasadiOptions:
    """Options of the ``casadi`` (IPOPT) refinement."""

    energy: str = "mx"  # "mx": symbolic rebuild of the network; "callback": torch through casadi.Callback
    max_iter: int = 300
    tol: float = 1e-8
    constr_viol_tol: float = 1e-7

    def __post_init__(self) -> None:
        if self.energy not in ("mx", "callback"):
            raise ValueError(f"casadi: energy: expected 'mx' or 'callback', got {self.energy!r}")


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
        nodes = net.node_embedding(st.feats, st.sizes)[0].double().numpy().T  # (D, N)
    sd = {k: v.detach().double().numpy() for k, v in net.state_dict().items()}
    n = len(scene)
    ls = cfg.length_scale
    x, y, th = poses[:, 0], poses[:, 1], poses[:, 2]
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    si = np.zeros((n, len(pairs)))
    sj = np.zeros((n, len(pairs)))
    for p, (i, j) in enumerate(pairs):
        si[i, p] = 1.0
        sj[j, p] = 1.0
    if cfg.absolute:
        v = ca.vertcat(ca.DM(nodes), (x / ls).T, (y / ls).T, ca.cos(th).T, ca.sin(th).T)
        e = None
    else:
        v = ca.DM(nodes)
        cols = []
        for i, j in pairs:
            dx, dy = x[i] - x[j], y[i] - y[j]
            c, s = ca.cos(th[j]), ca.sin(th[j])
            cols.append(
                ca.vertcat(
                    (c * dx + s * dy) / ls,
                    (-s * dx + c * dy) / ls,
                    ca.cos(th[i] - th[j]),
                    ca.sin(th[i] - th[j]),
                )
            )
        e = ca.horzcat(*cols)  # (4, P)
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


class _TorchCallback(ca.Callback):
    """A scalar torch function of ``n`` variables (value and gradient by autograd) as a CasADi function."""

    def __init__(self, name: str, fn, n: int):
        ca.Callback.__init__(self)
        self.fn, self.n = fn, n
        self._jac = None
        self.construct(name, {"enable_fd": False})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(1, 1)

    def eval(self, arg):
        z = torch.as_tensor(np.asarray(arg[0]).ravel(), dtype=torch.float64)
        with torch.no_grad():
            return [float(self.fn(z))]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        self._jac = _TorchGrad(name, self.fn, self.n, opts)
        return self._jac


class _TorchGrad(ca.Callback):
    def __init__(self, name: str, fn, n: int, opts):
        ca.Callback.__init__(self)
        self.fn, self.n = fn, n
        self.construct(name, opts)

    def get_n_in(self):
        return 2

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n, 1) if i == 0 else ca.Sparsity.dense(1, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(1, self.n)

    def eval(self, arg):
        z = torch.as_tensor(np.asarray(arg[0]).ravel(), dtype=torch.float64).requires_grad_(True)
        with torch.enable_grad():
            (g,) = torch.autograd.grad(self.fn(z), z)
        return [g.numpy()[None, :]]


class _Built:
    """The NLP of one problem, built once and reused across solves."""

    def __init__(self, problem: Problem, opts: CasadiOptions):
        self.problem = problem
        scene = problem.scene
        n = problem.n
        var_obj = [int(i) for i in np.flatnonzero(problem.movable_mask)]
        self.var_obj = var_obj
        nz = 3 * len(var_obj)
        z = ca.MX.sym("z", nz)
        pose_p = ca.MX.sym("p", n, 3)  # the poses of objects that do not move (parameters)
        rows = []
        for i in range(n):
            rows.append(
                z[3 * var_obj.index(i) : 3 * var_obj.index(i) + 3].T if i in var_obj else pose_p[i, :]
            )
        poses = ca.vertcat(*rows)  # (N, 3)
        base = problem.base_poses()
        self.callbacks = []
        f = 0
        exact = True
        for w, c in problem.cost.objective_items:
            if isinstance(c, LearnedEnergy) and opts.energy == "mx":
                seen = ca.vertcat(*[poses[i, :] for i in c.visible])
                f = f + w * energy_mx(c.model, c.visible_scene, seen)
            elif isinstance(c, PoseTarget):
                d = poses[c._i, :2] - ca.DM(c.xy).T
                th = 0.0 if c.theta is None else c.theta
                f = f + w * (ca.sumsqr(d) + c.theta_weight * (1 - ca.cos(poses[c._i, 2] - th)))
            else:
                exact = False

                def fn(zt: Tensor, c=c, w=w) -> Tensor:
                    x = base.clone()
                    x[var_obj] = zt.reshape(-1, 3)
                    return w * c(x[None])[0]

                cb = _TorchCallback(f"term_{len(self.callbacks)}", fn, nz)
                self.callbacks.append(cb)
                f = f + cb(z)
        g, lbg, ubg = [], [], []
        lines = []  # separating-line variables (phi, b) per pair
        cores = [footprint_core(o) for o in scene.objects]

        def world(i):
            core, r = cores[i]
            c, s = ca.cos(poses[i, 2]), ca.sin(poses[i, 2])
            return [(poses[i, 0] + c * px - s * py, poses[i, 1] + s * px + c * py) for px, py in core], r

        for term in problem.cost.constraint_terms:
            if isinstance(term, HingeCollision):
                for i, j in term.support():
                    phi, b = ca.MX.sym(f"phi_{i}_{j}"), ca.MX.sym(f"b_{i}_{j}")
                    lines.append((phi, b, i, j))
                    nx, ny = ca.cos(phi), ca.sin(phi)
                    va, ra = world(i)
                    vb, rb = world(j)
                    for px, py in va:  # object i on the negative side: n.v + r + m/2 <= b
                        g.append(nx * px + ny * py + ra + term.margin / 2 - b)
                        lbg.append(-ca.inf)
                        ubg.append(0.0)
                    for px, py in vb:  # object j on the positive side
                        g.append(b - (nx * px + ny * py) + rb + term.margin / 2)
                        lbg.append(-ca.inf)
                        ubg.append(0.0)
            elif isinstance(term, Bounds):
                lo, hi = term._lo.tolist(), term._hi.tolist()
                for i in term._idx:
                    if term.footprint:
                        v, r = world(i)
                    else:
                        v, r = [(poses[i, 0], poses[i, 1])], 0.0
                    for px, py in v:
                        g += [px, py]
                        lbg += [lo[0] + r, lo[1] + r]
                        ubg += [hi[0] - r, hi[1] - r]
            elif isinstance(term, ReachLimit):
                for i in term._idx:
                    g.append((poses[i, 0] - term.base[0]) ** 2 + (poses[i, 1] - term.base[1]) ** 2)
                    lbg.append(-ca.inf)
                    ubg.append(term.radius**2)
            else:
                raise ValueError(
                    f"casadi: constraint term {term.name!r} ({type(term).__name__}) has no CasADi form"
                )
        self.lines = lines
        xs = ca.vertcat(z, *[ca.vertcat(phi, b) for phi, b, _, _ in lines])
        self.nz = nz
        self.lbg, self.ubg = np.array(lbg, dtype=float), np.array(ubg, dtype=float)
        ipopt = {
            "print_level": 0,
            "max_iter": opts.max_iter,
            "tol": opts.tol,
            "constr_viol_tol": opts.constr_viol_tol,
            "sb": "yes",
        }
        if not exact:
            ipopt["hessian_approximation"] = "limited-memory"
        self.exact_hessian = exact
        nlp = {"x": xs, "p": ca.vec(pose_p), "f": f, "g": ca.vertcat(*g) if g else ca.MX(0, 1)}
        self.solver = ca.nlpsol("scenescore", "ipopt", nlp, {"ipopt": ipopt, "print_time": False})

    def start(self, x0: np.ndarray) -> np.ndarray:
        z0 = x0[self.var_obj].reshape(-1)
        extra = []
        for (
            _,
            _,
            i,
            j,
        ) in self.lines:  # the line between the two centres, normal along the centre-to-centre line
            d = x0[j, :2] - x0[i, :2]
            phi = math.atan2(d[1], d[0]) if np.hypot(*d) > 1e-9 else 0.0
            mid = (x0[i, :2] + x0[j, :2]) / 2
            extra += [phi, math.cos(phi) * mid[0] + math.sin(phi) * mid[1]]
        return np.concatenate([z0, np.array(extra)])


class CasadiSolver(StageSolver):
    """Refinement stage: ``solve(problem, init=None, seed=0) -> Result``."""

    name = "casadi"
    options_cls = CasadiOptions

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        t0 = time.perf_counter()
        key = (
            "casadi",
            self.options.energy,
            self.options.max_iter,
            self.options.tol,
            self.options.constr_viol_tol,
        )
        cache = problem.__dict__.setdefault("_solver_cache", {})
        if key not in cache:
            cache[key] = _Built(problem, self.options)
        built: _Built = cache[key]
        x0 = _start(problem, init, seed)[0].numpy()
        t1 = time.perf_counter()
        sol = built.solver(x0=built.start(x0), p=x0.reshape(-1, order="F"), lbg=built.lbg, ubg=built.ubg)
        t2 = time.perf_counter()
        stats = built.solver.stats()
        x = x0.copy()
        xz = np.asarray(sol["x"]).ravel()[: built.nz]
        x[built.var_obj] = xz.reshape(-1, 3)
        ret = stats.get("return_status", "")
        status = (
            Status.CONVERGED
            if stats.get("success")
            else (
                Status.MAX_ITERATIONS
                if ret == "Maximum_Iterations_Exceeded"
                else Status.INFEASIBLE
                if "Infeasible" in ret
                else Status.FAILED
            )
        )
        msg = "" if stats.get("success") else f"IPOPT: {ret}"
        r = make_result(
            problem, self.name, x, status, int(stats.get("iter_count", 0)), t1 - t0, t2 - t1, message=msg
        )
        if r.status == Status.CONVERGED and not r.success:
            r.status = Status.INFEASIBLE
        return r
