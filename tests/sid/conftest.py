"""Simulated systems with analytic modal parameters for the SSI tests.

Spring-mass chains (fixed-free, proportional damping) have real normal modes from the
generalised eigenproblem K φ = ω² M φ and damping ratios ζ = α/(2ω) + βω/2 (Rayleigh
damping C = αM + βK). White-noise forces act at every mass; with mass-normalised shapes
the modal forces are Φᵀ F, simulated exactly (ZOH) by :mod:`workbench.simulate.dynamics`. The demo
hull uses its own modal model (:mod:`workbench.simulate.hull`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy import linalg

from workbench.simulate.dynamics import simulate_modal_response
from workbench.simulate.hull import (
    CHANNELS,
    REFERENCE_CONDITIONS,
    mode_shapes,
    true_modal_parameters,
)


@dataclass(frozen=True)
class SimulatedSystem:
    acceleration: np.ndarray  # (n_samples, n_channels) [m/s²]
    sampling_rate_hz: float
    frequency_hz: np.ndarray  # (n_modes,)
    damping_ratio: np.ndarray  # (n_modes,)
    mode_shapes: np.ndarray  # (n_channels, n_modes), real


def chain(
    masses, stiffnesses, end_damping, sampling_rate_hz, n_samples, seed, noise=0.01
) -> SimulatedSystem:
    """Fixed-free chain: spring k_0 to the ground, k_j between masses j-1 and j.

    Rayleigh damping chosen to give ``end_damping`` = (ζ_first, ζ_last) at the first and
    last modes; 1 % (of each channel's RMS) white sensor noise.
    """
    n = len(masses)
    mass = np.diag(masses)
    stiffness = np.zeros((n, n))
    for j, k in enumerate(stiffnesses):
        stiffness[j, j] += k
        if j > 0:
            stiffness[j - 1, j - 1] += k
            stiffness[j - 1, j] -= k
            stiffness[j, j - 1] -= k
    omega2, shapes = linalg.eigh(stiffness, mass)  # mass-normalised: Φᵀ M Φ = I
    omega = np.sqrt(omega2)
    alpha, beta = rayleigh_for(omega[0], omega[-1], *end_damping)
    damping = alpha / (2 * omega) + beta * omega / 2
    rng = np.random.default_rng(seed)
    force = rng.standard_normal((n_samples, n))
    response = simulate_modal_response(
        omega / (2 * np.pi),
        damping,
        shapes.T,
        sampling_rate_hz,
        n_samples,
        modal_force=force @ shapes,
    ).response
    response += noise * response.std(axis=0) * rng.standard_normal(response.shape)
    return SimulatedSystem(response, sampling_rate_hz, omega / (2 * np.pi), damping, shapes)


def rayleigh_for(omega_1, omega_2, zeta_1, zeta_2):
    """α, β giving damping ratios ζ1, ζ2 at ω1, ω2."""
    matrix = np.array([[1 / (2 * omega_1), omega_1 / 2], [1 / (2 * omega_2), omega_2 / 2]])
    return tuple(np.linalg.solve(matrix, [zeta_1, zeta_2]))


@pytest.fixture(scope="session")
def chain3() -> SimulatedSystem:
    """3-DOF chain, 2 / 1 / 1 kg, springs 2e4, 1.5e4, 1e4 N/m: 8.70, 18.99, 29.90 Hz."""
    masses = [2.0, 1.0, 1.0]
    stiffnesses = [2.0e4, 1.5e4, 1.0e4]
    return chain(masses, stiffnesses, (0.02, 0.02), 200.0, 60_000, seed=3)


@pytest.fixture(scope="session")
def chain5() -> SimulatedSystem:
    """Uniform 5-DOF chain, 1 kg masses, 4e4 N/m springs: 9.06 to 61.08 Hz."""
    masses = [1.0] * 5
    stiffnesses = [4.0e4] * 5
    return chain(masses, stiffnesses, (0.02, 0.015), 200.0, 80_000, seed=5)


#: Modal acceleration RMS of the seven hull modes (as in the demo voyage at 5 kn). [m/s²]
HULL_MODE_RMS = np.array([0.020, 0.012, 0.015, 0.008, 0.012, 0.010, 0.008])


@pytest.fixture(scope="session")
def hull_block() -> SimulatedSystem:
    """One 20-minute block of the demo hull at 64 Hz, 19 channels, reference conditions.

    Modes scaled to the demo voyage's modal RMS; sensor noise 1 mm/s² RMS.
    """
    frequency, damping = true_modal_parameters(REFERENCE_CONDITIONS)
    frequency, damping = frequency[0], damping[0]
    shapes = mode_shapes()  # (7, 19)
    rate = 64.0
    rng = np.random.default_rng(2024)
    modal = simulate_modal_response(
        frequency, damping, shapes, rate, 20 * 60 * 64, rng=rng
    ).modal_response
    modal *= HULL_MODE_RMS / modal.std(axis=0)
    acceleration = modal @ shapes + 0.001 * rng.standard_normal((modal.shape[0], len(CHANNELS)))
    return SimulatedSystem(acceleration, rate, frequency, damping, shapes.T)
