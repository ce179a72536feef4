"""Covariance-driven SSI (:func:`ssi_cov`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..modal import OrderPoles, poles_all_orders
from .decomposition import _leading_singular
from .hankel import _halves_lagged_products, _lagged_products, _toeplitz_gram
from .preparation import (
    _EXTRA_SINGULAR_VALUES,
    DEFAULT_BLOCK_ROWS,
    DEFAULT_ORDERS,
    _check_length,
    _order_limits,
    _prepare,
    _single_threaded,
)
from .realisation import _assemble, _realisation
from .results import SSIResult, StochasticStateSpace

__all__ = ["ssi_cov", "ssi_cov_halves"]


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
    toeplitz, u, s, poles = _toeplitz_poles(correlations, orders, sampling_rate_hz)
    n_max = orders[-1]
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
    return _assemble(
        poles,
        orders,
        sampling_rate_hz,
        i,
        s,
        references,
        "ssi-cov",
        system,
        output_correlations=correlations,
    )


def _toeplitz_poles(
    correlations: np.ndarray,
    orders: tuple[int, ...],
    sampling_rate_hz: float,
    extra: int = _EXTRA_SINGULAR_VALUES,
):
    """Block Toeplitz matrix T of *correlations* (R_0 .. R_{2i-1}, each l x r), its leading
    left singular vectors and singular values (the largest order plus *extra*) and the
    poles of every order in *orders* (sorted)."""
    i = correlations.shape[0] // 2
    n_channels, n_refs = correlations.shape[1:]
    rows, cols = np.meshgrid(np.arange(i), np.arange(i), indexing="ij")
    toeplitz = (
        correlations[i + rows - cols].transpose(0, 2, 1, 3).reshape(i * n_channels, i * n_refs)
    )
    n_max = orders[-1]
    u, s = _leading_singular(toeplitz, n_max + extra, gram=_toeplitz_gram(correlations, toeplitz))
    _order_limits(n_max, s)
    poles = poles_all_orders(u[:, :n_max], n_channels, orders, sampling_rate_hz)
    return toeplitz, u, s, poles


@_single_threaded
def ssi_cov_halves(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    whole_correlations: np.ndarray,
    *,
    block_rows: int = DEFAULT_BLOCK_ROWS,
    orders: Sequence[int] = DEFAULT_ORDERS,
    reference_channels: Sequence[int] | None = None,
) -> tuple[OrderPoles, OrderPoles]:
    """Poles of :func:`ssi_cov` on each half of a record (the first N // 2 samples and the
    rest), from the whole record's output correlations and one FFT pass.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        The whole record, as given to :func:`ssi_cov`. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    whole_correlations : ndarray, shape (2·block_rows, n_channels, n_references)
        ``output_correlations`` of :func:`ssi_cov` on the whole *acceleration* with the
        same *block_rows* and *reference_channels*.
    block_rows, orders, reference_channels
        As for :func:`ssi_cov`; each half must allow them.

    Returns
    -------
    (OrderPoles, OrderPoles)
        Poles and shapes of every order of the first and the second half
        (:func:`~workbench.sid.modal.poles_all_orders`), without the system matrices and the
        stability flags of an :class:`SSIResult`.

    Raises
    ------
    ValueError
        As :func:`ssi_cov` on either half (too few samples for *block_rows*, fewer states
        than the largest order), or correlations that do not fit the record.

    Notes
    -----
    The halves are centred on their own means, as :func:`ssi_cov` on each alone. The
    second half's lagged products are computed from it (with a shorter FFT), the first
    half's are the whole record's less the second half's and the products across the
    middle (:func:`~workbench.sid.ssi.hankel._halves_lagged_products`): both equal those of
    :func:`ssi_cov` on each half up to rounding of order ε·|R_0|. The lagged products were
    most of the cost of SSI-cov on a half (``benchmarks/results/halves_cost_40.txt``).
    """
    acceleration = np.asarray(acceleration)
    n_whole = acceleration.shape[0]
    middle = n_whole // 2
    # the checks of ssi_cov on each half: both have the same channels, the first is shorter
    data, references, orders = _prepare(
        acceleration[middle:], sampling_rate_hz, block_rows, orders, reference_channels
    )
    i = int(block_rows)
    n_channels = data.shape[1]
    _check_length(middle, n_channels, references.size, i)
    if np.shape(whole_correlations) != (2 * i, n_channels, references.size):
        raise ValueError(
            f"whole_correlations of shape {np.shape(whole_correlations)} do not fit "
            f"block_rows={i} with {n_channels} channels and {references.size} references"
        )
    lags = np.arange(2 * i)
    whole_sums = whole_correlations * (n_whole - lags)[:, None, None]
    halves = _halves_lagged_products(acceleration, data, whole_sums, 2 * i - 1, references)
    poles = []
    for sums, n_samples in zip(halves, (middle, n_whole - middle), strict=True):
        correlations = sums / (n_samples - lags)[:, None, None]
        # no singular values beyond the largest order (dstemr: 4.9 ms for 60, 6.1 for 70)
        poles.append(_toeplitz_poles(correlations, orders, sampling_rate_hz, extra=0)[3])
    return poles[0], poles[1]
