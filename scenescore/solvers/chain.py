"""Chains of solvers: the best poses of one stage seed the next (a sampling stage seeds a refinement); a
stage that takes a batch (``takes_batch``) is seeded with every sample of the stage before."""

from __future__ import annotations

from torch import Tensor

from ..problem.problem import Problem, ProblemError
from .base import Solver
from .result import Result, Samples, make_result

__all__ = ["Chain", "takes_batch"]


def takes_batch(stage: Solver) -> bool:
    """Whether a stage refines a whole batch of starts (a class attribute ``takes_batch = True``)."""
    return bool(getattr(stage, "takes_batch", False))


class Chain:
    """Stages run in turn; the best poses of one stage seed the next, or all its samples when the next
    stage ``takes_batch``. The result is the last stage's, with every stage in ``stages``, timings summed,
    and the samples of the last batch stage kept (without one, the first sampling stage's)."""

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
            batch = k + 1 < len(self.stages) and takes_batch(self.stages[k + 1])
            x = problem.full(r.samples if batch and r.samples is not None else r.poses)
        last = results[-1]
        # the samples kept: the last batch stage's (it refined the population), else the first sampler's
        batched = [r for st, r in zip(self.stages, results) if takes_batch(st) and r.samples is not None]
        sampled = batched[-1] if batched else next((r for r in results if r.samples is not None), None)
        out = make_result(
            problem,
            self.name,
            last.poses,
            last.status,
            sum(r.iterations for r in results),
            sum(r.time_setup for r in results),
            sum(r.time_solve for r in results),
            message=last.message,
            samples=None if sampled is None else Samples.of(sampled),
        )
        out.stages = results
        return out
