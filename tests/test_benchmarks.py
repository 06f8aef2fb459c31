"""Every script under benchmarks/ runs: its imports resolve and its options parse (``--help``), so a
change to the library that breaks a benchmark fails here rather than when someone next measures."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = sorted((Path(__file__).resolve().parents[1] / "benchmarks").glob("*.py"))


def test_there_are_benchmarks():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_benchmark_help_runs(script, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", [str(script), "--help"])
    monkeypatch.syspath_prepend(
        str(script.parent)
    )  # as `python benchmarks/x.py` has it: its own folder first
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(script), run_name="__main__")
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage:"), out[:200]


def test_trust_margins_judges_the_share_flags_at_a_margin():
    """benchmarks/trust_margins.py: a share beyond the largest plus ``margin`` IQRs flags; the members
    flag needs that many members beyond their own limits; other recorded flags always flag."""
    script = Path(__file__).resolve().parents[1] / "benchmarks" / "trust_margins.py"
    flagged = runpy.run_path(str(script))["_flagged"]
    ref = np.array([-1.0, 0.0, 1.0])  # its largest 1, its interquartile range 1
    alone = {"shares": [1.5, 0.0, 0.0, 0.0], "refs": [ref] * 4}  # the mean's, then 3 members'
    case = {"flags": ["energy: ...", "members: ..."]}  # share flags: judged again, not read
    assert flagged(case, alone, 0.4, 1) and not flagged(case, alone, 0.5, 1)  # 1.5 > 1 + 0.4, not 1 + 0.5
    s = {"shares": [1.0, 1.2, 0.0, 3.0], "refs": [ref] * 4}
    assert flagged(case, s, 0.1, 2, 0.1) and not flagged(case, s, 0.1, 3, 0.1)  # members 1 and 3 > 1.1
    assert not flagged(case, s, 0.1, 0, 0.1) and not flagged(case, s, 0.1, 1, 2.5)  # none; 3.0 < 3.5
    assert flagged({"flags": ["far: ..."]}, s, 9.0, 0)  # another flag, as recorded


def test_trust_margins_lists_the_catastrophic_placements_left_unflagged(capsys):
    """benchmarks/trust_margins.py: a catastrophic placement no flag catches is listed with how much more
    its truth costs, by the mean energy and each member; a flagged one and a good one are not."""
    script = Path(__file__).resolve().parents[1] / "benchmarks" / "trust_margins.py"
    ns = runpy.run_path(str(script))
    ref = np.array([-1.0, 0.0, 1.0])
    cases = [
        {"seed": 0, "object": "book_1", "t_cm": 40.0, "oracle_t_cm": 0.2, "flags": []},
        {"seed": 1, "object": "book_2", "t_cm": 35.0, "oracle_t_cm": 0.2, "flags": ["rival: ..."]},
        {"seed": 2, "object": "book_3", "t_cm": 0.1, "oracle_t_cm": 0.2, "flags": []},
    ]
    quiet = {"shares": [0.0] * 3, "refs": [ref] * 3, "truth_minus_answer": [0.9, 1.2, 0.6]}
    ns["_misses"]({"zoo-books": cases}, {"zoo-books": [quiet, quiet, quiet]}, ns["TrainConfig"](members=2))
    out = capsys.readouterr().out
    assert "leaves unflagged: 1" in out
    assert "| zoo-books | 0 | book_1 | 40.0 | 0.90 | 1.20, 0.60 |" in out
    assert "book_2" not in out and "book_3" not in out
