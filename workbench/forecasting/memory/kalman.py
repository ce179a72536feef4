"""Kalman step of the memory forecast: the model correction c and the identification error
per mode, H = [1 1 ... 1], Huber-weighted update, Joseph-form covariance.

The identification error is one AR(1) state e (two states in all), or, for blocks that
share data with their L - 1 neighbours, the L segment terms g_k .. g_{k+L-1} whose sum is
the block's error (1 + L states): from block to block the terms shift by one and the
newest is new (:func:`transition_matrices`).

Used by :func:`~workbench.forecasting.memory.forecast.memory_forecast` (model in that module's docs).
"""

from __future__ import annotations

import numpy as np

from ..noise import NoiseModel

__all__ = [
    "estimate_variance",
    "kalman_predict",
    "kalman_update",
    "n_states",
    "stationary_covariance",
    "transition_matrices",
]


def n_states(error_segments: int) -> int:
    """States of the filter: c and one AR(1) state (``error_segments`` < 2), or c and the
    L = ``error_segments`` segment terms."""
    return 1 + error_segments if error_segments >= 2 else 2


def transition_matrices(noise: NoiseModel | None, states: int):
    """F, the diagonal of Q (without the block's measurement scale) and the stationary
    covariance of one mode's states in a filter of *states* states.

    AR(1) error (``noise.error_segments`` 0): F = diag(φ, ρ, 0, ...), Q = diag(σ_c²(1 - φ²),
    σ_e²(1 - ρ²), 0, ...). Segments (L = states - 1): F shifts g_{k+1} .. g_{k+L-1} into
    places 1 .. L - 1, Q = diag(σ_c²(1 - φ²), 0, ..., 0, σ_e² / L): each term has variance
    σ_e² / L and the block's error, their sum, σ_e². No noise model (no model yet):
    F = diag(1, 0, ...), Q = 0.

    Returns
    -------
    F : ndarray (states, states)
    q_c, q_e : ndarray (states,)
        The diagonal of Q split into the model correction's part and the identification
        error's (which the block's measurement scale multiplies). [Hz²]
    P : ndarray (states, states)
        The stationary covariance (:func:`stationary_covariance`). [Hz²]
    """
    F = np.zeros((states, states))
    q_c, q_e = np.zeros(states), np.zeros(states)
    P = np.zeros((states, states))
    if noise is None:
        F[0, 0] = 1.0
        return F, q_c, q_e, P
    phi = noise.transition
    F[0, 0] = phi
    q_c[0] = noise.correction_variance * (1 - phi**2)
    P[0, 0] = noise.correction_variance
    L = noise.error_segments
    if L >= 2:
        if states != 1 + L:
            raise ValueError(f"noise with error_segments={L} needs {1 + L} states, got {states}")
        F[1:L, 2 : 1 + L] = np.eye(L - 1)  # g_{k+1} .. g_{k+L-1} carry over
        q_e[L] = noise.error_variance / L
        P[1:, 1:] = np.eye(L) * noise.error_variance / L
    else:
        rho = noise.error_correlation
        F[1, 1] = rho
        q_e[1] = noise.error_variance * (1 - rho**2)
        P[1, 1] = noise.error_variance + 1e-300
    return F, q_c, q_e, P


def kalman_predict(state, P, F, Q):
    """Predict step of the filter (c and the identification error's states) for several
    modes at once: x = Fx, P = FPF' + Q.

    Parameters
    ----------
    state : ndarray (n, s)
        [c, e] (or [c, g_k, ..., g_{k+L-1}]) a-posteriori of the previous block.
    P : ndarray (n, s, s)
    F : ndarray (n, s) or (n, s, s)
        The diagonal of F (e.g. (φ, ρ)) or F itself (:func:`transition_matrices`).
    Q : ndarray (n, s)
        Diagonal of Q.

    Returns
    -------
    state, P a-priori (new arrays)
    """
    # x = Fx ; P = FPF' + Q
    if F.ndim == 2:
        state = state * F
        P = P * (F[:, :, None] * F[:, None, :])
    else:
        state = np.einsum("nij,nj->ni", F, state)
        P = F @ P @ np.transpose(F, (0, 2, 1))
    s = state.shape[1]
    P[:, np.arange(s), np.arange(s)] += Q
    return state, P


def kalman_update(
    state,
    P,
    residual,
    R,
    huber_sigma,
    model_variance=None,
    previous_run=None,
    persist_blocks=3,
):
    """Huber-weighted update of the filter's a-priori *state* and *P*
    (:func:`kalman_predict`) with the measurements' residuals, H = [1 ... 1], Joseph form.

    Parameters
    ----------
    state : ndarray (n, s)
    P : ndarray (n, s, s)
        A-priori state and covariance (not modified: the update returns new arrays).
    residual : ndarray (n,)
        z - m (NaN: no measurement, the a-priori values are returned). [Hz]
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
    state, P, white model correction δ̂ (n,), normalised innovation y/sqrt(S) (n,), the
    innovation variance S (n,) the normalisation used [Hz²] (NaN: no measurement), and the
    posterior variance of the estimate's error, var(δ + c) (n,) [Hz²]
    (:func:`estimate_variance`; without a measurement the a-priori P_cc + s_m²).

    Notes
    -----
    δ is a white state beside c and the identification error's states: the a-priori
    covariance of [δ, c, ...] is diag(s_m², P⁻), H = [1 1 ... 1]. Its Joseph-form update
    restricted to [c, ...] is the one below with R + s_m² as the measurement variance (δ is
    noise to c); the estimate m + δ̂ + ĉ needs the variance of δ + c, with their posterior
    covariance (negative: one measurement informs both).
    """
    state, P = state.copy(), P.copy()
    n, s = state.shape
    delta = np.zeros(n)
    normalised = np.full(n, np.nan)
    variance = np.full(n, np.nan)
    sm2_all = np.zeros(n) if model_variance is None else np.asarray(model_variance, dtype=float)
    # no measurement: the a-priori variance of c plus the model's
    estimated = np.maximum(P[:, 0, 0], 0.0) + sm2_all
    ok = np.isfinite(residual)
    if not ok.any():
        return state, P, delta, normalised, variance, estimated
    idx = np.flatnonzero(ok)
    Pm, xm = P[idx], state[idx]
    sm2 = sm2_all[idx]
    # y = z - Hx ; S = HPH' + R + s_m²  (H = [1 ... 1])
    y = residual[idx] - xm.sum(axis=1)
    S = Pm.sum(axis=(1, 2)) + R[idx] + sm2
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
    PH = Pm.sum(axis=2)
    K = PH / S[:, None]
    estimated[idx] = estimate_variance(Pm, sm2, S, R_eff)
    # x = x + Ky
    xm = xm + K * y[:, None]
    # P = (I - KH) P (I - KH)' + K R K'   (Joseph form)
    A = np.eye(s)[None, :, :] - K[:, :, None] * np.ones((1, 1, s))
    Pm = A @ Pm @ np.transpose(A, (0, 2, 1)) + (R_eff + sm2)[:, None, None] * (
        K[:, :, None] * K[:, None, :]
    )
    state[idx], P[idx] = xm, Pm
    return state, P, delta, normalised, variance, estimated


def estimate_variance(P_prior, model_variance, innovation_variance, measurement_variance):
    """Posterior variance of δ + c, the part of the blended estimate m + δ̂ + ĉ the
    measurement updates, after one update with H = [1 ... 1] (:func:`kalman_update`). [Hz²]

    Parameters
    ----------
    P_prior : ndarray (n, s, s)
        A-priori covariance of [c, identification error's states]. [Hz²]
    model_variance : ndarray (n,)
        s_m², a-priori variance of the white model error δ. [Hz²]
    innovation_variance : ndarray (n,)
        S = s_m² + H P⁻ H' + R (R with the Huber weight's extra variance). [Hz²]
    measurement_variance : ndarray (n,)
        That R. [Hz²]

    Notes
    -----
    With the augmented state a = [δ, c, ...], P_a = diag(s_m², P⁻), gain K_a = P_a H' / S and
    u = [1, 1, 0, ...] (δ + c), the Joseph form gives

    .. math::

        var(u'â - u'a) = b' P_a b + κ^2 R, \\quad κ = u'K_a = (s_m^2 + (P^- H')_c) / S,
        \\quad b = u - κ H',

    i.e. (1 - κ)² s_m² + P⁻_cc - 2κ (P⁻H')_c + κ² H P⁻ H' + κ² R, which is
    s_m² + P⁻_cc - (s_m² + (P⁻H')_c)² / S when R is the filter's own (no Huber weight).
    """
    PH_c = P_prior[:, 0, :].sum(axis=1)  # (P⁻H')_c
    HPH = P_prior.sum(axis=(1, 2))  # H P⁻ H'
    kappa = (model_variance + PH_c) / innovation_variance
    # var(δ + c)⁺ = (1 - κ)² s_m² + P_cc - 2κ (P⁻H')_c + κ² (H P⁻ H' + R)
    value = (
        (1.0 - kappa) ** 2 * model_variance
        + P_prior[:, 0, 0]
        - 2.0 * kappa * PH_c
        + kappa**2 * (HPH + measurement_variance)
    )
    return np.maximum(value, 0.0)


def stationary_covariance(noise: NoiseModel, states: int = 2) -> np.ndarray:
    """Stationary covariance of the *states* states under *noise*: diag(σ_c², σ_e²), or
    diag(σ_c², σ_e²/L, ..., σ_e²/L) for L segment terms. [Hz²]"""
    return transition_matrices(noise, states)[3]
