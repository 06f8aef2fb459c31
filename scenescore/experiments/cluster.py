"""An experiment's tasks run as jobs of a SLURM cluster through submitit, or as submitit's local jobs.

:class:`SubmititExecutor` is an executor of :class:`~scenescore.experiments.tasks.Sweep` (the signature of
:func:`~scenescore.runtime.workers.map_in_workers`): it submits each task as a job (on SLURM, one job array),
gathers the records as the jobs finish and hands each to the sweep, which keeps it under the run's
folder at once. A task that fails is reported with its spec and its log once the others are done; their
records are kept, so the same command run again computes only the failed ones. ``cluster="local"`` runs
the same path (pickling, submission, logs, gathering) in processes of this machine, at most ``jobs`` at
a time: a sweep can be tried here before it goes to the cluster, and CI tests the path without one.
Nothing here writes a batch script: submitit does.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["SlurmConfig", "SubmititExecutor", "TasksFailed", "CLUSTERS"]

CLUSTERS = ("slurm", "local")  # submitit's names: a SLURM cluster, or processes of this machine
# the parameters the named options set; the rest go through ``extra`` (submitit's own names)
_NAMED = ("slurm_partition", "timeout_min", "gpus_per_node", "cpus_per_task")

Log = Callable[[str], None]


class TasksFailed(RuntimeError):
    """Some tasks of a sweep failed: each named by its spec, with the reason and the job's log file."""


@dataclass
class SlurmConfig:
    """Where and how the jobs run. ``folder``: submitit's folder (pickled tasks, each job's logs);
    ``cluster``: ``"slurm"`` or ``"local"``; ``partition``: the SLURM partition (None: the cluster's
    default); ``time_min``: each job's time limit in minutes; ``gpus``: GPUs per job; ``cpus``: CPU
    cores per job, which is also the torch thread count a task runs on; ``extra``: any other submitit
    parameter by its name (``slurm_mem``, ``slurm_account``, ``slurm_array_parallelism``,
    ``slurm_additional_parameters``, ...); ``poll_s``: how often finished jobs are looked for."""

    folder: Path
    cluster: str = "slurm"
    partition: str | None = None
    time_min: int = 240
    gpus: int = 0
    cpus: int = 1
    extra: Mapping[str, Any] = field(default_factory=dict)
    poll_s: float | None = None

    def __post_init__(self) -> None:
        if self.cluster not in CLUSTERS:
            raise ValueError(f"cluster: expected one of {CLUSTERS}, got {self.cluster!r}")
        for name, value, lo in (
            ("time_min", self.time_min, 1),
            ("gpus", self.gpus, 0),
            ("cpus", self.cpus, 1),
        ):
            if not isinstance(value, int) or isinstance(value, bool) or value < lo:
                raise ValueError(f"{name}: expected an integer >= {lo}, got {value!r}")
        named = sorted(set(self.extra) & set(_NAMED))
        if named:
            raise ValueError(f"extra parameters {named} have their own options (partition, time, gpus, cpus)")

    def parameters(self) -> dict[str, Any]:
        """The submitit parameters of every job (``slurm_`` ones are ignored by the local cluster)."""
        params: dict[str, Any] = {"timeout_min": self.time_min, "gpus_per_node": self.gpus}
        params["cpus_per_task"] = self.cpus
        if self.partition:
            params["slurm_partition"] = self.partition
        params.update(self.extra)
        return params


def _run(fn: Callable[..., Any], item: Any, threads: int) -> tuple[Any, list[str]]:
    """One task in a job: on ``threads`` torch threads; its record and its log lines."""
    import torch

    torch.set_num_threads(threads)
    lines: list[str] = []
    return fn(item, log=lines.append), lines


def _label(item: Any) -> str:
    label = getattr(item, "label", None)
    return label() if callable(label) else repr(item)


def _why(error: BaseException) -> str:
    """A failed job's reason in one line: the task's own exception where submitit carries its traceback
    (the last line of the trace, above the log paths), else the first line of submitit's message (a job
    that timed out, or died without output)."""
    text = str(error).strip()
    if "Traceback" in text:
        trace = text.split("Traceback", 1)[1].split("\n-----", 1)[0]
        lines = [ln.strip() for ln in trace.splitlines() if ln.strip()]
        return lines[-1] if lines else type(error).__name__
    return text.splitlines()[0] if text else type(error).__name__


@dataclass
class SubmititExecutor:
    """Runs a sweep's tasks as submitit jobs (see the module's text); ``config``: where and how."""

    config: SlurmConfig

    def _executor(self) -> Any:
        try:
            import submitit
        except ImportError as e:
            raise TasksFailed(
                "running tasks through submitit needs the cluster extra: pip install 'scenescore[cluster]'"
            ) from e
        if self.config.cluster == "slurm" and shutil.which("sbatch") is None:
            raise TasksFailed(
                "--executor slurm: sbatch is not on this machine's PATH (submit from a SLURM login node; "
                "--executor submitit-local runs the same path on this machine)"
            )
        executor = submitit.AutoExecutor(folder=self.config.folder, cluster=self.config.cluster)
        try:
            executor.update_parameters(**self.config.parameters())
        except (ValueError, TypeError, NameError) as e:  # submitit's NameError: a parameter it does not know
            raise TasksFailed(f"submitit parameters: {str(e).splitlines()[0]}") from e
        return executor

    def __call__(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        jobs: int = 1,
        log: Log = print,
        bar: str | None = None,
        done: Callable[[int, Any], None] | None = None,
        lengths: Sequence[float] | None = None,
    ) -> list[Any]:
        from tqdm.auto import tqdm

        from ..runtime.workers import longest_first

        executor = self._executor()
        finished = done or (lambda k, value: None)
        local = self.config.cluster == "local"
        poll = self.config.poll_s if self.config.poll_s is not None else (0.5 if local else 15.0)
        waiting = longest_first(lengths, len(items))
        running: dict[int, Any] = {}
        results: dict[int, Any] = {}
        failed: list[str] = []
        if not local:  # one job array; the cluster decides how many run at once
            given = [items[k] for k in waiting]
            array = executor.map_array(_run, [fn] * len(given), given, [self.config.cpus] * len(given))
            running, waiting = dict(zip(waiting, array)), []
            job_id = array[0].job_id.split("_")[0]
            log(f"submitted {len(items)} tasks as SLURM job array {job_id} (logs under {self.config.folder})")

        def gather(k: int, job: Any, shown: Any) -> None:
            """Job ``k``'s record handed on and its log lines printed, or its failure noted."""
            shown.update()
            try:
                record, lines = job.result()
            except Exception as e:  # the task raised on its node, or the job died there
                failed.append(f"{_label(items[k])}: {_why(e)} (log: {job.paths.stderr})")
                return
            with shown.external_write_mode():
                for line in lines:
                    log(line)
            results[k] = record
            finished(k, record)

        try:
            with tqdm(total=len(items), desc=bar, disable=None if bar else True, unit="task") as shown:
                while waiting or running:
                    while local and waiting and len(running) < max(1, jobs):
                        k = waiting.pop(0)
                        running[k] = executor.submit(_run, fn, items[k], self.config.cpus)
                    for k in [k for k, job in running.items() if job.done()]:
                        gather(k, running.pop(k), shown)
                    if running:
                        time.sleep(poll)
        except BaseException:  # Ctrl-C, or a failure here: no job is left computing for nobody
            for job in running.values():
                job.cancel(check=False)
            raise
        if failed:
            raise TasksFailed(
                f"{len(failed)} of {len(items)} tasks failed; the records of the others are kept, and the "
                "same command run again computes only these:\n  " + "\n  ".join(failed)
            )
        return [results[k] for k in range(len(items))]
