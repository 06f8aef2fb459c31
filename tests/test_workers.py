"""Worker processes die with their run: on an error in the parent, and when the parent is killed."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from scenescore.runtime.workers import worker_pool


def _pid(_: int) -> int:
    return os.getpid()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by its parent) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


def _wait_gone(pids: list[int], timeout: float) -> list[int]:
    end = time.monotonic() + timeout
    while time.monotonic() < end and any(map(_alive, pids)):
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def test_a_pool_runs_tasks_in_other_processes():
    with worker_pool(2) as pool:
        pids = set(pool.map(_pid, range(8)))
    assert pids and os.getpid() not in pids


def test_an_error_in_the_parent_terminates_the_workers():
    with pytest.raises(RuntimeError, match="stop"):
        with worker_pool(2) as pool:
            pids = list(set(pool.map(_pid, range(8))))
            pool.submit(time.sleep, 60)
            raise RuntimeError("stop")
    assert _wait_gone(pids, 5.0) == []


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc and sends signals")
def test_workers_exit_when_their_parent_is_killed_outright(tmp_path):
    """``kill -9`` on the run: no cleanup runs in it, and its workers notice and exit by themselves."""
    code = textwrap.dedent(
        """
        import os, sys, time
        from scenescore.runtime.workers import worker_pool
        def pid(_):
            return os.getpid()
        if __name__ == "__main__":
            with worker_pool(2) as pool:
                pids = sorted(set(pool.map(pid, range(8))))
                pool.submit(time.sleep, 60)
                print(*pids, flush=True)
                time.sleep(60)
        """
    )
    script = tmp_path / "run.py"  # a file: spawned workers import the parent's main module from it
    script.write_text(code)
    run = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        assert run.stdout is not None
        pids = [int(p) for p in run.stdout.readline().split()]
        assert pids and all(map(_alive, pids))
        os.kill(run.pid, signal.SIGKILL)
        run.wait(10)
        assert _wait_gone(pids, 10.0) == []
    finally:
        run.kill()


def test_default_jobs_is_one_per_usable_core_on_the_cpu(monkeypatch):
    import torch

    from scenescore.runtime import cores
    from scenescore.runtime.workers import default_jobs

    monkeypatch.setattr(cores, "_cpus", lambda: [0, 3, 5])  # the affinity, not the machine's count
    assert cores.usable_cores() == 3
    assert default_jobs() == 3 and default_jobs(torch.device("cpu")) == 3
    assert default_jobs(torch.device("mps")) == 1


@pytest.mark.parametrize(
    "tasks, cores, jobs",
    [(1, 2, 1), (2, 2, 2), (3, 2, 3), (4, 2, 2), (5, 2, 2), (9, 2, 3), (3, 1, 1), (6, 4, 6), (8, 4, 4)],
)
def test_balanced_jobs_leave_no_core_idle_in_a_last_round(tasks, cores, jobs):
    from scenescore.runtime.workers import balanced_jobs

    assert balanced_jobs(tasks, cores) == jobs
    assert balanced_jobs([7.0] * tasks, cores) == jobs  # the unit of a length does not matter


def test_balanced_jobs_count_the_long_tasks_where_lengths_are_given():
    from scenescore.runtime.workers import SOONER, _ends, balanced_jobs

    trainings = [1.0] * 9 + [0.0] * 18  # Table 2: nine trainings among tasks of seconds
    assert balanced_jobs(27, 2, SOONER) == 2  # taken as equal, three processes gain too little
    assert balanced_jobs(trainings, 2, SOONER) == 3  # 4.5 trainings' time against two processes' 5
    assert _ends(sorted(trainings, reverse=True), 3, 2) == pytest.approx(4.5)
    assert _ends(sorted(trainings, reverse=True), 2, 2) == pytest.approx(5.0)
    assert balanced_jobs([3.0, 1.0, 1.0, 1.0], 2) == 2  # the long one on a core, the others on the other
    assert balanced_jobs([0.0, 0.0, 0.0], 2) == 2  # nothing to gain: one per core
    with pytest.raises(ValueError, match="length >= 0"):
        balanced_jobs([1.0, -1.0], 2)


def test_items_are_handed_out_longest_first_and_come_back_in_order(monkeypatch):
    from scenescore.runtime import workers

    assert workers.longest_first([0.0, 1.0, 0.5, 1.0], 4) == [1, 3, 2, 0]  # ties keep their order
    assert workers.longest_first(None, 3) == [0, 1, 2]
    with pytest.raises(ValueError, match="2 lengths for 3 items"):
        workers.longest_first([1.0, 2.0], 3)
    submitted: list[int] = []

    class Pool:  # runs each task as it is submitted, noting the order
        def submit(self, fn, task):
            from concurrent.futures import Future

            submitted.append(task[1])
            future: Future = Future()
            future.set_result(workers._one(task))
            return future

    monkeypatch.setattr(workers, "worker_pool", lambda jobs: contextlib.nullcontext(Pool()))
    finished: list[int] = []
    got = workers.map_balanced(
        _square,
        [1, 2, 3, 4],
        jobs=2,
        log=lambda s: None,
        done=lambda k, v: finished.append(k),
        lengths=[0.0, 5.0, 0.0, 1.0],
    )
    assert got == [1, 4, 9, 16] and submitted == [1, 3, 0, 2] and sorted(finished) == [0, 1, 2, 3]


def test_trainings_share_the_cores_where_they_end_sooner(monkeypatch):
    import torch

    from scenescore.learn.members import training_jobs
    from scenescore.runtime import cores

    monkeypatch.setattr(cores, "_cpus", lambda: [0, 1])
    cpu = torch.device("cpu")
    assert training_jobs(None, 3, cpu) == 3  # three members on two cores side by side
    assert training_jobs(None, 4, cpu) == 2
    assert training_jobs(2, 3, cpu) == 2  # as many as asked for
    assert training_jobs(5, 3, cpu) == 3


@pytest.mark.parametrize("free_gib, jobs", [(100, 3), (4.5, 2), (1, 1)])
def test_default_jobs_share_a_cuda_device_as_its_free_memory_allows(monkeypatch, free_gib, jobs):
    import torch

    from scenescore.runtime import cores
    from scenescore.runtime.workers import default_jobs

    monkeypatch.setattr(cores, "_cpus", lambda: [0, 3, 5])
    monkeypatch.setattr(
        torch.cuda, "mem_get_info", lambda device=None: (int(free_gib * 1024**3), 80 * 1024**3)
    )
    assert default_jobs(torch.device("cuda", 0)) == jobs  # at most one per usable core, 2 GiB each


def test_experiment_jobs_default_to_the_cores_and_say_so(monkeypatch, capsys, tmp_path):
    from scenescore.cli import experiment, main
    from scenescore.cli.experiment_runs import _sweep
    from scenescore.runtime import workers

    jobs, executors = [], []

    def runner(args, out):
        jobs.append(args.jobs)
        executors.append(_sweep(args, out).executor)
        return "## experiment", []

    monkeypatch.setattr(workers, "default_jobs", lambda device=None: 2)
    monkeypatch.setattr(experiment, "RUNNERS", {**experiment.RUNNERS, "missing": runner, "heatmap": runner})
    assert main(["experiment", "missing", "--out", str(tmp_path / "m")]) == 0
    assert "experiment: worker processes on 2 cores, one per core, or up to two" in capsys.readouterr().out
    assert main(["experiment", "missing", "--jobs", "1", "--out", str(tmp_path / "m")]) == 0
    assert jobs == [2, 1] and "worker processes" not in capsys.readouterr().out
    assert main(["experiment", "heatmap", "--out", str(tmp_path / "h")]) == 0  # its seeds in workers too
    assert jobs == [2, 1, 2] and "experiment: worker processes on 2 cores" in capsys.readouterr().out
    # by default the cores bound the processes, balanced to the tasks; --jobs names the processes
    assert executors == [workers.map_balanced, workers.map_in_workers, workers.map_balanced]
    assert main(["experiment", "heatmap", "--jobs", "2", "--out", str(tmp_path / "h")]) == 0
    assert executors[-1] is workers.map_in_workers


def test_equal_tasks_share_the_cores_where_they_end_sooner(monkeypatch):
    from scenescore.runtime import workers

    got = []
    real = workers.map_in_workers

    def counted(fn, items, jobs=1, log=print, bar=None, done=None, lengths=None):
        got.append(jobs)
        return real(fn, items, jobs, log, bar, done, lengths)

    monkeypatch.setattr(workers, "map_in_workers", counted)
    lines: list[str] = []
    assert workers.map_balanced(_square, [3, 1, 2], jobs=2, log=lines.append) == [9, 1, 4]
    assert got == [3] and "3 worker processes for 3 tasks on 2 cores" in lines  # not two, then one alone
    lines.clear()
    assert workers.map_balanced(_square, [1, 2, 3, 4], jobs=2, log=lines.append) == [1, 4, 9, 16]
    assert got == [3, 2] and not [line for line in lines if "worker processes" in line]
    assert workers.map_balanced(_square, [5], jobs=1, log=lines.append) == [25] and got[-1] == 1
    # 27 tasks: three processes would end them in 13.5 rounds against two's 14, a gain that tasks of
    # unequal length lose
    assert workers.map_balanced(_square, list(range(27)), jobs=2, log=lines.append)[-1] == 26**2
    assert got[-1] == 2


def test_experiment_all_shares_one_model_folder_that_lives_as_long_as_the_run_or_the_one_given(
    monkeypatch, tmp_path
):
    import os

    from scenescore.cli import experiment, main

    seen = []

    def runner(name):
        def run(args, out):
            seen.append((name, None if args.model_cache is None else str(args.model_cache)))
            return f"## {name}", []

        return run

    monkeypatch.setattr(experiment, "RUNNERS", {n: runner(n) for n in experiment.EXPERIMENTS})
    assert main(["experiment", "all", "--jobs", "1", "--out", str(tmp_path / "all")]) == 0
    folders = {f for _, f in seen}
    assert [n for n, _ in seen] == experiment.EXPERIMENTS and len(folders) == 1
    (folder,) = folders
    assert folder is not None and folder.startswith(str(tmp_path / "all"))
    assert not os.path.exists(folder)  # gone with the run
    assert (tmp_path / "all" / "report.md").exists()
    seen.clear()
    assert main(["experiment", "missing", "--jobs", "1", "--out", str(tmp_path / "m")]) == 0
    assert seen == [("missing", None)]  # one experiment alone keeps no models
    seen.clear()
    kept = tmp_path / "models"
    assert (
        main(
            ["experiment", "missing", "--jobs", "1", "--model-cache", str(kept), "--out", str(tmp_path / "m")]
        )
        == 0
    )
    assert seen == [("missing", str(kept))]
    seen.clear()
    assert (
        main(["experiment", "all", "--jobs", "1", "--model-cache", str(kept), "--out", str(tmp_path / "all")])
        == 0
    )
    assert seen == [(n, str(kept)) for n in experiment.EXPERIMENTS]  # the folder given, for every experiment


def _square(x: int, log) -> int:
    log(f"item {x}")
    return x * x


def test_map_in_workers_with_a_bar_keeps_results_in_order_and_every_log_line(capsys):
    from scenescore.runtime.workers import map_in_workers

    lines: list[str] = []
    assert map_in_workers(_square, [3, 1, 2], jobs=2, log=lines.append, bar="squares") == [9, 1, 4]
    assert sorted(lines) == ["item 1", "item 2", "item 3"]
    assert "squares" not in capsys.readouterr().err  # not a terminal: no bar drawn


def _die_on_one(x: int, log) -> int:
    if x == 1:
        os.kill(os.getpid(), signal.SIGKILL)  # as the system's out-of-memory killer would
    time.sleep(0.2)
    return x


@pytest.mark.skipif(sys.platform != "linux", reason="sends signals")
def test_a_worker_killed_in_its_task_ends_the_run_with_a_clear_error():
    """A worker that dies without an error of its own (SIGKILL) raises WorkerDied at once: the run
    neither waits for the lost task forever nor leaves the other workers running."""
    from scenescore.runtime.workers import WorkerDied, map_in_workers

    t0 = time.monotonic()
    with pytest.raises(WorkerDied, match="fewer worker processes"):
        map_in_workers(_die_on_one, [0, 1, 2, 3], jobs=2, log=lambda line: None)
    assert time.monotonic() - t0 < 30
