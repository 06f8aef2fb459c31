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
from dataclasses import dataclass

import torch
from torch import Tensor

from ..problem import FEASIBILITY_TOL, Problem
from .langevin import LangevinConfig, langevin, screen
from .projection import LinearisedProjection
from .result import Result, StageSolver, Status, make_result

__all__ = ["LangevinOptions", "LangevinSolver"]


@dataclass
class LangevinOptions:
    """Options of the ``langevin`` solver (schedule fields as :class:`LangevinConfig`)."""

    particles: int = 64
    candidates: int = 0  # uniform draws screened by cost (forward only) for the particles' start; 0: none
    steps: int = 100
    step_init: float = 0.05
    step_final: float = 1e-3
    power: float = 2.0
    noise: float = 1.0
    max_delta: float = 0.1
    final_descent: int = 20
    resample: int = 0  # population resampling points in the chain (0: independent chains)
    temperature: float = 1.0  # of the resampling weights softmax(-cost / temperature)
    projection: str = "closed_form"  # "none", "closed_form", or "qp" (also the linearised non-overlap QP)

    def __post_init__(self) -> None:
        if self.projection not in ("none", "closed_form", "qp"):
            raise ValueError(
                f"langevin: projection: expected 'none', 'closed_form' or 'qp', got {self.projection!r}"
            )
        if self.particles < 1 or self.steps < 0 or self.candidates < 0 or self.resample < 0:
            raise ValueError(
                "langevin: expected particles >= 1 and steps, candidates, resample >= 0, got "
                f"{self.particles}, {self.steps}, {self.candidates}, {self.resample}"
            )
        if not self.temperature > 0:
            raise ValueError(f"langevin: temperature: expected > 0, got {self.temperature!r}")


class LangevinSolver(StageSolver):
    """Sampling stage: ``solve(problem, init=None, seed=0) -> Result`` with every particle in ``samples``."""

    name = "langevin"
    options_cls = LangevinOptions

    def threads(self, problem: Problem) -> int:
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

        cfg = LangevinConfig(
            steps=o.steps,
            step_init=o.step_init,
            step_final=o.step_final,
            power=o.power,
            noise=o.noise,
            max_delta=o.max_delta,
            final_descent=o.final_descent,
            resample=o.resample,
            temperature=o.temperature,
        )
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
            o.steps + o.final_descent,
            t1 - t0,
            t2 - t1,
            message=msg if not ok[best] else "",
            samples=x,
            sample_costs=e,
        )
