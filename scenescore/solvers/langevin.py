"""The ``langevin`` solver: batched projected Langevin dynamics over the whole cost.

Particles start uniformly inside the bounds, the best ``particles`` of ``candidates`` uniform draws
by cost when ``candidates`` is set, or from ``init``; every step is followed by the
closed-form projections of the cost's constraints (bounds with the footprint's extent, reach) and,
with ``projection="qp"``, by the projection onto the linearised non-overlap constraints. The answer
is the best particle: the lowest cost among those within the violation tolerance, else the lowest cost.

With ``resample=k`` the particles are a population: ``k`` times during the chain they are resampled
by ``softmax(-cost / temperature)``, so particles stuck in high-cost basins are replaced by copies of
those in low-cost ones (population annealing). Far more samples end in good basins; fewer of them are
distinct.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, fields, replace
from typing import Any

import torch
from torch import Tensor

from ..problem import FEASIBILITY_TOL, Problem
from ..sampling import SAMPLING, LangevinConfig, langevin, screen
from .base import StageSolver
from .projection import LinearisedProjection
from .result import Result, Status, make_result

__all__ = ["LangevinOptions", "LangevinSolver"]


@dataclass(frozen=True)
class LangevinOptions:
    """Options of the ``langevin`` solver: the population, its start, projections, threads, and the
    chain's schedule (a :class:`~scenescore.sampling.LangevinConfig`, default :data:`~scenescore.sampling.SAMPLING`).

    From YAML or ``ss.solve(..., options={"langevin": {...}})`` the schedule's fields are given flat
    (``steps: 50``) beside the solver's own; :meth:`from_flat` sorts them.
    """

    particles: int = 64
    candidates: int = 0  # uniform draws screened by cost (forward only) for the particles' start; 0: none
    projection: str = "closed_form"  # "none", "closed_form", or "qp" (also the linearised non-overlap QP)
    threads: int | None = None  # torch threads; None: all of them for 256 particles or more, else one
    chain: LangevinConfig = SAMPLING

    def __post_init__(self) -> None:
        if self.projection not in ("none", "closed_form", "qp"):
            raise ValueError(
                f"langevin: projection: expected 'none', 'closed_form' or 'qp', got {self.projection!r}"
            )
        if self.particles < 1 or self.candidates < 0:
            raise ValueError(
                f"langevin: expected particles >= 1 and candidates >= 0, got {self.particles}, {self.candidates}"
            )
        if self.threads is not None and self.threads < 1:
            raise ValueError(f"langevin: threads: expected >= 1 or None, got {self.threads!r}")
        if not isinstance(self.chain, LangevinConfig):
            raise ValueError(f"langevin: chain: expected a LangevinConfig, got {type(self.chain).__name__}")

    @classmethod
    def from_flat(cls, **options: Any) -> LangevinOptions:
        """Options given flat: the schedule's fields (``steps``, ``step_init``, ...) go into ``chain``."""
        own = {f.name for f in fields(cls)}
        sched = {f.name for f in fields(LangevinConfig)}
        unknown = sorted(set(options) - own - sched)
        if unknown:
            raise TypeError(f"unknown option(s) {unknown}; valid: {sorted((own - {'chain'}) | sched)}")
        chain = options.pop("chain", SAMPLING)
        flat = {k: options.pop(k) for k in list(options) if k in sched}
        return cls(**options, chain=replace(chain, **flat) if flat else chain)


class LangevinSolver(StageSolver):
    """Sampling stage: ``solve(problem, init=None, seed=0) -> Result`` with every particle in ``samples``."""

    name = "langevin"
    options_cls = LangevinOptions

    def __init__(self, options: LangevinOptions | None = None, **flat: Any):
        if options is not None and flat:
            raise TypeError("langevin: give LangevinOptions or keyword options, not both")
        self.options = options if options is not None else LangevinOptions.from_flat(**flat)

    def default_threads(self, problem: Problem) -> int:
        """Every thread torch has for large populations (their tensors are big enough to pay for the
        pool), one for small ones."""
        return torch.get_num_threads() if self.options.particles >= 256 else 1

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        o = self.options
        t0 = time.perf_counter()
        gen = torch.Generator().manual_seed(int(seed))
        movable = torch.as_tensor(problem.movable_mask)
        if init is not None:
            x0 = problem.full(init)
        elif o.candidates > o.particles:
            x0 = screen(problem.cost, problem.initial(o.candidates, gen), o.particles)
        else:
            x0 = problem.initial(o.particles, gen)
        terms = problem.cost.constraint_terms
        qp = LinearisedProjection(problem) if o.projection == "qp" else None

        def project(x: Tensor) -> Tensor:
            if o.projection == "none":
                return x
            for c in terms:
                x = c.project(x, movable)
            if qp is not None:
                x = qp(x)
            return x

        cfg = o.chain
        t1 = time.perf_counter()
        x, e = langevin(problem.cost, project(x0), movable, problem.lo, problem.hi, cfg, gen, project=project)
        with torch.no_grad():
            viol = problem.violation(x)
        ok = viol <= FEASIBILITY_TOL
        rank = torch.where(ok, e, e + 1e12 + viol)  # feasible particles first, then by cost
        best = int(torch.argmin(rank))
        t2 = time.perf_counter()
        msg = f"{int(ok.sum())} of {len(e)} particles within the violation tolerance"
        if qp is not None:
            msg += f"; {qp.qp_solves} projection QPs"
        return make_result(
            problem,
            self.name,
            x[best],
            Status.SAMPLED,
            cfg.steps + cfg.final_descent,
            t1 - t0,
            t2 - t1,
            message=msg if not ok[best] else "",
            samples=x,
            sample_costs=e,
        )
