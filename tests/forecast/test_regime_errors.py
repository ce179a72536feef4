"""The identification-error generators of the forecast accuracy suite
(``benchmarks/forecast_regimes.py``): their correlations are the ones the docstring names.

``"segments"``: a block's error is the mean of its four 5-minute segments' independent
errors, so with a constant size the lag-h correlation is (4 - h)/4 for h < 4 and exactly
zero from lag 4 (an MA(3)); ``"ar1"``: 0.65^h. Tolerances: the sample autocorrelation of
n = 40 000 values has a standard deviation below sqrt((1 + 2 Σ r_h²) / n) < 0.011 for both
processes (Bartlett's formula), so 0.04 is more than three of them.
"""

import numpy as np
import pytest


def _autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    x = x - x.mean()
    return np.array([np.mean(x[: x.size - h] * x[h:]) for h in range(lags + 1)]) / np.mean(x * x)


def test_segment_errors_are_ma3_with_overlap_correlations_and_none_beyond(regimes):
    rng = np.random.default_rng(5)
    n = 40_000
    size = np.full((n, 1), 2e-3)
    error, segment_size = regimes.identification_error(
        size, rng.standard_normal((n, 1)), rng.standard_normal((3, 1)), 4
    )
    assert segment_size.shape == (n + 3, 1)
    assert np.std(error) == pytest.approx(2e-3, rel=0.02)  # variance size²
    r = _autocorrelation(error[:, 0], 6)
    np.testing.assert_allclose(r[1:], [0.75, 0.5, 0.25, 0.0, 0.0, 0.0], atol=0.04)


def test_ar1_errors_keep_correlating_beyond_the_overlap(regimes):
    rng = np.random.default_rng(6)
    n = 40_000
    error, segment_size = regimes.identification_error(
        np.full((n, 1), 2e-3), rng.standard_normal((n, 1))
    )
    assert segment_size is None
    r = _autocorrelation(error[:, 0], 4)
    np.testing.assert_allclose(r[1:], 0.65 ** np.arange(1, 5), atol=0.04)
    assert r[4] > 0.1  # 0.65^4 = 0.18: the leak the segments generator does not have


def test_both_generators_share_every_other_draw(regimes):
    ar1 = regimes.make_regime("wander_40min_2x", 0, n_blocks=60, shapes=False)
    seg = regimes.make_regime(
        "wander_40min_2x", 0, n_blocks=60, shapes=False, error_model="segments"
    )
    assert seg.truth.equals(ar1.truth)
    assert seg.predictors.equals(ar1.predictors)
    assert len(seg.poles) == len(ar1.poles)
    assert not np.allclose(seg.tracked["frequency_hz"], ar1.tracked["frequency_hz"])
    with pytest.raises(ValueError, match="error_model") as info:
        regimes.make_regime("wander_40min_2x", 0, n_blocks=60, error_model="white")
    assert "segments" in str(info.value)
