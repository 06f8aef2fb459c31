"""The results page and the README's headline table are rendered from results.json, never copied by
hand: rendering on small results built here, the README checked against the file its marker names,
and `experiment` recording where its figures came from."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from scenescore.cli import experiment, main
from scenescore.experiments.report import RESULTS_FORMAT, Row, experiment_entry, write_document
from scenescore.experiments.results_page import (
    ResultsError,
    headline_table,
    load_results,
    readme_table,
    render_page,
    replace_readme_table,
)
from scenescore.runtime.provenance import collect_provenance, git_commit

ROOT = Path(__file__).resolve().parents[2]

PROVENANCE = {
    "command": "scenescore experiment all --out runs/all",
    "options": {"name": "all", "seeds": 3},
    "commit": "0123abc",
    "dirty": False,
    "date": "2026-01-02T03:04:05+00:00",
    "versions": {"scenescore": "0.1.0", "torch": "2.13.0"},
    "device": "cpu (Test CPU)",
    "platform": "Linux",
    "cores": 2,
    "threads": 2,
    "wall_seconds": 4321.0,
}


def _doc() -> dict:
    """Two experiments' rows, as `experiment all` writes them (through JSON, as the file holds them)."""
    missing = [
        Row("NeatNet", {"mean_t_cm": 19.9, "mean_t_cm_std": 1.5, "mean_R_deg": 20.0, "mean_R_deg_std": 0.9}),
        Row(
            "SceneScore-Abs",
            {"mean_t_cm": 10.0, "mean_t_cm_std": 1.4, "mean_R_deg": 30.0},
            {"mean_t_cm": 6.5},
        ),
        Row("SceneScore (LeakyReLU)", {"mean_t_cm": 2.0, "mean_R_deg": 3.3}),  # not a baseline
        Row(
            "SceneScore",
            {"mean_t_cm": 1.654, "mean_t_cm_std": 0.16, "mean_R_deg": 2.8, "mean_R_deg_std": 0.09},
            {"mean_t_cm": 4.4, "mean_R_deg": 9.7},
        ),
        Row("Oracle", {"mean_t_cm": 0.69, "mean_t_cm_std": 0.02, "mean_R_deg": 2.58}),
    ]
    tidy = [
        Row("tidy (effort 1) default", {"accepted": 0.96, "cases": 215}),
        Row("missing placement", {"accepted": 0.95, "cases": 215}),
        Row("re-place all", {"accepted": 0.5, "cases": 215}),
    ]
    entries = [
        experiment_entry("missing", missing, "## Table 1: missing objects\n\n| a | b |", 600.4),
        experiment_entry("tidy", tidy, "## Tidying messy scenes\n\n### All cases\n\n| c |", 1500.0),
    ]
    doc = {"format": RESULTS_FORMAT, "provenance": PROVENANCE, "experiments": entries}
    return json.loads(json.dumps(doc))


def test_headline_table_picks_each_experiments_figures():
    table = headline_table(_doc()).splitlines()
    assert table[0].startswith("| experiment | measure | SceneScore | paper's SceneScore | best baseline")
    assert table[2] == (
        "| missing objects (Table 1) | position error (cm) | 1.65 ± 0.16 | 4.40 | "
        "10.00 ± 1.40 (SceneScore-Abs) | 0.69 ± 0.02 |"
    )
    # the lowest error of the baselines; no spread where the row has none
    assert table[3].endswith("| 2.80 ± 0.09 | 9.70 | 20.00 ± 0.90 (NeatNet) | 2.58 |")
    # higher is better for tidying, its label carries the case count, no oracle row
    assert (
        table[4] == "| tidying, 215 cases | accepted at effort 1 | 0.96 | - | 0.95 (missing placement) | - |"
    )
    assert len(table) == 5  # no novel or compose rows: the file holds neither


def test_a_missing_figure_renders_as_a_dash_not_an_error():
    doc = _doc()
    doc["experiments"][1]["rows"] = [{"method": "tidy (effort 1) default", "accepted": 0.9}]
    row = headline_table(doc).splitlines()[-1]
    assert row == "| tidying, ? cases | accepted at effort 1 | 0.90 | - | - | - |"


def test_page_holds_each_table_as_printed_and_the_provenance():
    page = render_page(_doc(), "runs/all/results.json")
    assert page.startswith("# Results\n") and "`scenescore report runs/all/results.json`" in page
    assert "## Table 1: missing objects\n\n| a | b |" in page and "### All cases\n\n| c |" in page
    assert page.index("Table 1") < page.index("Tidying") < page.index("## Provenance")
    for text in ("`scenescore experiment all --out runs/all`", "0123abc", "2026-01-02T03:04:05+00:00"):
        assert text in page
    assert "cpu (Test CPU)" in page and "2 usable cores, 2 torch threads" in page
    assert "4321 s (missing 600 s, tidy 1500 s)" in page and "torch 2.13.0" in page
    assert "uncommitted" not in page
    doc = _doc()
    doc["provenance"]["dirty"] = True
    assert "0123abc (with uncommitted changes)" in render_page(doc, "r.json")


def test_readme_markers_round_trip():
    text = "intro\n\n<!-- results:begin old.json -->\n| old |\n<!-- results:end -->\n\nafter\n"
    assert readme_table(text) == ("old.json", "| old |")
    new = replace_readme_table(text, "| new |\n|---|", "docs/results/results.json")
    assert new == (
        "intro\n\n<!-- results:begin docs/results/results.json -->\n| new |\n|---|\n<!-- results:end -->\n\nafter\n"
    )
    assert readme_table(new) == ("docs/results/results.json", "| new |\n|---|")
    assert readme_table("no markers here") is None
    with pytest.raises(ResultsError, match="results:begin"):
        replace_readme_table("no markers here", "| t |", "r.json")


def test_a_file_that_is_not_an_experiments_results_is_refused_naming_what(tmp_path):
    f = tmp_path / "results.json"
    f.write_text(json.dumps([{"method": "SceneScore"}]))  # a bare list of rows
    with pytest.raises(ResultsError, match="format"):
        load_results(f)
    doc = _doc()
    del doc["experiments"][0]["markdown"]
    f.write_text(json.dumps(doc))
    with pytest.raises(ResultsError, match=r"experiments\[0\].*'markdown'"):
        load_results(f)
    with pytest.raises(ResultsError, match="no such results file"):
        load_results(tmp_path / "absent.json")


def test_the_readme_table_is_the_one_its_results_file_renders():
    """The README's headline table between its markers is what `scenescore report` renders from the
    file the begin marker names: a hand edit of either fails here."""
    found = readme_table((ROOT / "README.md").read_text())
    if found is None:
        pytest.skip("the README has no results markers yet")
    source, table = found
    assert (ROOT / source).is_file(), f"README's results marker names {source}, which does not exist"
    assert table == headline_table(load_results(ROOT / source)).strip()


# provenance


def test_provenance_records_where_a_result_came_from():
    prov = collect_provenance(["experiment", "missing", "--methods", "a b"], {"seeds": 3}, 12.345, "cpu")
    assert prov["command"] == "scenescore experiment missing --methods 'a b'"
    assert prov["options"] == {"seeds": 3} and prov["wall_seconds"] == 12.3
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", prov["date"])
    assert prov["versions"]["torch"] and prov["versions"]["numpy"] and prov["versions"]["python"]
    assert prov["device"].startswith("cpu (") and prov["cores"] >= 1 and prov["threads"] >= 1
    json.dumps(prov)  # JSON as it is


def test_the_commit_is_the_one_the_run_started_from():
    """A long run records the commit read when it started, not the one checked out when it ends."""
    started = {"commit": "0" * 40, "dirty": False}
    assert collect_provenance(commit=started)["commit"] == "0" * 40


def test_no_git_is_an_unknown_commit_not_an_error(monkeypatch):
    monkeypatch.setenv("PATH", "")  # no git to run
    assert git_commit() == {"commit": "unknown", "dirty": None}
    assert collect_provenance()["commit"] == "unknown"


def _fake_runners(monkeypatch):
    """Every experiment's runner replaced by one that returns a small table at once."""

    def runner(name):
        def run(args, out):
            return f"## {name}\n\n| method | x |", [Row("SceneScore", {"x": 1.0}), Row("Oracle", {"x": 0.5})]

        return run

    monkeypatch.setattr(experiment, "RUNNERS", {n: runner(n) for n in experiment.EXPERIMENTS})


def test_experiment_writes_provenance_and_report_renders_it(monkeypatch, tmp_path, capsys):
    _fake_runners(monkeypatch)
    argv = ["experiment", "all", "--jobs", "1", "--seeds", "2", "--quiet", "--out", str(tmp_path / "all")]
    assert main(argv) == 0
    doc = load_results(tmp_path / "all" / "results.json")
    assert [e["name"] for e in doc["experiments"]] == experiment.EXPERIMENTS
    prov = doc["provenance"]
    assert prov["command"] == "scenescore " + " ".join(argv)
    assert (
        prov["options"]["seeds"] == 2 and prov["options"]["device"] == "cpu" and "func" not in prov["options"]
    )
    one = load_results(tmp_path / "all" / "missing" / "results.json")  # each experiment's own file too
    assert [e["name"] for e in one["experiments"]] == ["missing"]
    assert one["experiments"][0]["rows"][1] == {"method": "Oracle", "x": 0.5}

    readme = tmp_path / "README.md"
    readme.write_text("# R\n\n<!-- results:begin x.json -->\n| stale |\n<!-- results:end -->\n")
    page = tmp_path / "results.md"
    assert (
        main(["report", str(tmp_path / "all" / "results.json"), "--out", str(page), "--readme", str(readme)])
        == 0
    )
    assert "## zoo\n\n| method | x |" in page.read_text() and prov["commit"] in page.read_text()
    source, table = readme_table(readme.read_text())
    assert source == "all/results.json" and "stale" not in table  # named relative to the README
    assert table == headline_table(doc).strip()


def test_report_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "results.json"
    bad.write_text("[]")
    assert main(["report", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "format" in err
    write_document(bad, [], PROVENANCE)
    readme = tmp_path / "README.md"
    readme.write_text("# no markers\n")
    assert main(["report", str(bad), "--readme", str(readme)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--readme" in err and "results:begin" in err
    assert readme.read_text() == "# no markers\n"  # nothing written
