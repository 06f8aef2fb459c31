"""The ``langevin`` solver: batched projected Langevin dynamics over the whole cost.

Particles start uniformly inside the bounds, the best ``particles`` of ``candidates`` uniform draws
by cost when ``candidates`` is set, or from ``init``; with ``proposals``, that fraction of the draws
is proposed by the cost's guiding terms instead (:mod:`scenescore.costs.guide`; the learned energy:
poses beside the known objects that its data has); every step is followed by the
closed-form projections of the cost's constraints (bounds with the footprint's extent, reach) and,
with ``projection="qp"``, by the projection onto the linearised non-overlap constraints. The answer
is the best particle: the lowest cost among those within the violation tolerance, else the lowest cost;
with ``trusted_first`` (placement's default), in each group a particle that a guiding term doubts
(:meth:`~scenescore.problem.problem.Problem.doubted`; the learned energy: one that puts an object where its
data never had one, at a bound none comes near or far from the rest) comes after those it does not.

With ``resample=k`` the particles are a population: ``k`` times during the chain they are resampled
by ``softmax(-cost / temperature)``, so particles stuck in high-cost basins are replaced by copies of
those in low-cost ones (population annealing). Far more samples end in good basins; fewer of them are
distinct.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import torch
from torch import Tensor

from ..costs.base import stack_sums
from ..costs.guide import doubt_note
from ..errors import ConfigError, check_number
from ..problem.problem import FEASIBILITY_TOL, Problem, ProblemError
from ..runtime import check_memory, generator, torch_threads
from .base import StageSolver
from .kernel import SAMPLING, LangevinConfig, Limits, langevin, screen
from .projection import LinearisedProjection
from .result import Result, Samples, Status, best_first, make_result

MAX_PARTICLES = 65_536  # more is a typo, not a plan: memory grows with particles x objects^2
MAX_CANDIDATES = 1_000_000
# float64 copies of the (rows, N, 3) poses alive at once: candidate draws (the base poses, the uniform
# draws and their parts, the mix), and particles in the chain (poses, gradient, noise, step, projections,
# the costs' own copies); the energy network's working set is bounded by its own chunking
DRAW_COPIES = 8
STATE_COPIES = 24

__all__ = ["LangevinOptions", "LangevinSolver"]


@dataclass(frozen=True)
class LangevinOptions:
    """Options of the ``langevin`` solver: the population, its start, projections, and the
    chain's schedule (a :class:`~scenescore.solvers.kernel.LangevinConfig`, default :data:`~scenescore.solvers.kernel.SAMPLING`).

    From YAML or ``ss.solve(..., options={"langevin": {...}})`` the schedule's fields are given flat
    (``steps: 50``) beside the solver's own; :meth:`from_flat` sorts them.
    """

    particles: int = 64
    candidates: int = 0  # uniform draws screened by cost (forward only) for the particles' start; 0: none
    # the fraction of the start's draws that the cost's guiding terms propose instead of uniform ones
    # (the learned energy: its data's poses relative to the scene's known objects; Problem.initial)
    proposals: float = 0.0
    projection: str = "closed_form"  # "none", "closed_form", or "qp" (also the linearised non-overlap QP)
    chain: LangevinConfig = SAMPLING
    # the answer: among the feasible particles (else all), those that no guiding term doubts first
    # (Problem.doubted; the learned energy: no object at a bound its category never comes near, or
    # farther from the rest, or from every object of some category, than any of its category), then by cost; placement's default (off for
    # solve: a user's own costs may well ask for a wall)
    trusted_first: bool = False

    def __post_init__(self) -> None:
        if self.projection not in ("none", "closed_form", "qp"):
            raise ConfigError(
                f"langevin: projection: expected 'none', 'closed_form' or 'qp', got {self.projection!r}"
            )
        check_number("langevin", "particles", self.particles, 1, MAX_PARTICLES, integer=True)
        check_number("langevin", "candidates", self.candidates, 0, MAX_CANDIDATES, integer=True)
        check_number("langevin", "proposals", self.proposals, 0.0, 1.0)
        if not isinstance(self.trusted_first, bool):
            raise ConfigError(f"langevin: trusted_first: expected true or false, got {self.trusted_first!r}")
        if not isinstance(self.chain, LangevinConfig):
            raise ConfigError(f"langevin: chain: expected a LangevinConfig, got {type(self.chain).__name__}")

    @classmethod
    def flat_names(cls) -> set[str]:
        """The option names given flat (YAML, ``ss.solve``): the solver's own and the schedule's."""
        return ({f.name for f in fields(cls)} - {"chain"}) | {f.name for f in fields(LangevinConfig)}

    @classmethod
    def from_flat(cls, **options: Any) -> LangevinOptions:
        """Options given flat: the schedule's fields (``steps``, ``step_init``, ...) go into ``chain``."""
        own = {f.name for f in fields(cls)}
        sched = {f.name for f in fields(LangevinConfig)}
        unknown = sorted(set(options) - own - sched)
        if unknown:
            raise TypeError(f"unknown option(s) {unknown}; valid: {sorted(cls.flat_names())}")
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

    def solve_many(
        self, problems: Sequence[Problem], seed: int = 0, init: Sequence[Tensor] | None = None
    ) -> list[Result]:
        """Several problems with the same number of objects in one batched chain (particles in contiguous
        groups, one per problem): the same answers in distribution as solving each, in far fewer, larger
        tensor operations. ``init``: each problem's own starting particles ``(B_k, N, 3)``."""
        if not problems:
            return []
        if init is not None and len(init) != len(problems):
            raise ProblemError(
                f"langevin: init: expected {len(problems)} starts, one per problem, got {len(init)}"
            )
        with torch_threads(1):  # large batches of the learned energy go in pieces side by side
            return self._run(list(problems), None if init is None else list(init), seed)

    def _solve(self, problem: Problem, init: Tensor | None, seed: int) -> Result:
        return self._run([problem], init, seed)[0]

    def check_memory(self, problems: Sequence[Problem], init_rows: int | None = None) -> None:
        """Raise :class:`~scenescore.runtime.memory.MemoryBudgetError` before a population too large for the
        memory budget is drawn: ``candidates`` or ``particles`` per problem times its objects."""
        o, n, k = self.options, problems[0].n, len(problems)
        scenes = f" (x {k} problems)" if k > 1 else ""
        rows = o.particles if init_rows is None else init_rows
        if init_rows is None and o.candidates > o.particles:
            check_memory(
                DRAW_COPIES * 8 * 3 * k * o.candidates * n,
                f"langevin: {o.candidates} candidates x {n} objects{scenes}",
                "candidates",
            )
        check_memory(
            STATE_COPIES * 8 * 3 * k * rows * n,
            f"langevin: {rows} particles x {n} objects{scenes}",
            "particles" if init_rows is None else "the number of initial pose sets",
        )

    def _run(self, problems: list[Problem], init: Tensor | list[Tensor] | None, seed: int) -> list[Result]:
        """Draw each problem's start, run one chain over every particle, and answer each problem."""
        o = self.options
        t0 = time.perf_counter()
        n = problems[0].n
        if any(p.n != n for p in problems):
            raise ProblemError("langevin: problems solved together must have the same number of objects")
        rows = None if init is None else max(len(x) for x in init) if isinstance(init, list) else len(init)
        self.check_memory(problems, rows)
        gen = generator(seed, problems[0].device)
        starts = self._starts(problems, init, gen)
        sizes = [len(x) for x in starts]
        ends = np.cumsum(sizes).tolist()
        spans = list(zip([0, *ends[:-1]], ends))
        masks = [torch.as_tensor(p.movable_mask, device=p.device) for p in problems]
        movable = torch.cat([m[None].expand(k, n) for m, k in zip(masks, sizes)])  # (B, N)
        lo = torch.cat([p.lo[None].expand(k, 2) for p, k in zip(problems, sizes)])  # (B, 2)
        hi = torch.cat([p.hi[None].expand(k, 2) for p, k in zip(problems, sizes)])
        qps = [LinearisedProjection(p) if o.projection == "qp" else None for p in problems]
        project = self._projection(problems, masks, qps, spans)
        cost = problems[0].cost if len(problems) == 1 else stack_sums([p.cost for p in problems], sizes)
        t1 = time.perf_counter()
        groups = len(problems) if len(set(sizes)) == 1 else 1
        limits = Limits(movable, lo, hi, project)
        x, e = langevin(cost, project(torch.cat(starts)), limits, o.chain, gen, groups=groups)
        t2 = time.perf_counter()
        setup, solve = (t1 - t0) / len(problems), (t2 - t1) / len(problems)
        return [
            self._answer(p, x[a:b], e[a:b], qps[k], setup, solve)
            for k, (p, (a, b)) in enumerate(zip(problems, spans))
        ]

    def _starts(
        self, problems: list[Problem], init: Tensor | list[Tensor] | None, gen: torch.Generator
    ) -> list[Tensor]:
        """Each problem's starting particles: its own ``init``, the shared ``init``, the best ``particles``
        of ``candidates`` draws by cost, or ``particles`` draws (drawn by ``gen`` in problem order)."""
        o = self.options
        starts = []
        for k, p in enumerate(problems):
            if isinstance(init, list):
                starts.append(p.full(init[k]))
            elif init is not None:
                starts.append(p.full(init))
            elif o.candidates > o.particles:
                starts.append(
                    screen(p.cost, p.initial(o.candidates, gen, proposals=o.proposals), o.particles)
                )
            else:
                starts.append(p.initial(o.particles, gen, proposals=o.proposals))
        return starts

    def _projection(
        self,
        problems: list[Problem],
        masks: list[Tensor],
        qps: list[LinearisedProjection | None],
        spans: list[tuple[int, int]],
    ) -> Callable[[Tensor], Tensor]:
        """The projection after every step of the batch: each problem's rows (``spans``) onto its
        constraints' closed forms, then its linearised non-overlap QP (``projection="qp"``)."""
        o = self.options

        def project_one(k: int, x: Tensor) -> Tensor:
            for c in problems[k].cost.constraint_terms:
                x = c.project(x, masks[k])
            qp = qps[k]
            return x if qp is None else qp(x)

        def project(x: Tensor) -> Tensor:
            if o.projection == "none":
                return x
            if len(problems) == 1:
                return project_one(0, x)
            return torch.cat([project_one(k, x[a:b]) for k, (a, b) in enumerate(spans)])

        return project

    def _answer(
        self,
        p: Problem,
        xs: Tensor,
        es: Tensor,
        qp: LinearisedProjection | None,
        time_setup: float,
        time_solve: float,
    ) -> Result:
        """One problem's result from its particles ``xs`` and their costs ``es``: the best by
        :func:`best_first` (the doubted ones after the others with ``trusted_first``), every particle kept."""
        o, cfg = self.options, self.options.chain
        with torch.no_grad():
            viol = p.violation(xs)
        ok = viol <= FEASIBILITY_TOL
        trusted = ~p.doubted(xs) if o.trusted_first else None
        best = int(best_first(ok, torch.where(ok, es, es + viol), trusted)[0])
        notes = [] if ok[best] else [f"{int(ok.sum())} of {len(es)} particles within the violation tolerance"]
        if trusted is not None and not trusted.all():
            notes.append(
                f"{int((~trusted).sum())} of {len(es)} particles {doubt_note(p.cost)}"
                + ("" if trusted[best] else ", the answer among them")
            )
        if qp is not None and notes:
            notes.append(f"{qp.qp_solves} projection QPs")
        return make_result(
            p,
            self.name,
            xs[best],
            Status.SAMPLED,
            cfg.steps + cfg.final_descent,
            time_setup,
            time_solve,
            message="; ".join(notes),
            samples=Samples(xs, es),
        )
