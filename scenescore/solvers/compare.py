"""Solver comparisons: the same problem, seeds and initial particles for every solver; one table."""

from __future__ import annotations

import json
import math
import traceback
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..problem.problem import Problem
from ..runtime import generator
from .base import Solver
from .registry import get
from .result import Result

__all__ = ["Comparison", "compare"]


@dataclass
class Comparison:
    """Per-solver rows over seeds: rates, medians, timings; ``runs`` keeps every result (or error)."""

    problem: str
    seeds: list[int]
    rows: list[dict[str, Any]]
    runs: dict[str, list[Result | str]] = field(default_factory=dict)

    def table(self) -> str:
        """A markdown table, one row per solver."""
        terms = sorted({k for r in self.rows for k in r["terms"]})
        head = [
            "solver",
            "success",
            "feasible",
            "objective",
            *terms,
            "max viol (m)",
            "viol term",
            "median s",
            "p90 s",
        ]
        lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
        for r in self.rows:
            cells = [r["solver"], f"{r['success_rate']:.0%}", f"{r['feasible_rate']:.0%}", _g(r["objective"])]
            cells += [_g(r["terms"].get(t)) for t in terms]
            cells += [_g(r["max_violation"]), r["violated"] or "-", _g(r["time_median"]), _g(r["time_p90"])]
            lines.append("| " + " | ".join(cells) + " |")
        errs = [
            f"- {r['solver']}: {r['errors']} run(s) raised: {r['first_error']}"
            for r in self.rows
            if r["errors"]
        ]
        return "\n".join(lines + ([""] + errs if errs else []))

    def to_dict(self) -> dict[str, Any]:
        return {"problem": self.problem, "seeds": self.seeds, "rows": self.rows}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1)


def _g(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.4g}"


def compare(
    problem: Problem,
    solvers: list[str],
    seeds: int | list[int] = 5,
    options: dict[str, dict[str, Any]] | None = None,
    particles: int | None = None,
    progress: bool = False,
) -> Comparison:
    """Run every solver on every seed from the same initial particles; failures become rows, not exceptions."""
    options = options or {}
    seed_list = list(range(seeds)) if isinstance(seeds, int) else list(seeds)
    n_part = particles or int(options.get("langevin", {}).get("particles", 64))
    runs: dict[str, list[Result | str]] = {s: [] for s in solvers}
    built: dict[str, Solver | str] = {}
    for s in solvers:
        try:
            stages = [t.strip() for t in s.split(">")]
            mine = {t: options[t] for t in stages if t in options}  # each row takes its own stages' options
            built[s] = get(s, **mine) if len(stages) > 1 else get(s, **mine.get(s, {}))
        except Exception as e:  # an unknown solver or bad option is a row too
            built[s] = f"{type(e).__name__}: {e}"
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(seed_list) * len(solvers), desc="compare", unit="solve")
    for seed in seed_list:
        init = problem.initial(n_part, generator(seed, problem.device))  # shared by every solver
        for s in solvers:
            solver = built[s]
            if isinstance(solver, str):
                runs[s].append(solver)
            else:
                try:
                    runs[s].append(solver.solve(problem, init=init.clone(), seed=seed))
                except Exception as e:  # noqa: BLE001 - a failing solver is a row, with its message
                    last = traceback.extract_tb(e.__traceback__)[-1]
                    runs[s].append(f"{type(e).__name__}: {e} ({last.filename.split('/')[-1]}:{last.lineno})")
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    rows = []
    for s in solvers:
        res = [r for r in runs[s] if isinstance(r, Result)]
        errs = [r for r in runs[s] if isinstance(r, str)]
        k = len(runs[s])
        times = np.array([r.time_total for r in res]) if res else np.array([np.nan])
        names = list(res[0].terms) if res else []
        worst = max(res, key=lambda r: r.max_violation) if res else None
        rows.append(
            {
                "solver": s,
                "runs": k,
                "success_rate": sum(r.success for r in res) / k,
                "feasible_rate": sum(r.feasible for r in res) / k,
                "objective": float(np.median([r.objective for r in res])) if res else None,
                "terms": {t: float(np.median([r.terms[t]["weighted"] for r in res])) for t in names},
                "max_violation": float(worst.max_violation) if worst else None,
                "violated": worst.violated if worst else None,
                "time_median": float(np.median(times)) if res else None,
                "time_p90": float(np.percentile(times, 90)) if res else None,
                "statuses": {st: sum(r.status == st for r in res) for st in sorted({r.status for r in res})},
                "errors": len(errs),
                "first_error": errs[0] if errs else None,
            }
        )
    return Comparison(problem.name, seed_list, rows, runs)
