"""Stochastic subspace identification (SSI), covariance- and data-driven, reference-based.

Both variants identify, from output-only accelerations, the stochastic state-space model

.. math::

    x_{k+1} = A x_k + w_k, \\qquad y_k = C x_k + v_k,

and return the poles and mode shapes of *every* model order of a stabilisation diagram from
one singular value decomposition (:func:`workbench.sid.modal.poles_all_orders`).

Layers: private numerical kernels (lagged products by FFT, the exact Gram matrix of the block
Hankel matrix, the state-space realisation), the two public functions :func:`ssi_cov` and
:func:`ssi_data`, and the result classes :class:`SSIResult` and
:class:`StochasticStateSpace`.

Conventions
-----------
- The mean of every channel is removed first (no other conditioning: detrend, filter and
  decimate with :mod:`workbench.signals` beforehand).
- Reference channels (default: all) are the projection channels of Peeters & De Roeck [1]_.
- Non-physical poles are dropped consistently for both variants: real eigenvalues of A,
  the conjugate of every complex pair (only the eigenvalue with positive imaginary part is
  kept) and poles whose natural frequency is not strictly between 0 and the Nyquist
  frequency. Poles with negative damping are kept in the table (they are never flagged
  stable) so that a diagram shows them.
- Linear algebra runs with single-threaded BLAS: the matrices are moderate (a few hundred
  to a thousand rows), blocks are processed in parallel by processes, and multi-threaded
  LAPACK on such matrices is slower and collapses when other processes compete for the
  cores. Independent pieces (FFT batches, halves of a matrix product, the per-order
  eigenvalue problems) run on Python threads instead, as many as
  :func:`workbench.sid.threads.thread_budget` allows: the BLAS thread limit in effect when
  the function is called, so ``threadpoolctl.threadpool_limits(1)`` makes it serial.

References
----------
.. [1] B. Peeters, G. De Roeck, "Reference-based stochastic subspace identification for
   output-only modal analysis", Mechanical Systems and Signal Processing 13(6), 855-878,
   1999. doi:10.1006/mssp.1999.1249
.. [2] P. Van Overschee, B. De Moor, "Subspace Identification for Linear Systems",
   Kluwer, 1996. doi:10.1007/978-1-4613-0465-4
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd
from scipy import fft, linalg

from data_contracts import shapes_to_frame

from . import _lapack
from .assurance import continuous_pole
from .modal import modal_phase_collinearity, poles_all_orders
from .stabilisation import StabilityCriteria, stability_flags
from .threads import blas_threads, sid_threads, thread_budget

__all__ = [
    "SSIResult",
    "SSIWarning",
    "StochasticStateSpace",
    "ssi_cov",
    "ssi_data",
]

Weighting = Literal["pc", "upc", "cva"]
_WEIGHTINGS = ("pc", "upc", "cva")
DEFAULT_ORDERS = range(2, 81, 2)
DEFAULT_BLOCK_ROWS = 20
#: Singular values computed beyond the largest model order (kept on the result).
_EXTRA_SINGULAR_VALUES = 10


class SSIWarning(UserWarning):
    """A secondary SSI product (noise covariances, Kalman gain) could not be computed."""


@dataclass(frozen=True, eq=False)
class StochasticStateSpace:
    """Identified stochastic state-space model at the largest model order.

    Channels are in the order of the input columns. Matrices are those of the forward model
    x_{k+1} = A x_k + w_k, y_k = C x_k + v_k with covariances Q = E[w wᵀ], R = E[v vᵀ],
    S = E[w vᵀ], and of its innovation form x̂_{k+1} = A x̂_k + K e_k, y_k = C x̂_k + e_k.
    Fields that a variant does not estimate are None: SSI-cov gives A, C, G (reference
    columns) and Λ₀; SSI-data gives all of them (see :func:`ssi_data`).

    Parameters
    ----------
    state_matrix : ndarray, shape (n, n)
        A (discrete time).
    output_matrix : ndarray, shape (n_channels, n)
        C. [m/s² per state unit]
    next_state_output_covariance : ndarray, shape (n, n_columns)
        G = E[x_{k+1} y_kᵀ]; for SSI-cov only the columns of the reference channels.
    output_covariance : ndarray, shape (n_channels, n_channels)
        Λ₀ = E[y_k y_kᵀ]. [(m/s²)²]
    reference_channels : tuple of int
        Input columns of the references (the columns of G for SSI-cov).
    process_noise_covariance, measurement_noise_covariance, cross_noise_covariance : ndarray
        Q (n, n), R (n_channels, n_channels), S (n, n_channels) (SSI-data).
    state_covariance : ndarray, shape (n, n)
        Σ = E[x xᵀ], the solution of the Lyapunov equation Σ = AΣAᵀ + Q (SSI-data, stable A).
    predicted_state_covariance : ndarray, shape (n, n)
        P = E[x̂ x̂ᵀ] of the steady-state Kalman predictor, from a discrete algebraic
        Riccati equation.
    kalman_gain : ndarray, shape (n, n_channels)
        K of the innovation form.
    innovation_covariance : ndarray, shape (n_channels, n_channels)
        E[e eᵀ]. [(m/s²)²]
    """

    state_matrix: np.ndarray
    output_matrix: np.ndarray
    next_state_output_covariance: np.ndarray
    output_covariance: np.ndarray
    reference_channels: tuple[int, ...]
    process_noise_covariance: np.ndarray | None = None
    measurement_noise_covariance: np.ndarray | None = None
    cross_noise_covariance: np.ndarray | None = None
    state_covariance: np.ndarray | None = None
    predicted_state_covariance: np.ndarray | None = None
    kalman_gain: np.ndarray | None = None
    innovation_covariance: np.ndarray | None = None

    @property
    def model_order(self) -> int:
        return int(self.state_matrix.shape[0])

    def output_correlation(self, lag: int) -> np.ndarray:
        """Model output correlation R_k = C A^{k-1} G (k ≥ 1) or Λ₀ (k = 0)."""
        if lag == 0:
            return self.output_covariance
        return (
            self.output_matrix
            @ np.linalg.matrix_power(self.state_matrix, lag - 1)
            @ self.next_state_output_covariance
        )


class PoleTableMixin:
    """What every identification result with ``poles`` (one row per pole: model_order,
    frequency_hz, damping_ratio, ...) and ``mode_shapes`` (n_channels x n_poles) offers:
    SSI (:class:`SSIResult`) and LSCF (:class:`~workbench.sid.plscf.LSCFResult`)."""

    poles: pd.DataFrame
    mode_shapes: np.ndarray

    @property
    def n_channels(self) -> int:
        return int(self.mode_shapes.shape[0])

    @property
    def continuous_poles(self) -> np.ndarray:
        """Continuous-time poles λ = -ζω + iω√(1-ζ²) of the rows of *poles*. [rad/s]"""
        return continuous_pole(
            self.poles["frequency_hz"].to_numpy(), self.poles["damping_ratio"].to_numpy()
        )

    def poles_frame(self, channels: Sequence[str], block: int | None = None) -> pd.DataFrame:
        """The poles with mode-shape columns, ready for the pole-table contract.

        Parameters
        ----------
        channels : sequence of str
            Names of the input columns (length n_channels).
        block : int, optional
            Block number; adds the ``block`` column first (required by the contract).

        Returns
        -------
        pandas.DataFrame
            ``[block,] model_order, frequency_hz, damping_ratio, stable, mpc``,
            ``shape_re_<channel>``..., ``shape_im_<channel>``...
        """
        channels = list(channels)
        if len(channels) != self.n_channels:
            raise ValueError(
                f"channels has {len(channels)} names for {self.n_channels} identified channels"
            )
        frame = self.poles.reset_index(drop=True)
        if block is not None:
            frame.insert(0, "block", np.full(len(frame), int(block), dtype=np.int64))
        shapes = shapes_to_frame(channels, self.mode_shapes.T, index=frame.index)
        return pd.concat([frame, shapes], axis=1)


@dataclass(frozen=True, eq=False)
class SSIResult(PoleTableMixin):
    """Poles of every model order of one SSI run (a stabilisation diagram).

    Parameters
    ----------
    poles : pandas.DataFrame
        One row per physical pole (one per complex-conjugate pair), sorted by model order
        then frequency: ``model_order``, ``frequency_hz`` [Hz], ``damping_ratio`` [-],
        ``stable`` (against the previous order, see :mod:`workbench.sid.stabilisation`),
        ``mpc`` (modal phase collinearity) — the pole-table contract without ``block``.
    mode_shapes : ndarray of complex, shape (n_channels, n_poles)
        Φ = CΨ, unit norm, largest component real and positive; column k belongs to row k
        of *poles*.
    sampling_rate_hz : float
        Sampling rate of the data. [Hz]
    block_rows : int
        Number of block rows i.
    orders : tuple of int
        Model orders of the diagram (also those without physical poles).
    singular_values : ndarray
        Leading singular values of the (weighted) matrix decomposed (the largest model
        order plus ten, or all if fewer).
    reference_channels : tuple of int
        Input columns used as references.
    method : str
        ``"ssi-cov"`` or ``"ssi-data/<weighting>"``.
    system : StochasticStateSpace
        The state-space model of the largest order.
    criteria : StabilityCriteria
        Criteria behind the ``stable`` column.
    """

    poles: pd.DataFrame
    mode_shapes: np.ndarray
    sampling_rate_hz: float
    block_rows: int
    orders: tuple[int, ...]
    singular_values: np.ndarray
    reference_channels: tuple[int, ...]
    method: str
    system: StochasticStateSpace
    criteria: StabilityCriteria = field(default_factory=StabilityCriteria)


# --------------------------------------------------------------------------- validation
def _prepare(
    acceleration,
    sampling_rate_hz: float,
    block_rows: int,
    orders: Sequence[int],
    reference_channels: Sequence[int] | None,
) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Checked, mean-free data, reference indices and orders."""
    data = np.asarray(acceleration)
    if data.ndim != 2:
        raise ValueError(
            f"acceleration must be 2-D (n_samples, n_channels), got shape {data.shape}"
        )
    if not np.issubdtype(data.dtype, np.number) or np.iscomplexobj(data):
        raise TypeError(f"acceleration must hold real numbers, got dtype {data.dtype}")
    data = np.asarray(data, dtype=float)  # no copy for float64: the centring below copies
    n_samples, n_channels = data.shape
    mean = data.mean(axis=0)  # NaN or inf in a channel make its mean non-finite
    bad = np.zeros(0, dtype=int)
    if not np.isfinite(mean).all():
        bad = np.flatnonzero(~np.isfinite(data).all(axis=0))
    if bad.size:
        raise ValueError(
            f"acceleration channel(s) {bad.tolist()} (column index) contain NaN or inf; "
            "drop faulty channels before identification"
        )
    if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise ValueError(f"sampling_rate_hz={sampling_rate_hz} must be positive")
    if int(block_rows) != block_rows or block_rows < 2:
        raise ValueError(f"block_rows={block_rows} must be an integer >= 2")
    block_rows = int(block_rows)

    if reference_channels is None:
        references = np.arange(n_channels)
    else:
        references = np.asarray(reference_channels)
        if references.ndim != 1 or references.size == 0 or references.dtype.kind not in "iu":
            raise ValueError(
                f"reference_channels={reference_channels!r} must be a non-empty sequence of "
                "column indices"
            )
        if np.unique(references).size != references.size:
            raise ValueError(f"reference_channels={references.tolist()} has duplicates")
        if references.min() < 0 or references.max() >= n_channels:
            raise ValueError(
                f"reference_channels={references.tolist()} must lie in 0..{n_channels - 1}"
            )

    order_list = sorted({int(n) for n in orders})
    if not order_list or order_list[0] < 1:
        raise ValueError(f"orders={list(orders)!r} must be positive integers")
    n_refs = references.size
    capacity = min(n_refs * block_rows, n_channels * (block_rows - 1))
    if order_list[-1] > capacity:
        # r·i >= n and l·(i - 1) >= n
        needed = max(-(-order_list[-1] // n_refs), -(-order_list[-1] // n_channels) + 1)
        raise ValueError(
            f"orders up to {order_list[-1]} need block_rows >= {needed} with "
            f"{n_refs} reference and {n_channels} channels, got block_rows={block_rows}"
        )
    min_samples = (n_channels + n_refs + 2) * block_rows
    if n_samples < min_samples:
        raise ValueError(
            f"block_rows={block_rows} needs at least {min_samples} samples with "
            f"{n_channels} channels, got {n_samples}"
        )
    data = data - mean
    return data, references, tuple(order_list)


# --------------------------------------------------------------------------- kernels
def _lagged_products(data: np.ndarray, max_lag: int, columns: np.ndarray) -> np.ndarray:
    """Sums of lagged products S[d] = Σ_{m=0}^{N-1-d} y_{m+d} y_m[columns]ᵀ, d = 0..max_lag.

    Returns an array (max_lag + 1, n_channels, n_columns). Computed exactly (up to
    rounding) by segmented FFT correlation: the record is cut into segments of length
    L = n_fft - max_lag; segment s of the reference columns (zero padded) is correlated
    circularly with the data from the segment start over L + max_lag samples, which has no
    wrap-around for lags up to max_lag, and the cross spectra are summed over segments
    before one inverse FFT. Cost O(N l r) instead of O(N l r max_lag) for direct sums.
    """
    n_samples, n_channels = data.shape
    workers = thread_budget()
    n_fft = fft.next_fast_len(max(8 * (max_lag + 1), 2048), real=True)
    segment = n_fft - max_lag
    n_segments = -(-n_samples // segment)
    padded = np.zeros((n_segments * segment + max_lag, n_channels))
    padded[:n_samples] = data
    # (n_segments, n_channels, n_fft) windows starting every `segment` samples
    windows = np.lib.stride_tricks.sliding_window_view(padded, n_fft, axis=0)[::segment]
    spectra = fft.rfft(windows, axis=-1, workers=workers)  # (n_segments, n_channels, n_freq)
    # the reference columns of each segment, zero padded: (n_segments, n_ref, n_freq)
    reference_spectra = fft.rfft(windows[:, columns, :segment], n=n_fft, axis=-1, workers=workers)
    # Σ_s X_s(f) conj(Z_s(f))ᵀ as a batched product over frequencies, frequency bands on
    # the thread budget (numpy releases the GIL)
    left = spectra.transpose(2, 1, 0)
    right = reference_spectra.conj().transpose(2, 0, 1)
    cross = np.empty((left.shape[0], n_channels, right.shape[2]), dtype=complex)
    bands = np.linspace(0, left.shape[0], workers + 1).astype(int)

    def band(k):
        part = slice(bands[k], bands[k + 1])
        np.matmul(left[part], right[part], out=cross[part])

    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(band, range(workers)))
    else:
        band(0)
    correlation = fft.irfft(cross, n=n_fft, axis=0, workers=workers)
    return np.ascontiguousarray(correlation[: max_lag + 1])


def _hankel_gram(data: np.ndarray, n_blocks: int, lag_sums: np.ndarray) -> np.ndarray:
    """Exact Gram matrix H Hᵀ of the block Hankel matrix with *n_blocks* block rows.

    H has block row b = [y_b, y_{b+1}, ..., y_{b+j-1}] (all channels), j = N - n_blocks + 1.
    Block (b, b') with b <= b', d = b' - b, is

        Σ_{k<j} y_{b+k} y_{b'+k}ᵀ = F(d) - Σ_{m<b} y_m y_{m+d}ᵀ - Σ_{m>=b+j} y_m y_{m+d}ᵀ,

    with the full lagged sum F(d) = lag_sums[d]ᵀ and two short edge sums (at most n_blocks
    terms) taken from cumulative sums. Returns (n_blocks·l, n_blocks·l).
    """
    n_samples, n_channels = data.shape
    k = n_blocks
    lags = np.arange(k)
    full = lag_sums.transpose(0, 2, 1)  # F(d) = Σ y_m y_{m+d}ᵀ
    # head[b, d] = Σ_{m<b} y_m y_{m+d}ᵀ
    head_terms = np.einsum(
        "ma,mdb->mdab", data[: k - 1], data[np.arange(k - 1)[:, None] + lags[None, :]]
    )
    head = np.zeros((k, k, n_channels, n_channels))
    np.cumsum(head_terms, axis=0, out=head[1:])
    # tail[s, d] = Σ_{t<s} y_{N-1-d-t} y_{N-1-t}ᵀ
    t = np.arange(k - 1)
    tail_terms = np.einsum(
        "tda,tb->tdab",
        data[n_samples - 1 - lags[None, :] - t[:, None]],
        data[n_samples - 1 - t],
    )
    tail = np.zeros((k, k, n_channels, n_channels))
    np.cumsum(tail_terms, axis=0, out=tail[1:])

    first, second = np.triu_indices(k)
    lag = second - first
    blocks = full[lag] - head[first, lag] - tail[k - 1 - second, lag]
    gram = np.empty((k, k, n_channels, n_channels))
    gram[first, second] = blocks
    gram[second, first] = blocks.transpose(0, 2, 1)
    return gram.transpose(0, 2, 1, 3).reshape(k * n_channels, k * n_channels)


def _cholesky(matrix: np.ndarray, what: str) -> np.ndarray:
    """Lower Cholesky factor, with a tiny diagonal jitter if rounding makes it fail."""
    scale = np.trace(matrix) / matrix.shape[0]
    for jitter in (0.0, 1e-12, 1e-10, 1e-8):
        try:
            return linalg.cholesky(
                matrix + jitter * scale * np.eye(matrix.shape[0]), lower=True, check_finite=False
            )
        except linalg.LinAlgError:
            continue
    raise ValueError(
        f"the {what} is singular: are some channels constant or linear combinations of others?"
    )


def _toeplitz_gram(correlations: np.ndarray, toeplitz: np.ndarray) -> np.ndarray:
    """T Tᵀ of the block Toeplitz matrix T[p, k] = R_{i+p-k} by its displacement structure.

    *correlations* holds R_0 .. R_{2i-1} (each l x r), *toeplitz* is T (i·l x i·r). With
    G[p, q] = Σ_k R_{i+p-k} R_{i+q-k}ᵀ (l x l blocks), shifting both block indices adds
    one term and drops one:

    .. math::

        G_{p+1, q+1} = G_{p, q} + R_{i+p+1} R_{i+q+1}^T - R_{p+1} R_{q+1}^T,

    so the first block row (one product of l rows of T with Tᵀ) and two Gram matrices of
    stacked correlations give all of G in O(i² l² (l + r)) operations instead of the
    O(i³ l² r) of the product T Tᵀ. Only the upper block triangle is filled (the lower
    triangle is left uninitialised): :func:`_leading_eigh` reads the upper triangle.
    """
    i = correlations.shape[0] // 2
    n_channels = correlations.shape[1]
    size = i * n_channels
    gram = np.empty((size, size))
    gram[:n_channels] = toeplitz[:n_channels] @ toeplitz.T
    late = correlations[i + 1 : 2 * i].reshape((i - 1) * n_channels, -1)  # R_{i+1..2i-1}
    early = correlations[1:i].reshape((i - 1) * n_channels, -1)  # R_{1..i-1}
    for p in range(1, i):
        rows = slice(p * n_channels, (p + 1) * n_channels)
        previous = slice((p - 1) * n_channels, p * n_channels)
        start = (p - 1) * n_channels
        # G[p, q] = G[p-1, q-1] + R_{i+p} R_{i+q}ᵀ - R_p R_qᵀ for q = p .. i-1
        block = gram[rows, p * n_channels :]
        np.matmul(late[previous], late[start:].T, out=block)
        block -= early[previous] @ early[start:].T
        block += gram[previous, start : (i - 1) * n_channels]
    return gram


def _leading_singular(
    matrix: np.ndarray, count: int, gram: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Left singular vectors and singular values of the *count* largest singular triplets.

    Computed from the eigendecomposition of M Mᵀ restricted to its largest eigenvalues
    (:func:`_leading_eigh`), 3-5 times faster than a full SVD of the block Toeplitz /
    weighted projection matrices used here. Squaring costs relative accuracy ε σ₁²/σ_k² on
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
    (the largest single step of SSI-cov) and the back-transformation, run BLAS on
    :func:`thread_budget` threads. Falls back to dsyevr if dstemr fails.
    """
    n = symmetric.shape[0]
    lapack = linalg.lapack
    threads = thread_budget()
    # the Fortran-ordered view of the symmetric matrix is its transpose, equal to it
    work = int(lapack.dsytrd_lwork(n, lower=1)[0])
    with blas_threads(threads):
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
        with blas_threads(threads):
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


def _order_limits(n_max: int, singular_values: np.ndarray) -> None:
    if singular_values.size < n_max or singular_values[n_max - 1] <= 0:
        raise ValueError(
            f"the data support at most {int(np.sum(singular_values > 0))} states, "
            f"orders go up to {n_max}"
        )


def _assemble(
    poles,
    orders: tuple[int, ...],
    sampling_rate_hz: float,
    block_rows: int,
    singular_values: np.ndarray,
    references: np.ndarray,
    method: str,
    system: StochasticStateSpace,
    channel_order: np.ndarray | None = None,
) -> SSIResult:
    shapes = poles.mode_shapes
    if channel_order is not None:  # back to the input column order
        restored = np.empty_like(shapes)
        restored[channel_order] = shapes
        shapes = restored
    criteria = StabilityCriteria()
    frame = pd.DataFrame(
        {
            "model_order": poles.model_order.astype(np.int64),
            "frequency_hz": poles.frequency_hz,
            "damping_ratio": poles.damping_ratio,
            "stable": stability_flags(
                poles.model_order,
                poles.frequency_hz,
                poles.damping_ratio,
                shapes,
                orders,
                criteria,
            ),
            "mpc": modal_phase_collinearity(shapes),
        }
    )
    return SSIResult(
        poles=frame,
        mode_shapes=shapes,
        sampling_rate_hz=float(sampling_rate_hz),
        block_rows=block_rows,
        orders=orders,
        singular_values=singular_values,
        reference_channels=tuple(int(c) for c in references),
        method=method,
        system=system,
        criteria=criteria,
    )


def _realisation(
    poles, basis: np.ndarray, root: np.ndarray, n_outputs: int
) -> tuple[np.ndarray, np.ndarray]:
    """A = O↑⁺O↓ and C (first block row) of O_i = basis · diag(root).

    :func:`~workbench.sid.modal.poles_all_orders` already solved the shift equation in the
    coordinates of *basis* (one QR); scaling the columns by *root* is the similarity
    A = diag(root)⁻¹ A_basis diag(root).
    """
    state = poles.state_matrix * (root[None, :] / root[:, None])
    return state, basis[:n_outputs] * root


def _single_threaded(function):
    """Run *function* with single-threaded BLAS and a fixed thread budget (module docstring)."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with sid_threads():
            return function(*args, **kwargs)

    return wrapper


# --------------------------------------------------------------------------- SSI-cov
@_single_threaded
def ssi_cov(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    *,
    block_rows: int = DEFAULT_BLOCK_ROWS,
    orders: Sequence[int] = DEFAULT_ORDERS,
    reference_channels: Sequence[int] | None = None,
) -> SSIResult:
    """Covariance-driven stochastic subspace identification (reference-based).

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Measured accelerations, finite (drop dead channels first). [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    block_rows : int
        Number of block rows i; output correlations up to lag 2i - 1 are used. Must allow
        the largest order: max(orders) <= min(r·i, l·(i-1)) for r references, l channels.
    orders : sequence of int
        Model orders of the stabilisation diagram.
    reference_channels : sequence of int, optional
        Columns used as references (projection channels). Default: all.

    Returns
    -------
    SSIResult
        Poles of every order with shapes; ``system`` holds A, C, G (reference columns) and
        Λ₀ of the largest order (use :func:`ssi_data` for noise covariances and the Kalman
        gain).

    Raises
    ------
    ValueError
        NaN/inf in a channel (the message names its column index), too few samples for
        *block_rows*, or orders beyond what *block_rows* allows.

    Notes
    -----
    With the output correlations R_k = E[y_{t+k} y_{t,ref}ᵀ] = C A^{k-1} G_ref (later
    sample on the left: this orientation makes C, hence Φ = CΨ, the observed mode shapes),
    estimated as R_k = Σ_m y_{m+k} y_{m,ref}ᵀ / (N - k) by segmented FFT (exact sums), the
    block Toeplitz matrix

    .. math::

        T_{1|i} = \\begin{pmatrix} R_i & R_{i-1} & \\cdots & R_1 \\\\
                  R_{i+1} & R_i & \\cdots & R_2 \\\\
                  \\vdots & & & \\vdots \\\\
                  R_{2i-1} & R_{2i-2} & \\cdots & R_i \\end{pmatrix}
                = O_i Γ_i = U S Vᵀ

    factors into observability O_i = U₁S₁^{1/2} and reversed controllability
    Γ_i = S₁^{1/2}V₁ᵀ. One SVD serves every order n (first n singular triplets); A_n
    follows from the shift structure of O_i (:func:`workbench.sid.modal.poles_all_orders`).

    References
    ----------
    .. [1] B. Peeters, G. De Roeck, "Reference-based stochastic subspace identification
       for output-only modal analysis", MSSP 13(6), 855-878, 1999.
       doi:10.1006/mssp.1999.1249
    """
    data, references, orders = _prepare(
        acceleration, sampling_rate_hz, block_rows, orders, reference_channels
    )
    n_samples, n_channels = data.shape
    i = int(block_rows)
    n_refs = references.size
    sums = _lagged_products(data, 2 * i - 1, references)  # lags 0 .. 2i-1
    correlations = sums / (n_samples - np.arange(2 * i))[:, None, None]
    rows, cols = np.meshgrid(np.arange(i), np.arange(i), indexing="ij")
    toeplitz = (
        correlations[i + rows - cols].transpose(0, 2, 1, 3).reshape(i * n_channels, i * n_refs)
    )
    n_max = orders[-1]
    u, s = _leading_singular(
        toeplitz, n_max + _EXTRA_SINGULAR_VALUES, gram=_toeplitz_gram(correlations, toeplitz)
    )
    _order_limits(n_max, s)
    poles = poles_all_orders(u[:, :n_max], n_channels, orders, sampling_rate_hz)

    root = np.sqrt(s[:n_max])
    state, output = _realisation(poles, u[:, :n_max], root, n_channels)  # O_i = U₁S₁^{1/2}
    # G_ref = last block column of Γ_i = S₁^{-1/2} U₁ᵀ T = S₁^{1/2} V₁ᵀ
    next_state_output = (u[:, :n_max].T @ toeplitz[:, (i - 1) * n_refs :]) / root[:, None]
    if np.array_equal(references, np.arange(n_channels)):
        output_covariance = correlations[0]  # Λ₀ = R_0 = Σ y yᵀ / N, already summed
    else:
        output_covariance = data.T @ data / n_samples
    system = StochasticStateSpace(
        state_matrix=state,
        output_matrix=output,
        next_state_output_covariance=next_state_output,
        output_covariance=output_covariance,
        reference_channels=tuple(int(c) for c in references),
    )
    return _assemble(poles, orders, sampling_rate_hz, i, s, references, "ssi-cov", system)


# --------------------------------------------------------------------------- SSI-data
@_single_threaded
def ssi_data(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    *,
    block_rows: int = DEFAULT_BLOCK_ROWS,
    orders: Sequence[int] = DEFAULT_ORDERS,
    reference_channels: Sequence[int] | None = None,
    weighting: Weighting = "pc",
) -> SSIResult:
    """Data-driven stochastic subspace identification (reference-based).

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Measured accelerations, finite (drop dead channels first). [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    block_rows : int
        Number of block rows i (past and future horizons). max(orders) <= min(r·i, l·(i-1)).
    orders : sequence of int
        Model orders of the stabilisation diagram.
    reference_channels : sequence of int, optional
        Columns used as references for the past outputs. Default: all.
    weighting : {"pc", "upc", "cva"}
        Weighting of the projection before the SVD: principal components (PC), unweighted
        principal components (UPC) or canonical variate analysis (CVA).

    Returns
    -------
    SSIResult
        Poles of every order with shapes; ``system`` holds A, C, the noise covariances
        Q, R, S, the state covariance Σ, G, Λ₀, the Kalman gain K and the innovation
        covariance of the largest order.

    Raises
    ------
    ValueError
        NaN/inf in a channel (the message names its column index), too few samples, orders
        beyond what *block_rows* allows, or an unknown weighting.

    Notes
    -----
    The block Hankel matrix (normalised by 1/√j, j = N - 2i + 1) with the past references
    on top and the future outputs below (references first within a block row) has the LQ
    decomposition

    .. math::

        H = \\begin{pmatrix} Y_p^{ref} \\\\ Y_f \\end{pmatrix}
          = \\begin{pmatrix} L_{11} & 0 \\\\ L_{21} & L_{22} \\end{pmatrix}
            \\begin{pmatrix} Q_1^T \\\\ Q_2^T \\end{pmatrix}.

    L is computed as the Cholesky factor of H Hᵀ = L Lᵀ, whose blocks are the full lagged
    sums minus short edge sums (exact, O(N l²) work, never forming H or Q). The projection
    of the future on the past references is P_i = Y_f / Y_p^{ref} = L₂₁Q₁ᵀ = O_i X̂_i. The
    weighted matrix W₁P_iW₂ has the left singular vectors and singular values of

    - UPC (W₁ = W₂ = I): L₂₁;
    - PC (W₂ = Y_pᵀ(Y_pY_pᵀ)^{-1/2}Y_p): L₂₁L₁₁ᵀ (the covariance matrix Y_fY_pᵀ: PC is
      the data-driven twin of SSI-cov);
    - CVA (W₁ = (Y_fY_fᵀ)^{-1/2}, here its Cholesky version L_f⁻¹ with L_fL_fᵀ = Y_fY_fᵀ):
      L_f⁻¹L₂₁, and O_i = L_f U₁S₁^{1/2}.

    Every order then follows from one SVD as in :func:`ssi_cov`. At the largest order:

    - noise covariances: the Kalman state sequences X̂_i = O_i⁺P_i and
      X̂_{i+1} = O_{i-1}⁺P_{i-1} (P_{i-1} = Y_f⁻ / Y_p^{ref+}) give the residuals
      ρ_w = X̂_{i+1} - AX̂_i and ρ_v = Y_{i|i} - CX̂_i, whose covariance is
      [[Q, S], [Sᵀ, R]] [2]_; the state covariance solves the Lyapunov equation
      Σ = AΣAᵀ + Q (:func:`scipy.linalg.solve_discrete_lyapunov`; only for a stable A);
    - G and Λ₀: from the measured correlations, G = O_i⁺[R_1; …; R_i] (least squares of
      R_k = CA^{k-1}G) and Λ₀ = R₀. (The residual route G = AΣCᵀ + S, Λ₀ = CΣCᵀ + R is
      biased for finite i because the X̂ come from non-steady Kalman filters.)
    - Kalman gain and innovation covariance of the steady-state Kalman predictor (forward
      innovation model x̂_{k+1} = Ax̂_k + Ke_k, y_k = Cx̂_k + e_k) of the noise model,
      from the discrete algebraic Riccati equation
      (:func:`scipy.linalg.solve_discrete_are`, always solvable for PSD Q, R)

      .. math::

          P = APAᵀ + Q - (APCᵀ + S)(CPCᵀ + R)^{-1}(APCᵀ + S)ᵀ,

          K = (APCᵀ + S)(CPCᵀ + R)^{-1}, \\quad E[eeᵀ] = CPCᵀ + R.

      The residual noise model carries the finite-i bias of the non-steady Kalman states
      (it shrinks as A^i); the positive-real route P = APAᵀ + (G - APCᵀ)(Λ₀ - CPCᵀ)⁻¹(…)ᵀ
      would avoid it but fails whenever the identified (A, C, G, Λ₀) is not positive real,
      which is common for acceleration data (broadband feedthrough).

    References
    ----------
    .. [1] B. Peeters, G. De Roeck, "Reference-based stochastic subspace identification
       for output-only modal analysis", MSSP 13(6), 855-878, 1999.
       doi:10.1006/mssp.1999.1249
    .. [2] P. Van Overschee, B. De Moor, "Subspace Identification for Linear Systems",
       Kluwer, 1996, ch. 3. doi:10.1007/978-1-4613-0465-4
    """
    if weighting not in _WEIGHTINGS:
        raise ValueError(f"weighting={weighting!r} must be one of {_WEIGHTINGS}")
    data, references, orders = _prepare(
        acceleration, sampling_rate_hz, block_rows, orders, reference_channels
    )
    n_samples, n_channels = data.shape
    i = int(block_rows)
    n_refs = references.size
    # references first: then Y_{i|i}^{ref} is the first block of the future rows
    others = np.setdiff1d(np.arange(n_channels), references)
    channel_order = np.concatenate([references, others])
    data = data[:, channel_order]

    lag_sums = _lagged_products(data, 2 * i - 1, np.arange(n_channels))
    gram_all = _hankel_gram(data, 2 * i, lag_sums)
    past = (np.arange(i)[:, None] * n_channels + np.arange(n_refs)[None, :]).ravel()
    future = np.arange(i * n_channels, 2 * i * n_channels)
    rows = np.concatenate([past, future])
    n_columns = n_samples - 2 * i + 1
    gram = gram_all[np.ix_(rows, rows)] / n_columns
    lower = _cholesky(gram, "block Hankel matrix")
    p = n_refs * i  # past rows
    l11 = lower[:p, :p]
    l21 = lower[p:, :p]

    unweight = None
    if weighting == "upc":
        weighted = l21
    elif weighting == "pc":
        weighted = l21 @ l11.T
    else:  # cva
        unweight = _cholesky(gram[p:, p:], "future output covariance")
        weighted = linalg.solve_triangular(unweight, l21, lower=True, check_finite=False)
    n_max = orders[-1]
    u, s = _leading_singular(weighted, n_max + _EXTRA_SINGULAR_VALUES)
    _order_limits(n_max, s)
    basis = u[:, :n_max] if unweight is None else unweight @ u[:, :n_max]
    poles = poles_all_orders(basis, n_channels, orders, sampling_rate_hz)

    root = np.sqrt(s[:n_max])
    observability = basis * root
    correlations = lag_sums[: i + 1] / (n_samples - np.arange(i + 1))[:, None, None]
    system = _stochastic_model(
        observability,
        _realisation(poles, basis, root, n_channels),
        lower,
        correlations,
        p,
        references,
        channel_order,
    )
    return _assemble(
        poles,
        orders,
        sampling_rate_hz,
        i,
        s,
        references,
        f"ssi-data/{weighting}",
        system,
        channel_order=channel_order,
    )


def _kalman_from_noise(
    state: np.ndarray, output: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steady-state Kalman predictor (P, K, E[eeᵀ]) from the noise covariances Q, R, S."""
    # P = APAᵀ + Q - (APCᵀ + S)(CPCᵀ + R)⁻¹(APCᵀ + S)ᵀ  (dual of the control DARE)
    predicted = linalg.solve_discrete_are(state.T, output.T, q, r, s=s)
    predicted = 0.5 * (predicted + predicted.T)
    innovation = output @ predicted @ output.T + r  # E[eeᵀ] = CPCᵀ + R
    innovation = 0.5 * (innovation + innovation.T)
    # K = (APCᵀ + S)(CPCᵀ + R)⁻¹
    gain = linalg.solve(innovation, (state @ predicted @ output.T + s).T, assume_a="pos").T
    return predicted, gain, innovation


def _stochastic_model(
    observability: np.ndarray,
    realisation: tuple[np.ndarray, np.ndarray],
    lower: np.ndarray,
    correlations: np.ndarray,
    p: int,
    references: np.ndarray,
    channel_order: np.ndarray,
) -> StochasticStateSpace:
    """A, C, G, Λ₀, Q, R, S, Σ, P, K and E[eeᵀ] at the largest order (see :func:`ssi_data`).

    *realisation* is (A, C) of *observability* (:func:`_realisation`); *correlations* are
    R_k = E[y_{t+k} y_tᵀ], k = 0..i (permuted channel order). Row
    spaces of the state and output sequences are expressed in the orthonormal basis Qᵀ of
    the LQ decomposition, so a product X Yᵀ of two sequences is the product of their
    coordinate matrices.
    """
    n = observability.shape[1]
    n_channels = correlations.shape[1]
    block_rows = observability.shape[0] // n_channels
    n_refs = references.size
    width = p + n_channels  # coordinates up to the end of Y_{i|i}
    state, output = realisation
    # G from R_k = C A^{k-1} G, k = 1..i:  G = O_i⁺ [R_1; ...; R_i]
    stacked = correlations[1 : block_rows + 1].reshape(block_rows * n_channels, n_channels)
    next_state_output = linalg.lstsq(observability, stacked, check_finite=False)[0]
    output_covariance = correlations[0]
    # Kalman state sequences X_i = O_i⁺ P_i (P_i = L21 Q1ᵀ) and
    # X_{i+1} = O_{i-1}⁺ P_{i-1} (P_{i-1} = Y_{i+1|2i-1} / [Y_p^ref; Y_{i|i}^ref])
    x_now = np.zeros((n, width))
    x_now[:, :p] = linalg.lstsq(observability, lower[p:, :p], check_finite=False)[0]
    x_next = np.zeros((n, width))
    x_next[:, : p + n_refs] = linalg.lstsq(
        observability[:-n_channels], lower[p + n_channels :, : p + n_refs], check_finite=False
    )[0]
    y_now = lower[p : p + n_channels, :width]  # Y_{i|i}
    residual_w = x_next - state @ x_now  # ρ_w = X_{i+1} - A X_i
    residual_v = y_now - output @ x_now  # ρ_v = Y_{i|i} - C X_i
    q = residual_w @ residual_w.T
    r = residual_v @ residual_v.T
    s = residual_w @ residual_v.T

    restore = np.argsort(channel_order)  # input column c is permuted channel restore[c]
    output = output[restore]
    next_state_output = next_state_output[:, restore]
    output_covariance = output_covariance[np.ix_(restore, restore)]
    r = r[np.ix_(restore, restore)]
    s = s[:, restore]
    fields: dict = {
        "state_matrix": state,
        "output_matrix": output,
        "next_state_output_covariance": next_state_output,
        "output_covariance": output_covariance,
        "reference_channels": tuple(int(c) for c in references),
        "process_noise_covariance": q,
        "measurement_noise_covariance": r,
        "cross_noise_covariance": s,
    }
    if np.abs(np.linalg.eigvals(state)).max() < 1.0:
        # Σ = AΣAᵀ + Q
        sigma = linalg.solve_discrete_lyapunov(state, q)
        fields["state_covariance"] = 0.5 * (sigma + sigma.T)
    try:
        predicted, gain, innovation = _kalman_from_noise(state, output, q, r, s)
    except (linalg.LinAlgError, ValueError) as error:
        warnings.warn(
            f"no Kalman gain at order {n}: the Riccati equation has no stabilising "
            f"solution ({error})",
            SSIWarning,
            stacklevel=3,
        )
        return StochasticStateSpace(**fields)
    fields["predicted_state_covariance"] = predicted
    fields["kalman_gain"] = gain
    fields["innovation_covariance"] = innovation
    return StochasticStateSpace(**fields)
