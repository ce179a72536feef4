"""Data-driven SSI (:func:`ssi_data`) with PC, UPC and CVA weighting."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..modal import poles_all_orders
from .decomposition import _leading_singular
from .hankel import _cholesky, _hankel_gram, _lagged_products
from .preparation import (
    _EXTRA_SINGULAR_VALUES,
    _WEIGHTINGS,
    DEFAULT_BLOCK_ROWS,
    DEFAULT_ORDERS,
    Weighting,
    _order_limits,
    _prepare,
    _single_threaded,
)
from .realisation import _assemble, _realisation, _stochastic_model
from .results import SSIResult

__all__ = ["ssi_data"]


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
    n_max = orders[-1]
    projection = _weighted_projection(
        data, i, references, weighting, n_max, n_max + _EXTRA_SINGULAR_VALUES
    )
    channel_order, lag_sums = projection.channel_order, projection.lag_sums
    lower, p, basis, s = (
        projection.lower,
        projection.past_rows,
        projection.basis,
        projection.singular_values,
    )
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


@dataclass(frozen=True, eq=False)
class _WeightedProjection:
    """The LQ factor of the reference-based block Hankel matrix and the observability basis
    from the SVD of the weighted projection (:func:`ssi_data`, Notes); channels permuted
    references first (``channel_order``)."""

    channel_order: np.ndarray
    lag_sums: np.ndarray  # lagged products of the permuted channels, lags 0 .. 2i-1
    lower: np.ndarray  # L of H = L Qᵀ, [Y_p^ref; Y_f] normalised by 1/√j
    past_rows: int  # p = r·i rows of the past references
    basis: np.ndarray  # U₁ (L_f U₁ for CVA): O_i = basis · S₁^{1/2}, n_max columns
    singular_values: np.ndarray  # the leading singular values of W₁ P_i W₂


def _weighted_projection(
    data: np.ndarray,
    block_rows: int,
    references: np.ndarray,
    weighting: Weighting,
    n_max: int,
    n_singular: int,
) -> _WeightedProjection:
    """LQ factor of mean-free *data* and the observability basis of order *n_max* from the
    *n_singular* leading singular triplets of the weighted projection (see :func:`ssi_data`)."""
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
    u, s = _leading_singular(weighted, n_singular)
    _order_limits(n_max, s)
    basis = u[:, :n_max] if unweight is None else unweight @ u[:, :n_max]
    return _WeightedProjection(channel_order, lag_sums, lower, p, basis, s)
