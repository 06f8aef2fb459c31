"""The runtime: devices, threads, memory and worker processes, the one part of the package that knows
the machine.

The library's core (scenes, geometry, vision, encoders, models, costs, problems, scenarios, solvers)
reaches it only through the names below, a test enforces it: where tensors live and their random
numbers come from (:func:`resolve_device`, :func:`generator`, :func:`draw`), the memory budget's check
before a large allocation and the chunks it sets (:func:`check_memory`, :func:`chunk_rows`,
:func:`return_freed_memory`), and the pieces a large batch is cut into (:func:`in_parallel`,
:data:`POOL_ROWS`, :func:`usable_cores`, :func:`torch_threads`), and compiling a pass for this machine
(:func:`compile_fn`, :func:`first_compile`, :func:`mark_batch`, :func:`traced_autograd`,
:func:`backward_with_forward`).

The edge (training, the workflow, experiments, the command line) sets the budgets and starts workers
through the modules themselves: ``threads`` (:func:`~scenescore.runtime.threads.thread_budget`),
``memory`` (:func:`~scenescore.runtime.memory.set_budget`), ``workers`` (processes),
``cores`` (the free-core estimate), ``ahead`` (work on a second core) and ``provenance`` (where a
result came from).
"""

from .compiling import backward_with_forward, compile_fn, first_compile, mark_batch, traced_autograd
from .cores import usable_cores
from .devices import draw, generator, resolve_device
from .memory import MemoryBudgetError, chunk_rows, return_freed_memory
from .memory import check as check_memory
from .threads import POOL_ROWS, in_parallel, torch_threads

__all__ = [
    "resolve_device",
    "generator",
    "draw",
    "check_memory",
    "chunk_rows",
    "return_freed_memory",
    "MemoryBudgetError",
    "in_parallel",
    "torch_threads",
    "POOL_ROWS",
    "usable_cores",
    "compile_fn",
    "first_compile",
    "mark_batch",
    "traced_autograd",
    "backward_with_forward",
]
