"""Tasks and sweeps: each finished task's record kept as JSON under the sweep's folder, reused by the same
sweep run again (same spec, same code), ignored when damaged (a warning names the file) or ``fresh``."""

from __future__ import annotations

import json
import pickle

import pytest

from scenescore.experiments.tasks import Codec, Sweep, Task, run_tasks
from scenescore.runtime.provenance import code_version


def _square(task: Task, log=print) -> dict:
    """A record of numbers, strings and lists: what most experiments' tasks return."""
    k = task.seed
    log(f"seed {k}")
    return {"square": k * k, "half": k / 3, "tags": (task.method, k)}


class _Counted:
    """``_square`` that counts its calls and raises after ``fail_after`` of them (an interruption)."""

    def __init__(self, fail_after: int | None = None) -> None:
        self.calls: list[int] = []
        self.fail_after = fail_after

    def __call__(self, task: Task, log=print) -> dict:
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise KeyboardInterrupt
        self.calls.append(task.seed)
        return _square(task, log)


def _tasks(n: int = 5, **config) -> list[Task]:
    return [Task.of("demo", method="m", seed=k, config={"size": 2, **config}) for k in range(n)]


def test_a_task_is_a_small_hashable_picklable_spec_with_canonical_config():
    a = Task.of("demo", method="m", seed=1, scenario="s", config={"b": 1, "a": (1, 2)})
    b = Task.of("demo", method="m", seed=1, scenario="s", config={"a": [1, 2], "b": 1})
    assert a == b and hash(a) == hash(b) and pickle.loads(pickle.dumps(a)) == a
    assert a.config == '{"a":[1,2],"b":1}'
    assert a.key("v1") == b.key("v1") != a.key("v2")
    assert a.key("v1") != Task.of("demo", method="m", seed=2, scenario="s", config={"b": 1}).key("v1")
    with pytest.raises(TypeError, match="object is not JSON"):
        Task.of("demo", config={"f": object()})
    assert "scenescore" in code_version() and "source" in code_version()


def test_interrupted_sweep_reruns_only_the_missing_tasks_and_gives_the_same_records(tmp_path):
    tasks = _tasks()
    whole = run_tasks(_square, tasks, log=lambda s: None)
    first = _Counted(fail_after=2)
    with pytest.raises(KeyboardInterrupt):
        run_tasks(first, tasks, log=lambda s: None, sweep=Sweep(tmp_path))
    assert first.calls == [0, 1] and len(list(tmp_path.glob("*.json"))) == 2
    again, lines = _Counted(), []
    got = run_tasks(again, tasks, log=lines.append, sweep=Sweep(tmp_path))
    assert again.calls == [2, 3, 4]
    assert lines[0] == f"demo: reused 2 of 5 tasks ({tmp_path})"
    # records come back as JSON made them (tuples as lists), computed now or reused alike
    assert got == [{**r, "tags": list(r["tags"])} for r in whole]
    third = _Counted()
    assert run_tasks(third, tasks, log=lambda s: None, sweep=Sweep(tmp_path)) == got and third.calls == []


def test_fresh_recomputes_every_task_and_writes_it_again(tmp_path):
    tasks = _tasks(3)
    run_tasks(_square, tasks, log=lambda s: None, sweep=Sweep(tmp_path))
    again, lines = _Counted(), []
    run_tasks(again, tasks, log=lines.append, sweep=Sweep(tmp_path, fresh=True))
    assert again.calls == [0, 1, 2] and "every one computed afresh" in lines[0]
    assert len(list(tmp_path.glob("*.json"))) == 3


def test_a_record_of_another_spec_or_code_version_is_not_reused(tmp_path):
    run_tasks(_square, _tasks(3), log=lambda s: None, sweep=Sweep(tmp_path, code="v1"))
    other_code = _Counted()
    run_tasks(other_code, _tasks(3), log=lambda s: None, sweep=Sweep(tmp_path, code="v2"))
    assert other_code.calls == [0, 1, 2]
    other_spec = _Counted()
    run_tasks(other_spec, _tasks(3, size=3), log=lambda s: None, sweep=Sweep(tmp_path, code="v1"))
    assert other_spec.calls == [0, 1, 2]
    same = _Counted()
    run_tasks(same, _tasks(3), log=lambda s: None, sweep=Sweep(tmp_path, code="v1"))
    assert same.calls == []


@pytest.mark.parametrize(
    "damage",
    [
        lambda text: text[: len(text) // 2],  # cut short
        lambda text: "\udcff not utf-8",
        lambda text: "[1, 2]",  # JSON, not a record
        lambda text: text.replace('"seed": 1', '"seed": 4'),  # another task's spec under this name
        lambda text: text.replace('"square": 1', '"squared": 1'),  # a record the codec cannot read
    ],
)
def test_a_damaged_record_is_recomputed_with_a_warning_naming_it(tmp_path, capsys, damage):
    sweep = Sweep(tmp_path, code="v1")
    codec = Codec(decode=lambda r: {"square": r["square"], "half": r["half"], "tags": r["tags"]})
    tasks = _tasks(3)
    want = run_tasks(_square, tasks, log=lambda s: None, sweep=sweep, codec=codec)
    path = sweep.path(tasks[1])
    text = path.read_text()
    bad = damage(text)
    path.write_bytes(bad.encode("utf-8", "surrogateescape"))
    again = _Counted()
    assert run_tasks(again, tasks, log=lambda s: None, sweep=sweep, codec=codec) == want
    assert again.calls == [1]
    err = capsys.readouterr().err
    assert f"warning: {path}:" in err and "computed again" in err and "Traceback" not in err
    assert json.loads(path.read_text())["task"]["seed"] == 1  # written whole again


def test_records_are_written_as_each_task_finishes_in_worker_processes(tmp_path):
    tasks = _tasks(3)
    written: list[int] = []

    def local(fn, items, jobs, log, bar, done):  # the executor seam: what runs the tasks
        from scenescore.runtime.workers import map_in_workers

        def keep(k, value):
            done(k, value)
            written.append(len(list(tmp_path.glob("*.json"))))

        return map_in_workers(fn, items, jobs, log, bar, done=keep)

    got = run_tasks(_square, tasks, jobs=2, log=lambda s: None, sweep=Sweep(tmp_path, executor=local))
    assert sorted(written) == [1, 2, 3]
    assert [r["square"] for r in got] == [0, 1, 4]
    assert run_tasks(_Counted(fail_after=0), tasks, log=lambda s: None, sweep=Sweep(tmp_path)) == got


def test_an_executor_is_told_the_lengths_only_where_the_tasks_have_them(tmp_path):
    told: list[object] = []

    def local(fn, items, jobs, log, bar, done, **lengths):
        told.append(lengths.get("lengths"))
        for k, item in enumerate(items):
            done(k, fn(item, log=log))

    tasks = _tasks(3)
    assert [r["square"] for r in run_tasks(_square, tasks, sweep=Sweep(executor=local))] == [0, 1, 4]
    got = run_tasks(_square, tasks, sweep=Sweep(executor=local), length=lambda t: float(t.seed % 2))
    assert [r["square"] for r in got] == [0, 1, 4] and told == [None, [0.0, 1.0, 0.0]]


def test_a_record_json_cannot_keep_exactly_is_refused_by_name(tmp_path):
    import numpy as np

    def f32(task: Task, log=print) -> dict:
        return {"x": np.float32(0.1)}

    with pytest.raises(TypeError, match="float32"):
        run_tasks(f32, _tasks(1), log=lambda s: None, sweep=Sweep(tmp_path))
