"""Total prediction error (TPE) of the SSI-data innovation model, per model order.

SSI-data identifies, besides the poles, a stochastic model of the data: the noise
covariances Q, R, S and from them the steady-state Kalman gain K of the innovation form
x̂_{k+1} = A x̂_k + K e_k, y_k = C x̂_k + e_k (:func:`workbench.sid.ssi.ssi_data`). That
model predicts every sample one step ahead from the past ones; how much of the measured
signal it leaves unexplained, order by order, is a data-driven guide to the model order
(the error stops falling once the physical modes are in) that does not rely on the
stabilisation diagram.

References
----------
.. [1] P. Van Overschee, B. De Moor, "Subspace Identification for Linear Systems",
   Kluwer, 1996, ch. 3 (Kalman states and the innovation model of SSI-data).
   doi:10.1007/978-1-4613-0465-4
.. [2] L. Ljung, "System Identification: Theory for the User", 2nd ed., Prentice Hall,
   1999, ch. 16 (choice of model order from prediction errors).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import linalg, signal

from .ssi import SSIWarning
from .ssi.data_driven import _weighted_projection
from .ssi.preparation import DEFAULT_BLOCK_ROWS, DEFAULT_ORDERS, Weighting, _prepare
from .ssi.realisation import _stochastic_model
from .threads import sid_threads

__all__ = ["PredictionErrors", "one_step_prediction", "total_prediction_error"]


@dataclass(frozen=True, eq=False)
class PredictionErrors:
    """Total prediction error of the innovation model of every model order.

    Parameters
    ----------
    orders : tuple of int
        Model orders (state dimensions).
    total_prediction_error : ndarray, shape (n_orders,)
        TPE on the data: mean over channels of Σ_k e_ck² / Σ_k y_ck² after the warm-up
        (0: perfect one-step prediction, 1: no better than predicting zero); NaN where
        the order has no Kalman gain. [-]
    channel_errors : ndarray, shape (n_orders, n_channels)
        The same per channel. [-]
    model_prediction_error : ndarray, shape (n_orders,)
        What the model itself expects: mean over channels of diag(E[eeᵀ]) / diag(Λ₀). [-]
    warm_up : int
        Samples left out at the start (the predictor starts from x̂ = 0).
    """

    orders: tuple[int, ...]
    total_prediction_error: np.ndarray
    channel_errors: np.ndarray
    model_prediction_error: np.ndarray
    warm_up: int

    def frame(self) -> pd.DataFrame:
        """``model_order``, ``total_prediction_error``, ``model_prediction_error``."""
        return pd.DataFrame(
            {
                "model_order": np.asarray(self.orders, dtype=np.int64),
                "total_prediction_error": self.total_prediction_error,
                "model_prediction_error": self.model_prediction_error,
            }
        )


def one_step_prediction(
    data: np.ndarray, state_matrix: np.ndarray, output_matrix: np.ndarray, gain: np.ndarray
) -> np.ndarray:
    """One-step-ahead predictions ŷ_k = C x̂_k of the innovation model, x̂_0 = 0.

    Parameters
    ----------
    data : ndarray, shape (n_samples, n_channels)
        Measured outputs y_k (mean-free).
    state_matrix, output_matrix, gain : ndarray
        A (n, n), C (n_channels, n), K (n, n_channels).

    Returns
    -------
    ndarray, shape (n_samples, n_channels)

    Notes
    -----
    The predictor x̂_{k+1} = (A - KC) x̂_k + K y_k is diagonalised, F = A - KC = VΛV⁻¹, so
    every modal coordinate z = V⁻¹x̂ is a first-order recursion z_{k+1} = λ z_k + (V⁻¹K y)_k
    run by :func:`scipy.signal.lfilter` (compiled, no Python loop over samples); one of
    each conjugate pair suffices. If V is too ill-conditioned for that, the recursion runs
    on x̂ directly.
    """
    closed = state_matrix - gain @ output_matrix  # F = A - KC
    values, vectors = linalg.eig(closed)
    if np.linalg.cond(vectors) < 1e8:
        # F is real: of a conjugate pair only the member with Im λ > 0 is run, its
        # contribution doubled in the real part of ŷ; real eigenvalues count once
        keep = values.imag >= 0
        weight = np.where(values[keep].imag > 0, 2.0, 1.0)
        drive = linalg.solve(vectors, gain)[keep] @ data.T  # u_k = V⁻¹K y_k, (m, n_samples)
        modal = np.empty(drive.shape, dtype=complex)
        for m, value in enumerate(values[keep]):
            # z_{k+1} = λ z_k + u_k, z_0 = 0  ->  z = filter(b=[0, 1], a=[1, -λ], u)
            modal[m] = signal.lfilter([0.0, 1.0], [1.0, -value], drive[m])
        return (((output_matrix @ vectors[:, keep]) * weight) @ modal).real.T  # ŷ = C V z
    return _predict_by_loop(data, closed, output_matrix, gain)


def _predict_by_loop(data, closed, output_matrix, gain) -> np.ndarray:
    """ŷ_k = C x̂_k with x̂_{k+1} = F x̂_k + K y_k, x̂_0 = 0, sample by sample."""
    predicted = np.empty(data.shape)
    state = np.zeros(closed.shape[0])
    driven = data @ gain.T
    for k in range(data.shape[0]):
        predicted[k] = output_matrix @ state  # ŷ_k = C x̂_k
        state = closed @ state + driven[k]  # x̂_{k+1} = (A - KC) x̂_k + K y_k
    return predicted


def total_prediction_error(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    *,
    block_rows: int = DEFAULT_BLOCK_ROWS,
    orders: Sequence[int] = DEFAULT_ORDERS,
    reference_channels: Sequence[int] | None = None,
    weighting: Weighting = "pc",
    warm_up: int | None = None,
) -> PredictionErrors:
    """Total prediction error of the SSI-data innovation model of every model order.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Measured responses, finite. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    block_rows, orders, reference_channels, weighting
        As for :func:`workbench.sid.ssi.ssi_data` (same decomposition, same models).
    warm_up : int, optional
        Samples left out of the error sums (default: a tenth of the record).

    Returns
    -------
    PredictionErrors

    Notes
    -----
    For order n the first n columns of the SSI-data observability basis give A_n (shift
    equation) and C_n; the Kalman state sequences of that order give Q, R, S, and the
    discrete algebraic Riccati equation the gain K_n (as :func:`~workbench.sid.ssi.
    ssi_data` does at its largest order). The innovation model then predicts the block
    itself (:func:`one_step_prediction`), and

    .. math::

        \\mathrm{TPE}(n) = \\frac{1}{l}\\sum_{c=1}^{l}
            \\frac{\\sum_k (y_{ck} - \\hat y_{ck}(n))^2}{\\sum_k y_{ck}^2}.

    Each channel is normalised by its own energy, so mixed units (velocity beside
    acceleration) weigh alike. For a scalar AR(1) process y_{k+1} = a y_k + e_k the exact
    value is 1 - a².
    """
    data, references, orders = _prepare(
        acceleration, sampling_rate_hz, block_rows, orders, reference_channels
    )
    if weighting not in ("pc", "upc", "cva"):
        raise ValueError(f"weighting={weighting!r} must be one of ('pc', 'upc', 'cva')")
    n_samples, n_channels = data.shape
    if warm_up is None:
        warm_up = n_samples // 10
    if int(warm_up) != warm_up or not 0 <= warm_up < n_samples // 2:
        raise ValueError(f"warm_up={warm_up} must be an integer in [0, {n_samples // 2})")
    warm_up = int(warm_up)
    i = int(block_rows)
    with sid_threads():
        n_max = orders[-1]
        projection = _weighted_projection(data, i, references, weighting, n_max, n_max)
        channel_order, lag_sums = projection.channel_order, projection.lag_sums
        lower, p = projection.lower, projection.past_rows
        observability = projection.basis * np.sqrt(projection.singular_values[:n_max])
        correlations = lag_sums[: i + 1] / (n_samples - np.arange(i + 1))[:, None, None]

        energy = np.sum(data[warm_up:] ** 2, axis=0)
        energy = np.where(energy > 0, energy, 1.0)
        channel_errors = np.full((len(orders), n_channels), np.nan)
        model_errors = np.full(len(orders), np.nan)
        for row, n in enumerate(orders):
            gamma = observability[:, :n]
            # A_n from the shift structure, C_n the first block row
            state = linalg.lstsq(gamma[:-n_channels], gamma[n_channels:], check_finite=False)[0]
            output = gamma[:n_channels]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SSIWarning)
                model = _stochastic_model(
                    gamma, (state, output), lower, correlations, p, references, channel_order
                )
            if model.kalman_gain is None or model.innovation_covariance is None:
                continue
            predicted = one_step_prediction(
                data, model.state_matrix, model.output_matrix, model.kalman_gain
            )
            error = data[warm_up:] - predicted[warm_up:]
            channel_errors[row] = np.sum(error**2, axis=0) / energy
            model_errors[row] = np.mean(
                np.diag(model.innovation_covariance) / np.diag(model.output_covariance)
            )
    return PredictionErrors(
        orders=tuple(orders),
        total_prediction_error=channel_errors.mean(axis=1),
        channel_errors=channel_errors,
        model_prediction_error=model_errors,
        warm_up=warm_up,
    )
