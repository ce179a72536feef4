"""The thread budget of the identification kernels (SSI, LSCF, prediction errors).

The kernels run BLAS single-threaded and spread independent pieces of work (the per-order
eigenvalue problems, FFT batches) over Python threads instead. How many is
:func:`thread_budget`: the BLAS thread limit in effect when the SSI function is called,
at most :data:`MAX_THREADS` — so a caller that limits BLAS to one thread per process (as
:mod:`workbench.identification` does for its worker processes) gets fully serial SSI.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from contextvars import ContextVar

try:  # a dependency of scikit-learn, hence always installed with workbench
    from threadpoolctl import ThreadpoolController
except ImportError:  # pragma: no cover
    ThreadpoolController = None

#: Most Python threads an SSI call uses (see :func:`thread_budget`).
MAX_THREADS = 8
_BUDGET: ContextVar[int | None] = ContextVar("workbench_sid_thread_budget", default=None)

__all__ = ["MAX_THREADS", "blas_threads", "sid_threads", "single_threaded", "thread_budget"]

_blas: list = []  # the BLAS libraries of this process, found once (see _blas_libraries)
_pools: list = []  # every thread pool library of this process, found once


def _blas_libraries():
    """threadpoolctl controller of the loaded BLAS libraries, or None.

    Found once (a scan of the loaded libraries costs a few milliseconds, an SSI call used
    to pay it five times); numpy and scipy load their BLAS on import, before any SSI call.
    """
    if not _blas and ThreadpoolController is not None:
        controller = ThreadpoolController().select(user_api="blas")
        if controller.lib_controllers:
            _blas.append(controller)
    return _blas[0] if _blas else None


def single_threaded() -> contextlib.AbstractContextManager:
    """Context manager limiting every thread-pool library (BLAS, OpenMP) to one thread,
    as ``threadpoolctl.threadpool_limits(limits=1)`` does, with the libraries found once
    per process (the scan cost 9 ms per identified block; numpy and scipy load theirs on
    import, before any block)."""
    if ThreadpoolController is None:  # pragma: no cover
        return contextlib.nullcontext()
    if not _pools:
        _pools.append(ThreadpoolController())
    return _pools[0].limit(limits=1)


def blas_threads(limit: int) -> contextlib.AbstractContextManager:
    """Context manager limiting BLAS to *limit* threads (restored on exit)."""
    libraries = _blas_libraries()
    if libraries is None:  # pragma: no cover
        return contextlib.nullcontext()
    return libraries.limit(limits=int(limit))


def thread_budget() -> int:
    """Python threads the SSI kernels may use in the current context.

    Inside an SSI call, the budget fixed when the call started (:func:`sid_threads`);
    otherwise the smallest BLAS thread limit in effect (see :mod:`threadpoolctl`), capped
    by the number of cores and :data:`MAX_THREADS`.
    """
    fixed = _BUDGET.get()
    if fixed is not None:
        return fixed
    budget = min(MAX_THREADS, os.cpu_count() or 1)
    libraries = _blas_libraries()
    if libraries is not None:
        budget = min(budget, *(library.num_threads for library in libraries.lib_controllers))
    return max(1, int(budget))


@contextlib.contextmanager
def sid_threads() -> Iterator[int]:
    """Fix the thread budget of an SSI call, then run BLAS single-threaded inside it.

    Single-threaded BLAS: the per-order eigenvalue problems are small (n <= a few hundred),
    and multi-threaded LAPACK on them is slower, badly so when other processes compete for
    the cores (``benchmarks/results/docstring_numbers.txt``).
    """
    fixed = _BUDGET.get()
    if fixed is not None:  # nested in an SSI call: already set up
        yield fixed
        return
    token = _BUDGET.set(thread_budget())
    try:
        with blas_threads(1):
            yield _BUDGET.get()
    finally:
        _BUDGET.reset(token)
