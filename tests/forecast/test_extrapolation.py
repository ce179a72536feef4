"""A model that extrapolates says so: where a predictor leaves the range the model's refit saw,
the memory forecast raises the model's variance by s² Σ e² (e the excess in the predictor's
standard deviations over the refit's rows, at most 1), names the predictors in the row's
warning, and the blend leans on SSI there as far as that allows. The voyage: the water
temperature holds for 28 h (the stepwise selection has no evidence of its effect) and then
rises 4 °C in 2 h, which moves the mode - the README's 6-h worked example in its last hour
(``benchmarks/results/forecast_extrapolation_52.txt``)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast
from workbench.predictors import block_predictors

START = pd.Timestamp("2025-01-01T00:00:00Z")
#: minute from which the water warms, 2 °C an hour (the last 2 h of 30)
WARMING = 1680


def _ar1(rng, n, rho, std):
    """AR(1) of standard deviation *std* started in its stationary state."""
    white = rng.normal(0.0, std, n)
    white[1:] *= math.sqrt(1 - rho * rho)
    return lfilter([1.0], [1.0, -rho], white)


def _voyage(seed: int):
    """A 30-h minute log (20-min blocks every 5 min): the speed wanders between 2 and 14 kn,
    the water temperature is 3 °C (± 0.05) until minute WARMING and then rises 2 °C an
    hour; the mode is 5 Hz (1 - 0.004 v) - 0.02 Hz/°C (T - 3). SSI's error AR(1), rho 0.65,
    0.004 Hz. Returns the tracked table, the predictor table and the true frequencies."""
    rng = np.random.default_rng(seed)
    minute = np.arange(1800)
    slow = np.clip(8 + 5 * _ar1(rng, 361, math.exp(-1 / 24), 1.0), 2, 14)
    speed = np.interp(minute, np.arange(slow.size) * 5, slow)
    water = 3.0 + rng.normal(0, 0.05, minute.size) + np.maximum(minute - WARMING, 0) / 30
    log = pd.DataFrame(
        {
            "time": START + pd.to_timedelta(minute, unit="min"),
            "speed_kn": speed,
            "water_temp_c": water,
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predictors = block_predictors(log, despike=False).dropna(axis=1, how="all")
    first_minute = (pd.to_datetime(predictors["block_start"], utc=True) - START).dt.total_seconds()
    first_minute = (first_minute // 60).astype(int).to_numpy()
    true_speed = np.array([speed[s : s + 20].mean() for s in first_minute])
    true_water = np.array([water[s : s + 20].mean() for s in first_minute])
    truth = 5.0 * (1 - 0.004 * true_speed) - 0.02 * (true_water - 3.0)
    modal = pd.DataFrame(
        {
            "block": predictors["block"],
            "block_start": predictors["block_start"],
            "block_end": predictors["block_end"],
            "mode": 1,
            "frequency_hz": truth + _ar1(rng, truth.size, 0.65, 0.004),
            "damping_ratio": 0.01,
        }
    )
    return modal, predictors, pd.Series(truth, index=predictors["block"].to_numpy())


def _forecast(seed: int):
    modal, predictors, truth = _voyage(seed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ForecastWarning)
        table = sliding_forecast(
            modal, predictors, ForecastOptions(options=("A",)), poles=None
        ).table
    notes = [str(w.message) for w in caught if issubclass(w.category, ForecastWarning)]
    table = table[table["phase"] == "forecast"].set_index("block")
    ssi = modal.set_index("block")["frequency_hz"]
    return table, ssi, truth, notes


def test_supported_range_leaves_out_the_blocks_sharing_data_with_an_extreme():
    from workbench.forecasting.memory.terms import _supported_range

    X = np.array([[1.0, 5.0], [2.0, 5.0], [3.0, np.nan], [4.0, 5.0], [10.0, 5.0], [6.0, 5.0]])
    low, high, spread = _supported_range(X, 1)
    # the second smallest and second largest of 1, 2, 3, 4, 10, 6; of five 5.0
    np.testing.assert_array_equal(low, [2.0, 5.0])
    np.testing.assert_array_equal(high, [6.0, 5.0])
    np.testing.assert_allclose(spread, [np.std([1, 2, 3, 4, 10, 6], ddof=1), 0.0])
    # too few values for the trim: no range
    low, high, _ = _supported_range(X[:3], 1)
    assert np.isnan(low).all() and np.isnan(high).all()


def test_the_model_says_it_extrapolates_where_the_water_leaves_its_range():
    ratios = []
    for seed in range(4):
        table, ssi, truth, notes = _forecast(seed)
        # the blocks that start at least 20 min into the warming (all their minutes warm)
        warm = table.index[table["block_start"] >= str(START + pd.Timedelta(minutes=WARMING + 20))]
        cold = table.index[table["block_start"] < str(START + pd.Timedelta(minutes=WARMING))]
        assert len(warm) == 17
        t = truth.reindex(warm)
        e_ssi = (ssi.reindex(warm) - t).abs().sum()
        e_kalman = (table.loc[warm, "kalman_frequency_hz"] - t).abs().sum()
        e_model = (table.loc[warm, "model_frequency_hz"] - t).abs().sum()
        # the model does not know the temperature: it errs 2-11x as much as SSI there
        assert e_model > 2 * e_ssi
        ratios.append(e_kalman / e_ssi)
        # the model's 95 % half-width in the warm blocks against the blocks before: 11.8-12.6
        # mHz against 7.8-8.4 (s² added for the one predictor out of its range: x1.5); main
        # 8.6-9.9 against 7.8-8.4 (at most x1.27)
        half = (table["model_upper_hz"] - table["model_lower_hz"]) / 2
        assert half.reindex(warm).median() > 1.4 * half.reindex(cold).median()
        assert any("leave the range the model was fitted on" in note for note in notes)
        assert any("water_temp_c" in w for w in table.loc[warm, "warning"].dropna())
    # Kalman error / SSI error in the warm blocks, seeds 0-3: 0.78 2.06 3.27 1.51, median
    # 1.79 (main: 0.79 2.46 3.35 1.85, median 2.16): the blend leans on SSI a little more; one
    # predictor's s² cannot undo a model 2-11x SSI's error (see the module docstring)
    assert np.median(ratios) < 2.0, ratios
