"""Random vibration of a structure by modal superposition, discretised exactly.

Each mode m is a single-degree-of-freedom oscillator in the modal coordinate q_m,

.. math::

    \\ddot q_m + 2 \\zeta_m \\omega_m \\dot q_m + \\omega_m^2 q_m = f_m(t),

driven by a Gaussian white-noise modal force f_m that is *held constant over each sample*
(zero-order hold, ZOH). The channel response is the superposition
``y(t) = sum_m mode_shape[m] * q_m^{(r)}(t)`` with r = 0, 1, 2 for displacement, velocity,
acceleration. For a force that is piecewise constant between samples the ZOH
discretisation is exact: no integration error at any sampling rate.

Layers: :func:`discretize_modes` (the 2x2 matrix exponential and ZOH input gain, vectorised
over modes), :func:`stationary_covariance` (closed-form variances of the discrete model),
:func:`simulate_modal_response` (the recursion run as a two-pole IIR filter with
:func:`scipy.signal.lfilter`, with the modal state carried between calls).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import signal

__all__ = [
    "DiscreteModes",
    "ModalResponse",
    "ModalState",
    "discretize_modes",
    "draw_stationary_state",
    "simulate_modal_response",
    "stationary_covariance",
]

Output = Literal["acceleration", "velocity", "displacement"]
_OUTPUTS = ("acceleration", "velocity", "displacement")


@dataclass(frozen=True)
class ModalState:
    """State of every modal oscillator just before the next sample.

    Parameters
    ----------
    displacement : ndarray, shape (n_modes,)
        Modal displacements q_m. [m per unit modal mass]
    velocity : ndarray, shape (n_modes,)
        Modal velocities dq_m/dt. [m/s per unit modal mass]
    """

    displacement: np.ndarray
    velocity: np.ndarray

    @property
    def n_modes(self) -> int:
        return int(np.size(self.displacement))

    @classmethod
    def at_rest(cls, n_modes: int) -> ModalState:
        """All modes at rest (zero displacement and velocity)."""
        return cls(np.zeros(n_modes), np.zeros(n_modes))


@dataclass(frozen=True)
class ModalResponse:
    """Result of :func:`simulate_modal_response`.

    Parameters
    ----------
    response : ndarray, shape (n_samples, n_channels)
        Channel response (acceleration [m/s²], velocity [m/s] or displacement [m]).
    modal_response : ndarray, shape (n_samples, n_modes)
        The same quantity per mode (modal coordinates), before superposition.
    state : ModalState
        Modal state after the last sample; pass it to the next call for a continuous signal.
    """

    response: np.ndarray
    modal_response: np.ndarray
    state: ModalState


@dataclass(frozen=True)
class DiscreteModes:
    """Exact ZOH discretisation of uncoupled modal oscillators.

    The state x_k = (q_k, dq/dt_k) of mode m evolves as
    ``x_{k+1} = transition[m] @ x_k + input_gain[m] * f_k``.

    Parameters
    ----------
    transition : ndarray, shape (n_modes, 2, 2)
        State transition matrices exp(A_m T).
    input_gain : ndarray, shape (n_modes, 2)
        ZOH input vectors A_m^{-1} (exp(A_m T) - I) B.
    angular_frequency : ndarray, shape (n_modes,)
        Undamped natural angular frequencies ω_m. [rad/s]
    damping_ratio : ndarray, shape (n_modes,)
        Damping ratios ζ_m. [-]
    sampling_rate_hz : float
        Sampling rate 1/T. [Hz]
    """

    transition: np.ndarray
    input_gain: np.ndarray
    angular_frequency: np.ndarray
    damping_ratio: np.ndarray
    sampling_rate_hz: float

    def output_matrices(self, output: Output) -> tuple[np.ndarray, np.ndarray]:
        """Output row C_m (n_modes, 2) and feedthrough D_m (n_modes,) for *output*.

        Acceleration: q'' = -ω² q - 2ζω q' + f, so C = (-ω², -2ζω) and D = 1.
        """
        omega = self.angular_frequency
        n_modes = omega.size
        if output == "displacement":
            return np.column_stack([np.ones(n_modes), np.zeros(n_modes)]), np.zeros(n_modes)
        if output == "velocity":
            return np.column_stack([np.zeros(n_modes), np.ones(n_modes)]), np.zeros(n_modes)
        return (
            np.column_stack([-(omega**2), -2.0 * self.damping_ratio * omega]),
            np.ones(n_modes),
        )


def _as_mode_array(name: str, value, n_modes: int | None = None) -> np.ndarray:
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.ndim != 1:
        raise ValueError(f"{name} must be a scalar or 1-D array, got shape {array.shape}")
    if n_modes is not None and array.size not in (1, n_modes):
        raise ValueError(f"{name} has {array.size} values for {n_modes} modes")
    if n_modes is not None and array.size == 1:
        array = np.full(n_modes, array[0])
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}={array.tolist()} must be finite")
    return array


def _transition(omega: np.ndarray, zeta: np.ndarray, time: np.ndarray) -> np.ndarray:
    """exp(A t) for A = [[0, 1], [-ω², -2ζω]], 0 <= ζ < 1; broadcast over time and modes.

    Returns an array of shape time.shape + (2, 2) (time broadcast against the modes).
    """
    omega_d = omega * np.sqrt(1.0 - zeta**2)
    decay = np.exp(-zeta * omega * time)
    cos = np.cos(omega_d * time)
    sin = np.sin(omega_d * time)
    ratio = zeta * omega / omega_d
    out = np.empty(np.broadcast(time, omega).shape + (2, 2))
    out[..., 0, 0] = decay * (cos + ratio * sin)
    out[..., 0, 1] = decay * sin / omega_d
    out[..., 1, 0] = -decay * omega**2 * sin / omega_d
    out[..., 1, 1] = decay * (cos - ratio * sin)
    return out


def discretize_modes(frequency_hz, damping_ratio, sampling_rate_hz: float) -> DiscreteModes:
    """Exact zero-order-hold discretisation of modal oscillators.

    Parameters
    ----------
    frequency_hz : array_like, shape (n_modes,)
        Undamped natural frequencies, each below the Nyquist frequency. [Hz]
    damping_ratio : array_like, shape (n_modes,) or scalar
        Viscous damping ratios, 0 <= ζ < 1. [-]
    sampling_rate_hz : float
        Sampling rate. [Hz]

    Returns
    -------
    DiscreteModes

    Notes
    -----
    With A = [[0, 1], [-ω², -2ζω]], B = (0, 1)ᵀ and ω_d = ω sqrt(1 - ζ²), the transition
    matrix over one sample T is

    .. math::

        e^{AT} = e^{-\\zeta\\omega T} \\begin{pmatrix}
        \\cos\\omega_d T + \\frac{\\zeta\\omega}{\\omega_d}\\sin\\omega_d T &
        \\frac{\\sin\\omega_d T}{\\omega_d} \\\\
        -\\frac{\\omega^2}{\\omega_d}\\sin\\omega_d T &
        \\cos\\omega_d T - \\frac{\\zeta\\omega}{\\omega_d}\\sin\\omega_d T
        \\end{pmatrix}

    and the ZOH input gain is Γ = A⁻¹(e^{AT} - I)B = ((1 - Φ₁₁)/ω², Φ₁₂)ᵀ.

    References
    ----------
    .. [1] G. F. Franklin, J. D. Powell, M. Workman, "Digital Control of Dynamic Systems",
       3rd ed., Addison-Wesley, 1998, section 4.3.3 (ZOH equivalent of a state-space model).
    """
    rate = float(sampling_rate_hz)
    if not np.isfinite(rate) or rate <= 0:
        raise ValueError(f"sampling_rate_hz={sampling_rate_hz!r} must be a positive number")
    frequency = _as_mode_array("frequency_hz", frequency_hz)
    zeta = _as_mode_array("damping_ratio", damping_ratio, frequency.size)
    if np.any(frequency <= 0) or np.any(frequency >= rate / 2):
        raise ValueError(
            f"frequency_hz={frequency.tolist()} must lie in (0, {rate / 2:g}) Hz "
            f"(the Nyquist frequency of sampling_rate_hz={rate:g})"
        )
    if np.any(zeta < 0) or np.any(zeta >= 1):
        raise ValueError(f"damping_ratio={zeta.tolist()} must lie in [0, 1) (underdamped modes)")
    omega = 2.0 * np.pi * frequency
    transition = _transition(omega, zeta, np.full(omega.shape, 1.0 / rate))
    input_gain = np.column_stack([(1.0 - transition[:, 0, 0]) / omega**2, transition[:, 0, 1]])
    return DiscreteModes(transition, input_gain, omega, zeta, rate)


def stationary_covariance(
    frequency_hz, damping_ratio, sampling_rate_hz: float, *, excitation_std=1.0
) -> np.ndarray:
    """Stationary covariance of the discrete modal state under ZOH white-noise forcing.

    Parameters
    ----------
    frequency_hz, damping_ratio : array_like, shape (n_modes,)
        As for :func:`discretize_modes`. [Hz], [-]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    excitation_std : float or array_like, shape (n_modes,)
        Standard deviation σ of the modal force samples. [N per unit modal mass]

    Returns
    -------
    ndarray, shape (n_modes, 2, 2)
        Covariance P of (q, dq/dt), solution of P = Φ P Φᵀ + σ² Γ Γᵀ.

    Notes
    -----
    The variance of an output y = C x + D f is C P Cᵀ + D² σ² (x_k is independent of f_k).
    For ωT → 0 the model tends to continuous white noise of intensity σ²T, for which
    var(q) = σ²T / (4 ζ ω³) and var(dq/dt) = σ²T / (4 ζ ω) [1]_.

    References
    ----------
    .. [1] S. H. Crandall, W. D. Mark, "Random Vibration in Mechanical Systems", Academic
       Press, 1963, chapter 2. doi:10.1016/C2013-0-12129-9
    """
    modes = discretize_modes(frequency_hz, damping_ratio, sampling_rate_hz)
    sigma = _as_mode_array("excitation_std", excitation_std, modes.angular_frequency.size)
    covariance = np.empty_like(modes.transition)
    for m in range(sigma.size):
        phi = modes.transition[m]
        gamma = modes.input_gain[m]
        # vec(P) = (I - Φ⊗Φ)^{-1} vec(σ² Γ Γᵀ)
        kron = np.eye(4) - np.kron(phi, phi)
        rhs = (sigma[m] ** 2 * np.outer(gamma, gamma)).ravel()
        p = np.linalg.solve(kron, rhs).reshape(2, 2)
        covariance[m] = 0.5 * (p + p.T)
    return covariance


def draw_stationary_state(
    frequency_hz,
    damping_ratio,
    sampling_rate_hz: float,
    *,
    rng: np.random.Generator,
    excitation_std=1.0,
) -> ModalState:
    """A random modal state from the stationary distribution (no start-up transient)."""
    covariance = stationary_covariance(
        frequency_hz, damping_ratio, sampling_rate_hz, excitation_std=excitation_std
    )
    factor = np.linalg.cholesky(covariance)
    draw = np.einsum("mij,mj->mi", factor, rng.standard_normal((covariance.shape[0], 2)))
    return ModalState(draw[:, 0].copy(), draw[:, 1].copy())


def simulate_modal_response(
    frequency_hz,
    damping_ratio,
    mode_shapes: np.ndarray,
    sampling_rate_hz: float,
    n_samples: int,
    *,
    rng: np.random.Generator | None = None,
    excitation_std=1.0,
    output: Output = "acceleration",
    state: ModalState | None = None,
    modal_force: np.ndarray | None = None,
) -> ModalResponse:
    """Response of uncoupled modes to white-noise modal forces, by modal superposition.

    Parameters
    ----------
    frequency_hz : array_like, shape (n_modes,)
        Undamped natural frequencies, constant during this call. [Hz]
    damping_ratio : array_like, shape (n_modes,) or scalar
        Damping ratios, 0 <= ζ < 1, constant during this call. [-]
    mode_shapes : ndarray, shape (n_modes, n_channels)
        Real mode shapes, one row per mode (the layout of the modal tables).
    sampling_rate_hz : float
        Sampling rate. [Hz]
    n_samples : int
        Number of samples to simulate.
    rng : numpy.random.Generator, optional
        Source of the modal forces; required unless *modal_force* is given.
    excitation_std : float or array_like, shape (n_modes,)
        Standard deviation σ of the modal force samples. [N per unit modal mass]
    output : {"acceleration", "velocity", "displacement"}
        Response quantity. Acceleration includes the direct feedthrough of the force.
    state : ModalState, optional
        Modal state from the previous call (continuity across calls, also when frequencies
        and damping change between calls). Default: all modes at rest.
    modal_force : ndarray, shape (n_samples, n_modes), optional
        Explicit modal forces instead of random ones (``excitation_std`` is then ignored).

    Returns
    -------
    ModalResponse

    Notes
    -----
    The force f_k is held constant over [kT, (k+1)T) (ZOH), so the recursion
    x_{k+1} = Φ x_k + Γ f_k (see :func:`discretize_modes`) is exact. Output at sample k is
    y_k = C x_k + D f_k. The forced part (zero initial state) is the two-pole IIR filter

    .. math::

        X(z) = (zI - Φ)^{-1} Γ F(z), \\quad
        \\text{denominator } 1 - \\mathrm{tr}(Φ) z^{-1} + \\det(Φ) z^{-2},

    run with :func:`scipy.signal.lfilter` (one call per mode and state component). The
    free response of the initial state obeys the same recursion (Cayley-Hamilton), so it
    enters through the filter's initial conditions: ``zi = (x_0, (Φ x_0) + a_1 x_0)`` per
    component, a_1 = -tr(Φ). Splitting a
    record into consecutive calls that pass ``state`` on therefore reproduces the one-shot
    simulation up to rounding.
    """
    n_samples = int(n_samples)
    if n_samples < 0:
        raise ValueError(f"n_samples={n_samples} must be >= 0")
    if output not in _OUTPUTS:
        raise ValueError(f"output={output!r} must be one of {', '.join(_OUTPUTS)}")
    modes = discretize_modes(frequency_hz, damping_ratio, sampling_rate_hz)
    n_modes = modes.angular_frequency.size
    shapes = np.asarray(mode_shapes, dtype=float)
    if shapes.ndim != 2 or shapes.shape[0] != n_modes:
        raise ValueError(
            f"mode_shapes must have shape (n_modes={n_modes}, n_channels), got {shapes.shape}"
        )
    if state is None:
        state = ModalState.at_rest(n_modes)
    if state.n_modes != n_modes:
        raise ValueError(f"state has {state.n_modes} modes, frequency_hz has {n_modes}")
    if modal_force is None:
        if rng is None:
            raise ValueError("rng is required unless modal_force is given")
        sigma = _as_mode_array("excitation_std", excitation_std, n_modes)
        force = rng.standard_normal((n_samples, n_modes)) * sigma
    else:
        force = np.asarray(modal_force, dtype=float)
        if force.shape != (n_samples, n_modes):
            raise ValueError(
                f"modal_force must have shape (n_samples={n_samples}, n_modes={n_modes}), "
                f"got {force.shape}"
            )

    phi, gamma = modes.transition, modes.input_gain
    out_c, out_d = modes.output_matrices(output)
    x0 = np.column_stack([state.displacement, state.velocity]).astype(float)

    # States x_k for k = 0..n (x_n from f_0..f_{n-1}); a trailing zero input yields x_n.
    padded = np.concatenate([force, np.zeros((1, n_modes))], axis=0)
    displacement = np.empty((n_samples + 1, n_modes))
    velocity = np.empty((n_samples + 1, n_modes))
    for m in range(n_modes):
        p = phi[m]
        g = gamma[m]
        a1 = -(p[0, 0] + p[1, 1])
        denominator = np.array([1.0, a1, p[0, 0] * p[1, 1] - p[0, 1] * p[1, 0]])
        # adj(zI - Φ) Γ, in powers of z^{-1} after dividing by z²
        num_q = np.array([0.0, g[0], p[0, 1] * g[1] - p[1, 1] * g[0]])
        num_v = np.array([0.0, g[1], p[1, 0] * g[0] - p[0, 0] * g[1]])
        # Transposed direct form II with zero input gives y_0 = zi_0, y_1 = zi_1 - a1 y_0:
        # choose zi so that the free response starts at x_0 and Φ x_0 (Cayley-Hamilton).
        next_state = p @ x0[m]
        zi_q = np.array([x0[m, 0], next_state[0] + a1 * x0[m, 0]])
        zi_v = np.array([x0[m, 1], next_state[1] + a1 * x0[m, 1]])
        displacement[:, m] = signal.lfilter(num_q, denominator, padded[:, m], zi=zi_q)[0]
        velocity[:, m] = signal.lfilter(num_v, denominator, padded[:, m], zi=zi_v)[0]

    modal = (
        displacement[:n_samples] * out_c[:, 0] + velocity[:n_samples] * out_c[:, 1] + force * out_d
    )
    response = modal @ shapes
    final = ModalState(displacement[n_samples].copy(), velocity[n_samples].copy())
    return ModalResponse(response, modal, final)
