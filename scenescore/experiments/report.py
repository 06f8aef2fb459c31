"""Experiment tables: rows of named figures, markdown with the paper's figures beside ours, JSON."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..scene.outputs import atomic_write_text

__all__ = [
    "RESULTS_FORMAT",
    "Row",
    "SeedResults",
    "experiment_entry",
    "format_figure",
    "format_table",
    "over_seeds",
    "write_document",
    "write_results",
]


@dataclass
class Row:
    """One method's figures (``name -> value``) and the paper's for the same names, where it gives them."""

    method: str
    figures: dict[str, float]
    paper: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d: dict = {"method": self.method}
        d.update(
            {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in self.figures.items()}
        )
        if self.paper:
            d["paper"] = self.paper
        return d


@dataclass
class SeedResults:
    """Per-method, per-seed figures; :meth:`rows` averages over seeds and adds ``<key>_std`` for the
    keys in ``spread`` (every key when ``None``) and the paper's figures from ``paper``."""

    per_seed: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    paper: ClassVar[dict[str, dict[str, float]]] = {}
    spread: ClassVar[tuple[str, ...] | None] = None

    def rows(self) -> list[Row]:
        rows = []
        for method, runs in self.per_seed.items():
            fig = {k: float(np.mean([r[k] for r in runs])) for k in runs[0]}
            for k in (self.spread if self.spread is not None else list(runs[0])) if len(runs) > 1 else ():
                fig[f"{k}_std"] = float(np.std([r[k] for r in runs]))
            fig["seconds"] = self.seconds.get(method, 0.0)
            rows.append(Row(method, fig, self.paper.get(method, {})))
        return rows


def format_figure(v: float | str | None, digits: int = 2) -> str:
    """A table cell: ``-`` for a missing figure, integers as they are, floats to ``digits`` places."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    return f"{v:.{digits}f}"


def over_seeds(n: int) -> str:
    """How a table's figures aggregate seeds: ``mean ± std over n seeds``, or one seed's figures."""
    return f"mean ± std over {n} seeds" if n > 1 else "one seed, so no spread"


def format_table(
    rows: list[Row], columns: list[tuple[str, str]], std: dict[str, str] | None = None, digits: int = 2
) -> str:
    """Markdown: one row per method; a column shows ``ours (paper)`` where the paper has a figure,
    and ``mean +- std`` where ``std`` names the spread's key."""
    std = std or {}
    head = "| method | " + " | ".join(h for _, h in columns) + " |"
    sep = "|---|" + "---:|" * len(columns)
    lines = [head, sep]
    for r in rows:
        cells = []
        for key, _ in columns:
            v = r.figures.get(key)
            cell = format_figure(v, digits)
            if key in std and r.figures.get(std[key]) is not None and cell != "-":
                cell += f" ± {format_figure(r.figures[std[key]], digits)}"
            if key in r.paper:
                cell += f" (paper {format_figure(r.paper[key], digits)})"
            cells.append(cell)
        lines.append(f"| {r.method} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


RESULTS_FORMAT = "scenescore-results/1"  # results.json's ``format``: bumped when its layout changes


def experiment_entry(name: str, rows: list[Row], markdown: str, seconds: float) -> dict[str, Any]:
    """One experiment in ``results.json``: its name, wall time, table as printed, and rows."""
    return {
        "name": name,
        "seconds": round(float(seconds), 1),
        "markdown": markdown,
        "rows": [r.to_dict() for r in rows],
    }


def write_document(path: str | Path, entries: list[dict[str, Any]], provenance: dict[str, Any]) -> None:
    """``results.json`` at ``path``, written atomically: ``format``, ``provenance`` (where the figures
    came from: :func:`scenescore.runtime.provenance.collect_provenance`) and ``experiments`` (each an
    :func:`experiment_entry`, in the order they ran)."""
    doc = {"format": RESULTS_FORMAT, "provenance": provenance, "experiments": entries}
    atomic_write_text(path, json.dumps(doc, indent=1) + "\n")


def write_results(
    out_dir: str | Path,
    rows: list[Row],
    markdown: str,
    *,
    name: str,
    seconds: float,
    provenance: dict[str, Any],
) -> dict[str, Any]:
    """``table.md`` and ``results.json`` (this one experiment, see :func:`write_document`) in
    ``out_dir``, each written atomically; returns the experiment's entry."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "table.md", markdown + "\n")
    entry = experiment_entry(name, rows, markdown, seconds)
    write_document(out / "results.json", [entry], provenance)
    return entry
