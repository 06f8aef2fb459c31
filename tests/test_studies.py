"""Every script under studies/ runs (``--help``), each has its row in studies/README.md, and the trust
margins study judges the share flags as the trust check does."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest
from test_benchmarks import run_help  # tests/ is on the path

from scenescore.learn import TrainConfig

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "studies").glob("*.py"))


def test_there_are_studies():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_study_help_runs(script, monkeypatch, capsys):
    run_help(script, monkeypatch, capsys)


def test_every_study_is_in_the_index():
    """studies/README.md has one row per script, and names no script that is not there."""
    index = (ROOT / "studies" / "README.md").read_text()
    rows = {line.split("|")[1].strip().strip("`") for line in index.splitlines() if line.startswith("| `")}
    assert rows == {p.name for p in SCRIPTS}


def _study(name: str) -> dict:
    """The names ``studies/NAME`` defines, run as ``python studies/NAME`` would (its folder on the path,
    for the sibling study it imports)."""
    sys.path.insert(0, str(ROOT / "studies"))
    try:
        return runpy.run_path(str(ROOT / "studies" / name))
    finally:
        sys.path.remove(str(ROOT / "studies"))


def _trust_margins() -> dict:
    return _study("trust_margins.py")


def test_trust_margins_judges_the_share_flags_at_a_margin():
    """studies/trust_margins.py: a share beyond the largest plus ``margin`` IQRs flags; the members
    flag needs that many members beyond their own limits; other recorded flags always flag."""
    flagged = _trust_margins()["flagged"]
    ref = np.array([-1.0, 0.0, 1.0])  # its largest 1, its interquartile range 1
    alone = {"shares": [1.5, 0.0, 0.0, 0.0], "refs": [ref] * 4}  # the mean's, then 3 members'
    case = {"flags": ["energy: ...", "members: ..."]}  # share flags: judged again, not read
    assert flagged(case, alone, 0.4, 1) and not flagged(case, alone, 0.5, 1)  # 1.5 > 1 + 0.4, not 1 + 0.5
    s = {"shares": [1.0, 1.2, 0.0, 3.0], "refs": [ref] * 4}
    assert flagged(case, s, 0.1, 2, 0.1) and not flagged(case, s, 0.1, 3, 0.1)  # members 1 and 3 > 1.1
    assert not flagged(case, s, 0.1, 0, 0.1) and not flagged(case, s, 0.1, 1, 2.5)  # none; 3.0 < 3.5
    assert flagged({"flags": ["far: ..."]}, s, 9.0, 0)  # another flag, as recorded
    assert not flagged({"flags": ["members: ...", "relation: ..."]}, s, 9.0, 0)  # a note, no flag


def test_trust_margins_lists_the_catastrophic_placements_left_unflagged(capsys):
    """studies/trust_margins.py: a catastrophic placement no flag catches is listed with how much more
    its truth costs, by the mean energy and each member; a flagged one and a good one are not."""
    misses = _trust_margins()["misses"]
    ref = np.array([-1.0, 0.0, 1.0])
    cases = [
        {"seed": 0, "object": "book_1", "t_cm": 40.0, "oracle_t_cm": 0.2, "flags": []},
        {"seed": 1, "object": "book_2", "t_cm": 35.0, "oracle_t_cm": 0.2, "flags": ["rival: ..."]},
        {"seed": 2, "object": "book_3", "t_cm": 0.1, "oracle_t_cm": 0.2, "flags": []},
    ]
    quiet = {"shares": [0.0] * 3, "refs": [ref] * 3, "truth_minus_answer": [0.9, 1.2, 0.6]}
    misses({"zoo-books": cases}, {"zoo-books": [quiet, quiet, quiet]}, TrainConfig(members=2))
    out = capsys.readouterr().out
    assert "leaves unflagged: 1" in out
    assert "| zoo-books | 0 | book_1 | 40.0 | 0.90 | 1.20, 0.60 |" in out
    assert "book_2" not in out and "book_3" not in out


def test_zoo_configs_counts_each_kind_of_flag_on_catastrophic_and_good_placements():
    """studies/zoo_configs.py's ``flag_kinds``: the kinds of flag among each placement's flags, pooled
    over the scenarios, for the catastrophic and the good ones."""
    flag_kinds = _study("zoo_configs.py")["flag_kinds"]

    def case(t: float, flags: list[str]) -> dict:
        return {"t_cm": t, "oracle_t_cm": 1.0, "flagged": bool(flags), "flags": flags}

    per_case = {
        "a": [case(40.0, ["rival: another particle ..."]), case(1.0, []), case(1.0, ["energy: ..."])],
        "b": [case(50.0, []), case(0.5, []), case(0.8, [])],
    }
    assert flag_kinds(per_case) == (
        "flags on catastrophic placements: rival 1; flags on good placements: energy 1"
    )


def test_zoo_configs_counts_the_flags_with_the_members_flag_needing_more_members():
    """studies/zoo_configs.py's ``members_rules``: from the ``members`` flag's text, the placements that
    stay flagged when it needs 2 or 3 members to doubt, or counts only where they split; a placement
    flagged by another flag stays flagged, the ``relation`` line (no flag of its own) does not keep one."""
    members_rules = _study("zoo_configs.py")["members_rules"]

    def case(t: float, *flags: str) -> dict:
        return {"t_cm": t, "oracle_t_cm": 1.0, "flagged": bool(flags), "flags": list(flags)}

    def doubt(k: int) -> str:
        return f"members: {k} of 3 members put its share of their energy beyond any cup's in the data"

    per_case = {
        "a": [case(40.0, doubt(1), "relation: ..."), case(1.0, doubt(3), "relation: ...")],
        "b": [case(0.5, doubt(2)), case(35.0, doubt(3), "far: ..."), case(0.8, "energy: ...")],
    }
    assert members_rules(per_case).split("; ") == [
        "members needed 1: catastrophic 2 of 2 flagged, good 3 of 3",
        "members needed 2: catastrophic 1 of 2 flagged, good 3 of 3",
        "members needed 3: catastrophic 1 of 2 flagged, good 2 of 3",
        "members split: catastrophic 2 of 2 flagged, good 2 of 3",
    ]
    assert members_rules({"a": [case(40.0, "far: ...")]}) == ""


def test_few_examples_pools_records_of_several_runs(tmp_path, capsys):
    """studies/few_examples.py --from: each scenario's records of several runs (seeds apart) added up,
    the pooled line counting them all; a file without a way asked for is refused by name."""
    fe = _study("few_examples.py")

    def rec(t: float) -> dict:
        return {"t_cm": t, "oracle_t_cm": 1.0, "flagged": t > 30, "flags": ["far: ..."] if t > 30 else []}

    one, two = tmp_path / "seed0.json", tmp_path / "seed1.json"
    one.write_text(json.dumps({"zoo-a": {"network": [rec(40)], "prior": [rec(1)]}}))
    two.write_text(json.dumps({"zoo-a": {"network": [rec(2)], "prior": [rec(50)]}}))
    per = fe["merged"]([one, two], ("network", "prior"))
    assert [r["t_cm"] for r in per["zoo-a"]["network"]] == [40, 2]
    fe["report"](per, ("network", "prior"))
    out = capsys.readouterr().out
    assert "network: median scenario t / oracle 21.00, catastrophic 1 of 2 (1 flagged)" in out
    assert "prior: median scenario t / oracle 25.50, catastrophic 1 of 2 (1 flagged)" in out
    with pytest.raises(SystemExit, match="seed0.json: zoo-a has no records of the way 'sum'"):
        fe["merged"]([one], ("network", "sum"))


def test_train_as_user_sets_what_train_said_beside_the_test(capsys):
    """studies/train_as_user.py: per scenario, the held-out loss and the cross-validated error beside the
    test's and what train said of the category; the held-out loss's caveat left out of the counts, the
    catastrophic placements flagged by a validation caveat alone counted apart."""
    tu = _study("train_as_user.py")
    loss = "validation: the model's held-out InfoNCE loss (4.0) was not below chance (2.8): ..."
    cat = "validation: mug: held-out error ..."

    def rec(t: float, *flags: str) -> dict:
        return {"t_cm": t, "oracle_t_cm": 1.0, "flags": [loss, *flags]}

    run = {"seed": 0, "category": "mug", "cv_t_cm": 3.0, "free": False}
    records = [rec(40, cat), rec(30, "far: ..."), rec(1, "energy: ..."), rec(2)]
    tu["report"]({"zoo-a": [{**run, "records": records}]})
    out = capsys.readouterr().out
    assert (
        "| zoo-a | mug | above chance | 3.00 | 18.25 | 40.0 | 18.25 | unlearned | 2 (2, 1) | 1 (1) of 2 |"
        in out
    )
    assert (
        "catastrophic 2 of 4 (2 flagged, 1 by a validation caveat alone), good flagged 1 of 2 (50.0%" in out
    )
    tu["report"]({"zoo-a": [{**run, "heldout_loss": 2.0, "chance_loss": 2.83, "records": records[2:]}]})
    assert "| zoo-a | mug | 2.00 (2.83) | 3.00 | 1.50 | 2.0 | 1.50 | - |" in capsys.readouterr().out


def test_few_examples_pools_each_scenarios_own_verdicts(capsys):
    """The pooled line adds up each scenario's verdicts, each against its own oracle: a 30 cm error is
    catastrophic beside a 1 cm oracle and good beside a 20 cm one, whatever the other scenario's."""
    fe = _study("few_examples.py")

    def rec(t: float, oracle: float) -> dict:
        return {"t_cm": t, "oracle_t_cm": oracle, "flagged": False, "flags": []}

    per = {"zoo-fine": {"network": [rec(30, 1.0), rec(1, 1.0)]}, "zoo-wide": {"network": [rec(30, 20.0)]}}
    fe["report"](per, ("network",))
    assert "catastrophic 1 of 3 (0 flagged), good flagged 0 of 2 (0.0%)" in capsys.readouterr().out


def test_few_examples_mirrors_every_footprint_where_the_reflection_puts_it():
    """studies/few_examples.py --mirror: each object's outline lands on the reflection of its outline
    (checked with shapely), twice is the scene itself, and a scene whose relations the others show
    mirrored fits them as well mirrored."""
    from shapely.geometry import Polygon

    import scenescore as ss

    fe = _study("few_examples.py")
    scene = ss.scenarios.get("zoo-bedroom").generate(1, 0)[0]
    scene.objects[0].shape = {"polygon": [[0.0, 0.0], [0.4, 0.0], [0.4, 0.1], [0.1, 0.3]]}  # chiral
    (x0, _), (x1, _) = scene.bounds
    once = fe["mirrored"](scene)
    for o, m in zip(scene.objects, once.objects, strict=True):
        want = Polygon([(x0 + x1 - x, y) for x, y in o.world_polygon()])
        assert Polygon(m.world_polygon()).symmetric_difference(want).area < 1e-9
    twice = fe["mirrored"](once)
    assert np.allclose(twice.poses(), scene.poses(), atol=1e-12)
    assert twice.objects[0].shape == scene.objects[0].shape
    # the workstation's arrangement has a side: mirrored, its scenes fit the others' relations worse;
    # beside their mirror images (which the others then show), better
    four = ss.scenarios.get("zoo-workstation").generate(4, 0)
    own, mirror = fe["mirror_fit"](four)
    assert mirror > own + 1.0
    own, mirror = fe["mirror_fit"](four + [fe["mirrored"](s) for s in four])
    assert mirror < own
