"""The tidying experiment's results: each method's outcome on each messy case, the figures they pool
into, the tables (every case, shifts, swaps, each scenario) and the chart of desirability against
effort as the effort weight varies."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..planning.tidying import EFFORT
from .messy import MessyCase
from .report import Row, format_table

__all__ = [
    "COLUMNS",
    "EFFORTS",
    "Outcome",
    "TidyRun",
    "format_tidy",
    "method_name",
    "pareto_chart",
    "plot_pareto",
]

EFFORTS: tuple[float, ...] = (0.3, EFFORT, 3.0)


@dataclass
class Outcome:
    """One method on one case."""

    accepted: bool
    moved: list[str]
    displacement: float
    plan_steps: int
    plan_valid: bool
    buffers: int
    plan_made: bool = True  # False: the targets admit no plan (one outside the bounds, say)


@dataclass
class TidyRun:
    """Every case and every method's outcome on it, per scenario; seconds per method."""

    cases: list[MessyCase] = field(default_factory=list)
    outcomes: dict[str, list[Outcome]] = field(default_factory=dict)  # method -> one per case
    seconds: dict[str, float] = field(default_factory=dict)
    efforts: tuple[float, ...] = EFFORTS

    def figures(self, method: str, select: Callable[[MessyCase], bool] = lambda c: True) -> dict[str, float]:
        pairs = [(c, o) for c, o in zip(self.cases, self.outcomes[method]) if select(c)]
        if not pairs:
            return {}
        prec, rec = [], []
        for c, o in pairs:
            hit = len(set(o.moved) & set(c.displaced))
            prec.append(hit / len(o.moved) if o.moved else 1.0)
            rec.append(hit / len(c.displaced))
        made = [o for _, o in pairs if o.plan_made]
        disp = np.array([o.displacement for _, o in pairs])
        back = np.array([c.putback for c, _ in pairs])
        return {
            "cases": len(pairs),
            "accepted": float(np.mean([o.accepted for _, o in pairs])),
            "precision": float(np.mean(prec)),
            "recall": float(np.mean(rec)),
            "moved": float(np.mean([len(o.moved) for _, o in pairs])),
            "displacement_m": float(disp.mean()),
            "putback_m": float(back.mean()),
            "ratio": float(disp.sum() / max(back.sum(), 1e-12)),
            "plan_steps": float(np.mean([o.plan_steps for _, o in pairs])),
            "buffers": float(np.mean([o.buffers for _, o in pairs])),
            "no_plan": 1.0 - len(made) / len(pairs),
            **({"plans_valid": float(np.mean([o.plan_valid for o in made]))} if made else {}),
        }

    def to_dict(self) -> dict[str, Any]:
        """The run as JSON: a scenario and seed's record in a sweep's folder."""
        outcomes = {m: [asdict(o) for o in got] for m, got in self.outcomes.items()}
        cases = [c.to_dict() for c in self.cases]
        return {"cases": cases, "outcomes": outcomes, "seconds": self.seconds, "efforts": list(self.efforts)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TidyRun:
        outcomes = {str(m): [Outcome(**o) for o in got] for m, got in d["outcomes"].items()}
        seconds = {str(m): float(v) for m, v in d["seconds"].items()}
        efforts = tuple(float(e) for e in d["efforts"])
        return cls([MessyCase.from_dict(c) for c in d["cases"]], outcomes, seconds, efforts)

    def per_case(self) -> list[dict[str, Any]]:
        """Every case with each method's outcome on it (for ``cases.json``): which objects were displaced
        and how, which each method moved, whether the scenario's check accepted the result."""
        out = []
        for j, c in enumerate(self.cases):
            out.append(
                {
                    "scenario": c.scenario,
                    "seed": c.seed,
                    "kind": c.kind,
                    "size": c.size,
                    "displaced": c.displaced,
                    "methods": {
                        m: {
                            "moved": sorted(got[j].moved),
                            "accepted": bool(got[j].accepted),
                            "displacement_m": round(float(got[j].displacement), 4),
                            "plan_valid": bool(got[j].plan_valid),
                        }
                        for m, got in self.outcomes.items()
                    },
                }
            )
        return out

    def rows(self, select: Callable[[MessyCase], bool] = lambda c: True) -> list[Row]:
        out = []
        for m in self.outcomes:
            figs = self.figures(m, select)
            if figs:
                figs["seconds"] = self.seconds.get(m, 0.0)
                out.append(Row(m, figs))
        return out


def method_name(effort: float) -> str:
    return f"tidy (effort {effort:g})" + (" default" if effort == EFFORT else "")


COLUMNS = [
    ("cases", "cases"),
    ("accepted", "accepted"),
    ("precision", "precision"),
    ("recall", "recall"),
    ("moved", "moved"),
    ("displacement_m", "displacement (m)"),
    ("putback_m", "put-back (m)"),
    ("ratio", "ratio"),
    ("plan_steps", "plan steps"),
    ("buffers", "buffers"),
    ("no_plan", "no plan"),
    ("plans_valid", "plans valid"),
    ("seconds", "s"),
]


def _select(what: str) -> Callable[[MessyCase], bool]:
    if what == "all":
        return lambda c: True
    if what in ("shift", "swap"):
        return lambda c: c.kind == what
    return lambda c: c.scenario == what


def format_tidy(res: TidyRun) -> str:
    """Markdown: every case, then shifts and swaps apart, then each scenario."""
    sections = [("all", "All cases (1 or 2 objects displaced)"), ("shift", "Shifts"), ("swap", "Swaps")]
    sections += [(n, n) for n in dict.fromkeys(c.scenario for c in res.cases)]
    parts = []
    for what, title in sections:
        rows = res.rows(_select(what))
        if rows:
            parts.append(f"### {title}\n\n" + format_table(rows, COLUMNS))
    return "\n\n".join(parts)


def plot_pareto(res: TidyRun, path: Any) -> None:
    """Desirability (accepted fraction) against effort (total displacement over put-back) as the effort
    weight varies, the baselines as single points."""
    methods = [method_name(e) for e in res.efforts] + ["missing placement", "re-place all"]
    pareto_chart({m: res.figures(m) for m in methods}, res.efforts, path)


def pareto_chart(figures: dict[str, dict[str, float]], efforts: Sequence[float], path: Any) -> None:
    """:func:`plot_pareto` from each method's figures (``results.json``'s rows: ``ratio``, ``accepted``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullLocator

    from ..viz.plot import save_figure

    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    pts = [(e, figures[method_name(e)]) for e in efforts]
    xs = [f["ratio"] for _, f in pts]
    ys = [f["accepted"] for _, f in pts]
    ax.plot(xs, ys, "-", color="C0", lw=1.2, alpha=0.6)
    markers = "oDvP*Xh"
    for k, ((e, _), x, y) in enumerate(zip(pts, xs, ys)):
        # each weight its own marker in the legend: points that lie close together (or beside a
        # baseline's) stay told apart, with no label to sit on the wrong one
        default = " (default)" if e == EFFORT else ""
        ax.plot(
            [x],
            [y],
            markers[k % len(markers)],
            color="C0",
            ms=7,
            ls="none",
            label=f"tidy, effort {e:g}{default}",
        )
    for m, style in (("missing placement", ("s", "C2")), ("re-place all", ("^", "C3"))):
        f = figures[m]
        ax.plot([f["ratio"]], [f["accepted"]], style[0], color=style[1], ls="none", label=m)
    ax.set_xscale("symlog", linthresh=1.0)  # 0 (nothing moved) stays on the chart
    top = max([1.0, *xs, *(figures[m]["ratio"] for m in ("missing placement", "re-place all"))])
    ticks = [0, 0.5, 1] + [t for t in (2, 5, 10, 20, 50, 100) if t <= 1.2 * top]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlim(0, 1.25 * top)  # every tick up to the largest ratio shows
    ax.axvline(1.0, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("total displacement / put-back displacement (linear below 1, log above)")
    ax.set_ylabel("accepted by the scenario's check")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title("tidying: desirability against effort", fontsize=9)
    ax.legend(fontsize=7, frameon=False, loc="lower right")
    save_figure(fig, path)
