"""Operating cases: derivation rule, labels from time ranges, per-case fits beside the
stitched one, and the sliding forecast's per-case hook."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from workbench.stats import (
    CaseRule,
    StatsWarning,
    case_labels,
    case_training_mask,
    derive_cases,
    fit_cases,
)

START = pd.Timestamp("2024-03-01T00:00:00Z")


def test_derive_cases_rule():
    predictors = pd.DataFrame(
        {
            "speed_kn": [0.2, 0.9, 1.0, 5.0, 12.0, np.nan, 3.0, 0.1],
            "water_temp_c": [4.0, 4.0, 4.0, 3.0, 2.0, 2.0, -1.7, -1.8],
        }
    )
    labels = derive_cases(predictors)
    assert labels.tolist() == [
        "stationary",
        "stationary",
        "open_water",
        "open_water",
        "open_water",
        None,
        "ice",
        "ice",  # ice decides before speed: a ship at rest in pack ice
    ]
    banded = derive_cases(predictors, CaseRule(speed_bands_kn=(6.0,), ice_water_temp_c=None))
    assert banded.tolist()[:7] == [
        "stationary",
        "stationary",
        "open_water_1-6kn",
        "open_water_1-6kn",
        "open_water_6+kn",
        None,
        "open_water_1-6kn",
    ]
    # an ice-concentration column (percent) takes precedence over the water temperature
    with_ice = predictors.assign(ice_concentration=[0, 0, 0, 20, 0, 0, 0, 10])
    assert derive_cases(with_ice).tolist()[3] == "ice"
    assert derive_cases(with_ice).tolist()[6] == "open_water"
    with pytest.raises(ValueError, match="speed_bands_kn"):
        CaseRule(speed_bands_kn=(0.5,))
    with pytest.raises(ValueError, match="speed_kn"):
        derive_cases(predictors.drop(columns="speed_kn"))


def _voyage(n_blocks: int = 240, seed: int = 0):
    """Blocks alternating between stationary and transit stretches of 30 blocks.

    The frequency follows the water temperature at rest (no added-mass change) and the
    speed under way (added mass of the water set in motion, -0.01 Hz/kn), with a 0.02-Hz
    step between the regimes: one linear law cannot hold both.
    """
    rng = np.random.default_rng(seed)
    blocks = np.arange(n_blocks)
    moving = (blocks // 30) % 2 == 1
    speed = np.where(moving, rng.uniform(6.0, 12.0, n_blocks), rng.uniform(0.0, 0.4, n_blocks))
    water = 4.0 + np.cumsum(rng.normal(0.0, 0.05, n_blocks))
    wind = rng.uniform(0.0, 15.0, n_blocks)
    law = np.where(moving, 3.00 - 0.010 * speed, 3.02 + 0.004 * (water - 4.0))
    frequency = law + rng.normal(0.0, 0.0008, n_blocks)
    start = START + pd.to_timedelta(5 * blocks, unit="min")
    predictors = pd.DataFrame(
        {
            "block": blocks,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": 2.0 + np.cumsum(rng.normal(0.0, 0.1, n_blocks)),
            "wind_speed_ms": wind,
            "wind_dir_rel_deg": rng.uniform(0.0, 360.0, n_blocks),
        }
    )
    modal = pd.DataFrame(
        {
            "block": blocks,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "mode": 1,
            "frequency_hz": frequency,
            "damping_ratio": 0.01,
        }
    )
    return modal, predictors, moving


def test_fit_cases_recovers_each_regime_beside_the_stitched_model():
    modal, predictors, _ = _voyage()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StatsWarning)
        result = fit_cases(modal, predictors, "derive")
    assert result.cases == ["all", "stationary", "open_water"]
    transit = result.fits["open_water"][1].fit
    rest = result.fits["stationary"][1].fit
    stitched = result.fits["all"][1].fit
    assert "speed_kn" in transit.terms and "water_temp_c" not in transit.terms
    assert transit.coefficients.loc["speed_kn", "estimate"] == pytest.approx(-0.010, abs=4e-4)
    assert "water_temp_c" in rest.terms
    assert rest.coefficients.loc["water_temp_c", "estimate"] == pytest.approx(0.004, abs=1e-3)
    # the regimes' own models fit to the noise (0.8 mHz); the stitched one cannot
    assert transit.rmse < 0.0011 and rest.rmse < 0.0011
    assert stitched.rmse > 1.5 * max(transit.rmse, rest.rmse)
    assert transit.n_obs + rest.n_obs == stitched.n_obs == 240
    table = result.table()
    assert table.loc[("open_water", 1), "n_obs"] == 120
    # Durbin-Watson within contiguous runs: 30-block stretches, white residuals
    assert 1.4 < table.loc[("open_water", 1), "durbin_watson"] < 2.6
    summary = result.summary()
    assert "all (stitched)" in summary and "stationary" in summary
    coefficients = result.coefficients()
    assert coefficients.loc[("stationary", 1), "speed_kn"] == pytest.approx(
        rest.coefficients["estimate"].get("speed_kn", 0.0)
    )


def test_case_labels_from_a_time_range_table():
    _, predictors, moving = _voyage(120)
    ranges = pd.DataFrame(
        {
            "case": ["harbour", "sea"],
            "start": [START, START + pd.Timedelta(hours=5)],
            "end": [START + pd.Timedelta(hours=5), START + pd.Timedelta(hours=11)],
        }
    )
    labels = case_labels(predictors, ranges)
    # a 20-min block belongs to a case when it lies inside the range
    assert labels.iloc[0] == "harbour" and labels.iloc[56] == "harbour"
    assert labels.iloc[57] is None  # straddles 05:00
    assert labels.iloc[60] == "sea"
    assert case_labels(predictors, None).eq("all").all()


def test_case_training_mask_hook():
    labels = np.array(["a"] * 10 + ["b"] * 10 + ["a"] * 5, dtype=object)
    # forecast row 20 is in case "a": the window's rows of "a" train the model
    mask = case_training_mask(labels, slice(5, 20), 20, min_rows=3)
    np.testing.assert_array_equal(mask, labels[5:20] == "a")
    # too few rows of the case in the window: stitched (None)
    assert case_training_mask(labels, slice(12, 20), 20, min_rows=3) is None
    # no per-case models, or the current block has no case
    assert case_training_mask(None, slice(0, 10), 10, 3) is None
    unlabeled = labels.copy()
    unlabeled[20] = None
    assert case_training_mask(unlabeled, slice(5, 20), 20, 3) is None


def test_sliding_forecast_trains_on_the_current_case():
    from workbench.forecasting import sliding_forecast
    from workbench.forecasting.options import ForecastOptions

    modal, predictors, moving = _voyage(150, seed=1)
    labels = derive_cases(predictors).to_numpy()
    common = ForecastOptions(model="window", scheme=1, train_blocks=40, horizon=10, trust=0.65)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # window 15-54: blocks 30-54 are under way (25 rows), the forecast starts at 55
        result = sliding_forecast(modal, predictors, common, start_block=15, cases="derive")
        stitched = sliding_forecast(modal, predictors, common, start_block=15)
    model = result.models[0]
    assert labels[55] == "open_water"
    assert model.n_train == int((labels[15:55] == "open_water").sum()) == 25
    assert stitched.models[0].n_train == 40
    # the transit model: speed only, and within the noise on the transit blocks 55-59
    assert model.terms == ("speed_kn",)
    truth = modal.set_index("block")["frequency_hz"]
    table = result.table.set_index("block")
    forecast = table.loc[55:59, "model_frequency_hz"]
    assert np.abs(forecast - truth[55:59]).max() < 0.004


def test_cli_fit_with_derived_and_tabled_cases(tmp_path, close_figures):
    from data_contracts import MODAL, PREDICTORS, write_table
    from workbench.cli import main

    modal, predictors, _ = _voyage(120)
    write_table(modal, tmp_path / "modal.csv", MODAL)
    write_table(predictors, tmp_path / "predictors.csv", PREDICTORS)
    common = ["fit", "--modal", str(tmp_path / "modal.csv")]
    common += ["--predictors", str(tmp_path / "predictors.csv")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([*common, "--cases", "derive", "--out", str(tmp_path / "derived")]) == 0
    table = pd.read_csv(tmp_path / "derived" / "case_models.csv")
    assert sorted(set(table["case"])) == ["all", "open_water", "stationary"]
    ranges = tmp_path / "cases.csv"
    ranges.write_text(
        "case,start,end\nfirst,2024-03-01T00:00:00Z,2024-03-01T05:00:00Z\n"
        "second,2024-03-01T05:00:00Z,2024-03-01T10:00:00Z\n",
        encoding="utf-8",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([*common, "--cases", str(ranges), "--out", str(tmp_path / "tabled")]) == 0
    summary = (tmp_path / "tabled" / "fit_summary.txt").read_text(encoding="utf-8")
    assert "first (57 blocks)" in summary and "second" in summary
    assert main([*common, "--cases", str(tmp_path / "none.csv"), "--out", str(tmp_path / "x")]) == 1
