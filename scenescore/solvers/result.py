"""Solver results: the best poses found (also on failure), status, feasibility, per-term values, timings."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, cast

import numpy as np
import torch
from torch import Tensor

from ..costs.energy import LearnedEnergy
from ..costs.guide import Alternatives, Verdict, guides, verdicts
from ..models.explain import Explanation
from ..problem.problem import FEASIBILITY_TOL, Problem
from ..scene.outputs import atomic_write_text
from ..scene.scene import Scene

__all__ = ["Result", "Samples", "Status", "make_result", "best_first"]


class Status(StrEnum):
    """What a solve ended with; serialises to its (lower-case) name."""

    CONVERGED = "converged"  # a refinement met its optimality and feasibility tolerances
    SAMPLED = "sampled"  # a sampler ran its schedule (no optimality claim)
    MAX_ITERATIONS = "max_iterations"
    INFEASIBLE = "infeasible"  # the solver ended with constraints violated
    FAILED = "failed"  # the solver gave up (numerical trouble, a QP failure)
    ERROR = "error"  # an exception; the message says which

    @property
    def ok(self) -> bool:
        """A status that can count as success (when the constraints hold too)."""
        return self in (Status.CONVERGED, Status.SAMPLED)


@dataclass
class Result:
    """What a solver returns. ``poses (N, 3)`` is the best pose set found, also when the solve failed."""

    solver: str
    poses: np.ndarray
    status: Status
    success: bool
    feasible: bool
    objective: float
    terms: dict[str, dict[str, float | None]]
    max_violation: float
    violated: str | None  # "term: row" of the largest violation, or None
    iterations: int
    time_setup: float
    time_solve: float
    message: str = ""
    # (B, N, 3): every particle (sampling solvers; batched refinements: best first)
    samples: np.ndarray | None = None
    sample_costs: np.ndarray | None = None  # (B,)
    sample_status: np.ndarray | None = None  # (B,) str: each sample's Status value, for batched refinements
    sample_violations: np.ndarray | None = None  # (B,) each sample's largest violation (metres)
    stages: list[Result] = field(default_factory=list)
    problem: Problem | None = field(default=None, repr=False)
    qp_time_mean: float | None = None  # seconds per QP, for solvers that solve QPs
    wall_time: float | None = None  # seconds from ss.solve's call to its return (set by ss.solve)
    # each moving object a guiding term judges (the learned energy: by its data), by name
    confidence: dict[str, Verdict] = field(default_factory=dict)

    @property
    def warnings(self) -> list[str]:
        """One line per flagged object and reason: the placements not to trust blindly."""
        return [f"{name}: {flag}" for name, a in self.confidence.items() for flag in a.flags]

    @property
    def time_total(self) -> float:
        return self.time_setup + self.time_solve

    @property
    def scene(self) -> Scene:
        """The problem's scene with the found poses."""
        if self.problem is None:
            raise ValueError("this result carries no problem")
        return self.problem.scene.with_poses(self.poses)

    def summary(self) -> str:
        """A readable table: status, objective, every term, the largest violation, timings."""
        lines = [
            f"solver {self.solver}: {self.status} (success {self.success}, feasible {self.feasible})",
            f"objective {self.objective:.6g}   max violation {self.max_violation:.3g}"
            + (f" ({self.violated})" if self.violated else "")
            + f"   iterations {self.iterations}   setup {self.time_setup:.3f} s   solve {self.time_solve:.3f} s",
        ]
        if self.message:
            lines.append(f"message: {self.message}")
        w = max([len("term")] + [len(k) for k in self.terms])
        lines.append(f"{'term':<{w}}  {'value':>12}  {'weight':>8}  {'weighted':>12}  {'violation':>10}")
        for k, t in self.terms.items():
            v = "-" if t["violation"] is None else f"{t['violation']:.3g}"
            lines.append(
                f"{k:<{w}}  {t['value']:>12.6g}  {t['weight']:>8.3g}  {t['weighted']:>12.6g}  {v:>10}"
            )
        for name, a in self.confidence.items():
            lines.append(f"{name}: confidence {a.confidence:.2f}" + ("" if a.flags else " (in distribution)"))
            lines += [f"{name}: {note}" for note in getattr(a, "notes", [])]
        lines += [f"warning: {w}" for w in self.warnings]
        if self.stages:
            lines.append(
                "stages: "
                + " > ".join(
                    f"{s.solver} ({s.status}, {s.iterations} it, {s.time_total:.3f} s)" for s in self.stages
                )
            )
        return "\n".join(lines)

    def explain(self, name: str | None = None, scenes: Sequence[Scene] | None = None) -> Explanation:
        """What holds the moving object ``name`` (default: the one moving object) at its found pose, by
        the problem's learned energy: the well's depth and each neighbour's part in it
        (:func:`scenescore.models.explain.explain`; ``scenes``: the example scenes, to name the ones
        showing each relation)."""
        if self.problem is None:
            raise ValueError("this result carries no problem to explain")
        energies = [c for _, c in self.problem.cost if isinstance(c, LearnedEnergy)]
        if not energies:
            raise ValueError(
                "explain: the problem has no learned energy (a LearnedEnergy term) to explain by"
            )
        return energies[0].explain(self.poses, name, scenes)

    def to_dict(self) -> dict[str, Any]:
        names = (
            self.problem.scene.names if self.problem is not None else [str(i) for i in range(len(self.poses))]
        )
        return {
            "solver": self.solver,
            "status": self.status.value,
            "success": self.success,
            "feasible": self.feasible,
            "objective": _num(self.objective),
            "max_violation": _num(self.max_violation),
            "violated": self.violated,
            "iterations": self.iterations,
            "time_setup": self.time_setup,
            "time_solve": self.time_solve,
            "message": self.message,
            "terms": {k: {kk: _num(vv) for kk, vv in t.items()} for k, t in self.terms.items()},
            "poses": {n: [float(v) for v in p] for n, p in zip(names, self.poses)},
            "stages": [s.to_dict() for s in self.stages],
            "confidence": {n: a.to_dict() for n, a in self.confidence.items()},
            **self._sample_counts(),
        }

    def _sample_counts(self) -> dict[str, Any]:
        """For a batched refinement: how many samples ended with each status (counts, not the samples)."""
        if self.sample_status is None:
            return {}
        names, counts = np.unique(self.sample_status, return_counts=True)
        return {"sample_status": {str(k): int(c) for k, c in zip(names, counts)}}

    def to_json(self, path: str | os.PathLike | None = None) -> str:
        """The result as JSON; written atomically to ``path`` when given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            atomic_write_text(path, text + "\n")
        return text


def best_first(feasible: Tensor, cost: Tensor, trusted: Tensor | None = None) -> Tensor:
    """The order ``(B,)`` of a population: feasible rows first, then (given ``trusted``) within each group
    the trusted rows (not :meth:`~scenescore.problem.problem.Problem.doubted`), every group by ``cost`` (not finite:
    last; a stable sort)."""
    key = torch.where(torch.isfinite(cost), cost, torch.full_like(cost, float("inf")))
    order = torch.argsort(key, stable=True)
    group = 2 * (~feasible[order]).to(torch.int8)
    if trusted is not None:
        group = group + (~trusted[order]).to(torch.int8)
    return order[torch.argsort(group, stable=True)]


def _num(v: float | None) -> float | None:
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _numpy(a: np.ndarray | torch.Tensor) -> np.ndarray:
    """``a`` as a float64 numpy array (a tensor copied to the CPU first)."""
    if isinstance(a, torch.Tensor):
        a = a.detach().cpu()
    return np.asarray(a, dtype=float)


@dataclass
class Samples:
    """Every particle a sampling or batched stage ends with, for :func:`make_result`: ``poses (B, N, 3)``,
    each one's cost ``(B,)``, its :class:`Status` value and its largest violation in metres (batched
    refinements), those it has."""

    poses: np.ndarray | torch.Tensor
    costs: np.ndarray | torch.Tensor | None = None
    status: np.ndarray | None = None
    violations: np.ndarray | torch.Tensor | None = None

    @classmethod
    def of(cls, r: Result) -> Samples | None:
        """A result's own samples (None where it kept none)."""
        if r.samples is None:
            return None
        return cls(r.samples, r.sample_costs, r.sample_status, r.sample_violations)


def _alternatives(
    problem: Problem, samples: Samples | None, objective: float, tol: float
) -> Alternatives | None:
    """The samples that satisfy the constraints within ``tol`` and that no guide doubts, with their
    cost's margin over the answer's ``objective``; None without samples and their costs, or without a
    guide to judge them (then nothing is evaluated)."""
    if samples is None or samples.costs is None or not math.isfinite(objective) or not guides(problem.cost):
        return None
    x = problem.full(samples.poses)
    with torch.no_grad():
        keep = (problem.violation(x) <= tol) & ~problem.doubted(x)
    margins = _numpy(samples.costs) - objective
    keep_np = keep.cpu().numpy() & np.isfinite(margins)
    return Alternatives(_numpy(x)[keep_np], margins[keep_np])


def make_result(
    problem: Problem,
    solver: str,
    poses: np.ndarray | torch.Tensor,
    status: Status,
    iterations: int,
    time_setup: float,
    time_solve: float,
    message: str = "",
    samples: Samples | None = None,
    tol: float = FEASIBILITY_TOL,
) -> Result:
    """Evaluate ``poses (N, 3)`` on the problem: terms, violations, the exact feasibility check; a
    sampling or batched stage's every particle kept from ``samples``."""
    x = problem.full(poses)[:1]
    with torch.no_grad():
        tv = problem.cost.terms(x)
    terms = {
        k: {
            "value": float(t.value[0]),
            "weight": t.weight,
            "weighted": float(t.weighted[0]),
            "violation": None if t.violation is None else float(t.violation[0]),
        }
        for k, t in tv.items()
    }
    objective = float(sum(cast(float, t["weighted"]) for t in terms.values()))
    max_v, violated = 0.0, None
    for c in problem.cost.constraint_terms:
        w = c.worst(x[0])
        if w is not None and w[1] > max_v:
            max_v, violated = w[1], f"{c.name}: {w[0]}"
    feas = problem.check(x[0], tol)
    pose_np = _numpy(x[0])
    alternatives = _alternatives(problem, samples, objective, tol)
    confidence = verdicts(problem.cost, pose_np, alternatives)
    success = status.ok and max_v <= tol and math.isfinite(objective)
    if status == Status.CONVERGED and max_v > tol:
        status = Status.INFEASIBLE  # a status never says converged beside a violated constraint
    if max_v <= tol:
        violated = None  # a term is named as violated only above the tolerance
    else:
        message = (
            message + "; " if message else ""
        ) + f"largest violation: {violated} by {max_v * 1000:.3g} mm"
    if not feas.feasible:
        message = (message + "; " if message else "") + "exact check: " + feas.describe()
    return Result(
        solver=solver,
        poses=_numpy(x[0]),
        status=status,
        success=success,
        feasible=feas.feasible,
        objective=objective,
        terms=terms,
        max_violation=max_v,
        violated=violated,
        iterations=iterations,
        time_setup=time_setup,
        time_solve=time_solve,
        message=message,
        samples=None if samples is None else _numpy(samples.poses),
        sample_costs=None if samples is None or samples.costs is None else _numpy(samples.costs),
        sample_status=None
        if samples is None or samples.status is None
        else np.asarray(samples.status, dtype=str),
        sample_violations=None
        if samples is None or samples.violations is None
        else _numpy(samples.violations),
        problem=problem,
        confidence=confidence,
    )
