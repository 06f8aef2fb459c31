"""An experiment as tasks: a small spec per unit of work, the record it returns, and sweeps that resume.

A :class:`Task` names one unit of an experiment (the experiment, a method, a seed, a scenario and a JSON
config of every other setting its result depends on); a function of the task returns its record, and the
experiment reduces the records to its table, whatever ran them. :func:`run_tasks` hands the tasks to an
executor (the local worker processes of :func:`~scenescore.runtime.workers.map_in_workers` unless a
:class:`Sweep` names another) and, when the sweep has a folder, writes each finished record there as JSON
(``<folder>/<key>.json``, atomically, as soon as the task is done; the key hashes the spec and
:func:`code_version`), so the same sweep run again computes only the tasks it has no record of. Records
are JSON, never pickles: what is read back is data, not code.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..runtime.provenance import code_version
from ..runtime.workers import map_in_workers
from ..scene.outputs import atomic_write_text

__all__ = ["Task", "Codec", "RECORD", "Sweep", "Executor", "code_version", "describe", "run_tasks"]

Log = Callable[[str], None]
# runs ``fn(task, log=...)`` for each task, calling ``done(k, record)`` in this process as task ``k``
# finishes: :func:`~scenescore.runtime.workers.map_in_workers`'s signature (the local executor); given
# ``lengths=`` (each task's expected length, where the experiment estimates them) only where an
# experiment passes ``length`` to :func:`run_tasks`
Executor = Callable[..., list[Any]]


def _plain(value: Any) -> Any:
    """A config value JSON cannot write as it is: settings objects as their fields, paths and numpy
    scalars as what they hold; anything else is refused, naming its type (a key must not hold an
    object's address, which would differ on every run)."""
    if hasattr(value, "to_dict"):
        return value.to_dict()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    if type(value).__module__ == "numpy" and hasattr(value, "item"):
        return value.item()
    raise TypeError(f"task config: a {type(value).__name__} is not JSON ({value!r})")


def describe(obj: Any) -> str | None:
    """How a task's config names a function or object it cannot hold (a graph builder, an encoder):
    its module and qualified name, with the encoder's name where it has one; None for None."""
    if obj is None:
        return None
    name = getattr(obj, "__qualname__", None) or type(obj).__qualname__
    label = getattr(obj, "name", None)
    return f"{getattr(obj, '__module__', '?')}.{name}" + (f" {label}" if isinstance(label, str) else "")


@dataclass(frozen=True)
class Task:
    """One unit of an experiment: picklable and hashable, so it can travel to a worker and key a record.
    ``config``: the canonical JSON text of every setting the record depends on beyond the other fields
    (build it with :meth:`of`)."""

    experiment: str
    method: str = ""
    seed: int = 0
    scenario: str = ""
    config: str = "{}"

    @classmethod
    def of(
        cls,
        experiment: str,
        *,
        method: str = "",
        seed: int = 0,
        scenario: str = "",
        config: Mapping[str, Any] | None = None,
    ) -> Task:
        """A task whose ``config`` mapping is written as canonical JSON (sorted keys; settings objects as
        their fields)."""
        text = json.dumps(dict(config or {}), sort_keys=True, separators=(",", ":"), default=_plain)
        return cls(experiment, method, int(seed), scenario, text)

    def to_dict(self) -> dict[str, Any]:
        return {
            "experiment": self.experiment,
            "method": self.method,
            "seed": self.seed,
            "scenario": self.scenario,
            "config": json.loads(self.config),
        }

    def key(self, code: str) -> str:
        """The record's name: a hash of this spec and the code's version ``code``."""
        text = json.dumps({"task": self.to_dict(), "code": code}, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:32]

    def label(self) -> str:
        """The task in a message: its experiment and whichever of method, scenario, seed it names."""
        parts = [p for p in (self.method, self.scenario) if p]
        return f"{self.experiment} task ({', '.join(parts + [f'seed {self.seed}'])})"


def _same(value: Any) -> Any:
    return value


def _json_scalar(value: Any) -> Any:
    """numpy's integers and booleans as Python's (the same value); anything else is refused."""
    if type(value).__module__ == "numpy" and type(value).__name__.startswith(("int", "uint", "bool")):
        return value.item()
    raise TypeError(f"a task record holds a {type(value).__name__}, which JSON cannot keep exactly")


@dataclass(frozen=True)
class Codec:
    """How a record becomes JSON and back: ``encode`` makes plain lists, mappings, strings and numbers of
    it (floats keep every bit in JSON); ``decode`` makes the record the reduce step reads of them."""

    encode: Callable[[Any], Any] = _same
    decode: Callable[[Any], Any] = _same


RECORD = Codec()  # records of numbers, strings, lists and mappings (tuples come back as lists)


@dataclass
class Sweep:
    """Where a sweep keeps its records and what runs its tasks. ``folder``: the records' folder (None:
    none kept); ``fresh``: compute every task, reading no record (each is written again); ``code``:
    the code version records are keyed by (default :func:`code_version`); ``executor``: what runs the
    tasks (default the local worker processes)."""

    folder: Path | None = None
    fresh: bool = False
    code: str | None = None
    executor: Executor = field(default=map_in_workers)

    def path(self, task: Task) -> Path:
        assert self.folder is not None
        return self.folder / f"{task.key(self.version())}.json"

    def version(self) -> str:
        return self.code if self.code is not None else code_version()


def _warn(path: Path, why: str) -> None:
    print(f"warning: {path}: {why}; its task is computed again", file=sys.stderr)


_NONE = object()  # no usable record


def _read(sweep: Sweep, task: Task, codec: Codec) -> Any:
    """The record kept for ``task``, decoded; :data:`_NONE` when there is none or it is damaged (a
    warning names the file)."""
    path = sweep.path(task)
    if not path.is_file():
        return _NONE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as e:
        _warn(path, f"not a readable task record ({type(e).__name__}: {e})")
        return _NONE
    if not isinstance(data, dict) or not {"task", "code", "record"} <= set(data):
        _warn(path, "not a task record (expected an object with 'task', 'code' and 'record')")
        return _NONE
    if data["task"] != task.to_dict() or data["code"] != sweep.version():
        _warn(path, "the record of another task or code version")
        return _NONE
    try:
        return codec.decode(data["record"])
    except Exception as e:  # data read back: any shape it cannot be decoded from is a damaged record
        _warn(path, f"a damaged task record ({type(e).__name__}: {e})")
        return _NONE


def _write(sweep: Sweep, task: Task, codec: Codec, record: Any) -> Any:
    """Write ``record`` for ``task`` atomically; returns it as read back (decoded from its JSON), so a
    record computed now and one reused later reduce alike."""
    plain = codec.encode(record)
    text = json.dumps(
        {"task": task.to_dict(), "code": sweep.version(), "record": plain}, default=_json_scalar
    )
    path = sweep.path(task)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, text + "\n")
    return codec.decode(json.loads(text)["record"])


def run_tasks(
    fn: Callable[..., Any],
    tasks: Sequence[Task],
    jobs: int = 1,
    log: Log = print,
    bar: str | None = None,
    sweep: Sweep | None = None,
    codec: Codec = RECORD,
    length: Callable[[Task], float] | None = None,
) -> list[Any]:
    """``fn(task, log=log)`` for each of ``tasks``, the records in order. With ``sweep.folder``, a task
    with a record there (of the same spec and code version) is not run again, and each task run writes
    its record as it finishes (``sweep.fresh``: none is read); the log says how many were reused.
    ``jobs``, ``bar``: as :func:`~scenescore.runtime.workers.map_in_workers`. ``length(task)``: its
    expected length in any unit, where tasks differ (a training against a lookup): the executor hands
    the longest out first and, on a CPU by default, counts them in choosing its processes."""
    sweep = sweep or Sweep()
    records: dict[int, Any] = {}
    if sweep.folder is not None and tasks:
        name = tasks[0].experiment
        if sweep.fresh:
            log(f"{name}: {len(tasks)} tasks, every one computed afresh (--fresh)")
        else:
            for k, task in enumerate(tasks):
                got = _read(sweep, task, codec)
                if got is not _NONE:
                    records[k] = got
            log(f"{name}: reused {len(records)} of {len(tasks)} tasks ({sweep.folder})")
    todo = [k for k in range(len(tasks)) if k not in records]

    def done(j: int, record: Any) -> None:
        k = todo[j]
        records[k] = record if sweep.folder is None else _write(sweep, tasks[k], codec, record)

    if todo:
        given = [tasks[k] for k in todo]
        # an executor written without ``lengths`` still runs tasks that have none
        told = {} if length is None else {"lengths": [float(length(t)) for t in given]}
        sweep.executor(fn, given, jobs, log, bar, done=done, **told)
    return [records[k] for k in range(len(tasks))]
