"""Where a result came from: the code's commit, the date, the dependency versions, the device, the cores
and threads, the wall time and the command line. Recorded beside every figure a run writes, so a table
can be traced to the run that made it."""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import platform
import shlex
import subprocess
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

__all__ = ["PACKAGES", "code_version", "collect_provenance", "git_commit", "version_of"]

# the distributions whose versions matter for results and for bug reports
PACKAGES = ["torch", "numpy", "scipy", "casadi", "osqp", "cvxpy", "shapely", "safetensors", "pyyaml"]

_PACKAGE_DIR = Path(__file__).resolve().parents[1]  # the scenescore package


def version_of(dist: str) -> str | None:
    """The installed version of the distribution ``dist`` (None: not installed)."""
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """The code a record was computed by: the package's version, torch's and numpy's, and a hash of every
    Python source file of the package (so a record of edited code, committed or not, is never reused).
    Computed once per process."""
    h = hashlib.sha256()
    for path in sorted(_PACKAGE_DIR.rglob("*.py")):
        h.update(path.relative_to(_PACKAGE_DIR).as_posix().encode("utf-8") + b"\0")
        h.update(path.read_bytes() + b"\0")
    versions = ", ".join(f"{p} {version_of(p)}" for p in ("scenescore", "torch", "numpy"))
    return f"{versions}; source {h.hexdigest()[:20]}"


def _git(*args: str) -> str | None:
    """One git command's output in the package's folder; None when git is missing or fails."""
    try:
        done = subprocess.run(
            ["git", "-C", str(_PACKAGE_DIR), *args], capture_output=True, text=True, timeout=10, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def git_commit() -> dict[str, Any]:
    """``{"commit": sha, "dirty": bool}`` of the checkout this package is imported from; ``"unknown"``
    (and ``dirty`` None) outside a checkout of scenescore (an installed wheel, say, even one whose
    environment lies inside some other repository). Never raises."""
    top = _git("rev-parse", "--show-toplevel")
    ours = top is not None and (Path(top) / "scenescore").resolve() == _PACKAGE_DIR
    sha = _git("rev-parse", "HEAD") if ours else None
    if not sha:
        return {"commit": "unknown", "dirty": None}
    status = _git("status", "--porcelain", "--untracked-files=no")
    return {"commit": sha, "dirty": None if status is None else bool(status)}


def cpu_name() -> str:
    """The processor's model name (Linux's /proc/cpuinfo), else what the platform module says."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _device_name(device: Any) -> str:
    """``cpu (<processor>)`` or ``cuda:0 (<GPU name>)`` for the device a run used."""
    import torch

    dev = torch.device(device if device is not None else "cpu")
    if dev.type == "cuda" and torch.cuda.is_available():
        return f"{dev} ({torch.cuda.get_device_name(dev)})"
    return f"{dev} ({cpu_name()})" if dev.type == "cpu" else str(dev)


def _jsonable(value: Any) -> Any:
    """A command-line option's value as JSON: numbers, strings, booleans and None as they are, lists
    element by element, anything else (paths, devices) as its text."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return str(value)


def collect_provenance(
    argv: Sequence[str] | None = None,
    options: Mapping[str, Any] | None = None,
    wall_seconds: float | None = None,
    device: Any = None,
    commit: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Everything that says where a result came from, as a JSON-ready mapping: ``command`` (``argv`` as
    one shell line), ``options`` (the parsed options, defaults included), ``commit`` and ``dirty``
    (``commit``: as :func:`git_commit` read them when the run started, since the checkout may change
    while a long run goes on; default: now), ``date`` (UTC, ISO 8601), ``versions``, ``device``,
    ``platform``, ``cores`` (usable) and ``threads`` (the run's torch thread budget), ``wall_seconds``.
    Never raises for a missing git or package."""
    from .cores import usable_cores
    from .threads import budget

    return {
        "command": None if argv is None else "scenescore " + shlex.join(argv),
        "options": {k: _jsonable(v) for k, v in (options or {}).items()},
        **(dict(commit) if commit is not None else git_commit()),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "versions": {
            "scenescore": version_of("scenescore"),  # the installed distribution's
            "python": platform.python_version(),
            **{p: version_of(p) for p in PACKAGES},
        },
        "device": _device_name(device),
        "platform": platform.platform(),
        "cores": usable_cores(),
        "threads": budget(),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "wall_seconds": None if wall_seconds is None else round(float(wall_seconds), 1),
    }
