"""LAPACK routines called without holding the GIL, for the few places SSI needs it.

scipy's Python LAPACK wrappers (``scipy.linalg.lapack``) hold the GIL while they run, so
two Python threads calling them run one after the other. scipy also publishes its LAPACK
for compiled extensions (``scipy.linalg.cython_lapack``, a documented API): every routine
as a C function pointer in a capsule. Calling that pointer through :mod:`ctypes` releases
the GIL for the duration of the call, which lets SSI split a tridiagonal eigenproblem over
threads. Only what is used is wrapped; every wrapper checks its LAPACK ``info``.
"""

from __future__ import annotations

import ctypes

import numpy as np

__all__ = ["available", "stemr_vectors"]

try:
    from scipy.linalg import cython_lapack as _cython_lapack

    _capsule_name = ctypes.pythonapi.PyCapsule_GetName
    _capsule_name.restype = ctypes.c_char_p
    _capsule_name.argtypes = [ctypes.py_object]
    _capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    _capsule_pointer.restype = ctypes.c_void_p
    _capsule_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
except (ImportError, AttributeError):  # pragma: no cover - scipy always ships cython_lapack
    _cython_lapack = None


def _routine(name: str, n_arguments: int):
    """The C function of LAPACK routine *name* (all arguments by pointer), or None."""
    if _cython_lapack is None:  # pragma: no cover
        return None
    capsule = getattr(_cython_lapack, "__pyx_capi__", {}).get(name)
    if capsule is None:  # pragma: no cover
        return None
    address = _capsule_pointer(capsule, _capsule_name(capsule))
    # CFUNCTYPE (not PYFUNCTYPE): ctypes releases the GIL around the call
    return ctypes.CFUNCTYPE(None, *([ctypes.c_void_p] * n_arguments))(address)


# void dstemr(char *jobz, char *range, int *n, d *d, d *e, d *vl, d *vu, int *il, int *iu,
#             int *m, d *w, d *z, int *ldz, int *nzc, int *isuppz, bint *tryrac, d *work,
#             int *lwork, int *iwork, int *liwork, int *info)
_dstemr = _routine("dstemr", 21)


def available() -> bool:
    """Whether the GIL-free routines could be bound (else callers use scipy.linalg.lapack)."""
    return _dstemr is not None


def _int(value: int) -> ctypes.c_int:
    return ctypes.c_int(int(value))


def stemr_vectors(
    diagonal: np.ndarray, off_diagonal: np.ndarray, first: int, last: int
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs *first*..*last* (1-based, ascending) of a symmetric tridiagonal matrix.

    LAPACK dstemr (multiple relatively robust representations), range 'I', run without
    the GIL.

    Parameters
    ----------
    diagonal : ndarray, shape (n,)
        Diagonal. Not modified.
    off_diagonal : ndarray, shape (n - 1,)
        Sub-diagonal. Not modified.
    first, last : int
        Index range of the wanted eigenvalues in ascending order, 1 <= first <= last <= n.

    Returns
    -------
    values : ndarray, shape (last - first + 1,)
        Eigenvalues, ascending.
    vectors : ndarray, shape (n, last - first + 1), Fortran order
        Orthonormal eigenvectors.

    Raises
    ------
    RuntimeError
        If the routine is unavailable or dstemr reports a failure (info != 0).
    """
    if _dstemr is None:  # pragma: no cover
        raise RuntimeError("LAPACK dstemr is not available through scipy.linalg.cython_lapack")
    n = int(diagonal.size)
    count = int(last) - int(first) + 1
    if not (1 <= first <= last <= n):
        raise ValueError(f"eigenvalue indices {first}..{last} must lie in 1..{n}")
    d = np.array(diagonal, dtype=np.float64)  # overwritten by dstemr
    e = np.zeros(n)
    e[: n - 1] = off_diagonal
    values = np.empty(n)
    vectors = np.empty((n, count), order="F")
    support = np.empty(2 * count, dtype=np.intc)
    work = np.empty(18 * n)
    iwork = np.empty(10 * n, dtype=np.intc)
    found, info, try_relative = ctypes.c_int(0), ctypes.c_int(0), ctypes.c_int(1)
    bound = ctypes.c_double(0.0)  # vl, vu: unused for range 'I'
    _dstemr(
        ctypes.c_char_p(b"V"),
        ctypes.c_char_p(b"I"),
        ctypes.byref(_int(n)),
        d.ctypes.data,
        e.ctypes.data,
        ctypes.byref(bound),
        ctypes.byref(bound),
        ctypes.byref(_int(first)),
        ctypes.byref(_int(last)),
        ctypes.byref(found),
        values.ctypes.data,
        vectors.ctypes.data,
        ctypes.byref(_int(n)),
        ctypes.byref(_int(count)),
        support.ctypes.data,
        ctypes.byref(try_relative),
        work.ctypes.data,
        ctypes.byref(_int(work.size)),
        iwork.ctypes.data,
        ctypes.byref(_int(iwork.size)),
        ctypes.byref(info),
    )
    if info.value != 0 or found.value != count:
        raise RuntimeError(f"LAPACK dstemr failed (info={info.value}, {found.value}/{count})")
    return values[:count], vectors
