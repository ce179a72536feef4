"""Effective sample size of autocorrelated series (Bartlett 1935; Bretherton et al. 1999)."""

import numpy as np
import pandas as pd
import pytest

from workbench.stats.correlation import (
    correlation_table_effective,
    effective_p_value,
    effective_sample_size,
    pairwise_pearson,
)


def _ar1(rng, n, phi):
    e = rng.standard_normal(n + 200)
    x = np.empty_like(e)
    x[0] = e[0]
    for t in range(1, len(e)):
        x[t] = phi * x[t - 1] + e[t]
    return x[200:]


def test_ar1_pairs_match_bretherton_eq31():
    # Two independent AR(1) series: N_eff / N = (1 - a b) / (1 + a b) (Bretherton et al.
    # 1999, eq. 31). The sample autocorrelation is biased low at lag k by ~(1 + phi)/(1 - phi)/N
    # and noisy: the median of 20 seeds must be within 10 % of the closed form.
    n = 2000
    for a, b in ((0.8, 0.8), (0.9, 0.5), (0.0, 0.9)):
        expected = (1 - a * b) / (1 + a * b)
        ratios = [
            effective_sample_size(_ar1(rng, n, a), _ar1(rng, n, b)) / n
            for rng in (np.random.default_rng(seed) for seed in range(20))
        ]
        assert np.median(ratios) == pytest.approx(expected, rel=0.10), (a, b)


def test_gaps_keep_lags_in_time():
    rng = np.random.default_rng(1)
    x, y = _ar1(rng, 1500, 0.8), _ar1(rng, 1500, 0.8)
    full = effective_sample_size(x, y)
    keep = np.ones(1500, dtype=bool)
    keep[rng.choice(1500, 150, replace=False)] = False
    # dropping 10 % of the rows at random: N_eff scales with the pairs left, not more
    gapped = effective_sample_size(x[keep], y[keep], positions=np.flatnonzero(keep))
    assert gapped == pytest.approx(0.9 * full, rel=0.15)
    # without positions the gaps would close up; with NaN in place the result is the same
    x_nan = np.where(keep, x, np.nan)
    assert effective_sample_size(x_nan, y) == pytest.approx(gapped)


def test_adjusted_test_holds_its_level_on_overlapping_blocks():
    # Independent random walks averaged over 4-step overlapping windows (blocks of 20 min
    # every 5 min): the naive t-test rejects H0 far too often, the effective one near alpha.
    rng = np.random.default_rng(7)
    naive = effective = 0
    trials = 300
    for _ in range(trials):
        raw = rng.standard_normal((204, 2)).cumsum(axis=0) * 0.2 + rng.standard_normal((204, 2))
        blocks = np.stack([raw[k : k + 4].mean(axis=0) for k in range(200)])
        r, p, _ = pairwise_pearson(blocks[:, :1], blocks[:, 1:])
        n_eff = effective_sample_size(blocks[:, 0], blocks[:, 1])
        naive += p[0, 0] < 0.05
        effective += effective_p_value(r[0, 0], n_eff) < 0.05
    assert naive / trials > 0.4
    assert effective / trials < 0.15


def test_white_noise_keeps_n():
    rng = np.random.default_rng(3)
    ratios = [
        effective_sample_size(rng.standard_normal(1000), rng.standard_normal(1000)) / 1000
        for _ in range(20)
    ]
    assert np.median(ratios) == pytest.approx(1.0, abs=0.1)


def test_degenerate_inputs():
    assert np.isnan(effective_sample_size(np.array([1.0, 2.0]), np.array([1.0, 3.0])))
    assert np.isnan(effective_sample_size(np.ones(10), np.arange(10.0)))
    with pytest.raises(ValueError, match="equal length"):
        effective_sample_size(np.ones(3), np.ones(4))
    assert effective_p_value(0.5, 2.0) != effective_p_value(0.5, 2.0)  # NaN: no dof


def _speed_driven_mode(seed: int, n_blocks: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A modal table of one mode whose frequency falls with an AR(1) speed, and its
    predictors, on 5-min steps of 20-min blocks (overlapping: N_eff < n)."""
    rng = np.random.default_rng(seed)
    blocks = np.arange(n_blocks)
    start = pd.Timestamp("2024-01-01", tz="UTC") + pd.to_timedelta(5 * blocks, unit="min")
    speed = _ar1(rng, n_blocks, 0.9)
    predictors = pd.DataFrame(
        {
            "block": blocks,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": _ar1(rng, n_blocks, 0.9),
        }
    )
    modal = pd.DataFrame(
        {
            "block": blocks,
            "mode": 1,
            "frequency_hz": 3.0 - 0.01 * speed + 0.002 * rng.standard_normal(n_blocks),
            "damping_ratio": 0.01 + 0.001 * _ar1(rng, n_blocks, 0.9),
        }
    )
    return modal, predictors


def test_table_adds_effective_columns():
    modal, predictors = _speed_driven_mode(5, 120)
    table = correlation_table_effective(modal, predictors)
    assert {"n_effective", "p_effective", "significant_effective", "small"} <= set(table)
    assert (table["n_effective"] <= table["n"]).all()
    assert (table["p_effective"] >= table["p_value"] - 1e-12).all()
    row = table[(table.x == "speed_kn") & (table.y == "mode1_frequency_hz")].iloc[0]
    assert row["significant_effective"] and not row["small"]


def test_the_correlate_stage_gives_the_same_effective_table():
    # CorrelateResult.effective() (what the report shows) is correlation_table_effective
    # of the same tables, and leaves the stage's own table as it was
    from workbench.stages import correlate

    modal, predictors = _speed_driven_mode(7, 80)
    result = correlate(modal, predictors)
    columns = list(result.table.columns)
    table = result.effective()
    pd.testing.assert_frame_equal(table, correlation_table_effective(modal, predictors))
    assert list(result.table.columns) == columns  # the stage's table is untouched
    row = table[(table.x == "speed_kn") & (table.y == "mode1_frequency_hz")].iloc[0]
    assert row["significant_effective"] and row["n_effective"] < row["n"]
