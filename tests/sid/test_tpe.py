"""Tests for workbench.sid.tpe: total prediction error of the SSI-data innovation model."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from workbench.sid import tpe as tpe_module
from workbench.sid.tpe import one_step_prediction, total_prediction_error


def test_ar1_matches_the_closed_form():
    """y_{k+1} = a y_k + e_k: the best one-step predictor leaves var(e)/var(y) = 1 - a².

    Scatter of the ratio for N = 50 000, a = 0.9: the sample variance of y has relative
    standard deviation sqrt(2(1 + a²)/((1 - a²)N)) ≈ 2 %; 6 % is three of them.
    """
    rng = np.random.default_rng(0)
    a = 0.9
    y = signal.lfilter([1.0], [1.0, -a], rng.standard_normal(50_000))[:, None]
    result = total_prediction_error(y, 1.0, block_rows=5, orders=[1, 2, 3])
    np.testing.assert_allclose(result.total_prediction_error, 1 - a**2, rtol=0.06)
    np.testing.assert_allclose(result.model_prediction_error, 1 - a**2, rtol=0.06)
    assert result.frame()["model_order"].tolist() == [1, 2, 3]


def test_chain3_error_stops_falling_at_the_true_order(chain3):
    """Three modes need six states: the error falls steeply up to order 6, then stays."""
    result = total_prediction_error(
        chain3.acceleration, chain3.sampling_rate_hz, block_rows=20, orders=[2, 4, 6, 8, 10]
    )
    tpe = result.total_prediction_error
    assert tpe[0] > 2 * tpe[1] > 2 * tpe[2]
    np.testing.assert_allclose(tpe[3:], tpe[2], rtol=0.05)
    # the data agree with what the identified model expects of itself
    np.testing.assert_allclose(result.model_prediction_error[2:], tpe[2:], rtol=0.1)
    assert result.channel_errors.shape == (5, 3)


def test_diagonalised_predictor_equals_the_recursion():
    rng = np.random.default_rng(3)
    n, channels = 6, 2
    state = rng.standard_normal((n, n))
    state *= 0.95 / np.abs(np.linalg.eigvals(state)).max()
    output = rng.standard_normal((channels, n))
    gain = 0.1 * rng.standard_normal((n, channels))
    data = rng.standard_normal((500, channels))
    fast = one_step_prediction(data, state, output, gain)
    slow = tpe_module._predict_by_loop(data, state - gain @ output, output, gain)
    np.testing.assert_allclose(fast, slow, atol=1e-9)


def test_bad_warm_up_and_weighting(chain3):
    with pytest.raises(ValueError, match="warm_up") as error:
        total_prediction_error(chain3.acceleration[:4000], 200.0, orders=[2], warm_up=3000)
    assert "[0, 2000)" in str(error.value)
    with pytest.raises(ValueError, match="weighting"):
        total_prediction_error(chain3.acceleration[:4000], 200.0, orders=[2], weighting="x")
