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
