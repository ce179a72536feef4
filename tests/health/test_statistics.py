"""Control-chart statistics: the CUSUM's in-control simulation and the chart's estimators,
checked against closed forms (truncated normal, Siegmund's run length) and known
efficiencies."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from workbench.shm.statistics import (
    OUTLIER_SIGMA,
    InControlResiduals,
    _robust_location_scale,
    cusum_limits,
    trimmed_location_scale,
    truncated_normal_variance,
)


def _siegmund_arl(drift: float, limit: float) -> float:
    """Average run length of S_k = max(0, S_{k-1} + y_k), y ~ N(-drift, 1), to exceed
    *limit*: (e^{2 d b} - 2 d b - 1) / (2 d²), b = limit + 1.166 (Siegmund 1985, p. 27)."""
    b = limit + 1.166
    if abs(drift) < 1e-9:
        return b * b
    return (math.exp(2 * drift * b) - 2 * drift * b - 1) / (2 * drift * drift)


def test_truncated_normal_variance_is_scipys():
    for cut in (1.0, 2.0, OUTLIER_SIGMA):
        expected = stats.truncnorm(-cut, cut).var()
        assert truncated_normal_variance(cut) == pytest.approx(expected, rel=1e-12)
    assert truncated_normal_variance(3.5) == pytest.approx(0.993888, abs=1e-6)


def test_trimmed_location_scale_drops_wrong_poles_and_is_unbiased():
    rng = np.random.default_rng(0)
    values = 2.0 + 0.5 * rng.standard_normal(100_000)
    values[:1000] = 50.0  # 1 % wrong poles, all on one side
    location, scale = trimmed_location_scale(values[:, None])
    # standard errors of the mean and of the standard deviation: 0.5/√n and 0.5/√(2n)
    assert location[0] == pytest.approx(2.0, abs=4 * 0.5 / math.sqrt(99_000))
    assert scale[0] == pytest.approx(0.5, abs=4 * 0.5 / math.sqrt(2 * 99_000))


def test_trimmed_scale_is_about_three_times_as_efficient_as_the_mad():
    # the MAD's asymptotic efficiency for Gaussian data is 0.37 (Hampel et al. 1986,
    # "Robust Statistics", section 2.3); a standard deviation trimmed at 3.5 sigma loses
    # almost nothing: var(trimmed) / var(MAD) ≈ 0.37. 4000 samples of 288 (a day of blocks):
    # the ratio of two sample variances is known to about ±5 %
    rng = np.random.default_rng(1)
    samples = rng.standard_normal((288, 4000))
    trimmed = trimmed_location_scale(samples)[1]
    mad = _robust_location_scale(samples)[1]
    assert np.var(trimmed) / np.var(mad) == pytest.approx(0.37, abs=0.05)
    assert np.mean(trimmed) == pytest.approx(1.0, abs=0.005)


def _limit(**kw):
    options = {
        "reference_blocks": 4000,  # a long reference: little location and scale error
        "blocks_per_day": 288.0,
        "false_alarms_per_day": 0.1,
        "replicates": 3000,
        "clip_sigma": 10.0,
        "rng": np.random.default_rng(2),
    }
    residuals = {"segments": 1, **{k: kw.pop(k) for k in list(kw) if k not in options}}
    options.update(kw)
    return cusum_limits(np.array([0.5]), InControlResiduals(**residuals), **options)[0]


def test_missing_estimates_count_as_fewer_blocks_a_day():
    # the CUSUM holds where an estimate is missing: with half of them missing a day of 288
    # blocks is a day of 144; 288 blocks without missing need ln(2)/(2k) = 0.69 more
    # (Siegmund: the ARL grows by e^{2k} per unit of H, k = 0.5)
    half_missing = _limit(missing_rate=0.5)
    fewer_blocks = _limit(blocks_per_day=144.0, rng=np.random.default_rng(3))
    full = _limit(rng=np.random.default_rng(4))
    # each quantile of 3000 daily maxima is known to about ±0.2 (see test_chart.py)
    assert half_missing == pytest.approx(fewer_blocks, abs=0.3)
    assert full - half_missing == pytest.approx(math.log(2.0), abs=0.3)


def test_the_model_offset_is_in_the_limit():
    # each day's residuals carry a persistent offset b ~ N(0, 0.3²): the daily false-alarm
    # probability E_b[1 - exp(-288 / ARL(K + b))] with Siegmund's ARL must be the target
    # 1 - exp(-0.1) at the returned H (Siegmund's ARL is within about 10 %, the quantile
    # of 3000 maxima within ±6 %: ±25 % on the probability)
    offset_std = 0.3
    limit = _limit(offset_std=np.array([offset_std]))
    nodes, weights = np.polynomial.hermite_e.hermegauss(40)
    weights = weights / weights.sum()

    def daily_alarm_probability(h):
        p = [1 - math.exp(-288.0 / _siegmund_arl(0.5 + offset_std * b, h)) for b in nodes]
        return float(np.dot(weights, p))

    target = 1 - math.exp(-0.1)
    assert daily_alarm_probability(limit) == pytest.approx(target, rel=0.25)
    # without the offset in the simulation the limit would give 1.5 x the target or more
    assert daily_alarm_probability(_limit()) > 1.5 * target


def test_wrong_poles_cost_less_than_the_variance_they_add():
    # blocks of four segments (20 min every 5 min), K = 1: 0.5 % wrong poles clipped at 4
    # add 0.005 x 16 = 0.08 to the variance; simulated as they are (rare, independent
    # jumps) they raise H less than inflating every residual to that variance did (the
    # previous calibration), and more than not at all. The same draws for all three
    # (common random numbers), so the differences are not Monte Carlo noise
    def limit(**kw):
        return cusum_limits(
            np.array([1.0]),
            InControlResiduals(segments=4, **kw),
            reference_blocks=4000,
            blocks_per_day=288.0,
            false_alarms_per_day=0.1,
            replicates=3000,
            clip_sigma=4.0,
            rng=np.random.default_rng(2),
        )[0]

    clean, wrong, inflated = limit(), limit(outlier_rate=0.005), limit(variance=1.08)
    assert 0.05 < wrong - clean < 0.4  # 9.27 -> 9.43 when written
    assert inflated - wrong > 0.4  # 10.08
