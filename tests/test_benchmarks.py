"""Every script under benchmarks/ runs: its imports resolve and its options parse (``--help``), so a
change to the library that breaks a benchmark fails here rather than when someone next measures. Each
is a durable benchmark, named in docs/performance.md's table of scripts."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("*.py"))


def run_help(script: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> str:
    """``python FOLDER/script.py --help``'s output, the script's own folder first on the path as
    Python puts it; fails unless it exits 0 with a usage line."""
    monkeypatch.setattr(sys, "argv", [str(script), "--help"])
    monkeypatch.syspath_prepend(str(script.parent))
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(script), run_name="__main__")
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage:"), out[:200]
    return out


def test_there_are_benchmarks():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_benchmark_help_runs(script, monkeypatch, capsys):
    run_help(script, monkeypatch, capsys)


def test_every_benchmark_is_on_the_performance_page():
    """benchmarks/ keeps the scripts docs/performance.md names in its table; a one-off investigation
    belongs under studies/."""
    page = (ROOT / "docs" / "performance.md").read_text()
    missing = [p.name for p in SCRIPTS if f"| `{p.name}` |" not in page]
    assert not missing, f"not in docs/performance.md's table of scripts: {missing}"


def test_bench_rooms_writes_its_rooms_for_train(monkeypatch, capsys, tmp_path):
    script = ROOT / "benchmarks" / "bench_rooms.py"
    out = tmp_path / "rooms.jsonl"
    monkeypatch.setattr(sys, "argv", [str(script), "--sizes", "10", "--write", str(out)])
    monkeypatch.syspath_prepend(str(script.parent))
    runpy.run_path(str(script), run_name="__main__")
    from scenescore.scene.scene import read_jsonl

    rooms = read_jsonl(out)
    assert len(rooms) == 48 and {len(r) for r in rooms} == {10}
    assert "wrote 48 rooms of 10 objects" in capsys.readouterr().out
