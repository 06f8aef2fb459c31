"""Compiling a function with torch.compile (inductor) for this machine: where compiled kernels are kept
between runs, the compiler's mode for the device, and the per-thread settings a compiled call needs.

Compiled kernels are kept in the user's cache folder (``inductor/``, :mod:`~scenescore.runtime.cache`)
unless ``TORCHINDUCTOR_CACHE_DIR`` names another, so that a second run on this machine reads them
instead of compiling again. On a CUDA device the compiled graphs replay as CUDA graphs
(``mode="reduce-overhead"``): one launch per graph instead of one per kernel. On a CPU the graph's
wrapper is C++ too (inductor's ``cpp_wrapper``): a call runs its kernels one after another without
Python between them and without holding Python's GIL, so the pieces of a batch that run side by side
on worker threads (:func:`~scenescore.runtime.threads.in_parallel`) use every core (a wrapper in
Python holds the GIL for each kernel, and the pieces take turns).

Worker processes that start alike (an ensemble's members, an experiment's seeds) meet the same graph
at once. :func:`first_compile` lets one of them compile it while the others wait for its kernels in the
cache folder, instead of each compiling the same graph on cores they share.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import torch
from filelock import FileLock

from .cache import cache_folder

__all__ = [
    "GRAPHS_KEPT",
    "compile_fn",
    "compile_settings",
    "first_compile",
    "traced_autograd",
    "backward_with_forward",
    "mark_batch",
]

F = TypeVar("F", bound=Callable[..., Any])
INDUCTOR_CACHE_ENV = "TORCHINDUCTOR_CACHE_DIR"
# whether the user named inductor's cache: read when the package is imported, since torch sets the
# variable to its own default (a temporary folder) the first time anything of its compiler asks
_USER_CACHE = bool(os.environ.get(INDUCTOR_CACHE_ENV))


def compile_settings(device_type: str) -> dict[str, Any]:
    """torch.compile's settings on a device of ``device_type`` (it takes a mode or inductor's options, not
    both): CUDA graphs on CUDA (``mode="reduce-overhead"``), the C++ wrapper on a CPU (see the module's
    description), the defaults elsewhere."""
    if device_type == "cuda":
        return {"mode": "reduce-overhead"}
    if device_type == "cpu":
        return {"options": {"cpp_wrapper": True}}
    return {}


def _kernel_folder() -> Path:
    """Where compiled kernels are kept: the user's cache folder's ``inductor/`` unless
    ``TORCHINDUCTOR_CACHE_DIR`` named another when the package was imported (set for torch here)."""
    if not _USER_CACHE:
        os.environ[INDUCTOR_CACHE_ENV] = str(cache_folder("inductor"))
    return Path(os.environ[INDUCTOR_CACHE_ENV])


def compile_fn(fn: F, device_type: str) -> F:
    """``fn`` compiled as one graph (``fullgraph``: a break is an error, not a silent slow path), its
    kernels kept in the user's cache folder."""
    _kernel_folder()
    return torch.compile(fn, fullgraph=True, **compile_settings(device_type))  # type: ignore[return-value]


@contextmanager
def first_compile(key: str) -> Iterator[None]:
    """Around a compiled function's first call in this process, ``key`` naming the graph it compiles
    (whatever decides the graph: the function, the settings it closes over, its inputs' kinds): the
    first process to reach it with that key compiles while any other that reaches it waits, then finds
    the kernels in the cache folder; once the graph has been compiled there, no process waits. A
    lock held by a process that dies is let go by the system. A wrong key costs time only: two graphs
    under one key compile one after the other, one graph under two keys compiles twice at once."""
    folder = _kernel_folder() / "scenescore-graphs"
    name = hashlib.sha256(f"{key} torch {torch.__version__}".encode()).hexdigest()[:32]
    done = folder / f"{name}.done"
    if done.exists():
        yield
        return
    folder.mkdir(parents=True, exist_ok=True)
    with FileLock(str(folder / f"{name}.lock")):
        if not done.exists():  # else another process compiled it while this one waited
            yield
            done.touch()
            return
    yield  # the kernels are there: read them without holding up the other waiting processes


#: the graphs one compiled function may keep (torch's default keeps 8, then fails a ``fullgraph``
#: call): one for each network it serves in a process (a network's settings are constants of its graph)
#: and each way it is called (a training's inputs, a placement's), over every task a worker process runs
GRAPHS_KEPT = 64


def traced_autograd() -> Any:
    """The settings a compiled call that takes a gradient inside its graph needs, for the calling thread
    (torch keeps the compiler's settings per thread: a worker thread does not see the caller's), with
    room for :data:`GRAPHS_KEPT` graphs."""
    return torch._dynamo.config.patch(trace_autograd_ops=True, recompile_limit=GRAPHS_KEPT)


@contextmanager
def backward_with_forward() -> Iterator[None]:
    """The setting, for the calling thread, under which a compiled call that will be differentiated
    compiles its backward graph with its forward one, under the compiler's lock (by default the
    backward graph compiles at the first backward pass, which takes no lock, so that two threads
    differentiating their pieces at once could both compile it), with room for :data:`GRAPHS_KEPT`
    graphs."""
    with (
        torch._functorch.config.patch(force_non_lazy_backward_lowering=True),
        torch._dynamo.config.patch(recompile_limit=GRAPHS_KEPT),
    ):
        yield


def mark_batch(*tensors: torch.Tensor | None) -> None:
    """Mark the batch and object dimensions of ``tensors`` as varying, so that pieces and size groups of
    other sizes reuse one compiled graph."""
    for t in tensors:
        if t is not None:
            for d in range(min(t.dim(), 2)):
                torch._dynamo.maybe_mark_dynamic(t, d)
