"""The suite's torch threads, and the tolerance for float results of different computation orders.

Every test runs under a thread budget of ``SCENESCORE_TEST_THREADS``, else ``OMP_NUM_THREADS``, else 1
(this library's tensors are mostly tiny, where a thread pool only adds overhead). The budget is given, not automatic, so that no
choice depends on how busy the machine is (:func:`scenescore.runtime.threads.workers`). CI runs the tests
marked ``float_order`` a second time with the other of 1 and 2 threads: a test whose exact comparison holds only for one
split of the work fails there too, on any machine.

A test that compares float results computed in different orders (in pieces against one pass, batched
against one at a time) uses :func:`assert_close_to_rounding`; exact equality is for results computed by the
same operations in the same order (the same seed twice, a copy, elementwise work split into pieces).
"""

from __future__ import annotations

import os

import pytest
import torch

from scenescore.runtime.threads import thread_budget

THREADS = int(os.environ.get("SCENESCORE_TEST_THREADS") or os.environ.get("OMP_NUM_THREADS") or "1")


@pytest.fixture(autouse=True, scope="session")
def _own_cache(tmp_path_factory: pytest.TempPathFactory):
    """The library's user cache (compiled kernels, tidy calibrations) in a folder of the test session's
    own: no test reads what another run left, none writes to the user's. ``SCENESCORE_TEST_CACHE_DIR``
    names a folder instead, for runs of one checkout that may share kernels (CI's second pass)."""
    old = os.environ.get("SCENESCORE_CACHE_DIR")
    shared = os.environ.get("SCENESCORE_TEST_CACHE_DIR")
    os.environ["SCENESCORE_CACHE_DIR"] = shared or str(tmp_path_factory.mktemp("cache"))
    yield
    if old is None:
        os.environ.pop("SCENESCORE_CACHE_DIR", None)
    else:
        os.environ["SCENESCORE_CACHE_DIR"] = old


@pytest.fixture(autouse=True)
def _thread_budget(request: pytest.FixtureRequest):
    """The test's torch threads and budget; torch's setting is restored afterwards, so that no test's own
    setting leaks into the next. ``own_threads`` tests (of the budget itself) start on one plain thread."""
    before = torch.get_num_threads()
    try:
        if request.node.get_closest_marker("own_threads"):
            torch.set_num_threads(1)
            yield
        else:
            with thread_budget(THREADS):
                yield
    finally:
        torch.set_num_threads(before)


def rounding_tolerance(expected: torch.Tensor, terms: int, dtype: torch.dtype | None = None) -> float:
    """An absolute bound on the difference between two float computations of ``expected`` that add the
    same ``terms`` products in different orders: ``terms`` units of rounding at the largest magnitude in
    ``expected`` (the classic bound for a recursive sum, n * eps * sum|x|, with sum|x| taken as the result's
    own scale: for these networks the terms do not cancel by orders of magnitude). ``dtype``: the one the
    work was done in, where ``expected`` was converted after (default its own)."""
    scale = float(expected.detach().abs().max()) if expected.numel() else 0.0
    return terms * torch.finfo(dtype or expected.dtype).eps * max(scale, 1.0)


def assert_close_to_rounding(
    actual: torch.Tensor, expected: torch.Tensor, terms: int, dtype: torch.dtype | None = None
) -> None:
    """``actual`` equals ``expected`` up to the rounding of a reduction of ``terms`` terms (see
    :func:`rounding_tolerance`)."""
    tol = rounding_tolerance(expected, terms, dtype)
    torch.testing.assert_close(actual, expected, rtol=0.0, atol=tol, check_dtype=False)


@pytest.fixture
def own_registries():
    """What a test registers (YAML cost types, solvers, CasADi forms: a documentation snippet's
    ``keep_left``) is unregistered when it ends, so that no other test, in this process or in the order
    another worker runs them, sees it."""
    from scenescore.costs import spec, symbolic
    from scenescore.solvers import registry

    tables = [spec._COST_TYPES, registry._REGISTRY, symbolic._FORMS]
    saved = [dict(t) for t in tables]
    try:
        yield
    finally:
        for table, before in zip(tables, saved):
            table.clear()
            table.update(before)
