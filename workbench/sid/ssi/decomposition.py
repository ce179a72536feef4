"""The leading singular triplets of the matrices SSI decomposes, from a partial symmetric
eigendecomposition (LAPACK dsytrd, dstemr, dormqr)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy import linalg

from .. import _lapack
from ..threads import blas_threads, thread_budget


def _leading_singular(
    matrix: np.ndarray, count: int, gram: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Left singular vectors and singular values of the *count* largest singular triplets.

    Computed from the eigendecomposition of M Mᵀ restricted to its largest eigenvalues
    (:func:`_leading_eigh`), faster than a full SVD of the block Toeplitz / weighted
    projection matrices used here (``benchmarks/results/docstring_numbers.txt``). Squaring costs relative accuracy ε σ₁²/σ_k² on
    σ_k; when σ_k/σ₁ < 1e-5 for a requested triplet the full SVD is used instead. *gram*,
    if given, is M Mᵀ (at least its upper triangle).
    """
    rows = matrix.shape[0]
    count = min(count, rows, matrix.shape[1])
    if gram is None:
        gram = matrix @ matrix.T  # the product runs as syrk
    values, vectors = _leading_eigh(gram, count)
    if values[-1] > 1e-10 * values[0]:
        return vectors, np.sqrt(values)
    u, s, _ = linalg.svd(matrix, full_matrices=False, check_finite=False, lapack_driver="gesdd")
    return u[:, :count], s[:count]


def _leading_eigh(symmetric: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The *count* largest eigenvalues (decreasing) and eigenvectors of a symmetric matrix.

    Only the upper triangle of *symmetric* is read.

    Householder tridiagonalisation (LAPACK dsytrd, blocked), the wanted eigenpairs of the
    tridiagonal matrix by multiple relatively robust representations (dstemr) and the
    back-transformation of those vectors only (dormqr). This is what dsyevr does for the
    whole spectrum; for an index subset dsyevr switches to bisection and inverse iteration
    (slower on the Gram matrices here). The two BLAS-bound steps, the tridiagonalisation
    (the largest single step of SSI-cov) and the back-transformation, run single-threaded
    BLAS like every other step of SSI (:func:`~workbench.sid.threads.sid_threads`):
    multi-threaded BLAS gained little here on two cores and, with other processes on the
    cores, spent several times the CPU time (benchmarks/results/throughput_33_kernels.txt);
    the wanted eigenpairs are split over the :func:`thread_budget` threads instead. Falls
    back to dsyevr if dstemr fails.
    """
    n = symmetric.shape[0]
    lapack = linalg.lapack
    threads = thread_budget()
    # the Fortran-ordered view of the symmetric matrix is its transpose, equal to it
    work = int(lapack.dsytrd_lwork(n, lower=1)[0])
    with blas_threads(1):
        reduced, diagonal, off_diagonal, tau, info = lapack.dsytrd(
            symmetric.T, lower=1, lwork=max(work, 1)
        )
    pairs = _tridiagonal_top(diagonal, off_diagonal, count, threads) if info == 0 else None
    if pairs is None:
        values, vectors = linalg.eigh(
            symmetric,
            lower=False,
            subset_by_index=(n - count, n - 1),
            driver="evr",
            check_finite=False,
        )
        return values[::-1], vectors[:, ::-1]
    values, vectors = pairs
    if n > 1:
        # Q = H(1)···H(n-1); reflector k acts on rows k+1..n-1: a QR factor of reduced[1:, :n-1]
        reflectors = reduced[1:, : n - 1]
        work = int(lapack.dormqr("L", "N", reflectors, tau, vectors[1:], -1)[1][0])
        with blas_threads(1):
            vectors[1:], _, info = lapack.dormqr(
                "L", "N", reflectors, tau, vectors[1:], max(work, 1), overwrite_c=1
            )
        if info != 0:  # pragma: no cover - only for invalid arguments
            raise RuntimeError(f"LAPACK dormqr failed with info={info}")
    return values[::-1], vectors[:, ::-1]


def _tridiagonal_top(
    diagonal: np.ndarray, off_diagonal: np.ndarray, count: int, threads: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The *count* largest eigenpairs (ascending; vectors in Fortran order) of a symmetric
    tridiagonal matrix by dstemr, or None if dstemr fails.

    With a thread budget and enough vectors, the index range is split in contiguous parts
    computed at the same time by GIL-free dstemr calls (:mod:`workbench.sid._lapack`). MRRR
    makes vectors orthogonal within one call; across parts the orthogonality is checked
    (|zᵢᵀzⱼ| <= 1e-10, else one call for all).
    """
    n = diagonal.size
    parts = min(threads, count // 32)
    if parts >= 2 and _lapack.available():
        bounds = np.linspace(n - count, n, parts + 1).astype(int)  # 0-based, ascending
        with ThreadPoolExecutor(parts) as pool:
            try:
                pieces = list(
                    pool.map(
                        lambda k: _lapack.stemr_vectors(
                            diagonal, off_diagonal, bounds[k] + 1, bounds[k + 1]
                        ),
                        range(parts),
                    )
                )
            except RuntimeError:
                pieces = None
        if pieces is not None:
            vectors = np.asfortranarray(np.hstack([piece[1] for piece in pieces]))
            across = max(np.abs(pieces[k][1].T @ pieces[k + 1][1]).max() for k in range(parts - 1))
            if across <= 1e-10:
                return np.concatenate([piece[0] for piece in pieces]), vectors
    found, values, vectors, info = linalg.lapack.dstemr(
        diagonal, np.append(off_diagonal, 0.0), 2, 0.0, 0.0, n - count + 1, n
    )
    if info != 0 or found != count:
        return None
    return values[:count], np.asfortranarray(vectors[:, :count])
