"""Chains of solvers: the best poses of one stage seed the next (a sampling stage seeds a refinement)."""

from __future__ import annotations

from torch import Tensor

from ..problem import Problem, ProblemError
from .base import Solver
from .result import Result, make_result

__all__ = ["Chain"]


class Chain:
    """Stages run in turn; the best poses of one stage seed the next. The result is the last stage's, with
    every stage in ``stages``, timings summed, and the sampling stage's particles kept."""

    def __init__(self, stages: list[Solver]):
        if not stages:
            raise ProblemError("a chain needs at least one stage")
        self.stages = stages
        self.name = ">".join(s.name for s in stages)

    def solve(self, problem: Problem, init: Tensor | None = None, seed: int = 0) -> Result:
        results: list[Result] = []
        x = init
        for k, s in enumerate(self.stages):
            r = s.solve(problem, init=x, seed=seed + k)
            results.append(r)
            x = problem.full(r.poses)
        last = results[-1]
        sampled = next((r for r in results if r.samples is not None), None)
        out = make_result(
            problem,
            self.name,
            last.poses,
            last.status,
            sum(r.iterations for r in results),
            sum(r.time_setup for r in results),
            sum(r.time_solve for r in results),
            message=last.message,
            samples=None if sampled is None else sampled.samples,
            sample_costs=None if sampled is None else sampled.sample_costs,
            threads=max(r.threads for r in results),
        )
        out.stages = results
        return out
