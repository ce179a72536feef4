"""Tests of the Kalman building blocks against closed forms and filterpy itself."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.forecasting.kalman import (
    ModeKalmanBank,
    ScalarKalmanFilter,
    process_variance_for_gain,
    relaxation_factor,
    scalar_kalman_predict,
    scalar_kalman_update,
    steady_state,
)


def _iterate_riccati(q: float, r: float, f: float, n: int = 2000) -> tuple[float, float]:
    """Steady state by running filterpy's own KalmanFilter (independent of our code)."""
    kf = KalmanFilter(dim_x=1, dim_z=1)
    kf.F[:] = f
    kf.H[:] = 1.0
    kf.Q[:] = q
    kf.R[:] = r
    kf.P[:] = 1.0
    for _ in range(n):
        kf.predict()
        prior = float(kf.P[0, 0])
        kf.update(np.array([[0.0]]))
    return prior, float(kf.K[0, 0])


@pytest.mark.parametrize(("q", "r"), [(1e-4, 1e-3), (1.0, 1.0), (2.5, 0.1), (1e-8, 4e-6)])
def test_random_walk_steady_state_gain_closed_form(q, r):
    # scalar random walk x_{k+1} = x_k + w, z = x + v: P⁻ = (Q + sqrt(Q² + 4QR)) / 2
    prior = (q + math.sqrt(q * q + 4 * q * r)) / 2
    gain = prior / (prior + r)
    result = steady_state(q, r)
    assert result.prior_variance == pytest.approx(prior, rel=1e-12)
    assert result.gain == pytest.approx(gain, rel=1e-12)
    assert result.posterior_variance == pytest.approx((1 - gain) * prior, rel=1e-12)
    # and the fixed point is the one filterpy's KalmanFilter converges to
    iter_prior, iter_gain = _iterate_riccati(q, r, 1.0)
    assert result.prior_variance == pytest.approx(iter_prior, rel=1e-9)
    assert result.gain == pytest.approx(iter_gain, rel=1e-9)


@pytest.mark.parametrize("f", [0.5, 0.9, 0.99])
def test_steady_state_with_relaxation_matches_iteration(f):
    iter_prior, iter_gain = _iterate_riccati(0.01, 0.2, f)
    result = steady_state(0.01, 0.2, transition=f)
    assert result.prior_variance == pytest.approx(iter_prior, rel=1e-9)
    assert result.gain == pytest.approx(iter_gain, rel=1e-9)


@pytest.mark.parametrize("f", [1.0, 0.97, 0.5])
@pytest.mark.parametrize("trust", [0.1, 0.65, 0.9])
def test_process_variance_for_gain_gives_that_gain(trust, f):
    r = 3e-4
    q = process_variance_for_gain(trust, r, transition=f)
    assert steady_state(q, r, transition=f).gain == pytest.approx(trust, rel=1e-12)
    if f == 1.0:  # Q/R = K²/(1 - K)
        assert q / r == pytest.approx(trust**2 / (1 - trust), rel=1e-12)


def test_invalid_trust_and_variances_raise():
    with pytest.raises(ValueError, match="trust=1.2"):
        process_variance_for_gain(1.2, 1.0)
    with pytest.raises(ValueError, match="measurement_variance"):
        steady_state(1.0, 0.0)
    with pytest.raises(ValueError, match="correction_time_blocks"):
        relaxation_factor(0.0)
    assert relaxation_factor(math.inf) == 1.0
    assert relaxation_factor(10.0) == pytest.approx(math.exp(-0.1))


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-10, 10),
    p=st.floats(1e-6, 10),
    z=st.floats(-10, 10),
    r=st.floats(1e-6, 10),
)
def test_joseph_and_simple_forms_agree(x, p, z, r):
    joseph = scalar_kalman_update(x, p, z, measurement_variance=r, joseph=True)
    simple = scalar_kalman_update(x, p, z, measurement_variance=r, joseph=False)
    assert joseph.state == pytest.approx(simple.state, rel=1e-9, abs=1e-12)
    # the simple form loses digits to the cancellation in 1 - K when R << P: its relative
    # round-off is about eps * P / R, hence the tolerance
    assert joseph.variance == pytest.approx(simple.variance, rel=1e-12 * (1 + p / r))
    assert joseph.gain == pytest.approx(p / (p + r), rel=1e-12)
    assert joseph.innovation == pytest.approx(z - x, abs=1e-12)
    assert joseph.variance > 0  # P⁺ = PR/(P+R) > 0


def test_predict_applies_transition_control_and_process_noise():
    x, p = scalar_kalman_predict(2.0, 0.5, process_variance=0.1, transition=0.8, control=0.3)
    assert x == pytest.approx(0.8 * 2.0 + 0.3)  # x = Fx + Bu
    assert p == pytest.approx(0.64 * 0.5 + 0.1)  # P = FPF' + Q


def test_scalar_filter_starts_at_steady_state_and_gap_recovers():
    q, r = 1e-4, 1e-3
    kf = ScalarKalmanFilter(5.0, process_variance=q, measurement_variance=r)
    ss = steady_state(q, r)
    assert kf.variance == pytest.approx(ss.posterior_variance)
    kf.predict()
    assert kf.variance == pytest.approx(ss.prior_variance)
    assert kf.update(5.01).gain == pytest.approx(ss.gain)
    variances = []
    for _ in range(10):  # predict-only: P grows by Q per block
        kf.predict()
        assert kf.update(np.nan) is None
        variances.append(kf.variance)
    assert np.allclose(np.diff(variances), q)
    for _ in range(30):  # measurements return: P shrinks back to the steady state
        kf.predict()
        kf.update(5.0)
    assert kf.variance == pytest.approx(ss.posterior_variance, rel=1e-6)


def test_bank_equals_independent_scalar_filters():
    rng = np.random.default_rng(3)
    n_modes, n_blocks, phi = 3, 40, 0.95
    q = np.array([1e-5, 4e-5, 2e-6])
    r = np.array([1e-4, 2e-4, 5e-5])
    model = 5.0 + np.cumsum(rng.normal(0, 0.01, (n_blocks, n_modes)), axis=0)
    z = model + rng.normal(0, 0.01, (n_blocks, n_modes))
    z[rng.random((n_blocks, n_modes)) < 0.3] = np.nan
    bank = ModeKalmanBank(n_modes, transition=phi)
    bank.set_noise(q, r)
    bank.initialise(np.arange(n_modes), model[0])
    filters = [
        ScalarKalmanFilter(
            model[0, j],
            process_variance=q[j],
            measurement_variance=r[j],
            transition=phi,
            variance=steady_state(q[j], r[j], transition=phi).prior_variance,
        )
        for j in range(n_modes)
    ]
    for k in range(n_blocks):
        if k > 0:
            bank.predict(model[k] - phi * model[k - 1])
            for j, kf in enumerate(filters):
                kf.predict(model[k, j] - phi * model[k - 1, j])
        gain = bank.update(z[k])
        for j, kf in enumerate(filters):
            result = kf.update(z[k, j])
            assert gain[j] == pytest.approx(0.0 if result is None else result.gain, abs=1e-15)
        assert np.allclose(bank.state, [kf.state for kf in filters], rtol=0, atol=1e-12)
        assert np.allclose(bank.variance, [kf.variance for kf in filters], rtol=1e-12)
        assert np.all(bank.variance > 0)


def test_bank_mode_not_started_does_not_leak_nan():
    bank = ModeKalmanBank(3, transition=0.9)
    bank.set_noise(np.full(3, 1e-4), np.full(3, 1e-3))
    bank.initialise(np.array([0, 2]), np.array([3.0, 7.0]))
    x, p = bank.predict(np.array([0.1, 0.2, 0.3]))
    assert np.isnan(x[1]) and np.isnan(p[1])
    assert x[0] == pytest.approx(0.9 * 3.0 + 0.1) and x[2] == pytest.approx(0.9 * 7.0 + 0.3)
    bank.update(np.array([3.0, 5.0, np.nan]))
    assert np.isfinite(bank.state[[0, 2]]).all() and np.isnan(bank.state[1])
    assert np.all(bank.variance[[0, 2]] > 0)
