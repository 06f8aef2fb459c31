"""How an experiment runs, whatever it measures: the settings every experiment's ``run`` takes alike.

An experiment's own settings (its seeds, methods, problem sizes, training) decide its figures; these
decide only where and how the work is done, what is told along the way and where the records are kept
to resume from. The figures do not depend on them, save ``device`` (a record names the device it was
computed on, so records of one device are never reused on another).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..scene.scene import SceneError
from .tasks import Sweep, Task

__all__ = ["Execution", "network_trainings"]


@dataclass(frozen=True)
class Execution:
    """Where and how an experiment's tasks run.

    ``progress``: progress bars (training's only with one process, where several workers would draw
    over each other) and an experiment's lines of progress within a task; ``log``: where every line
    goes (each task's result among them); ``device``: where the learned models train and place (a
    torch device or its name; None: the CPU; the baselines stay on the CPU whatever it is); ``jobs``:
    how many worker processes of one thread each run the tasks (1: in this process, in turn; the
    figures do not depend on it, and seconds are summed over the workers); ``cache``: a model cache
    folder (:mod:`scenescore.learn.cache`; None: none, save where an experiment keeps one for its run
    alone); ``sweep``: where each task's record is kept, to resume from, and what runs the tasks
    (:mod:`scenescore.experiments.tasks`; None: no record kept, this machine's worker processes)."""

    progress: bool = True
    log: Callable[[str], None] = field(default=print)
    device: Any = None
    jobs: int = 1
    cache: Any = None
    sweep: Sweep | None = None

    def __post_init__(self) -> None:
        # checked here, before any task starts: a bool is an int to Python but never a count of workers
        jobs = self.jobs
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise SceneError(f"jobs must be a whole number >= 1, got {jobs!r}")


def network_trainings(task: Task) -> float:
    """A table's task's expected length (:func:`~scenescore.experiments.tasks.run_tasks`'s ``length``), in
    trainings of SceneScore's network: one for a SceneScore row, which trains its network (the long
    tasks), none for a baseline or the oracle, seconds each."""
    return 1.0 if task.method.startswith("SceneScore") else 0.0
