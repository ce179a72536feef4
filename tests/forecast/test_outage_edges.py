"""Blocks at the edge of an outage of the ship log: the log covers part of them, and their
predictors are means of that part (``log_coverage`` below 1). Where the outage hides a stop,
those means are the wrong speed; the memory forecast raises such a block's model variance by
what its unlogged share can hide, (1 - c)² times the fill's error variance, so the blend leans
on SSI there - and leaves partly logged blocks alone where no block misses a predictor (a
short hole inside logged data)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast
from workbench.predictors import block_predictors

START = pd.Timestamp("2025-01-01T00:00:00Z")
#: minutes of the voyage the log misses (a 40-min outage: blocks 199-205 missing, 197-198
#: and 206-207 logged by 75 % and 50 % of their 20 minutes)
OUTAGE = (1000, 1040)


def _ar1(rng, n, rho, std):
    """AR(1) of standard deviation *std* started in its stationary state."""
    white = rng.normal(0.0, std, n)
    white[1:] *= math.sqrt(1 - rho * rho)
    return lfilter([1.0], [1.0, -rho], white)


def _voyage(seed: int, hole=OUTAGE, stop=OUTAGE, water_hole=None):
    """A 30-h minute log (20-min blocks every 5 min); the speed wanders between 2 and 14 kn
    and sets the mode, 5 Hz (1 - 0.004 v); the ship makes 1 kn in the minutes *stop*
    (None: no stop), the log is out in *hole*, the water temperature alone in
    *water_hole* (None: nowhere else). SSI's error AR(1), rho 0.65, 0.004 Hz. Returns the
    tracked table, the predictor table of the logged minutes and the blocks' true
    frequencies."""
    rng = np.random.default_rng(seed)
    minute = np.arange(1800)
    slow = np.clip(8 + 5 * _ar1(rng, 361, math.exp(-1 / 24), 1.0), 2, 14)
    speed = np.interp(minute, np.arange(slow.size) * 5, slow)
    if stop is not None:
        speed[stop[0] : stop[1]] = 1.0
    log = pd.DataFrame(
        {
            "time": START + pd.to_timedelta(minute, unit="min"),
            "speed_kn": speed,
            "water_temp_c": 3.0 + rng.normal(0, 0.1, minute.size),
        }
    )
    if water_hole is not None:
        log.loc[(minute >= water_hole[0]) & (minute < water_hole[1]), "water_temp_c"] = np.nan
    logged = log[(minute < hole[0]) | (minute >= hole[1])]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predictors = block_predictors(logged, despike=False).dropna(axis=1, how="all")
    first_minute = (pd.to_datetime(predictors["block_start"], utc=True) - START).dt.total_seconds()
    first_minute = (first_minute // 60).astype(int).to_numpy()
    truth = 5.0 * (1 - 0.004 * np.array([speed[s : s + 20].mean() for s in first_minute]))
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


def _forecasts(modal, predictors):
    """Option A's forecast table with the log's coverage and without it (indexed by block)."""
    options = ForecastOptions(options=("A",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        marked = sliding_forecast(modal, predictors, options).table
        unmarked = sliding_forecast(modal, predictors.drop(columns="log_coverage"), options).table
    return marked.set_index("block"), unmarked.set_index("block")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_outage_edge_leans_on_ssi_where_its_partial_means_hide_a_stop(seed):
    modal, predictors, truth = _voyage(seed)
    coverage = predictors.set_index("block")["log_coverage"]
    edges = [197, 198, 206, 207]
    np.testing.assert_allclose(coverage.loc[edges], [0.75, 0.5, 0.5, 0.75])
    marked, unmarked = _forecasts(modal, predictors)
    assert marked.loc[edges, "warning"].str.contains("edge of a log outage").all()
    assert not marked.drop(index=edges)["warning"].fillna("").str.contains("edge of a").any()

    def error(table, blocks, column):
        return float(np.abs(table.loc[blocks, column] - truth.loc[blocks]).sum())

    # the partial means are the logged speed, the ship stopped in the unlogged part: the
    # model errs by 93-177 mHz summed over the four blocks, SSI by 7-26
    assert error(marked, edges, "model_frequency_hz") > 3 * error(marked, edges, "ssi_frequency_hz")
    # without the coverage the blend takes the model's error for SSI's and is 2-8 x worse
    # than SSI there (51-115 mHz); with it 7-42 mHz (measured 0.14-0.37 x the unmarked)
    assert error(marked, edges, "kalman_frequency_hz") <= 0.5 * error(
        unmarked, edges, "kalman_frequency_hz"
    )
    # the filter does not carry the edges' error into the voyage: better overall too
    assert error(marked, truth.index, "kalman_frequency_hz") < error(
        unmarked, truth.index, "kalman_frequency_hz"
    )
    # the model's bounds widen by the unlogged share's variance only on the edge rows
    width = marked["model_upper_hz"] - marked["model_lower_hz"]
    width_unmarked = unmarked["model_upper_hz"] - unmarked["model_lower_hz"]
    assert (width.loc[edges] > width_unmarked.loc[edges]).all()


def test_a_short_hole_inside_logged_data_changes_nothing():
    # an 8-min hole: every block keeps at least 60 % of its log, none misses a predictor;
    # the partial means (both sides of the hole logged) are taken as they are
    modal, predictors, _ = _voyage(0, hole=(1000, 1008), stop=None)
    assert predictors["log_coverage"].min() == pytest.approx(0.6)
    assert predictors["speed_kn"].notna().all()
    marked, unmarked = _forecasts(modal, predictors)
    pd.testing.assert_frame_equal(marked.drop(columns="log_coverage"), unmarked)


@pytest.mark.parametrize("seed", [1, 3])
def test_an_edge_rows_warning_names_each_partly_logged_column_with_its_own_share(seed):
    # the stop as the log returns, the water temperature (a column the model does not use)
    # out in minutes 1030-1060 (206-207 without it) or 1040-1045 (206 with a quarter of its
    # minutes, too few for a mean; 207 with half): the least share over the log's columns
    # (log_coverage, the c the edge's variance takes) is the water temperature's, the
    # speed's own share is 50 % and 75 %; the warnings name both
    exit_edge = [206, 207]
    expected = {
        (1030, 1060): ["speed_kn 50%; log_coverage 0%", "speed_kn 75%; log_coverage 0%"],
        (1040, 1045): ["speed_kn 50%; log_coverage 25%", "speed_kn 75%; log_coverage 50%"],
        None: ["speed_kn 50%; log_coverage 50%", "speed_kn 75%; log_coverage 75%"],
    }
    for water_hole, named in expected.items():
        modal, predictors, _ = _voyage(seed, stop=(1040, 1060), water_hole=water_hole)
        shares = predictors.set_index("block").loc[exit_edge]
        np.testing.assert_allclose(shares["log_coverage_speed_kn"], [0.5, 0.75])
        marked, _ = _forecasts(modal, predictors)
        for block, text in zip(exit_edge, named, strict=True):
            warning = marked.loc[block, "warning"]
            assert f"partly logged ({text}) at the edge of a log outage" in warning, warning
