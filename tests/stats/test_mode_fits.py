"""Tests for residual diagnostics, per-mode fits, the coefficient table and the fit report."""

from __future__ import annotations

import json
import warnings

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from scipy import stats
from statsmodels.stats.stattools import durbin_watson as sm_durbin_watson

from workbench.reporting.diagnostics_plot import plot_residual_diagnostics
from workbench.stages import FitOptions, fit
from workbench.stats import (
    StatsWarning,
    coefficient_table,
    durbin_watson,
    fit_modes,
    fit_statistics_table,
    residual_diagnostics,
    stepwise,
)


# --------------------------------------------------------------------------- diagnostics
def test_durbin_watson_matches_statsmodels_and_ar1_limit():
    rng = np.random.default_rng(0)
    e = rng.standard_normal(200)
    assert durbin_watson(e) == pytest.approx(sm_durbin_watson(e), rel=1e-12)
    # AR(1) with φ = 0.6: d → 2 (1 - φ) = 0.8 (standard error about 0.02 at n = 20000)
    ar = np.empty(20000)
    ar[0] = 0.0
    shocks = rng.standard_normal(ar.size)
    for t in range(1, ar.size):
        ar[t] = 0.6 * ar[t - 1] + shocks[t]
    assert durbin_watson(ar) == pytest.approx(0.8, abs=0.05)
    with_nan = e.copy()
    with_nan[[5, 50]] = np.nan
    assert durbin_watson(with_nan) == pytest.approx(sm_durbin_watson(e[np.isfinite(with_nan)]))


def test_normality_tests_match_scipy():
    rng = np.random.default_rng(1)
    normal = residual_diagnostics(rng.normal(0, 2, 300))
    assert normal.normal and normal.n == 300
    e = rng.exponential(1.0, 300)
    skewed = residual_diagnostics(e)
    assert not skewed.normal
    jb = stats.jarque_bera(e)
    assert skewed.jarque_bera_statistic == pytest.approx(jb.statistic, rel=1e-10)
    assert skewed.jarque_bera_p_value == pytest.approx(jb.pvalue, rel=1e-8, abs=1e-300)
    sw = stats.shapiro(e)
    assert skewed.shapiro_statistic == pytest.approx(sw.statistic, rel=1e-12)
    assert skewed.skewness == pytest.approx(stats.skew(e), rel=1e-10)
    assert skewed.excess_kurtosis == pytest.approx(stats.kurtosis(e), rel=1e-10)
    assert "Shapiro-Wilk" in skewed.summary() and "REJECTED" in skewed.summary()
    json.dumps(skewed.to_dict(), allow_nan=False)
    empty = residual_diagnostics([np.nan])
    assert empty.n == 0 and np.isnan(empty.durbin_watson)
    json.dumps(empty.to_dict(), allow_nan=False)


def test_durbin_watson_within_contiguous_runs():
    rng = np.random.default_rng(3)
    # two runs of blocks (0-99 and 200-299): the jump between them is not a lag-1 pair
    first, second = rng.standard_normal(100) + 5.0, rng.standard_normal(100) - 5.0
    e = np.concatenate([first, second])
    blocks = np.concatenate([np.arange(100), np.arange(200, 300)])
    inside = np.sum(np.diff(first) ** 2) + np.sum(np.diff(second) ** 2)
    expected = inside / np.sum(e**2) * (e.size - 1) / 198
    assert durbin_watson(e, blocks) == pytest.approx(expected, rel=1e-12)
    # without the blocks the 10-unit jump counts as one more pair
    jump = (second[0] - first[-1]) ** 2
    assert durbin_watson(e) == pytest.approx((inside + jump) / np.sum(e**2), rel=1e-12)
    # interleaved runs (every other block, as in a case stitched from alternating
    # stretches): no pair is contiguous, so the statistic is undefined
    assert np.isnan(durbin_watson(e, np.arange(0, 400, 2)))
    diagnostics = residual_diagnostics(e, blocks=blocks)
    assert diagnostics.durbin_watson == pytest.approx(expected, rel=1e-12)
    pairs = np.concatenate([np.arange(99), np.arange(100, 199)])
    lag1 = np.corrcoef(e[pairs], e[pairs + 1])[0, 1]
    assert diagnostics.lag1_autocorrelation == pytest.approx(lag1, rel=1e-12)


def test_fit_modes_keeps_blocks_with_nan_in_an_unused_predictor(block_tables):
    modal, predictors = block_tables
    predictors = predictors.copy()
    predictors["hull_strain"] = np.nan  # a logged channel that is mostly missing
    predictors.loc[predictors.index[:5], "hull_strain"] = np.arange(5.0)
    fits = fit_modes(modal, predictors, predictors_used=["speed_kn", "water_temp_c", "hull_strain"])
    for mode, item in fits.items():
        assert "hull_strain" not in item.fit.used_predictors
        assert item.fit.n_obs == item.blocks.size == 80, mode
    # stepwisefit's rule keeps only the 5 blocks where every candidate is finite
    complete = fit_modes(
        modal,
        predictors,
        predictors_used=["speed_kn", "water_temp_c", "hull_strain"],
        missing="complete",
    )
    assert {item.fit.n_obs for item in complete.values()} == {5}


def test_diagnostics_figure_panels(close_figures):
    rng = np.random.default_rng(2)
    residuals = rng.standard_normal(50)
    fitted = np.linspace(2.8, 3.0, 50)
    fig = plot_residual_diagnostics(residuals, fitted, title="mode 1", unit="Hz")
    assert len(fig.axes) == 4
    lagged = fig.axes[2].lines[0]
    np.testing.assert_array_equal(lagged.get_xdata(), residuals[:-1])
    np.testing.assert_array_equal(lagged.get_ydata(), residuals[1:])
    assert "Durbin-Watson" in fig.axes[2].get_title()
    np.testing.assert_array_equal(fig.axes[3].lines[0].get_xdata(), fitted)
    plt.close(fig)
    with pytest.raises(ValueError, match="differ in shape"):
        plot_residual_diagnostics(residuals, fitted[:10])


# --------------------------------------------------------------------------- per-mode fits
def test_fit_modes_recovers_the_law(block_tables):
    modal, predictors = block_tables
    fits = fit_modes(modal, predictors)
    assert list(fits) == [1, 2, 3]
    # mode 1 carries the speed x water interaction, modes 2 and 3 do not (conftest law)
    assert set(fits[1].fit.terms) >= {"speed_kn", "water_temp_c", "speed_kn:water_temp_c"}
    for mode in (1, 2, 3):
        terms = fits[mode].fit.terms
        assert "speed_kn" in terms
        assert not any("wind" in term for term in terms)
        assert fits[mode].fit.r_squared > 0.9
        assert fits[mode].blocks.size == fits[mode].fit.n_obs == 80
    coefficient = fits[2].fit.coefficients.loc["speed_kn", "estimate"]
    assert coefficient == pytest.approx(-0.012, abs=0.001)
    np.testing.assert_allclose(
        fits[1].residuals, fits[1].observed - fits[1].fitted, rtol=0, atol=1e-15
    )


def test_coefficient_table_has_zeros_for_absent_terms(block_tables):
    modal, predictors = block_tables
    fits = fit_modes(modal, predictors, predictors_used=["speed_kn", "water_temp_c"])
    table = coefficient_table(fits)
    assert table.index.tolist() == [1, 2, 3]
    assert table.columns[0] == "(Intercept)"
    present = set()
    for mode, item in fits.items():
        estimates = item.fit.coefficients["estimate"]
        for term in table.columns:
            expected = estimates.get(term, 0.0)
            assert table.loc[mode, term] == expected
        present |= set(estimates.index)
    assert set(table.columns) == present
    assert "speed_kn:water_temp_c" in table.columns
    # the same from bare stepwise fits
    bare = {m: f.fit for m, f in fits.items()}
    pd.testing.assert_frame_equal(coefficient_table(bare), table)
    statistics = fit_statistics_table(fits)
    assert statistics.loc[1, "formula"].startswith("mode1_frequency_hz ~ 1 + speed_kn")
    assert statistics["n_obs"].tolist() == [80, 80, 80]


def test_fit_modes_errors_name_the_column_or_mode(block_tables):
    modal, predictors = block_tables
    with pytest.raises(ValueError, match="modal table has no column 'damping_ratio'"):
        fit_modes(modal.drop(columns="damping_ratio"), predictors, quantity="damping_ratio")
    with pytest.raises(ValueError, match="predictor table has no column 'heading_deg'"):
        fit_modes(modal, predictors, predictors_used=["speed_kn", "heading_deg"])
    empty = modal.copy()
    empty.loc[empty["mode"] == 2, "frequency_hz"] = np.nan
    with pytest.raises(ValueError, match="mode 2: no finite frequency_hz"):
        fit_modes(empty, predictors)
    with pytest.warns(StatsWarning, match="mode 2: no finite frequency_hz"):
        fits = fit_modes(empty, predictors, errors="warn")
    assert list(fits) == [1, 3]
    chosen = ["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms"]
    flat = predictors.assign(wind_speed_ms=7.0)
    with pytest.raises(ValueError, match="predictor 'wind_speed_ms' is constant"):
        fit_modes(modal, flat, predictors_used=chosen)
    collinear = predictors.assign(air_temp_c=predictors["water_temp_c"] * 2 - 1)
    with pytest.raises(ValueError, match="'air_temp_c' is a linear combination of"):
        fit_modes(modal, collinear, predictors_used=chosen)
    missing = predictors.assign(wind_speed_ms=np.nan)
    with pytest.raises(ValueError, match="predictor 'wind_speed_ms' has no finite value"):
        fit_modes(modal, missing, predictors_used=chosen)
    # predictors taken by default: such columns are left out with a warning
    for table, match in (
        (flat, "'wind_speed_ms' is constant"),
        (collinear, "'air_temp_c' is a linear combination of 'speed_kn', 'water_temp_c'"),
        (missing, "'wind_speed_ms' has no finite value"),
    ):
        with pytest.warns(StatsWarning, match=match):
            fits = fit_modes(modal, table, modes=[1])
        left_out = match.split("'")[1]
        assert left_out not in fits[1].fit.predictor_names


def test_fit_options_reach_stepwise(block_tables):
    modal, predictors = block_tables
    fits = fit_modes(modal, predictors, modes=[1], upper="linear", criterion="bic")
    assert list(fits) == [1]
    assert not any(":" in term for term in fits[1].fit.terms)
    assert fits[1].fit.criterion == "bic"
    X = predictors[["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"]]
    y = modal[modal["mode"] == 1]["frequency_hz"].to_numpy()
    direct = stepwise(X, y, upper="linear", criterion="bic")
    assert direct.terms == fits[1].fit.terms


# --------------------------------------------------------------------------- report
def test_write_fit_report(block_tables, tmp_path, close_figures):
    modal, predictors = block_tables
    modal = modal.copy()
    modal.loc[modal["mode"] == 3, "frequency_hz"] = np.nan  # left out with a warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit(
            modal, predictors, options=FitOptions(p_enter=0.01, p_remove=0.02, min_presence=0.0)
        )
        paths = result.save(tmp_path / "fit")
    assert any(issubclass(w.category, StatsWarning) for w in caught)
    assert set(paths) == {
        "summary",
        "json",
        "coefficients",
        "statistics",
        "influence",
        "diagnostics_mode1",
        "diagnostics_mode2",
    }
    for path in paths.values():
        assert path.is_file() and path.stat().st_size > 0
    table = pd.read_csv(paths["coefficients"], index_col="mode")
    assert table.index.tolist() == [1, 2]
    assert "speed_kn" in table.columns
    payload = json.loads(paths["json"].read_text())
    assert payload["options"] == {"p_enter": 0.01, "p_remove": 0.02}
    assert [m["mode"] for m in payload["modes"]] == [1, 2]
    assert payload["modes"][0]["model"]["terms"] == list(table.columns[table.loc[1] != 0][1:])
    text = paths["summary"].read_text()
    assert "=== Mode 1 (frequency_hz) ===" in text and "Durbin-Watson" in text
    assert plt.get_fignums() == sorted(close_figures)
