"""Kalman blending of a regression model's predictions with SSI frequency estimates.

Three layers, as in filterpy: pure scalar functions (:func:`scalar_kalman_predict`,
:func:`scalar_kalman_update`, :func:`steady_state`, :func:`process_variance_for_gain`), a
small class holding one mode's filter (:class:`ScalarKalmanFilter`), and a bank of
independent per-mode filters advanced together (:class:`ModeKalmanBank`) that the sliding
forecast uses. The predict and update steps are filterpy's
(:func:`filterpy.kalman.predict`, :func:`filterpy.kalman.update`, Joseph-form update).

State model
-----------
The state of mode j at block k is its natural frequency x_k [Hz]. The regression model
predicts m_k from block k's predictors; the Kalman state carries the *correction*
c = x - m, the part of the frequency the model does not explain, from block to block:

.. math::

    x_k^- = m_k + φ (x_{k-1}^+ - m_{k-1})
          = φ x_{k-1}^+ + (m_k - φ m_{k-1}) = F x_{k-1}^+ + B u_k,

i.e. F = φ, B = 1, u_k = m_k - φ m_{k-1}. With φ = 1 (``correction_time_blocks=inf``) the
correction is a random walk (the design of [1]_: a-priori = model prediction + carried
correction); with φ = exp(-1 / τ) < 1 it relaxes to zero with time constant τ blocks, so
through a long stretch without SSI estimates the track returns smoothly to the model
instead of keeping a stale correction forever. The SSI estimate z_k = x_k + v_k is the
measurement (H = 1). Process noise w_k ~ N(0, Q) drives the correction, v_k ~ N(0, R).

Trust parameter
---------------
R is the measured scatter of the SSI estimates about the model. Q is chosen so that the
steady-state Kalman gain equals the trust placed in the SSI estimates, K_ss = trust
(:func:`process_variance_for_gain`):

.. math::

    Q = K R \\left(\\frac{1}{1 - K} - φ^2\\right)
    \\quad(φ = 1:\\; Q/R = K^2 / (1 - K)).

A steady-state gain K means each update moves the estimate a fraction K of the way from the
a-priori (model + correction) to the SSI estimate.

References
----------
.. [1] R. E. Kalman, "A new approach to linear filtering and prediction problems",
   J. Basic Eng. 82(1), 35-45, 1960. doi:10.1115/1.3662552
.. [2] R. Labbe, "Kalman and Bayesian Filters in Python" (filterpy), 2015-2020,
   https://github.com/rlabbe/Kalman-and-Bayesian-Filters-in-Python
.. [3] R. S. Bucy, P. D. Joseph, "Filtering for stochastic processes with applications to
   guidance", Interscience, 1968 (Joseph-form covariance update).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import predict as _filterpy_predict
from filterpy.kalman import update as _filterpy_update

__all__ = [
    "ModeKalmanBank",
    "ScalarKalmanFilter",
    "ScalarUpdate",
    "SteadyState",
    "process_variance_for_gain",
    "relaxation_factor",
    "scalar_kalman_predict",
    "scalar_kalman_update",
    "steady_state",
]


def _check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    value = float(value)
    ok = value >= 0.0 if allow_zero else value > 0.0
    if not (np.isfinite(value) and ok):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}={value!r} must be finite and {bound}")
    return value


def relaxation_factor(correction_time_blocks: float) -> float:
    """Block-to-block factor φ = exp(-1/τ) of the Kalman correction.

    Parameters
    ----------
    correction_time_blocks : float
        Time constant τ with which the correction relaxes to zero without measurements;
        ``inf`` gives φ = 1 (random walk). [blocks]

    Returns
    -------
    float
        φ in (0, 1].
    """
    tau = float(correction_time_blocks)
    if not tau > 0.0:
        raise ValueError(f"correction_time_blocks={tau!r} must be > 0 (inf for a random walk)")
    return 1.0 if math.isinf(tau) else math.exp(-1.0 / tau)


# --------------------------------------------------------------------------- pure functions
@dataclass(frozen=True)
class SteadyState:
    """Steady-state solution of the scalar Riccati recursion.

    Parameters
    ----------
    prior_variance : float
        P⁻, variance of the a-priori estimate. [Hz²]
    posterior_variance : float
        P⁺ = (1 - K) P⁻, variance of the a-posteriori estimate. [Hz²]
    gain : float
        K = P⁻ / (P⁻ + R). [-]
    """

    prior_variance: float
    posterior_variance: float
    gain: float


def steady_state(
    process_variance: float, measurement_variance: float, *, transition: float = 1.0
) -> SteadyState:
    """Steady state of the scalar Kalman filter x_k = F x_{k-1} + w, z = x + v.

    Parameters
    ----------
    process_variance : float
        Q, variance of w. [Hz²]
    measurement_variance : float
        R, variance of v, > 0. [Hz²]
    transition : float
        F, |F| <= 1. [-]

    Returns
    -------
    SteadyState

    Notes
    -----
    The Riccati recursion P⁻_{k+1} = F² P⁻_k R / (P⁻_k + R) + Q has the fixed point

    .. math::

        P^- = \\frac{-(R(1 - F^2) - Q) + \\sqrt{(R(1 - F^2) - Q)^2 + 4 Q R}}{2},

    which for the random walk (F = 1) is P⁻ = (Q + sqrt(Q² + 4QR)) / 2. Then
    K = P⁻ / (P⁻ + R) and P⁺ = (1 - K) P⁻.
    """
    q = _check_positive("process_variance", process_variance, allow_zero=True)
    r = _check_positive("measurement_variance", measurement_variance)
    f = float(transition)
    if not abs(f) <= 1.0:
        raise ValueError(f"transition={f!r} must satisfy |transition| <= 1")
    b = r * (1.0 - f * f) - q
    # P⁻ = (-b + sqrt(b² + 4QR)) / 2, written to avoid cancellation when b > 0
    root = math.sqrt(b * b + 4.0 * q * r)
    prior = (root - b) / 2.0 if b <= 0.0 else 2.0 * q * r / (root + b)
    gain = prior / (prior + r)  # K = P⁻ / (P⁻ + R)
    return SteadyState(prior, (1.0 - gain) * prior, gain)  # P⁺ = (1 - K) P⁻


def process_variance_for_gain(
    gain: float, measurement_variance: float, *, transition: float = 1.0
) -> float:
    """Process variance Q that makes the steady-state gain equal *gain*.

    Parameters
    ----------
    gain : float
        Wanted steady-state gain K in (0, 1): the trust in the measurement. [-]
    measurement_variance : float
        R. [Hz²]
    transition : float
        F = φ in (0, 1]. [-]

    Returns
    -------
    float
        Q. [Hz²]

    Notes
    -----
    At steady state P⁻ = K R / (1 - K) and P⁺ = K R; P⁻ = F² P⁺ + Q gives

    .. math:: Q = K R \\left(\\frac{1}{1 - K} - F^2\\right),

    Q / R = K² / (1 - K) for F = 1.
    """
    k = float(gain)
    if not 0.0 < k < 1.0:
        raise ValueError(f"trust={k!r} must be in (0, 1) (steady-state gain on the measurement)")
    r = _check_positive("measurement_variance", measurement_variance)
    f = float(transition)
    return k * r * (1.0 / (1.0 - k) - f * f)


def scalar_kalman_predict(
    state: float,
    variance: float,
    *,
    process_variance: float,
    transition: float = 1.0,
    control: float = 0.0,
) -> tuple[float, float]:
    """Kalman predict step for one scalar state (filterpy's :func:`~filterpy.kalman.predict`).

    Parameters
    ----------
    state, variance : float
        x⁺_{k-1} [Hz] and P⁺_{k-1} [Hz²].
    process_variance : float
        Q. [Hz²]
    transition : float
        F. [-]
    control : float
        B u, here m_k - φ m_{k-1}. [Hz]

    Returns
    -------
    tuple of float
        x⁻_k = F x + B u [Hz] and P⁻_k = F P F' + Q [Hz²].
    """
    # x = Fx + Bu ; P = FPF' + Q
    x, p = _filterpy_predict(state, variance, F=transition, Q=process_variance, u=control, B=1.0)
    return float(x), float(p)


@dataclass(frozen=True)
class ScalarUpdate:
    """Result of one scalar Kalman update.

    Parameters
    ----------
    state : float
        x⁺. [Hz]
    variance : float
        P⁺. [Hz²]
    gain : float
        K. [-]
    innovation : float
        y = z - H x⁻. [Hz]
    innovation_variance : float
        S = H P⁻ H' + R. [Hz²]
    """

    state: float
    variance: float
    gain: float
    innovation: float
    innovation_variance: float


def scalar_kalman_update(
    state: float,
    variance: float,
    measurement: float,
    *,
    measurement_variance: float,
    joseph: bool = True,
) -> ScalarUpdate:
    """Kalman update step for one scalar state measured directly (H = 1).

    Parameters
    ----------
    state, variance : float
        x⁻ [Hz] and P⁻ [Hz²].
    measurement : float
        z. [Hz]
    measurement_variance : float
        R. [Hz²]
    joseph : bool
        Joseph-form covariance update (filterpy's :func:`~filterpy.kalman.update`), which
        keeps P symmetric positive under round-off; ``False`` uses the simple form
        P = (1 - KH) P⁻ (for comparison).

    Returns
    -------
    ScalarUpdate

    Notes
    -----
    y = z - Hx⁻; S = HP⁻H' + R; K = P⁻H'S⁻¹; x⁺ = x⁻ + Ky;
    Joseph: P⁺ = (I - KH) P⁻ (I - KH)' + KRK'; simple: P⁺ = (I - KH) P⁻.
    """
    r = _check_positive("measurement_variance", measurement_variance)
    x_prior, p_prior = float(state), float(variance)
    if joseph:
        x, p, y, k, s, _ = _filterpy_update(
            np.array([x_prior]),
            np.array([[p_prior]]),
            float(measurement),
            np.array([[r]]),
            H=np.array([[1.0]]),
            return_all=True,
        )
        return ScalarUpdate(
            float(np.ravel(x)[0]),
            float(np.ravel(p)[0]),
            float(np.ravel(k)[0]),
            float(np.ravel(y)[0]),
            float(np.ravel(s)[0]),
        )
    y = float(measurement) - x_prior  # y = z - Hx
    s = p_prior + r  # S = HPH' + R
    k = p_prior / s  # K = PH'S^-1
    x = x_prior + k * y  # x = x + Ky
    p = (1.0 - k) * p_prior  # P = (I - KH)P
    return ScalarUpdate(x, p, k, y, s)


# --------------------------------------------------------------------------- small class
class ScalarKalmanFilter:
    """One mode's frequency filter: x⁻ = F x⁺ + B u, z = x + v.

    Parameters
    ----------
    state : float
        Initial estimate x. [Hz]
    process_variance, measurement_variance : float
        Q and R. [Hz²]
    transition : float
        F = φ. [-]
    variance : float, optional
        Initial P; default the steady-state posterior P⁺ of :func:`steady_state`. [Hz²]

    Attributes
    ----------
    state, variance : float
        Current estimate and its variance (a-priori after :meth:`predict`, a-posteriori
        after :meth:`update`).
    gain : float
        Gain of the last update (0 after a predict-only step).
    """

    def __init__(
        self,
        state: float,
        *,
        process_variance: float,
        measurement_variance: float,
        transition: float = 1.0,
        variance: float | None = None,
    ):
        self.transition = float(transition)
        self.process_variance = _check_positive(
            "process_variance", process_variance, allow_zero=True
        )
        self.measurement_variance = _check_positive("measurement_variance", measurement_variance)
        if variance is None:
            variance = steady_state(
                self.process_variance, self.measurement_variance, transition=self.transition
            ).posterior_variance
        self.state = float(state)
        self.variance = _check_positive("variance", variance, allow_zero=True)
        self.gain = 0.0

    def predict(self, control: float = 0.0) -> tuple[float, float]:
        """Predict step; returns (x⁻, P⁻)."""
        self.state, self.variance = scalar_kalman_predict(
            self.state,
            self.variance,
            process_variance=self.process_variance,
            transition=self.transition,
            control=control,
        )
        self.gain = 0.0
        return self.state, self.variance

    def update(self, measurement: float | None) -> ScalarUpdate | None:
        """Update with *measurement*; ``None`` or NaN is a predict-only step (no change)."""
        if measurement is None or not np.isfinite(measurement):
            return None
        result = scalar_kalman_update(
            self.state,
            self.variance,
            measurement,
            measurement_variance=self.measurement_variance,
        )
        self.state, self.variance, self.gain = result.state, result.variance, result.gain
        return result


# --------------------------------------------------------------------------- mode bank
class ModeKalmanBank:
    """Independent frequency filters for several modes, advanced block by block.

    The modes' filters are uncoupled (diagonal F, Q, R, P), so the bank is exactly one
    :class:`ScalarKalmanFilter` per mode; it is stored as one multi-mode filter and stepped
    with filterpy's matrix :func:`~filterpy.kalman.predict` / :func:`~filterpy.kalman.update`
    (Joseph form), measuring only the modes with an estimate in the block
    (H = rows of the identity).

    Parameters
    ----------
    n_modes : int
    transition : float
        φ, the same for every mode. [-]
    """

    def __init__(self, n_modes: int, *, transition: float = 1.0):
        if n_modes < 1:
            raise ValueError(f"n_modes={n_modes} must be >= 1")
        self.n_modes = int(n_modes)
        self.transition = float(transition)
        self.state = np.full(self.n_modes, np.nan)
        self.variance = np.full(self.n_modes, np.nan)
        self.process_variance = np.zeros(self.n_modes)
        self.measurement_variance = np.ones(self.n_modes)
        self._identity = np.eye(self.n_modes)
        self._F = self.transition * self._identity

    def set_noise(self, process_variance: np.ndarray, measurement_variance: np.ndarray) -> None:
        """Set Q and R per mode (after a window's model is fitted). [Hz²]"""
        q = np.asarray(process_variance, dtype=float)
        r = np.asarray(measurement_variance, dtype=float)
        if np.any(~np.isfinite(q) | (q < 0)) or np.any(~np.isfinite(r) | (r <= 0)):
            raise ValueError("process_variance must be >= 0 and measurement_variance > 0")
        self.process_variance = q.copy()
        self.measurement_variance = r.copy()

    def initialise(self, modes: np.ndarray, state: np.ndarray) -> None:
        """Start the filters of *modes* (indices) at *state*, P at the steady-state P⁻.

        The first step of a started mode is then an update (no predict), so P⁻ of the
        first block is the steady-state prior.
        """
        for j, x in zip(np.atleast_1d(modes), np.atleast_1d(state), strict=True):
            self.state[j] = x
            self.variance[j] = steady_state(
                self.process_variance[j], self.measurement_variance[j], transition=self.transition
            ).prior_variance

    def inflate(self, modes: np.ndarray, prior_variance: np.ndarray) -> None:
        """Raise the a-priori variance of *modes* (indices) to at least *prior_variance*.

        Covariance inflation for a track whose prior has been wrong: between
        :meth:`predict` and :meth:`update`, P⁻_j ← max(P⁻_j, v_j). With v = y² (the
        squared innovation of the measurement about to be used) the gain becomes
        K = y² / (y² + R) ≈ 1, so the update moves the estimate to the measurement, and P
        then returns to its steady state over the following blocks. [Hz²]
        """
        idx = np.atleast_1d(np.asarray(modes, dtype=np.int64))
        value = np.broadcast_to(np.asarray(prior_variance, dtype=float), idx.shape)
        if np.any(~np.isfinite(value) | (value < 0)):
            raise ValueError("prior_variance must be finite and >= 0")
        # P⁻ = max(P⁻, v)
        self.variance[idx] = np.fmax(self.variance[idx], value)

    def _active(self, active: np.ndarray | None) -> np.ndarray:
        ok = np.isfinite(self.state) & np.isfinite(self.variance)
        return ok if active is None else ok & np.asarray(active, dtype=bool)

    def predict(
        self, control: np.ndarray, active: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Predict the *active* modes; returns copies of x⁻ and the diagonal of P⁻.

        Parameters
        ----------
        control : ndarray, shape (n_modes,)
            B u = m_k - φ m_{k-1} per mode. [Hz]
        active : ndarray of bool, optional
            Modes to step (default all started modes); the others keep their state.
        """
        step = self._active(active) & np.isfinite(control)
        if step.any():
            # zeros stand in for inactive modes (NaN x 0 would leak through the products)
            x0 = np.where(step, self.state, 0.0)
            P = np.diag(np.where(step, self.variance, 0.0))
            Q = np.diag(np.where(step, self.process_variance, 0.0))
            u = np.where(step, control, 0.0)
            # x = Fx + Bu ; P = FPF' + Q
            x, P = _filterpy_predict(x0, P, F=self._F, Q=Q, u=u, B=self._identity)
            self.state = np.where(step, np.asarray(x, dtype=float), self.state)
            self.variance = np.where(step, np.diag(P), self.variance)
        return self.state.copy(), self.variance.copy()

    def update(self, measurement: np.ndarray) -> np.ndarray:
        """Update the modes with a finite *measurement*; NaN modes are predict-only.

        Returns
        -------
        ndarray, shape (n_modes,)
            Gain K applied to each mode (0 where not measured).
        """
        z = np.asarray(measurement, dtype=float)
        ok = self._active(None)
        mask = np.isfinite(z) & ok
        measured = np.flatnonzero(mask)
        gain = np.zeros(self.n_modes)
        if measured.size == 0:
            return gain
        H = self._identity[measured]
        R = np.diag(self.measurement_variance[measured])
        # zeros stand in for modes not started (NaN x 0 would leak through the products)
        x0 = np.where(ok, self.state, 0.0)
        P = np.diag(np.where(ok, self.variance, 0.0))
        # y = z - Hx ; S = HPH' + R ; K = PH'inv(S) ; x = x + Ky ;
        # P = (I-KH)P(I-KH)' + KRK'   (Joseph form, filterpy.kalman.update)
        x, P = _filterpy_update(x0, P, z[measured], R, H=H)
        # the filters are uncoupled, so K is diagonal: K_j = P⁻_j / (P⁻_j + R_j)
        prior = self.variance[measured]
        gain[measured] = prior / (prior + self.measurement_variance[measured])
        # P stays diagonal (off-diagonal terms are exactly zero for diagonal inputs)
        self.state = np.where(mask, np.asarray(x, dtype=float), self.state)
        self.variance = np.where(mask, np.diag(P), self.variance)
        return gain
