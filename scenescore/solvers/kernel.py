"""The one Langevin kernel: batched projected Langevin dynamics over object poses.

Training's counter-examples, placement and the ``langevin`` solver all run :func:`langevin` with a
:class:`LangevinConfig`; each use has one named default (:data:`TRAINING`, :data:`PLACEMENT`,
:data:`SAMPLING`).

``x_t = x_{t-1} - lambda_t (grad E(x_{t-1}) + w_t)``, ``w_t ~ N(0, sigma^2)``, with a polynomially decaying
step size, run in normalised coordinates (positions scaled by the bounds' half-extent, angles by pi) so
that one step size suits both. Objects that are not movable never move; after every step movable
objects are projected back inside their bounds (and through an optional user projection).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

from ..costs.finite import FiniteWatch, watching
from ..costs.terms import CostError
from ..errors import check_number
from ..runtime import draw
from ..runtime import generator as make_generator

__all__ = [
    "LangevinConfig",
    "Limits",
    "TRAINING",
    "PLACEMENT",
    "SAMPLING",
    "chain",
    "langevin",
    "best_of",
    "screen",
    "resample",
    "finite_or_inf",
    "sweep_headings",
]


MAX_STEPS = 1_000_000  # a chain longer than this is a typo, not a plan
MAX_HEADINGS = 3600  # a heading sweep finer than a tenth of a degree is a typo, not a plan


@dataclass(frozen=True)
class LangevinConfig:
    """Settings of :func:`langevin` (defaults after implicit behaviour cloning, tuned here).

    Vary one with :func:`dataclasses.replace`, e.g. ``replace(PLACEMENT, steps=30)``.
    """

    steps: int = 100
    step_init: float = 0.05  # lambda_0, in normalised units per unit gradient
    step_final: float = 1e-3  # lambda_T
    power: float = 2.0  # polynomial decay exponent
    noise: float = 1.0  # sigma of w_t
    max_delta: float = 0.1  # clip on one step's move per coordinate at lambda_0 (normalised units)
    final_descent: int = 0  # noise-free gradient steps at lambda_T after the chain
    resample: int = 0  # population resampling points, evenly spaced in the chain (0: independent chains)
    temperature: float = 1.0  # of the resampling weights softmax(-E / temperature)
    # before the final descent, each moving object's heading in turn becomes the lowest-energy of its
    # own and this many evenly spaced ones (0: none): a narrow basin in the heading (an object turned to
    # face another) is found wherever the chain left the heading, not only from nearby
    heading_sweep: int = 0

    def __post_init__(self) -> None:
        for name in ("steps", "final_descent", "resample"):
            check_number("langevin", name, getattr(self, name), 0, MAX_STEPS, integer=True)
        check_number("langevin", "heading_sweep", self.heading_sweep, 0, MAX_HEADINGS, integer=True)
        for name, zero_ok in (
            ("temperature", False),
            ("step_init", False),
            ("step_final", False),
            ("max_delta", False),
            ("noise", True),
            ("power", True),
        ):
            check_number("langevin", name, getattr(self, name), 0, open_lo=not zero_ok)

    def step_size(self, t: int | Tensor) -> float | Tensor:
        """``lambda_t``, decaying from ``step_init`` to ``step_final`` over ``steps`` (then constant)."""
        span = max(self.steps - 1, 1)
        if isinstance(t, Tensor):
            frac_t = (1.0 - t.clamp(max=self.steps - 1) / span).clamp(min=0.0)
            return (self.step_init - self.step_final) * frac_t**self.power + self.step_final
        frac = max(1.0 - min(t, self.steps - 1) / span, 0.0)
        return (self.step_init - self.step_final) * frac**self.power + self.step_final

    def clip(self, lam: float | Tensor) -> float | Tensor:
        """The move clip at step size ``lam``: it shrinks with the step size, so that a sharp energy
        (large gradients, every step clipped) still lets the chain settle into its minimum."""
        return self.max_delta * lam / self.step_init


#: counter-examples in training: persistent chains advanced a few steps per iteration, no final descent
TRAINING = LangevinConfig(steps=60, step_init=0.05, step_final=5e-4, noise=1.0)
#: placing objects whose pose is unknown (``place``): a shorter chain, then a noise-free descent
PLACEMENT = LangevinConfig(steps=60, step_init=0.05, step_final=5e-4, noise=1.0, final_descent=20)
#: sampling whole arrangements with the ``langevin`` solver
SAMPLING = LangevinConfig(steps=100, step_init=0.05, step_final=1e-3, noise=1.0, final_descent=20)


def screen(energy_fn: Callable[[Tensor], Tensor], draws: Tensor, keep: int, chunk: int = 1024) -> Tensor:
    """The ``keep`` of ``draws (M, N, 3)`` with the lowest energy (forward passes only, in chunks): ``(keep, N, 3)``."""
    return draws[_energies(energy_fn, draws, chunk).argsort()[:keep]]


def finite_or_inf(e: Tensor) -> Tensor:
    """NaN and -inf energies become +inf, so that no ranking or weighting ever prefers them."""
    return torch.where(torch.isfinite(e), e, torch.full_like(e, float("inf")))


def _energies(energy_fn: Callable[[Tensor], Tensor], x: Tensor, chunk: int) -> Tensor:
    with torch.no_grad():
        e = torch.cat([energy_fn(x[i : i + chunk]) for i in range(0, len(x), chunk)])
    return finite_or_inf(e)


def resample(x: Tensor, e: Tensor, temperature: float, groups: int, generator: torch.Generator) -> Tensor:
    """Systematic resampling of particles ``x (G * P, ...)`` within each contiguous group of ``P`` by
    weights ``softmax(-e / temperature)``: particles in low-cost basins are copied, the rest dropped."""
    p = x.shape[0] // groups
    e = finite_or_inf(e.reshape(groups, p))
    w = torch.softmax(-(e - e.min(dim=1, keepdim=True).values) / temperature, dim=1)  # (G, P)
    offsets = torch.arange(p, dtype=w.dtype, device=w.device)
    u = (draw("rand", (groups, 1), generator, w.device, w.dtype) + offsets) / p
    idx = torch.searchsorted(torch.cumsum(w, dim=1), u).clamp(max=p - 1)  # (G, P)
    return x[(idx + p * torch.arange(groups, device=idx.device)[:, None]).flatten()]


def _grad(energy_fn: Callable[[Tensor], Tensor], x: Tensor) -> Tensor:
    """The energy's gradient at ``x``, taken without asking the device whether it is finite (a chain
    checks its gradients once, at its end: :func:`_finite`)."""
    with torch.enable_grad():
        x = x.detach().requires_grad_(True)
        (g,) = torch.autograd.grad(energy_fn(x).sum(), x)
    return g


def _finite(ok: Tensor, watch: FiniteWatch) -> None:
    """Raise unless every gradient a chain took (``ok``: one flag, and-ed over its steps) and every cost
    term's value (``watch``) was finite: one read; a term that was not is named."""
    if not bool(ok & watch.all_finite(ok.device)):
        bad = watch.first_bad()
        if bad is not None:
            raise CostError(f"cost term {bad!r} is not finite (NaN or inf) at some particle of the chain")
        raise FloatingPointError(
            "Langevin: the energy's gradient is not finite (NaN or inf) at some particle"
        )


@dataclass(frozen=True)
class Limits:
    """What a chain may move and where: ``movable`` ``(N,)`` or ``(B, N)`` bool, the position bounds
    ``lo``/``hi`` ``(2,)`` or ``(B, 2)``, and an optional projection applied after every step."""

    movable: Tensor
    lo: Tensor
    hi: Tensor
    project: Callable[[Tensor], Tensor] | None = None


@dataclass(frozen=True)
class _Frame:
    """A chain's fixed tensors, shaped for its ``B`` particles: the bounds ``(B, 1, 2)``, the normalising
    scale ``(B, 1, 3)`` (the bounds' half-extent, pi for angles) and the movable mask ``(B, N, 1)``."""

    lo: Tensor
    hi: Tensor
    scale: Tensor
    move: Tensor
    project: Callable[[Tensor], Tensor] | None

    @classmethod
    def of(cls, x: Tensor, limits: Limits) -> _Frame:
        b, n, _ = x.shape
        lo = limits.lo.to(x.dtype).reshape(-1, 1, 2).expand(b, 1, 2)
        hi = limits.hi.to(x.dtype).reshape(-1, 1, 2).expand(b, 1, 2)
        pi = torch.full((b, 1, 1), math.pi, dtype=x.dtype, device=x.device)
        scale = torch.cat([(hi - lo) / 2, pi], dim=-1)
        move = limits.movable.reshape(-1, n).expand(b, n)[..., None].bool()
        return cls(lo, hi, scale, move, limits.project)


def _step(
    energy_fn: Callable[[Tensor], Tensor],
    x: Tensor,
    frame: _Frame,
    cfg: LangevinConfig,
    lam: float | Tensor,
    noise: float,
    generator: torch.Generator,
) -> tuple[Tensor, Tensor]:
    """One projected Langevin step at step size ``lam``: the gradient in normalised coordinates plus
    noise, each coordinate's move clipped, movable objects kept inside their bounds, angles wrapped; the
    new poses and whether the gradient was finite (a flag on the device, not read here)."""
    g = _grad(energy_fn, x)
    gn = g * frame.scale  # gradient in normalised coordinates
    w = draw("randn", tuple(x.shape), generator, x.device, x.dtype) * noise if noise > 0 else 0.0
    clip = torch.as_tensor(cfg.clip(lam), dtype=x.dtype, device=x.device)
    delta = torch.maximum(torch.minimum(lam * (gn + w), clip), -clip)
    moved = x - delta * frame.scale
    moved = torch.cat(
        [
            torch.minimum(torch.maximum(moved[..., :2], frame.lo), frame.hi),
            torch.remainder(moved[..., 2:] + math.pi, 2 * math.pi) - math.pi,
        ],
        dim=-1,
    )
    x = torch.where(frame.move, moved, x)  # fixed objects never move, not even by projection
    return (x if frame.project is None else frame.project(x)), torch.isfinite(g).all()


def chain(
    energy_fn: Callable[[Tensor], Tensor],
    init: Tensor,
    limits: Limits,
    cfg: LangevinConfig | None = None,
    generator: torch.Generator | None = None,
    age: Tensor | None = None,
    run_steps: int | None = None,
    groups: int = 1,
) -> Tensor:
    """Run the chain from ``init (B, N, 3)`` within ``limits``; returns the final poses (:func:`langevin`
    returns their energies too).

    ``age``: ``(B,)`` steps each chain has already run (persistent chains continue their schedule);
    ``run_steps``: how many steps to run now (default ``cfg.steps``, the schedule's length).
    ``groups``: particles form this many contiguous groups (one per scene) for ``cfg.resample``.
    No gradient flows through the chain, and nothing in it waits on the device: its gradients are checked
    once, at its end (a non-finite one raises ``FloatingPointError``). Everything runs on the device of
    ``init``; ``generator`` (default: seed 0 on that device) draws the noise.
    """
    cfg = cfg or LangevinConfig()
    if generator is None:
        generator = make_generator(0, init.device)
    if cfg.resample and age is not None:
        raise ValueError("langevin: population resampling needs one schedule for all chains (age=None)")
    x = init.detach().clone()
    frame = _Frame.of(x, limits)
    ok = torch.ones((), dtype=torch.bool, device=x.device)
    total = cfg.steps if run_steps is None else run_steps
    marks = {round(total * (k + 1) / (cfg.resample + 1)) for k in range(cfg.resample)}
    with watching() as watch:  # the cost terms' values are checked with the gradients, at the end
        for t in range(total):
            if t in marks:
                with torch.no_grad():
                    x = resample(x, energy_fn(x), cfg.temperature, groups, generator)
            if age is None:
                lam: float | Tensor = cfg.step_size(t)
            else:  # each chain at its own place in the schedule
                lam = torch.as_tensor(cfg.step_size((age + t).to(x.dtype))).reshape(-1, 1, 1)
            x, fine = _step(energy_fn, x, frame, cfg, lam, cfg.noise, generator)
            ok = ok & fine
        if cfg.heading_sweep:
            _finite(ok, watch)  # the sweep reads its energies back
            x = sweep_headings(energy_fn, x, frame.move[..., 0], cfg.heading_sweep)
            if frame.project is not None:
                x = frame.project(x)
        for _ in range(cfg.final_descent):
            x, fine = _step(energy_fn, x, frame, cfg, cfg.step_final, 0.0, generator)
            ok = ok & fine
        _finite(ok, watch)
    return x.detach()


def langevin(
    energy_fn: Callable[[Tensor], Tensor],
    init: Tensor,
    limits: Limits,
    cfg: LangevinConfig | None = None,
    generator: torch.Generator | None = None,
    groups: int = 1,
) -> tuple[Tensor, Tensor]:
    """:func:`chain` from ``init (B, N, 3)`` within ``limits``, its whole schedule: the final poses and
    their energies ``(B,)``."""
    x = chain(energy_fn, init, limits, cfg, generator, groups=groups)
    with torch.no_grad():
        e = energy_fn(x)
    return x, e.detach()


def sweep_headings(energy_fn: Callable[[Tensor], Tensor], x: Tensor, movable: Tensor, k: int) -> Tensor:
    """``x (B, N, 3)`` with each object that ``movable (B, N)`` moves, in turn, turned to the
    lowest-energy of its current heading and ``k`` evenly spaced ones from -pi (ties keep the current
    one): one energy call of ``B * (k + 1)`` rows per object."""
    b, n, _ = x.shape
    angles = torch.linspace(-math.pi, math.pi, k + 1, dtype=x.dtype, device=x.device)[:-1]
    rows = torch.arange(b, device=x.device)
    moving = movable.any(dim=0).tolist()  # one read, not one per object
    with torch.no_grad():
        for i in range(n):
            if not moving[i]:
                continue
            cand = x[:, None].repeat(1, k + 1, 1, 1)  # (B, k + 1, N, 3); candidate 0 keeps the heading
            cand[:, 1:, i, 2] = angles
            e = finite_or_inf(energy_fn(cand.reshape(b * (k + 1), n, 3)).reshape(b, k + 1))
            turned = cand[rows, e.argmin(dim=1)]
            x = torch.where(movable[:, i, None, None], turned, x)
    return x


def best_of(poses: Tensor, energies: Tensor, groups: int) -> tuple[Tensor, Tensor]:
    """Best particle per group: ``poses (G * P, N, 3)`` in contiguous groups -> ``(G, N, 3)``, ``(G,)``."""
    p = poses.shape[0] // groups
    e = finite_or_inf(energies.reshape(groups, p))
    idx = e.argmin(dim=1)
    rows = torch.arange(groups, device=idx.device)
    return poses.reshape(groups, p, *poses.shape[1:])[rows, idx], e[rows, idx]
