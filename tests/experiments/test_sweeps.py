"""Resumable experiment sweeps: `scenescore experiment` keeps each finished task's record under
OUT/tasks; the same command run again after an interruption computes only the rest and prints the same
table; --fresh computes every task; a damaged record is computed again with a warning naming it."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from scenescore.cli import main
from scenescore.evaluation.cases import MissingCase
from scenescore.experiments import missing, zoo
from scenescore.experiments import tidy as T
from scenescore.experiments.execution import Execution
from scenescore.experiments.tasks import Task
from scenescore.learn import TrainConfig
from scenescore.planning.tidying import TidyOptions
from scenescore.solvers.kernel import PLACEMENT
from scenescore.solvers.langevin import LangevinOptions

# six tasks (two methods, three seeds) that train nothing: a second or so in all
ARGS = ["experiment", "missing", "--seeds", "3", "--methods", "Nearest-Nbr,Oracle", "--jobs", "1", "--quiet"]


@pytest.fixture
def calls(monkeypatch):
    """The (seed, method) pairs fitted, in order; ``calls.fail_after = K`` interrupts the K+1-th task as
    Ctrl-C would."""
    real = missing.fit_predict

    class Calls(list):
        fail_after: int | None = None

    seen = Calls()

    def counted(factory, train, cases, seed, progress):
        if seen.fail_after is not None and len(seen) >= seen.fail_after:
            raise KeyboardInterrupt
        seen.append(seed)
        return real(factory, train, cases, seed, progress)

    monkeypatch.setattr(missing, "fit_predict", counted)
    return seen


def _rows(path):
    """results.json's rows without their seconds (the one figure a rerun need not repeat)."""
    rows = json.loads((path / "results.json").read_text())["experiments"][0]["rows"]
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


def test_an_interrupted_run_resumes_with_only_the_missing_tasks_and_the_same_table(tmp_path, calls, capsys):
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main(ARGS + ["--out", str(whole)]) == 0
    assert len(calls) == 6
    calls.clear()
    calls.fail_after = 3
    assert main(ARGS + ["--out", str(cut)]) == 130  # interrupted after three tasks
    assert len(list((cut / "tasks").glob("*.json"))) == 3 and not (cut / "table.md").exists()
    calls.clear()
    calls.fail_after = None
    capsys.readouterr()
    assert main(ARGS + ["--out", str(cut)]) == 0
    out = capsys.readouterr().out
    assert f"missing: reused 3 of 6 tasks ({cut / 'tasks'})" in out
    assert calls == [1, 2, 2]  # seed 1's second method, seed 2's two
    assert (cut / "table.md").read_text() == (whole / "table.md").read_text()
    assert _rows(cut) == _rows(whole)
    # the same figures as a run that keeps no records (the tasks change no random stream)
    quiet = Execution(progress=False, log=lambda s: None)
    plain = missing.run(seeds=3, methods=["Nearest-Nbr", "Oracle"], execution=quiet)
    assert missing.format_missing(plain) in (whole / "table.md").read_text()


def test_fresh_computes_every_task_again(tmp_path, calls, capsys):
    assert main(ARGS + ["--out", str(tmp_path)]) == 0
    calls.clear()
    assert main(ARGS + ["--out", str(tmp_path), "--fresh"]) == 0
    assert len(calls) == 6 and "6 tasks, every one computed afresh (--fresh)" in capsys.readouterr().out
    calls.clear()
    assert main(ARGS + ["--out", str(tmp_path)]) == 0
    assert calls == []


def test_a_damaged_record_is_computed_again_with_a_warning_naming_it(tmp_path, calls, capsys):
    assert main(ARGS + ["--out", str(tmp_path)]) == 0
    records = sorted((tmp_path / "tasks").glob("*.json"))
    records[0].write_text(records[0].read_text()[:40])
    records[1].write_text(records[1].read_text().replace('"seed": ', '"seed": 1'))  # another task's spec
    calls.clear()
    capsys.readouterr()
    assert main(ARGS + ["--out", str(tmp_path)]) == 0
    got = capsys.readouterr()
    assert len(calls) == 2 and "reused 4 of 6 tasks" in got.out
    for path in records[:2]:
        assert f"warning: {path}:" in got.err
    assert "Traceback" not in got.err


def test_a_record_names_whether_its_seeds_networks_compile_together(tmp_path, calls, capsys, monkeypatch):
    from scenescore.learn import config

    monkeypatch.setattr(config, "compiler_available", lambda device_type: True)
    assert main(ARGS + ["--out", str(tmp_path)]) == 0  # three seeds' dining networks: compiled
    calls.clear()
    one_seed = [a if a != "3" else "1" for a in ARGS]
    assert main(one_seed + ["--out", str(tmp_path)]) == 0  # one network alone: eager, another record
    assert calls == [0, 0] and "reused 0 of 2 tasks" in capsys.readouterr().out
    monkeypatch.setattr(config, "compiler_available", lambda device_type: False)
    calls.clear()
    assert main(ARGS + ["--out", str(tmp_path)]) == 0  # no compiler: eager whatever the seeds
    assert calls == [1, 1, 2, 2] and "reused 2 of 6 tasks" in capsys.readouterr().out


def test_records_of_other_settings_are_not_reused(tmp_path, calls, capsys):
    assert main(ARGS + ["--out", str(tmp_path)]) == 0
    calls.clear()
    assert main(ARGS + ["--out", str(tmp_path), "--quick"]) == 0  # another config: every task again
    assert len(calls) == 6 and "reused 0 of 6 tasks" in capsys.readouterr().out


TINY = LangevinOptions(particles=2, candidates=4, chain=replace(PLACEMENT, steps=2, final_descent=1))


def _json(value):
    return json.loads(json.dumps(value))


def test_tidy_and_zoo_records_come_back_from_json_whole():
    """The two records that hold scenes: a scenario and seed's tidying run, a zoo pair's cases and worst
    placement; read back from their JSON they equal what was computed."""
    part = T.run_scenario(
        Task.of("tidy", scenario="desk", seed=0),
        efforts=(1.0,),
        test_scenes=1,
        config=TrainConfig(members=1, iterations=2, batch_scenes=4),
        sizes=(0.4,),
        options=TidyOptions(propose=TINY, refine_options={"max_iter": 2}),
        place_options=TINY,
        execution=Execution(progress=False, device=None, log=lambda s: None),
    )
    back = T.TidyRun.from_dict(_json(part.to_dict()))
    assert back.cases == part.cases and back.outcomes == part.outcomes and back.seconds == part.seconds
    assert T.format_tidy(back) == T.format_tidy(part)
    one = zoo.run_one("zoo-hall", 0, TrainConfig(members=1, iterations=3, batch_scenes=4, negatives=2))
    again = zoo.PAIR_RECORD.decode(_json(zoo.PAIR_RECORD.encode(one)))
    assert again["cases"] == one["cases"] and again["seconds"] == one["seconds"]
    assert again["worst"] == one["worst"] and isinstance(again["worst"][0], MissingCase)
