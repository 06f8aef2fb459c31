"""The ``alm`` solver: an augmented Lagrangian refinement of every particle at once, in torch.

The objective is the cost's terms that are not constraints (the learned energy, targets, user
functions); the constraints are the constraint terms' rows ``g(poses) >= 0`` (metres), each aimed
``slack`` inside. For rows ``c = slack - g`` (feasible where ``c <= 0``) the augmented Lagrangian of a
particle is::

    L(x; lam, rho) = f(x) + sum_r (relu(lam_r + rho_r c_r(x)) ** 2 - lam_r ** 2) / (2 rho_r)

with a multiplier ``lam`` and a penalty ``rho`` per particle and per row. The multipliers are
warm-started from the problem's own penalty (the force a violated row feels from its weighted hinge),
so particles from a sampler run on the penalised cost start with the multipliers that explain where
they stand. Each outer iteration runs ``inner`` projected quasi-Newton steps on ``L``, batched: every
particle has its own L-BFGS memory and step fraction (a sufficient-decrease test accepts or quarters
it; no coordinate moves more than ``step_max``: metres, or radians for an angle), then the multipliers
become ``relu(lam + rho c)`` and ``rho`` grows by ``penalty_growth`` on rows whose violation did not
fall by a quarter.

A row above ``slack + lam / rho`` adds a constant to ``L`` (no gradient, no multiplier), so only its
being there matters: the rows are asked for with that floor (``ConstraintCost.constraints_below``),
and the collision term bounds far-apart pairs by their bounding circles instead of computing them.
The iterates are the same, bit for bit, as with every row computed.

Every particle has its own convergence test: its largest violation (metres) within ``tolerance`` and
stationarity: the Lagrangian's gradient within ``tol_grad``, or the particle stopped moving (less than
``tol_step`` in an outer iteration; contacts between boxes are kinks where no gradient vanishes).
With ``polish: false`` the refinement is a repair: a particle is done as soon as it is feasible (one
feasible from the start does not move), which keeps a sampler's spread where polishing would merge
the particles of one basin into one arrangement. A looser ``tol_grad`` is the step between: every
particle takes at least one outer iteration's ``inner`` steps of descent, then stops once feasible
and the objective nearly flat, short of the minimum where the particles of a basin meet. Converged particles leave the active set, so later iterations only pay for the particles still
moving. A particle still violated when the iterations run out falls back to its last feasible iterate
(its start, if that was feasible). Fixed objects, and objects the problem does not move, never move.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from ..costs import ConstraintCost
from ..errors import ConfigError, check_number
from ..problem.problem import FEASIBILITY_TOL, Problem
from .base import StageSolver, start_poses
from .result import Result, Samples, Status, best_first, make_result

__all__ = ["ALMOptions", "ALMSolver", "ParticleStatus"]

MAX_ITERATIONS = 100_000  # more is a typo, not a plan
ARMIJO = 1e-4  # sufficient decrease: a step must win this fraction of its first-order prediction
SHRINK = 0.25  # the step fraction after a rejected step


@dataclass(frozen=True)
class ALMOptions:
    """Options of the ``alm`` batched refinement."""

    iterations: int = 25  # outer iterations (multiplier updates)
    inner: int = 3  # projected gradient steps per outer iteration
    tolerance: float = FEASIBILITY_TOL  # largest violation (metres) that counts as feasible
    tol_grad: float = 1e-2  # stationarity: the Lagrangian's gradient (cost per metre) ...
    tol_step: float = 1e-5  # ... or it moved less than this in an outer iteration (metres)
    slack: float = 1e-5  # rows are aimed this far inside (metres)
    penalty: float = 1e4  # initial penalty per row (cost per metre^2)
    penalty_growth: float = 10.0  # factor on the penalty of a row whose violation did not fall enough
    penalty_max: float = 1e9
    memory: int = 5  # L-BFGS pairs per particle
    step: float = 0.01  # a gradient step's largest coordinate move (metres; radians for an angle)
    step_max: float = 0.1  # the largest move of any coordinate in one step
    polish: bool = True  # keep minimising the objective once feasible; False: a particle stops when feasible

    def __post_init__(self) -> None:
        check_number("alm", "iterations", self.iterations, 0, MAX_ITERATIONS, integer=True)
        check_number("alm", "inner", self.inner, 1, MAX_ITERATIONS, integer=True)
        check_number("alm", "memory", self.memory, 1, 100, integer=True)
        for name in ("tolerance", "tol_grad", "tol_step", "penalty", "step", "step_max", "penalty_max"):
            check_number("alm", name, getattr(self, name), 0, open_lo=True)
        check_number("alm", "slack", self.slack, 0, self.tolerance)
        check_number("alm", "penalty_growth", self.penalty_growth, 1)
        check_number("alm", "step_max", self.step_max, self.step)
        check_number("alm", "penalty_max", self.penalty_max, self.penalty)
        if not isinstance(self.polish, bool):
            raise ConfigError(f"alm: polish: expected true or false, got {self.polish!r}")


class ParticleStatus:
    """What each particle ended with (strings of :class:`~scenescore.solvers.result.Status`)."""

    CONVERGED = Status.CONVERGED.value  # feasible and stationary
    MAX_ITERATIONS = Status.MAX_ITERATIONS.value  # feasible, still improving when the iterations ran out
    INFEASIBLE = Status.INFEASIBLE.value  # a row still violated by more than the tolerance
    FAILED = Status.FAILED.value  # the cost is not finite there


class _Lagrangian:
    """The problem as the refinement sees it: objective, rows, the AL value and its gradient, batched."""

    def __init__(self, problem: Problem, o: ALMOptions):
        self.problem, self.o = problem, o
        self.objective = problem.cost.objective_items
        self.rows_of: list[ConstraintCost] = problem.cost.constraint_terms
        weights = {c.name: w for w, c in problem.cost}
        f64, dev = torch.float64, problem.device
        self.weight = torch.cat(  # (R,): each row's penalty weight in the problem's cost
            [torch.full((len(c.labels()),), weights[c.name], dtype=f64, device=dev) for c in self.rows_of]
            or [torch.zeros(0, dtype=f64, device=dev)]
        )
        self.power = torch.cat(  # (R,)
            [torch.full((len(c.labels()),), float(c.power), dtype=f64, device=dev) for c in self.rows_of]
            or [torch.zeros(0, dtype=f64, device=dev)]
        )
        self.movable = torch.as_tensor(problem.movable_mask, device=problem.device)  # (N,)
        self.sizes = [len(c.labels()) for c in self.rows_of]

    def rows(self, x: Tensor, floor: Tensor | None = None) -> Tensor:
        """``g (B, R)``: every constraint row, feasible where ``>= 0`` (metres). With ``floor (B, R)``: exact
        where a row may be below it, elsewhere any value above it (see ``ConstraintCost.constraints_below``)."""
        if not self.rows_of:
            return x.new_zeros(x.shape[0], 0)
        if floor is None:
            return torch.cat([c.constraints(x) for c in self.rows_of], dim=1)
        out, a = [], 0
        for c, m in zip(self.rows_of, self.sizes):
            out.append(c.constraints_below(x, floor[:, a : a + m]))
            a += m
        return torch.cat(out, dim=1)

    def warm_multipliers(self, g: Tensor) -> Tensor:
        """``lam (B, R)``: the force each violated row feels from its weighted penalty ``w relu(-g) ** p``."""
        v = torch.relu(-g)
        force = self.weight * self.power * torch.where(v > 0, v ** (self.power - 1), torch.zeros_like(v))
        return torch.where(g < 0, force, torch.zeros_like(force))

    def inactive_above(self, lam: Tensor, rho: Tensor) -> Tensor:
        """``(B, R)``: above this a row's term is constant (``relu(lam + rho (slack - g)) = 0``, rounding
        allowed for), so that its value only needs to be known to be there: no multiplier, no violation,
        no gradient (the rows a term can bound cheaply, far-apart pairs, are then not computed)."""
        level = self.o.slack + lam / rho
        return level + 1e3 * torch.finfo(level.dtype).eps * (1 + level.abs())

    def __call__(self, x: Tensor, lam: Tensor, rho: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        """At ``x (B, N, 3)``: the AL value ``(B,)``, its gradient ``(B, N, 3)`` (zero on objects that do not
        move), the rows ``g (B, R)`` and the objective ``(B,)``. One forward and one backward pass."""
        with torch.enable_grad():
            x = x.detach().requires_grad_(True)
            f = x.new_zeros(x.shape[0])
            for w, c in self.objective:
                f = f + w * c(x)
            g = self.rows(x, self.inactive_above(lam, rho))
            c_ = self.o.slack - g
            shifted = torch.relu(lam + rho * c_)
            value = f + ((shifted**2 - lam**2) / (2 * rho)).sum(-1)
            (grad,) = torch.autograd.grad(value.sum(), x) if value.requires_grad else (torch.zeros_like(x),)
        grad = torch.where(self.movable[None, :, None], grad, torch.zeros_like(grad))
        return value.detach(), grad, g.detach(), f.detach()

    def step(self, x: Tensor, move: Tensor) -> Tensor:
        """``x + move`` on the moving objects, angles wrapped; the others keep their poses bit for bit."""
        return torch.where(self.movable[None, :, None], _wrap(x + move), x)

    def project(self, x: Tensor) -> Tensor:
        """The constraint terms' closed-form projections (bounds, reach) on the moving objects."""
        for c in self.rows_of:
            x = c.project(x, self.movable)
        return x


@dataclass
class _State:
    """The active particles: poses, multipliers, penalties, step sizes and the last evaluation."""

    idx: Tensor  # (A,) rows of the population
    x: Tensor  # (A, N, 3)
    lam: Tensor  # (A, R)
    rho: Tensor  # (A, R)
    t: Tensor  # (A,) the fraction of the quasi-Newton step to try next
    value: Tensor  # (A,) the AL at x
    grad: Tensor  # (A, N, 3)
    g: Tensor  # (A, R)
    before: Tensor  # (A, R) each row's violation at the last multiplier update (metres)
    mem_s: Tensor  # (A, M, 3N) the last M accepted moves, oldest first (zeros: empty)
    mem_y: Tensor  # (A, M, 3N) the gradient's change over each

    def keep(self, mask: Tensor) -> _State:
        return _State(*(t[mask] for t in self.__dict__.values()))


def _wrap(x: Tensor) -> Tensor:
    """Angles into ``[-pi, pi)``."""
    return torch.cat([x[..., :2], torch.remainder(x[..., 2:] + math.pi, 2 * math.pi) - math.pi], dim=-1)


def _violation(g: Tensor) -> Tensor:
    """The largest violation per particle ``(B,)`` in metres (0 without rows)."""
    if g.shape[-1] == 0:
        return g.new_zeros(g.shape[0])
    return torch.relu(-g).max(-1).values


def _largest(v: Tensor) -> Tensor:
    """The largest coordinate of ``v (A, N, 3)`` in absolute value, per particle ``(A,)``."""
    return v.abs().flatten(1).amax(-1)


def _direction(s: _State, first_step: float) -> Tensor:
    """The L-BFGS direction ``(A, N, 3)`` of each particle from its own memory (two-loop recursion,
    batched); a particle with an empty memory, or whose direction does not descend, takes the
    gradient's direction scaled so that its largest move is ``first_step``."""
    a, m, _ = s.mem_s.shape
    q = s.grad.flatten(1)  # (A, D)
    sy = (s.mem_s * s.mem_y).sum(-1)  # (A, M)
    inv = torch.where(sy > 0, 1.0 / sy.clamp_min(1e-300), torch.zeros_like(sy))  # 0 on empty slots
    alpha = q.new_zeros(a, m)
    for i in reversed(range(m)):
        alpha[:, i] = inv[:, i] * (s.mem_s[:, i] * q).sum(-1)
        q = q - alpha[:, i, None] * s.mem_y[:, i]
    yy = (s.mem_y[:, -1] * s.mem_y[:, -1]).sum(-1)
    gamma = torch.where((sy[:, -1] > 0) & (yy > 0), sy[:, -1] / yy.clamp_min(1e-300), torch.zeros_like(yy))
    r = gamma[:, None] * q
    for i in range(m):
        beta = inv[:, i] * (s.mem_y[:, i] * r).sum(-1)
        r = r + s.mem_s[:, i] * (alpha[:, i] - beta)[:, None]
    d = -r.reshape(s.grad.shape)
    steepest = -s.grad * (first_step / _largest(s.grad).clamp_min(1e-300))[:, None, None]
    use = (gamma > 0) & ((d * s.grad).flatten(1).sum(-1) < 0)
    return torch.where(use[:, None, None], d, steepest)


def _inner(lag: _Lagrangian, s: _State, steps: int) -> tuple[_State, Tensor]:
    """``steps`` projected quasi-Newton steps on the AL, batched: each particle its own L-BFGS direction,
    step fraction (1 after an accepted step, a quarter of the last after a rejected one: a
    sufficient-decrease test) and memory. A move never exceeds ``step_max`` in any coordinate (metres,
    or radians for an angle). Returns the state and, per particle, whether it stalled: its last step,
    shorter than ``tol_step``, was rejected."""
    o = lag.o
    stalled = torch.zeros_like(s.t, dtype=torch.bool)
    for _ in range(steps):
        d = _direction(s, o.step)
        size = _largest(d) * s.t  # (A,)
        move = d * (s.t * (o.step_max / size.clamp_min(1e-300)).clamp(max=1.0))[:, None, None]
        trial = lag.project(lag.step(s.x, move))
        value, grad, g, _ = lag(trial, s.lam, s.rho)
        pred = -(s.grad * move).flatten(1).sum(-1)  # (A,) first-order decrease
        ok = torch.isfinite(value) & (value <= s.value - ARMIJO * pred)
        du, dg = _wrap(trial - s.x).flatten(1), (grad - s.grad).flatten(1)  # (A, 3N)
        push = (ok & ((du * dg).sum(-1) > 1e-12 * (du * du).sum(-1)))[:, None, None]  # curvature holds
        k = ok[:, None, None]
        s = _State(
            s.idx,
            torch.where(k, trial, s.x),
            s.lam,
            s.rho,
            torch.where(ok, torch.ones_like(s.t), s.t * SHRINK),
            torch.where(ok, value, s.value),
            torch.where(k, grad, s.grad),
            torch.where(ok[:, None], g, s.g),
            s.before,
            torch.where(push, torch.cat([s.mem_s[:, 1:], du[:, None]], 1), s.mem_s),
            torch.where(push, torch.cat([s.mem_y[:, 1:], dg[:, None]], 1), s.mem_y),
        )
        stalled = ~ok & (_largest(move) < o.tol_step)
    return s, stalled


def refine(problem: Problem, x0: Tensor, o: ALMOptions) -> tuple[Tensor, Tensor, list[str], int]:
    """Refine every particle of ``x0 (B, N, 3)``: poses ``(B, N, 3)``, largest violation ``(B,)`` (metres),
    each particle's status, and the outer iterations run."""
    lag = _Lagrangian(problem, o)
    b = x0.shape[0]
    x = lag.project(x0.clone())
    with torch.no_grad():
        g0 = lag.rows(x)
    lam = lag.warm_multipliers(g0)
    rho = torch.full_like(lam, o.penalty)
    value, grad, g, _ = lag(x, lam, rho)
    out = x.clone()
    viol = _violation(g)  # (B,)
    last_ok, last_ok_viol = x.clone(), viol.clone()  # each particle's last feasible iterate
    status = np.full(b, ParticleStatus.INFEASIBLE, dtype=object)
    failed = ~torch.isfinite(value)
    status[failed.cpu().numpy()] = ParticleStatus.FAILED
    ones = torch.ones(b, dtype=x.dtype, device=x.device)
    mem = x.new_zeros(b, o.memory, x[0].numel())
    s = _State(
        torch.arange(b, device=x.device),
        x,
        lam,
        rho,
        ones,
        value,
        grad,
        g,
        torch.relu(o.slack - g),
        mem,
        mem.clone(),
    )
    done = failed
    if not o.polish:  # a repair: particles feasible from the start are done
        status[(~failed & (viol <= o.tolerance)).cpu().numpy()] = ParticleStatus.CONVERGED
        done = failed | (viol <= o.tolerance)
    s = s.keep(~done)
    it = 0
    for it in range(1, o.iterations + 1):
        if not len(s.idx):
            break
        start = s.x
        s, stalled = _inner(lag, s, o.inner)
        moved = _largest(_wrap(s.x - start))  # (A,) the largest move of any coordinate this iteration
        v = _violation(s.g)
        # the gradient at the last accepted point is the Lagrangian's at the updated multipliers
        kkt = _largest(s.grad)
        stationary = (kkt <= o.tol_grad) | stalled | (moved <= o.tol_step)
        done = (v <= o.tolerance) & (stationary if o.polish else torch.ones_like(stationary))
        out[s.idx] = s.x
        viol[s.idx] = v
        ok = s.idx[v <= o.tolerance]
        last_ok[ok], last_ok_viol[ok] = out[ok], viol[ok]
        status[s.idx[done].cpu().numpy()] = ParticleStatus.CONVERGED
        s = s.keep(~done)
        if not len(s.idx) or it == o.iterations:
            break
        c = o.slack - s.g
        new_lam = torch.relu(s.lam + s.rho * c)
        now = torch.relu(c)
        # rows still violated and not a quarter better than at the last update: a stiffer penalty
        stuck = (now > o.tolerance) & (now > 0.25 * s.before)
        rho = torch.where(stuck, (s.rho * o.penalty_growth).clamp(max=o.penalty_max), s.rho)
        value, grad = s.value.clone(), s.grad.clone()
        changed = ((new_lam != s.lam) | (rho != s.rho)).any(-1)  # (A,) the others' AL is unchanged
        if changed.any():
            value[changed], grad[changed], _, _ = lag(s.x[changed], new_lam[changed], rho[changed])
        s = _State(s.idx, s.x, new_lam, rho, s.t, value, grad, s.g, now, s.mem_s, s.mem_y)
    # still moving when the iterations ran out: the last feasible iterate (the start, if it was) stands
    # in for a particle that ends violated
    back = s.idx[(viol[s.idx] > o.tolerance) & (last_ok_viol[s.idx] <= o.tolerance)]
    out[back], viol[back] = last_ok[back], last_ok_viol[back]
    active = s.idx.cpu().numpy()
    feasible = (viol[s.idx] <= o.tolerance).cpu().numpy()
    status[active[feasible]] = ParticleStatus.MAX_ITERATIONS
    status[active[~feasible]] = ParticleStatus.INFEASIBLE
    return out, viol, [str(v) for v in status], it


class ALMSolver(StageSolver):
    """Batched refinement stage: ``solve(problem, init=None, seed=0) -> Result`` refines every row of
    ``init`` (in a chain: every particle of the stage before); ``samples`` keeps them all, best first."""

    name = "alm"
    options_cls = ALMOptions
    takes_batch = True

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        o = self.options
        t0 = time.perf_counter()
        x0 = start_poses(problem, None, seed) if init is None else problem.full(init).clone()
        t1 = time.perf_counter()
        x, viol, status, it = refine(problem, x0, o)
        with torch.no_grad():
            cost = problem.evaluate(x)
        feasible = viol <= o.tolerance
        order = best_first(feasible, cost)
        x, viol, cost = x[order], viol[order], cost[order]
        status = [status[int(k)] for k in order]
        t2 = time.perf_counter()
        n_ok = int(feasible.sum())
        n_conv = status.count(ParticleStatus.CONVERGED)
        msg = f"{n_ok} of {len(status)} particles feasible, {n_conv} converged"
        r = make_result(
            problem,
            self.name,
            x[0],
            Status(status[0]),
            it,
            t1 - t0,
            t2 - t1,
            message=msg,
            samples=Samples(x, cost, np.asarray(status), viol),
            tol=o.tolerance,
        )
        return r
