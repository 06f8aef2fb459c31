"""Sweeps through submitit: `--executor submitit-local` runs the SLURM path (pickling, submission, logs,
gathering) in processes of this machine and prints the table `--executor local` prints; a task that fails
in its job is reported with its spec, its error and its log once the others are done, their records kept;
the options are checked before any work."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from scenescore.cli import main
from scenescore.experiments.cluster import SlurmConfig, SubmititExecutor, TasksFailed
from scenescore.experiments.tasks import Sweep, Task, run_tasks

pytest.importorskip("submitit")

# six tasks (two methods, three seeds) that train nothing
ARGS = ["experiment", "missing", "--seeds", "3", "--methods", "Nearest-Nbr,Oracle", "--jobs", "2", "--quiet"]


def _rows(path: Path) -> list[dict]:
    rows = json.loads((path / "results.json").read_text())["experiments"][0]["rows"]
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


def _table(path: Path) -> list[str]:
    """table.md without the seconds column's figures (the one figure two runs need not repeat)."""
    return [
        line.rsplit("|", 2)[0] if line.startswith("|") else line
        for line in (path / "table.md").read_text().splitlines()
    ]


@pytest.mark.slow
def test_submitit_local_prints_the_table_of_the_local_workers(tmp_path, capsys):
    local, jobs = tmp_path / "local", tmp_path / "jobs"
    assert main(ARGS + ["--out", str(local)]) == 0
    assert main(ARGS + ["--out", str(jobs), "--executor", "submitit-local", "--slurm-time", "10"]) == 0
    assert _table(jobs) == _table(local) and _rows(jobs) == _rows(local)
    assert len(list((jobs / "tasks").glob("*.json"))) == 6  # each record kept as with the local workers
    assert len(list((jobs / "slurm").glob("*_log.out"))) == 6  # one job per task, its log kept
    capsys.readouterr()
    assert (
        main(ARGS + ["--out", str(jobs), "--executor", "submitit-local"]) == 0
    )  # resumes: nothing submitted
    assert "missing: reused 6 of 6 tasks" in capsys.readouterr().out
    assert len(list((jobs / "slurm").glob("*_log.out"))) == 6


def _square(task: Task, log) -> int:
    log(f"task {task.seed}")
    if task.seed == 2:
        raise ValueError("seed two is refused")
    return task.seed**2


@pytest.mark.slow
def test_a_failed_task_is_named_with_its_log_and_the_others_are_kept(tmp_path):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # a job cannot import this test module
    sweep = Sweep(
        tmp_path / "tasks", executor=SubmititExecutor(SlurmConfig(tmp_path / "slurm", cluster="local"))
    )
    tasks = [Task.of("toy", seed=s) for s in range(4)]
    lines: list[str] = []
    with pytest.raises(TasksFailed) as err:
        run_tasks(_square, tasks, jobs=2, log=lines.append, sweep=sweep)
    message = str(err.value)
    assert (
        message.startswith("1 of 4 tasks failed")
        and "toy task (seed 2): ValueError: seed two is refused" in message
    )
    log = Path(message.split("(log: ")[1].rstrip(")"))
    assert log.is_file() and log.parent == tmp_path / "slurm" and "seed two is refused" in log.read_text()
    assert sorted(lines)[:3] == ["task 0", "task 1", "task 3"]  # the finished tasks' logs, printed here
    assert len(list((tmp_path / "tasks").glob("*.json"))) == 3
    lines.clear()  # the same sweep again: only the failed task runs
    with pytest.raises(TasksFailed, match="1 of 1 tasks failed"):
        run_tasks(_square, tasks, jobs=2, log=lines.append, sweep=sweep)
    assert lines == ["toy: reused 3 of 4 tasks (" + str(tmp_path / "tasks") + ")"]


def test_named_options_become_submitit_parameters():
    config = SlurmConfig(
        Path("f"),
        partition="gpu",
        time_min=30,
        gpus=1,
        cpus=4,
        extra={"slurm_mem": "8GB", "slurm_array_parallelism": 8},
    )
    assert config.parameters() == {
        "timeout_min": 30,
        "gpus_per_node": 1,
        "cpus_per_task": 4,
        "slurm_partition": "gpu",
        "slurm_mem": "8GB",
        "slurm_array_parallelism": 8,
    }
    with pytest.raises(ValueError, match="own options"):
        SlurmConfig(Path("f"), extra={"timeout_min": 5})
    with pytest.raises(ValueError, match="cluster"):
        SlurmConfig(Path("f"), cluster="pbs")
    with pytest.raises(ValueError, match="time_min"):
        SlurmConfig(Path("f"), time_min=0)


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--slurm-time", "5"], ["--slurm-time", "--executor slurm or submitit-local"]),
        (["--executor", "submitit-local", "--slurm-set", "nonsense"], ["KEY=VALUE"]),
        (["--executor", "submitit-local", "--slurm-set", "timeout_min=5"], ["own options"]),
        (["--executor", "submitit-local", "--slurm-set", "no_such_parameter=1"], ["no_such_parameter"]),
    ],
)
def test_bad_cluster_options_get_one_line_before_any_work(tmp_path, capsys, extra, words):
    try:
        code = main(ARGS + ["--out", str(tmp_path / "o")] + extra)
    except SystemExit as e:  # argparse's refusal of a malformed value
        code = e.code
    err = capsys.readouterr().err
    assert code != 0 and "Traceback" not in err and all(w in err for w in words), err
    assert not (tmp_path / "o" / "tasks").exists() or not list((tmp_path / "o" / "tasks").iterdir())


@pytest.mark.skipif(shutil.which("sbatch") is not None, reason="this machine has SLURM")
def test_slurm_without_sbatch_says_where_to_submit_from(tmp_path, capsys):
    assert main(ARGS + ["--out", str(tmp_path / "o"), "--executor", "slurm"]) != 0
    err = capsys.readouterr().err
    assert (
        "sbatch is not on this machine's PATH" in err and "submitit-local" in err and "Traceback" not in err
    )
