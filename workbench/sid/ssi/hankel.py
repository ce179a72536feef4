"""Output correlations and the Gram matrices of the block Hankel (SSI-data) and block
Toeplitz (SSI-cov) matrices, computed exactly without forming the matrices."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy import fft, linalg

from ..threads import thread_budget

#: Shortest FFT of :func:`_lagged_products` (the default; a longer one for long lags). [-]
_LAGGED_FFT_LENGTH = 2048
#: The FFT length the halves of a block use (:func:`_halves_lagged_products`): with lags up
#: to 39, 512 took 2/3 of the time of 2048 on a 19-channel half block (the inverse FFT of
#: every channel pair is 4 times shorter; ``benchmarks/results/halves_cost_40.txt``). [-]
_HALVES_FFT_LENGTH = 512


def _lagged_products(
    data: np.ndarray,
    max_lag: int,
    columns: np.ndarray,
    shortest_fft: int = _LAGGED_FFT_LENGTH,
) -> np.ndarray:
    """Sums of lagged products S[d] = Σ_{m=0}^{N-1-d} y_{m+d} y_m[columns]ᵀ, d = 0..max_lag.

    Returns an array (max_lag + 1, n_channels, n_columns). Computed exactly (up to
    rounding) by segmented FFT correlation: the record is cut into segments of length
    L = n_fft - max_lag; segment s of the reference columns (zero padded) is correlated
    circularly with the data from the segment start over L + max_lag samples, which has no
    wrap-around for lags up to max_lag, and the cross spectra are summed over segments
    before one inverse FFT. Cost O(N l r) instead of O(N l r max_lag) for direct sums.
    n_fft is at least *shortest_fft* and 8 (max_lag + 1); it changes the sums only by
    rounding.
    """
    n_samples, n_channels = data.shape
    workers = thread_budget()
    n_fft = fft.next_fast_len(max(8 * (max_lag + 1), shortest_fft), real=True)
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


def _halves_lagged_products(
    acceleration: np.ndarray,
    second_centred: np.ndarray,
    whole_sums: np.ndarray,
    max_lag: int,
    columns: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Lagged-product sums S[d] (as :func:`_lagged_products`) of each half of a record, the
    first n₁ = N // 2 samples and the rest, each half centred on its own mean, from the sums
    of the whole record centred on its mean (*whole_sums*) and one FFT pass over the second
    half (*second_centred*: ``acceleration[n₁:]`` less its mean).

    Notes
    -----
    With x the record centred on its whole mean and A[d] = Σ_{k=a}^{b-1-d} x_{k+d} x_k[c]ᵀ
    the sums over a stretch [a, b), the whole record's sums split into those of its halves
    and the d products that cross the middle:

    .. math::

        S[d] = A_1[d] + A_2[d] + \\sum_{j<d} x_{n_1+j} x_{n_1-d+j}[c]^T.

    A stretch of n_h samples centred on its own mean, w = x - δ, has the sums

    .. math::

        S_h[d] = A[d] - \\Big(\\sum_{k=d}^{n_h-1} w_k\\Big) δ[c]^T
                 - δ \\Big(\\sum_{k=0}^{n_h-1-d} w_k[c]\\Big)^T - (n_h - d)\\, δ δ[c]^T,

    where both sums are w's total (zero up to rounding) less d samples at one end. The
    second half's sums come from :func:`_lagged_products` of the half alone (with the
    shorter FFT :data:`_HALVES_FFT_LENGTH`), the first half's from the whole record's less
    the second half's and the crossing products: one FFT pass instead of two and no pass
    over the first half but its sum, the same sums up to rounding of order ε·|S[0]|
    (``tests/sid/test_ssi_cov_halves.py``).
    """
    data = np.asarray(acceleration, dtype=float)
    n_samples, n_channels = data.shape
    middle = n_samples // 2
    lags = np.arange(max_lag + 1)
    first_sum = data[:middle].sum(axis=0)
    first_mean = first_sum / middle
    second_mean = data[middle:].mean(axis=0)  # as the second half was centred
    whole_mean = (middle * first_mean + (n_samples - middle) * second_mean) / n_samples
    second = _lagged_products(second_centred, max_lag, columns, _HALVES_FFT_LENGTH)

    def centring(ends: np.ndarray, total: np.ndarray, n_h: int, delta: np.ndarray):
        # S_h[d] - A[d] from the first and last max_lag samples of w (ends) and its total
        head = np.zeros((max_lag + 1, n_channels))  # Σ_{k<d} w_k
        np.cumsum(ends[:max_lag], axis=0, out=head[1:])
        tail = np.zeros((max_lag + 1, n_channels))  # Σ_{k>=n_h-d} w_k
        np.cumsum(ends[::-1][:max_lag], axis=0, out=tail[1:])
        later = total - head  # Σ_{k=d}^{n_h-1} w_k
        earlier = (total - tail)[:, columns]  # Σ_{k=0}^{n_h-1-d} w_k[c]
        return -(
            (n_h - lags)[:, None, None] * np.outer(delta, delta[columns])
            + later[:, :, None] * delta[columns]
            + delta[:, None] * earlier[:, None, :]
        )

    second_ends = np.concatenate([second_centred[:max_lag], second_centred[-max_lag:]])
    second_whole = second - centring(
        second_ends,
        second_centred.sum(axis=0),
        n_samples - middle,
        second_mean - whole_mean,
    )  # A₂
    # x around the middle, and the products that cross it: Σ_{j<d} x_{n₁+j} x_{n₁-d+j}[c]ᵀ
    near = data[middle - max_lag : middle + max_lag] - whole_mean
    crossing = np.zeros_like(second)
    for d in range(1, max_lag + 1):
        crossing[d] = near[max_lag : max_lag + d].T @ near[max_lag - d : max_lag, columns]
    first_whole = whole_sums - second_whole - crossing  # A₁
    first_ends = np.concatenate([data[:max_lag], data[middle - max_lag : middle]]) - first_mean
    first_total = first_sum - middle * first_mean
    return first_whole + centring(first_ends, first_total, middle, first_mean - whole_mean), second


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
