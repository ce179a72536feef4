"""The identification error of overlapping blocks as the blend's states (issue 27).

A 20-minute block with a new block every 5 minutes shares its data with 3 neighbours on
each side: its identification error is the mean of L = 4 independent segment errors, an
MA(3) with correlation (L - h) / L at lag h < L and 0 from lag L. The blend carries the
L segment terms as states (:func:`~workbench.forecasting.memory.kalman.transition_matrices`)
and the covariance matching fits that shape (:func:`~workbench.forecasting.noise.estimate_noise`
with ``error_segments``). Closed forms: the correlation of the state model, and for a constant
frequency the Kalman estimate equals generalised least squares with the MA's Toeplitz
covariance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from workbench.forecasting.memory.kalman import (
    kalman_predict,
    kalman_update,
    n_states,
    stationary_covariance,
    transition_matrices,
)
from workbench.forecasting.noise import (
    MAX_LAG,
    NoiseModel,
    _grid_fits,
    _winsorise,
    error_autocorrelation,
    estimate_noise,
    lagged_autocovariance,
)

L = 4


def _step(state, P, F, Q, *update, **options):
    """One predict + update of the blend's filter (kalman_predict, then kalman_update)."""
    return kalman_update(*kalman_predict(state, P, F, Q), *update, **options)


def _segments_error(rng, n, std, segments=L):
    """Block errors as the mean of *segments* independent segment errors (variance std²)."""
    shocks = rng.normal(0.0, std, n + segments - 1)
    return np.convolve(shocks, np.ones(segments), mode="valid") / math.sqrt(segments)


def test_overlap_correlation_is_the_shared_fraction_and_zero_beyond_the_overlap():
    rho = error_autocorrelation(np.arange(7), segments=L)
    np.testing.assert_allclose(rho, [1.0, 0.75, 0.5, 0.25, 0.0, 0.0, 0.0], rtol=0, atol=0)
    # AR(1) and white as before
    np.testing.assert_allclose(error_autocorrelation(np.arange(3), rho=0.5), [1.0, 0.5, 0.25])
    np.testing.assert_allclose(error_autocorrelation(np.arange(3)), [1.0, 0.0, 0.0])


def test_segment_states_reproduce_the_overlap_autocovariance():
    # cov(e_{k+h}, e_k) = H_e F^h P H_e' of the state model, exactly σ_e² (L - h) / L
    noise = NoiseModel(1e-4, 12.0, 4e-4, 0.75, 1e-5, n_residuals=100, error_segments=L)
    states = n_states(L)
    assert states == 1 + L
    F, q_c, q_e, P = transition_matrices(noise, states)
    np.testing.assert_allclose(P, stationary_covariance(noise, states))
    # stationary: P = FPF' + Q
    np.testing.assert_allclose(F @ P @ F.T + np.diag(q_c + q_e), P, rtol=1e-12, atol=1e-20)
    H_e = np.r_[0.0, np.ones(L)]
    lagged = [H_e @ np.linalg.matrix_power(F, h) @ P @ H_e for h in range(7)]
    np.testing.assert_allclose(lagged, 4e-4 * error_autocorrelation(np.arange(7), segments=L))
    # the model correction c: σ_c² φ^h
    H_c = np.r_[1.0, np.zeros(L)]
    phi = math.exp(-1 / 12)
    assert H_c @ np.linalg.matrix_power(F, 5) @ P @ H_c == pytest.approx(1e-4 * phi**5)


def test_kalman_estimate_of_a_constant_is_gls_with_the_overlap_covariance():
    # x constant (φ = 1, no process noise, a diffuse prior): after n measurements
    # z = x + e + v the filter's x̂ is the GLS mean (1'Σ⁻¹z) / (1'Σ⁻¹1), Σ = σ_e² T + σ_v² I
    # with T the Toeplitz matrix of (L - |i - j|) / L. Agreement to 1e-6 relative: the
    # diffuse prior (1e8 σ²) perturbs it by ~1e-8.
    rng = np.random.default_rng(3)
    n, se2, sv2 = 40, 4e-4, 1e-4
    z = 5.0 + _segments_error(rng, n, math.sqrt(se2)) + rng.normal(0, math.sqrt(sv2), n)
    noise = NoiseModel(1e-300, 1e300, se2, 0.75, sv2, n_residuals=100, error_segments=L)
    states = n_states(L)
    F, _, q_e, P = transition_matrices(noise, states)
    F[0, 0] = 1.0
    P[0, 0] = 1e8 * se2
    state, P = np.zeros((1, states)), P[None]
    first = True
    for value in z:
        if first:  # the prior is the a-priori state of the first block: no predict step
            Fk, Qk = np.eye(states)[None], np.zeros((1, states))
            first = False
        else:
            Fk, Qk = F[None], q_e[None]
        state, P, *_ = _step(state, P, Fk, Qk, np.array([value]), np.array([sv2]), np.inf)
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    sigma = se2 * np.clip(1 - lag / L, 0, None) + sv2 * np.eye(n)
    w = np.linalg.solve(sigma, np.ones(n))
    gls = w @ z / w.sum()
    assert state[0, 0] == pytest.approx(gls, rel=1e-6)
    assert P[0, 0, 0] == pytest.approx(1.0 / w.sum(), rel=1e-6)


def test_covariance_matching_with_the_overlap_shape_separates_a_wander_from_the_error():
    # r = c + e + v: c AR(1) τ = 12 blocks (a 1-hour wander, on the τ grid), std 0.02 Hz,
    # twice the identification error's 0.01 Hz (MA(3), the overlap), v 0.003 Hz. 20 000
    # blocks: the lag products scatter by ~1 % relative; 25 % on the variances covers it.
    # (A τ between grid points, e.g. 8, can move the whole of e into c: noise.CORRECTION_TIMES.)
    rng = np.random.default_rng(11)
    n = 20000
    phi = math.exp(-1 / 12)
    c = np.empty(n)
    c[0] = rng.normal(0, 0.02)
    for k in range(1, n):
        c[k] = phi * c[k - 1] + math.sqrt(1 - phi**2) * rng.normal(0, 0.02)
    r = c + _segments_error(rng, n, 0.01) + rng.normal(0, 0.003, n)
    noise = estimate_noise(r, 5.0, correlated_lags=L, error_segments=L)
    assert noise.error_segments == L
    assert noise.error_correlation == 0.75
    assert noise.error_variance == pytest.approx(1e-4, rel=0.25)
    assert noise.correction_variance == pytest.approx(4e-4, rel=0.25)
    assert noise.correction_time_blocks == pytest.approx(12.0, rel=0.05)
    # the AR(1) grid on the same residuals over-states e (it takes part of the wander)
    ar1 = estimate_noise(r, 5.0, correlated_lags=L)
    assert ar1.error_variance > 1.05 * noise.error_variance


def test_the_split_moves_smoothly_as_residuals_arrive():
    # r = c + e + v: c AR(1) τ = 8 blocks (a 40-min wander, between the grid's 6 and 12),
    # std 0.02 Hz; e the overlap's MA(3), 0.01 Hz; v 0.003 Hz. Refitted every 5 residuals
    # from 200 to 600 (as the forecast refits). The grid's best point alone flips between
    # (τ 6, σ_e ≈ 0) and (τ 12, σ_e ≈ σ) from one refit to the next on this record (a step
    # of 0.0099 Hz in σ_e); averaged over the points that fit as well (noise._soft_choice)
    # σ_e moves by at most 0.0016 Hz a refit, and its mean is within 15 % of the truth
    # (the best point alone: 0.0059 Hz, 41 % short).
    rng = np.random.default_rng(3)
    n = 600
    phi = math.exp(-1 / 8)
    c = np.empty(n)
    c[0] = rng.normal(0, 0.02)
    for k in range(1, n):
        c[k] = phi * c[k - 1] + math.sqrt(1 - phi**2) * rng.normal(0, 0.02)
    r = c + _segments_error(rng, n, 0.01) + rng.normal(0, 0.003, n)
    soft, best = [], []
    for m in range(200, n, 5):
        noise = estimate_noise(r[:m], 5.0, correlated_lags=L, error_segments=L)
        soft.append(math.sqrt(noise.error_variance))
        gamma, count = lagged_autocovariance(_winsorise(r[:m]), MAX_LAG)
        lags = np.flatnonzero(count >= 10)
        _, _, misfit, coefs = _grid_fits(lags, gamma[lags], np.sqrt(count[lags] / count[0]), L)
        best.append(math.sqrt(coefs[np.argmin(misfit), 1]))
    assert np.abs(np.diff(best)).max() > 0.009  # the flip this record shows
    assert np.abs(np.diff(soft)).max() < 0.002
    assert np.mean(soft) == pytest.approx(0.01, rel=0.15)
