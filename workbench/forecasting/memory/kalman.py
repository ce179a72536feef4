"""Kalman step of the memory forecast: two states (model correction c, identification
error e) per mode, H = [1 1], Huber-weighted update, Joseph-form covariance.

Used by :func:`~workbench.forecasting.memory.forecast.memory_forecast` (model in that module's docs).
"""

from __future__ import annotations

import numpy as np

from ..noise import NoiseModel

__all__ = ["kalman_pass_step", "stationary_covariance"]


def kalman_pass_step(
    state,
    P,
    F,
    Q,
    residual,
    R,
    huber_sigma,
    model_variance=None,
    previous_run=None,
    persist_blocks=3,
):
    """One predict + update of the two-state filter for several modes at once.

    Parameters
    ----------
    state : ndarray (n, 2)
        [c, e] a-posteriori of the previous block.
    P : ndarray (n, 2, 2)
    F : ndarray (n, 2)
        Diagonal of F: (φ, ρ).
    Q : ndarray (n, 2)
        Diagonal of Q.
    residual : ndarray (n,)
        z - m (NaN: predict only). [Hz]
    R : ndarray (n,)
        White measurement variance. [Hz²]
    huber_sigma : float or ndarray (n,)
    model_variance : ndarray (n,), optional
        s_m², variance of the model's mean prediction in this block: a white error of the
        model term, x = m + δ + c with δ ~ N(0, s_m²). [Hz²]
    previous_run : ndarray of int (n,), optional
        Signed count of the consecutive measured blocks just before, whose normalised
        innovation was beyond *huber_sigma* (+: above, -: below). When this block's makes
        the run *persist_blocks* long, the model is wrong, not the measurement: no Huber
        weight, and P_cc is raised to y² (gain on c about 1). Shorter runs are what an
        AR(1) identification error with heavy tails produces and get the Huber weight.
    persist_blocks : int

    Returns
    -------
    state, P, white model correction δ̂ (n,), normalised innovation y/sqrt(S) (n,), and
    the innovation variance S (n,) the normalisation used [Hz²] (NaN: no measurement)
    """
    # x = Fx ; P = FPF' + Q
    state = state * F
    P = P * (F[:, :, None] * F[:, None, :])
    P[:, 0, 0] += Q[:, 0]
    P[:, 1, 1] += Q[:, 1]
    n = state.shape[0]
    delta = np.zeros(n)
    normalised = np.full(n, np.nan)
    variance = np.full(n, np.nan)
    ok = np.isfinite(residual)
    if not ok.any():
        return state, P, delta, normalised, variance
    idx = np.flatnonzero(ok)
    Pm, xm = P[idx], state[idx]
    sm2 = np.zeros(idx.size) if model_variance is None else model_variance[idx]
    # y = z - Hx ; S = HPH' + R + s_m²  (H = [1 1])
    y = residual[idx] - xm.sum(axis=1)
    S = Pm[:, 0, 0] + Pm[:, 1, 1] + 2 * Pm[:, 0, 1] + R[idx] + sm2
    nu = y / np.sqrt(S)
    normalised[idx] = nu
    variance[idx] = S
    huber_sigma = np.broadcast_to(np.asarray(huber_sigma, dtype=float), (n,))[idx]
    keep_on = np.zeros(idx.size, dtype=bool)
    if previous_run is not None:
        before = previous_run[idx]
        keep_on = (np.abs(nu) > huber_sigma) & (np.abs(before) >= persist_blocks - 1)
        keep_on &= np.sign(nu) == np.sign(before)
    if keep_on.any():  # the model is off: P_cc ← max(P_cc, y²)
        grow = np.maximum(y[keep_on] ** 2 - Pm[keep_on, 0, 0], 0.0)
        Pm[keep_on, 0, 0] += grow
        S[keep_on] += grow
    # Huber weight: beyond huber_sigma sqrt(S) an isolated measurement counts as if it
    # were there, i.e. R ← R + S (ν/k - 1), ν = |y| / sqrt(S)
    a = np.abs(nu)
    extra = np.where((a > huber_sigma) & ~keep_on, S * (a / huber_sigma - 1.0), 0.0)
    R_eff = R[idx] + extra
    S = S + extra
    delta[idx] = sm2 / S * y  # δ̂ = s_m² S⁻¹ y
    # K = PH'S⁻¹
    PH = np.stack([Pm[:, 0, 0] + Pm[:, 0, 1], Pm[:, 1, 0] + Pm[:, 1, 1]], axis=1)
    K = PH / S[:, None]
    # x = x + Ky
    xm = xm + K * y[:, None]
    # P = (I - KH) P (I - KH)' + K R K'   (Joseph form)
    A = np.eye(2)[None, :, :] - K[:, :, None] * np.ones((1, 1, 2))
    Pm = A @ Pm @ np.transpose(A, (0, 2, 1)) + (R_eff + sm2)[:, None, None] * (
        K[:, :, None] * K[:, None, :]
    )
    state[idx], P[idx] = xm, Pm
    return state, P, delta, normalised, variance


def stationary_covariance(noise: NoiseModel) -> np.ndarray:
    """Stationary covariance diag(σ_c², σ_e²) of the two states under *noise*. [Hz²]"""
    return np.diag([noise.correction_variance, noise.error_variance + 1e-300])
