"""From the decomposition to the identified system: the state-space matrices A and C, the
noise covariances and steady-state Kalman predictor (SSI-data), and the assembled
:class:`~workbench.sid.ssi.SSIResult` with stability flags and MPC."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import linalg

from ..modal import modal_phase_collinearity
from ..stabilisation import StabilityCriteria, stability_flags
from .results import SSIResult, SSIWarning, StochasticStateSpace


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
    output_correlations: np.ndarray | None = None,
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
        output_correlations=output_correlations,
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
