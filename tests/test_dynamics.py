"""Tests for workbench.simulate.dynamics: exact discretisation, variances, continuity across calls."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, linalg, signal

from workbench.simulate.dynamics import (
    ModalState,
    discretize_modes,
    draw_stationary_state,
    simulate_modal_response,
    stationary_covariance,
)

FREQUENCY_HZ = np.array([2.9, 4.7, 5.4])
DAMPING = np.array([0.01, 0.02, 0.005])
RATE_HZ = 64.0


def _continuous_matrix(frequency_hz: float, damping_ratio: float) -> np.ndarray:
    omega = 2 * np.pi * frequency_hz
    return np.array([[0.0, 1.0], [-(omega**2), -2 * damping_ratio * omega]])


def _loop_reference(modes, force, x0, output):
    """Sample-by-sample recursion x_{k+1} = Φ x_k + Γ f_k, y_k = C x_k + D f_k."""
    c, d = modes.output_matrices(output)
    x = x0.copy()
    out = []
    for f in force:
        out.append(np.einsum("mi,mi->m", c, x) + d * f)
        x = np.einsum("mij,mj->mi", modes.transition, x) + modes.input_gain * f[:, None]
    return np.array(out), x


def test_transition_and_input_gain_match_matrix_exponential_and_quadrature():
    modes = discretize_modes(FREQUENCY_HZ, DAMPING, RATE_HZ)
    period = 1 / RATE_HZ
    for m, (f, z) in enumerate(zip(FREQUENCY_HZ, DAMPING, strict=True)):
        a = _continuous_matrix(f, z)
        np.testing.assert_allclose(modes.transition[m], linalg.expm(a * period), atol=1e-14)
        # Γ = ∫_0^T exp(A s) B ds, by adaptive quadrature
        gamma, _ = integrate.quad_vec(lambda s, a=a: linalg.expm(a * s)[:, 1], 0, period)
        np.testing.assert_allclose(modes.input_gain[m], gamma, rtol=1e-10)


@pytest.mark.parametrize("output", ["displacement", "velocity", "acceleration"])
def test_filter_equals_sample_loop_including_initial_state(output):
    rng = np.random.default_rng(1)
    force = rng.standard_normal((400, 3))
    x0 = np.array([[0.01, 0.3], [-0.02, 0.1], [0.0, -0.2]])
    state = ModalState(x0[:, 0], x0[:, 1])
    result = simulate_modal_response(
        FREQUENCY_HZ,
        DAMPING,
        np.eye(3),
        RATE_HZ,
        400,
        modal_force=force,
        state=state,
        output=output,
    )
    modes = discretize_modes(FREQUENCY_HZ, DAMPING, RATE_HZ)
    expected, x_end = _loop_reference(modes, force, x0, output)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(result.modal_response, expected, atol=1e-12 * scale)
    np.testing.assert_allclose(result.state.displacement, x_end[:, 0], atol=1e-12 * scale)
    np.testing.assert_allclose(result.state.velocity, x_end[:, 1], atol=1e-12 * scale)


def test_superposition_with_mode_shapes():
    rng = np.random.default_rng(2)
    shapes = rng.standard_normal((3, 5))
    result = simulate_modal_response(FREQUENCY_HZ, DAMPING, shapes, RATE_HZ, 100, rng=rng)
    assert result.response.shape == (100, 5)
    np.testing.assert_allclose(result.response, result.modal_response @ shapes, rtol=1e-13)


def test_chunked_simulation_equals_one_shot():
    rng = np.random.default_rng(3)
    force = rng.standard_normal((3000, 3))
    shapes = np.random.default_rng(4).standard_normal((3, 4))
    one = simulate_modal_response(FREQUENCY_HZ, DAMPING, shapes, RATE_HZ, 3000, modal_force=force)
    state = None
    parts = []
    for start, stop in [(0, 1), (1, 1000), (1000, 1000), (1000, 2500), (2500, 3000)]:
        part = simulate_modal_response(
            FREQUENCY_HZ,
            DAMPING,
            shapes,
            RATE_HZ,
            stop - start,
            modal_force=force[start:stop],
            state=state,
        )
        state = part.state
        parts.append(part.response)
    chunked = np.vstack(parts)
    np.testing.assert_allclose(chunked, one.response, atol=1e-12 * np.abs(one.response).max())
    np.testing.assert_allclose(state.velocity, one.state.velocity, rtol=1e-11)


def test_state_is_continuous_when_parameters_change_between_calls():
    rng = np.random.default_rng(5)
    first = simulate_modal_response(
        FREQUENCY_HZ, DAMPING, np.eye(3), RATE_HZ, 500, rng=rng, output="displacement"
    )
    # Same force in the next call under new parameters: displacement at its first sample
    # must be the carried state (displacement has no feedthrough).
    second = simulate_modal_response(
        1.05 * FREQUENCY_HZ,
        2 * DAMPING,
        np.eye(3),
        RATE_HZ,
        10,
        rng=rng,
        output="displacement",
        state=first.state,
    )
    np.testing.assert_array_equal(second.modal_response[0], first.state.displacement)
    # and it follows the new parameters' recursion from there
    modes = discretize_modes(1.05 * FREQUENCY_HZ, 2 * DAMPING, RATE_HZ)
    x0 = np.column_stack([first.state.displacement, first.state.velocity])
    zero = np.zeros((10, 3))
    free = simulate_modal_response(
        1.05 * FREQUENCY_HZ,
        2 * DAMPING,
        np.eye(3),
        RATE_HZ,
        10,
        modal_force=zero,
        output="displacement",
        state=first.state,
    )
    expected, _ = _loop_reference(modes, zero, x0, "displacement")
    np.testing.assert_allclose(free.modal_response, expected, rtol=1e-11, atol=1e-18)


def test_stationary_covariance_tends_to_continuous_white_noise_formula():
    # Fast sampling (ωT = 0.006): ZOH noise of variance σ² ≈ continuous white noise of
    # intensity σ²T, var(q) = σ²T/(4ζω³), var(q') = σ²T/(4ζω) (Crandall & Mark 1963).
    # The ZOH error is O(ωT) relative, so 1 % is ample.
    frequency, damping, rate, sigma = 2.0, 0.02, 2000.0, 3.0
    omega = 2 * np.pi * frequency
    covariance = stationary_covariance(frequency, damping, rate, excitation_std=sigma)[0]
    intensity = sigma**2 / rate
    assert covariance[0, 0] == pytest.approx(intensity / (4 * damping * omega**3), rel=0.01)
    assert covariance[1, 1] == pytest.approx(intensity / (4 * damping * omega), rel=0.01)
    assert abs(covariance[0, 1]) < 0.01 * np.sqrt(covariance[0, 0] * covariance[1, 1])


def test_stationary_covariance_solves_discrete_lyapunov_equation():
    modes = discretize_modes(FREQUENCY_HZ, DAMPING, RATE_HZ)
    covariance = stationary_covariance(FREQUENCY_HZ, DAMPING, RATE_HZ, excitation_std=2.0)
    for m in range(3):
        g = modes.input_gain[m][:, None]
        expected = linalg.solve_discrete_lyapunov(modes.transition[m], 4.0 * g @ g.T)
        np.testing.assert_allclose(covariance[m], expected, rtol=1e-9)


@pytest.mark.parametrize("output", ["displacement", "acceleration"])
def test_simulated_variance_matches_discrete_theory(output):
    # One mode, ζ = 5 %, 2**18 samples (4096 s): the variance estimate of a narrow-band
    # process has relative std ≈ 1/sqrt(ζ ω T_total) ≈ 1.2 %; assert within 5 % (4 σ).
    frequency, damping, sigma = 5.0, 0.05, 0.7
    rng = np.random.default_rng(6)
    state = draw_stationary_state(frequency, damping, RATE_HZ, rng=rng, excitation_std=sigma)
    result = simulate_modal_response(
        frequency,
        damping,
        np.ones((1, 1)),
        RATE_HZ,
        2**18,
        rng=rng,
        excitation_std=sigma,
        output=output,
        state=state,
    )
    covariance = stationary_covariance(frequency, damping, RATE_HZ, excitation_std=sigma)[0]
    c, d = discretize_modes(frequency, damping, RATE_HZ).output_matrices(output)
    expected = c[0] @ covariance @ c[0] + d[0] ** 2 * sigma**2
    assert np.var(result.response[:, 0]) == pytest.approx(expected, rel=0.05)


def test_psd_peak_at_natural_frequency():
    # Displacement PSD of a lightly damped mode peaks at ω sqrt(1 - 2ζ²) ≈ f (ζ = 1 %:
    # shift 1e-4 f); Welch resolution 64/8192 Hz = 0.0078 Hz, allow two bins.
    rng = np.random.default_rng(7)
    result = simulate_modal_response(
        FREQUENCY_HZ, DAMPING, np.eye(3), RATE_HZ, 2**17, rng=rng, output="displacement"
    )
    for m, f in enumerate(FREQUENCY_HZ):
        freqs, psd = signal.welch(result.response[:, m], fs=RATE_HZ, nperseg=8192)
        assert abs(freqs[np.argmax(psd)] - f) <= 2 * RATE_HZ / 8192


def test_draw_stationary_state_has_stationary_covariance():
    rng = np.random.default_rng(8)
    draws = np.array(
        [
            [s.displacement[0], s.velocity[0]]
            for s in (draw_stationary_state(4.7, 0.02, RATE_HZ, rng=rng) for _ in range(4000))
        ]
    )
    expected = stationary_covariance(4.7, 0.02, RATE_HZ)[0]
    # 4000 draws: variance estimates have relative std sqrt(2/4000) = 2.2 %; allow 10 %.
    np.testing.assert_allclose(np.diag(np.cov(draws.T)), np.diag(expected), rtol=0.1)


def test_bad_arguments_are_rejected_with_named_parameter():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="frequency_hz") as above_nyquist:
        discretize_modes([40.0], 0.01, 64.0)
    with pytest.raises(ValueError, match="damping_ratio") as overdamped:
        discretize_modes([4.0], 1.2, 64.0)
    with pytest.raises(ValueError, match="mode_shapes") as bad_shapes:
        simulate_modal_response([4.0, 5.0], 0.01, np.ones((3, 2)), 64.0, 10, rng=rng)
    with pytest.raises(ValueError, match="rng") as no_rng:
        simulate_modal_response([4.0], 0.01, np.ones((1, 2)), 64.0, 10)
    with pytest.raises(ValueError, match="output") as bad_output:
        simulate_modal_response([4.0], 0.01, np.ones((1, 2)), 64.0, 10, rng=rng, output="jerk")
    with pytest.raises(ValueError, match="state") as bad_state:
        simulate_modal_response(
            [4.0], 0.01, np.ones((1, 2)), 64.0, 10, rng=rng, state=ModalState.at_rest(2)
        )
    assert "32" in str(above_nyquist.value)
    assert "[0, 1)" in str(overdamped.value)
    assert "(3, 2)" in str(bad_shapes.value)
    assert "modal_force" in str(no_rng.value)
    assert "jerk" in str(bad_output.value)
    assert "2 modes" in str(bad_state.value)
