"""The results page and the README's headline table, rendered from a ``results.json`` that
``scenescore experiment`` wrote, so no published figure is ever copied by hand.

The page holds each experiment's table as the experiment printed it and the run's provenance. The
headline table picks one figure per experiment (:data:`HEADLINES`); it sits in the README between
``<!-- results:begin FILE -->`` and ``<!-- results:end -->``, the begin marker naming the results file
it was rendered from, so a test can render it again and compare.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..scene.textfiles import loads_json, read_text
from .report import RESULTS_FORMAT, format_figure

__all__ = [
    "HEADLINES",
    "Headline",
    "ResultsError",
    "headline_table",
    "load_results",
    "readme_table",
    "render_page",
    "replace_readme_table",
]

BEGIN, END = "<!-- results:begin", "<!-- results:end -->"
_BLOCK = re.compile(r"<!-- results:begin (\S+) -->\n(.*?)<!-- results:end -->", flags=re.S)


class ResultsError(ValueError):
    """A results file or README that cannot be rendered: names the file and the key or marker."""


@dataclass(frozen=True)
class Headline:
    """One row of the headline table: ``figure`` of the ``scenescore`` row beside the paper's, the best
    of ``baselines`` (lowest, or highest with ``higher_is_better``) and the ``oracle`` row. ``label``
    and ``measure`` are format strings over the ``scenescore`` row's figures (``{cases:.0f}``)."""

    experiment: str
    label: str
    measure: str
    figure: str
    scenescore: str
    baselines: tuple[str, ...]
    oracle: str | None = "Oracle"
    higher_is_better: bool = False
    digits: int = 2
    spread: bool = True  # show ``± std`` where the rows carry ``<figure>_std``


HEADLINES: list[Headline] = [
    Headline(
        "missing",
        "missing objects (Table 1)",
        "position error (cm)",
        "mean_t_cm",
        "SceneScore",
        ("NeatNet", "Nearest-Nbr", "SceneScore-Abs"),
    ),
    Headline(
        "missing",
        "missing objects (Table 1)",
        "orientation error (deg)",
        "mean_R_deg",
        "SceneScore",
        ("NeatNet", "Nearest-Nbr", "SceneScore-Abs"),
    ),
    Headline(
        "novel", "novel objects (Table 2)", "position error (cm)", "mean_cm", "SceneScore", ("NeatNet-R",)
    ),
    Headline(
        "compose",
        "composing (Fig. 4), 5 clutter boxes",
        "correct samples of {samples:.0f} (`langevin>alm`)",
        "correct_at_5_objects",
        "SceneScore (langevin>alm)",
        ("NeatNet",),
        oracle=None,
        higher_is_better=True,
        digits=0,
        spread=False,
    ),
    Headline(
        "tidy",
        "tidying, {cases:.0f} cases",
        "accepted at effort 1",
        "accepted",
        "tidy (effort 1) default",
        ("missing placement", "re-place all"),
        oracle=None,
        higher_is_better=True,
        spread=False,
    ),
]


def _require(data: dict, key: str, kind: type, where: str) -> Any:
    if not isinstance(data.get(key), kind):
        raise ResultsError(f"{where}: expected {kind.__name__} under {key!r}, got {data.get(key)!r:.60}")
    return data[key]


def load_results(path: str | Path) -> dict[str, Any]:
    """A ``results.json`` written by ``scenescore experiment``, checked: its ``format``, its
    ``provenance`` and each experiment's ``name``, ``markdown`` and ``rows``."""
    text = read_text(path, ResultsError, "results file")
    doc = loads_json(text, str(path), ResultsError)
    if not isinstance(doc, dict) or doc.get("format") != RESULTS_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise ResultsError(
            f"{path}: not a results file of `scenescore experiment` (format {got!r}, expected {RESULTS_FORMAT!r})"
        )
    _require(doc, "provenance", dict, str(path))
    for k, exp in enumerate(_require(doc, "experiments", list, str(path))):
        where = f"{path}: experiments[{k}]"
        if not isinstance(exp, dict):
            raise ResultsError(f"{where}: expected an object, got {exp!r:.60}")
        _require(exp, "name", str, where)
        _require(exp, "markdown", str, where)
        for j, row in enumerate(_require(exp, "rows", list, where)):
            if not isinstance(row, dict) or not isinstance(row.get("method"), str):
                raise ResultsError(f"{where}: rows[{j}]: expected an object with a 'method', got {row!r:.60}")
    return doc


def _cell(text: Any) -> str:
    """Text safe inside a markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _provenance_block(doc: dict[str, Any]) -> str:
    """The run's provenance as a two-column table, each experiment's wall time included."""
    prov = doc["provenance"]
    commit = str(prov.get("commit", "unknown")) + (" (with uncommitted changes)" if prov.get("dirty") else "")
    versions = ", ".join(f"{k} {v}" for k, v in (prov.get("versions") or {}).items() if v is not None)
    options = ", ".join(f"{k}={v}" for k, v in (prov.get("options") or {}).items())
    wall = prov.get("wall_seconds")
    each = ", ".join(f"{e['name']} {e.get('seconds', 0):.0f} s" for e in doc["experiments"])
    items = [
        ("command", f"`{prov['command']}`" if prov.get("command") else "-"),
        ("commit", commit),
        ("date (UTC)", prov.get("date", "-")),
        ("device", prov.get("device", "-")),
        (
            "cores and threads",
            f"{prov.get('cores', '-')} usable cores, {prov.get('threads', '-')} torch threads",
        ),
        ("wall time", f"{wall:.0f} s ({each})" if isinstance(wall, (int, float)) else each or "-"),
        ("versions", versions or "-"),
        ("platform", prov.get("platform", "-")),
        ("options", f"`{options}`" if options else "-"),
    ]
    return "| | |\n|---|---|\n" + "\n".join(f"| {k} | {_cell(v)} |" for k, v in items)


def render_page(doc: dict[str, Any], source: str) -> str:
    """The results page in Markdown: each experiment's table as it printed it, then the provenance of
    the run; ``source`` names the results file in the page's opening line."""
    parts = [
        "# Results",
        f"Rendered by `scenescore report {source}` from the file `scenescore experiment` wrote; "
        "every figure below is the run's own, with where it came from at the end.",
    ]
    parts += [e["markdown"].strip() for e in doc["experiments"]]
    parts += ["## Provenance", _provenance_block(doc)]
    return "\n\n".join(parts) + "\n"


def _rows_of(doc: dict[str, Any]) -> dict[str, dict[str, dict[str, Any]]]:
    """``experiment -> method -> row`` (the last experiment of a name wins)."""
    return {e["name"]: {r["method"]: r for r in e["rows"]} for e in doc["experiments"]}


def _value(row: dict[str, Any] | None, h: Headline) -> str:
    """``mean ± std`` of the headline's figure in ``row`` (``-`` when absent)."""
    if row is None or row.get(h.figure) is None:
        return "-"
    text = format_figure(row[h.figure], h.digits)
    std = row.get(f"{h.figure}_std")
    return text + (f" ± {format_figure(std, h.digits)}" if h.spread and std is not None else "")


def _best(rows: dict[str, dict[str, Any]], h: Headline) -> str:
    """The best of the headline's baselines present, with its name."""
    have = [rows[m] for m in h.baselines if m in rows and isinstance(rows[m].get(h.figure), (int, float))]
    if not have:
        return "-"
    pick = max if h.higher_is_better else min
    best = pick(have, key=lambda r: r[h.figure])
    return f"{_value(best, h)} ({best['method']})"


class _Missing:
    """A figure a label names that the row lacks: ``?`` whatever the format."""

    def __format__(self, spec: str) -> str:
        return "?"


class _Figures(dict):
    """A row's figures for a label's format string; a missing one shows as ``?``."""

    def __missing__(self, key: str) -> _Missing:
        return _Missing()


def headline_table(doc: dict[str, Any]) -> str:
    """The README's headline table: one row per :data:`HEADLINES` entry whose experiment the file
    holds; SceneScore, the paper's SceneScore, the best baseline and the oracle."""
    by_experiment = _rows_of(doc)
    lines = [
        "| experiment | measure | SceneScore | paper's SceneScore | best baseline | oracle |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for h in HEADLINES:
        rows = by_experiment.get(h.experiment)
        if rows is None:
            continue
        ours = rows.get(h.scenescore)
        figures = _Figures({k: v for k, v in (ours or {}).items() if isinstance(v, (int, float))})
        label, measure = h.label.format_map(figures), h.measure.format_map(figures)
        paper = (ours or {}).get("paper", {}).get(h.figure)
        oracle = _value(rows.get(h.oracle), h) if h.oracle else "-"
        cells = [label, measure, _value(ours, h), format_figure(paper, h.digits), _best(rows, h), oracle]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def readme_table(text: str) -> tuple[str, str] | None:
    """``(results file named by the begin marker, the table between the markers)`` of a README's text,
    or None when it has no markers."""
    m = _BLOCK.search(text)
    return None if m is None else (m.group(1), m.group(2).strip())


def replace_readme_table(text: str, table: str, source: str) -> str:
    """``text`` with the table between the markers replaced by ``table`` and the begin marker naming
    ``source``; a README without both markers is an error that shows them."""
    if _BLOCK.search(text) is None:
        raise ResultsError(
            f"no '{BEGIN} FILE -->' ... '{END}' markers, each on a line of its own, around the table to fill"
        )
    block = f"{BEGIN} {source} -->\n{table.strip()}\n{END}"
    return _BLOCK.sub(lambda _: block, text, count=1)
