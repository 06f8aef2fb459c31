"""Validation errors print in the unit the data names (metres as cm, millimetres as mm), and in the
data's own unit, said so, when it names none; ``scenescore generate`` names metres."""

from __future__ import annotations

from dataclasses import replace

import pytest

import scenescore as ss
from scenescore.cli import main
from scenescore.evaluation.report import CategoryErrors, EvalReport
from scenescore.learn import NetworkConfig, TrainConfig
from scenescore.scenarios import get
from scenescore.scene.units import declared_unit
from scenescore.workflow import Outputs, Validation

TINY = TrainConfig(
    members=1, iterations=2, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=8, layers=1)
)


def _table(t_cm: float, nn_cm: float, unit: str | None) -> list[str]:
    monitor = CategoryErrors("computer monitor", 4, t_cm, 3.0, baseline_t_cm=nn_cm, baseline_R_deg=9.0)
    rep = EvalReport([monitor], scenes=2, placements=4, mean_t_cm=t_cm, mean_R_deg=3.0, heldout_loss=1.0,
                     chance_loss=2.8, seed=0, baseline="Nearest-Nbr", unit=unit)  # fmt: skip
    return rep.table().splitlines()


def test_the_table_prints_in_the_unit_the_data_names():
    # a 30.24 mm error is stored as 3024 "cm" (100 times the data's length): printed as 30.24 mm
    mm = _table(3024.01, 4400.0, "mm")  # rows: ... t, R, NN t, NN R
    assert "t (mm)" in mm[0] and mm[1].split()[-4:] == ["30.24", "3.00", "44.00", "9.00"]
    m = _table(3.02, 4.4, "m")  # metres print as centimetres, as they always have
    assert "t (cm)" in m[0] and m[1].split()[-4:] == ["3.02", "3.00", "4.40", "9.00"]
    assert m[2].split()[-2:] == ["3.02", "3.00"] and not any("own length unit" in line for line in m)
    assert _table(302.4, 440.0, "cm")[1].split()[-4] == "3.02"  # centimetre data: cm
    # naming no unit: the data's own, three significant digits at the mean, and a line that says so
    own = _table(3.02, 4.4, None)
    assert "t (units)" in own[0] and own[1].split()[-4:] == ["0.0302", "3.00", "0.0440", "9.00"]
    assert any(line.startswith("t: in the data's own length unit") for line in own)
    assert _table(3024.01, 4400.0, None)[1].split()[-4] == "30.24"


def test_the_unit_is_read_from_the_scenes_meta():
    scenes = get("dining").generate(3, seed=0)
    assert declared_unit(scenes) is None
    named = [replace(s, meta={"unit": "mm"}) for s in scenes]
    assert declared_unit(named) == "mm" and declared_unit([*scenes, named[0]]) == "mm"
    with pytest.raises(ss.SceneError, match=r"^scene 1: key 'meta.unit': 'cm', but scene 0 names 'mm'"):
        declared_unit([named[0], replace(scenes[1], meta={"unit": "cm"})])
    with pytest.raises(ss.SceneError, match=r"^scene 0: key 'meta.unit': expected one of"):
        declared_unit([replace(scenes[0], meta={"unit": "millimetres"})])


def test_generate_names_metres(tmp_path):
    out = tmp_path / "d.jsonl"
    assert main(["generate", "dining", "--n", "2", "--out", str(out), "--quiet"]) == 0
    assert declared_unit(ss.read_jsonl(out)) == "m"


def _validation_rows(k: float, unit: str) -> tuple[str, dict[str, list[float]]]:
    """Train briefly on dining scenes times ``k`` named in ``unit``: the table's header and, per
    category, its printed t and NN t."""
    sc = get("dining")
    train = [replace(s.scaled(k), meta={"unit": unit}) for s in sc.generate(6, 0)]
    held = [replace(s.scaled(k), meta={"unit": unit}) for s in sc.generate(2, 1)]
    lines: list[str] = []
    ss.train(
        train,
        TINY,
        seed=0,
        force=True,
        progress=False,
        validation=Validation(heldout=held),
        outputs=Outputs(log=lines.append),
    )
    said = next(x for x in lines if "leave-one-object-out" in x).strip().splitlines()
    table = said[1:]  # the header, then a row per category
    cats = {"plate", "fork", "knife", "bowl"}
    rows = {r.split()[0]: [float(r.split()[2]), float(r.split()[4])] for r in table if r.split()[0] in cats}
    return table[0], rows


@pytest.mark.slow
def test_millimetre_data_prints_millimetres(capsys):
    """The same draws in metres and times 1024 named millimetres (a power of two, so the model and its
    placements scale exactly: tests/test_scale.py): the table reads cm, then mm ten times larger
    (1.024 m per 1000 mm); the warnings say the same unit."""
    head_m, cm = _validation_rows(1.0, "m")
    head_mm, mm = _validation_rows(1024.0, "mm")
    assert "t (cm)" in head_m and "t (mm)" in head_mm and set(cm) == set(mm) and len(cm) == 4
    for cat in cm:
        for a, b in zip(cm[cat], mm[cat]):
            assert b == pytest.approx(10.24 * a, abs=0.06), cat  # printed to 0.01 cm and 0.01 mm
    err = capsys.readouterr().err
    assert " mm, no better than nearest neighbour's " in err and "cm, no better" in err
