"""``scenescore explain``: the table, the JSON and the plot for the README's scene; clear refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from scenescore.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "examples" / "dining_scene.json"


def test_explain_places_then_explains_and_writes_json_and_a_plot(tmp_path, capsys):
    out, plot = tmp_path / "why.json", tmp_path / "why.png"
    argv = ["explain", "dining", str(SCENE), "--object", "bowl_0", "--out", str(out), "--plot", str(plot)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "placing bowl_0 first (seed 0)" in printed and "well depth" in printed
    why = json.loads(out.read_text())
    assert why["name"] == "bowl_0" and len(why["relations"]) == 8
    parts = sum(r["part"] for r in why["relations"]) + why["others"] + (why["walls"] or 0.0)
    assert abs(parts + why["rest"] - why["depth"]) < 1e-9
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"
    # the relations listed are the largest parts: fewer asked for, the rest summed as the others
    assert main([*argv[:5], "--neighbours", "2", "--out", str(out)]) == 0
    short = json.loads(out.read_text())
    assert [r["neighbour"] for r in short["relations"]] == [
        r["neighbour"] for r in sorted(why["relations"], key=lambda r: -abs(r["part"]))[:2]
    ]
    assert short["unlisted"] == 6


@pytest.mark.parametrize(
    "extra, message",
    [(["--object", "mug"], "no object 'mug'"), (["--object", "bowl_0", "--neighbours", "0"], "neighbours")],
)
def test_explain_refuses_bad_input(extra, message, capsys):
    try:
        rc = main(["explain", "dining", str(SCENE), *extra])
    except SystemExit as e:  # argparse's own refusals
        rc = e.code
    assert rc == 2
    assert message in capsys.readouterr().err


def test_place_with_the_examples_relations(tmp_path):
    import scenescore as ss

    truth = ss.scenarios.get("dining").generate(6, 3)
    ss.write_jsonl(tmp_path / "ex.jsonl", truth[:5])
    query = truth[5].without("fork_0")
    query.to_json(tmp_path / "q.json")
    plain, mixed = tmp_path / "plain.json", tmp_path / "mixed.json"
    base = ["place", "dining", str(tmp_path / "q.json"), "--quiet"]
    assert main([*base, "--out", str(plain)]) == 0
    assert (
        main([*base, "--out", str(mixed), "--examples", str(tmp_path / "ex.jsonl"), "--examples-weight", "5"])
        == 0
    )
    a, b = ss.Scene.from_json(plain)["fork_0"].pose, ss.Scene.from_json(mixed)["fork_0"].pose
    assert a is not None and b is not None and a != b
