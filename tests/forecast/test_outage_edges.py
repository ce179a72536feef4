"""Blocks at the edge of an outage of the ship log: the log covers part of them, and their
predictors are means of that part (``log_coverage`` below 1). Where the outage hides a stop,
those means are the wrong speed; the memory forecast takes the outage's fill for the unlogged
share (c times the logged means plus 1 - c times the fill) and raises the block's model
variance by what that share can hide, (1 - c)² times the fill's error variance, so the blend
leans on SSI there - and leaves partly logged blocks alone where no block misses a predictor
(a short hole inside logged data)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast
from workbench.forecasting.memory.model import MemoryModel
from workbench.forecasting.memory.terms import MemoryRefits
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
def test_a_stop_just_after_the_log_returns_is_not_taken_for_the_whole_edge_block(seed):
    # the ship holds its wandering speed through the outage and stops (1 kn) as the log
    # returns (minutes 1040-1060): the exit edge's logged part (206: 1040-1050, 207:
    # 1040-1055) is the stop, its unlogged part the run before it. The block's predictors
    # are c times the logged means plus (1 - c) times the outage's fill (its last value
    # before the outage), whose error is what the edge's model variance, (1 - c)² V,
    # describes; the logged means alone took the stop for the whole block
    modal, predictors, truth = _voyage(seed, stop=(1040, 1060))
    exit_edge = [206, 207]
    coverage = predictors.set_index("block")["log_coverage"]
    np.testing.assert_allclose(coverage.loc[exit_edge], [0.5, 0.75])
    marked, _ = _forecasts(modal, predictors)
    rows = marked.loc[exit_edge]

    def error(column):
        return float(np.abs(rows[column] - truth.loc[exit_edge]).sum())

    # the model: 37 and 30 mHz off summed over the two blocks (the fill's error, the
    # speed's wander over the outage), the logged means alone 114 and 167
    assert error("model_frequency_hz") < 50e-3
    # ... within its bounds (the logged means alone: outside on both blocks)
    assert (rows["model_lower_hz"] <= truth.loc[exit_edge]).all()
    assert (truth.loc[exit_edge] <= rows["model_upper_hz"]).all()
    # the blend: 7.0 and 6.0 mHz against SSI's 5.7 and 7.0 (the logged means alone: 11.9
    # and 38.9)
    assert error("kalman_frequency_hz") < 1.5 * error("ssi_frequency_hz")


@pytest.mark.parametrize("seed", [1, 3])
def test_an_edge_row_missing_another_column_takes_the_speed_by_its_own_share(seed):
    # the same stop as the log returns, and the water temperature (a column the model does
    # not use) out as well: in minutes 1030-1060 (rows 206-207 without it) or 1040-1045
    # (206 without it, 207 with half its minutes). The speed's own share (50 % and 75 %)
    # sets its mix with the fill: the edge rows' model, bounds and blend equal those of the
    # voyage with the water temperature logged, and their warnings name the speed's share.
    # The least share over the columns (log_coverage: 0 and 0, or 0 and 0.5) kept the
    # logged means on 206-207 (the model 110 and 57 mHz off, seed 3) or mixed 207 half and
    # half
    exit_edge = [206, 207]
    columns = ["model_frequency_hz", "model_lower_hz", "model_upper_hz", "kalman_frequency_hz"]
    tables = {}
    for water_hole in (None, (1030, 1060), (1040, 1045)):
        modal, predictors, truth = _voyage(seed, stop=(1040, 1060), water_hole=water_hole)
        tables[water_hole], _ = _forecasts(modal, predictors)
        coverage = predictors.set_index("block").loc[exit_edge]
        np.testing.assert_allclose(coverage["log_coverage_speed_kn"], [0.5, 0.75])
    assert (tables[(1030, 1060)].loc[exit_edge, "log_coverage"] == 0.0).all()
    assert tables[(1040, 1045)].loc[207, "log_coverage"] == pytest.approx(0.5)
    expected = tables[None].loc[exit_edge]
    for water_hole in ((1030, 1060), (1040, 1045)):
        rows = tables[water_hole].loc[exit_edge]
        np.testing.assert_allclose(rows[columns], expected[columns], rtol=1e-9, atol=0)
        assert rows.loc[206, "warning"].count("partly logged (speed_kn 50%) at the edge") == 1
        assert rows.loc[207, "warning"].count("partly logged (speed_kn 75%) at the edge") == 1
    # the mix: the model within 50 mHz summed over the two rows (22.6 + 14.7 seed 1,
    # 21.4 + 8.3 seed 3)
    error = np.abs(expected["model_frequency_hz"] - truth.loc[exit_edge]).sum()
    assert error < 50e-3


def _refits_of(X: np.ndarray) -> MemoryRefits:
    """The refits of a one-mode forecast over the predictor rows *X* (speed, water
    temperature)."""
    return MemoryRefits(
        ForecastOptions(), X, ["speed_kn", "water_temp_c"], np.zeros((len(X), 1)), None, 0, 200
    )


def _filled_error(refits, m, row, mixed):
    """The fill's error measured independently: the largest over the two fills (the last
    value, one block lagged; the mean of the history) of the mean square of the model's
    output on the history rows against its output with each column replaced by
    *mixed*(column, logged, filled) - for a model of main effects, the scaled sum of the
    terms' errors."""
    history = refits.X_all[max(0, row - int(refits.model.selection_blocks)) : row]
    logged = m.predict(history, refits.limit)[0]
    errors = []
    for fill in ("last", "mean"):
        out = history.copy()
        for c in range(history.shape[1]):
            if fill == "last":
                filled = np.r_[np.nan, history[:-1, c]]
            else:
                filled = np.full(len(history), history[:, c].mean())
            out[:, c] = mixed(c, history[:, c], filled)
        error = logged - m.predict(out, refits.limit)[0]
        errors.append(np.nanmean(error**2))
    return max(errors)


def test_the_edge_variance_scales_each_terms_fill_error_by_its_columns_unlogged_share():
    # a model of the speed and the water temperature (main effects, 20 and 5 mHz per
    # standard deviation) over 120 blocks of wandering predictors; row 100 at an outage's
    # edge with the speed logged over 50 % of it and the water temperature over 75 %
    rng = np.random.default_rng(7)
    X = np.column_stack(
        [8 + np.cumsum(rng.normal(0, 0.4, 120)), 3 + np.cumsum(rng.normal(0, 0.05, 120))]
    )
    m = MemoryModel(
        "memory",
        (0, 1),
        ("speed_kn", "water_temp_c"),
        ((), (0,), (1,)),
        X[:100].mean(axis=0),
        X[:100].std(axis=0),
        np.array([5.0, -0.020, 0.005]),
        np.eye(3) / 100,
        1e-6,
        90.0,
        100,
    )
    refits = _refits_of(X)
    row, share = 100, np.array([0.5, 0.75])
    mean, variance = refits.partly_logged(m, row, [0, 1], share, fill_row=row)
    # each term's error scaled by its column's unlogged share: the history mixed as the row
    expected = _filled_error(refits, m, row, lambda c, x, f: share[c] * x + (1 - share[c]) * f)
    assert variance == pytest.approx(expected, rel=1e-9)
    # one share for both: (1 - c)² times the whole fill's error, V
    whole = _filled_error(refits, m, row, lambda c, x, f: f)
    _, equal = refits.partly_logged(m, row, [0, 1], 0.5, fill_row=row)
    assert equal == pytest.approx(0.25 * whole, rel=1e-9)
    # not (1 - c)² V with any one c: 8.5e-5 Hz² against 7.3e-5 with the least share for
    # both (the terms' errors, opposite in sign here, cancel less when scaled unlike)
    assert variance == pytest.approx(8.49e-5, rel=1e-3)
    assert equal == pytest.approx(7.29e-5, rel=1e-3)
    # a term whose column is fully logged adds nothing: the speed's 50 % alone 1.0e-4, the
    # water temperature's 25 % alone 1.6e-6 (its 5 mHz per standard deviation)
    _, speed_only = refits.partly_logged(m, row, [0, 1], [0.5, 1.0], fill_row=row)
    _, water_only = refits.partly_logged(m, row, [0, 1], [1.0, 0.75], fill_row=row)
    assert speed_only == pytest.approx(
        _filled_error(refits, m, row, lambda c, x, f: x if c else 0.5 * x + 0.5 * f), rel=1e-9
    )
    assert water_only < 0.02 * speed_only
    # the row: each column at its share of the logged value and the last one before
    x = X[row].copy()
    x[:] = share * x + (1 - share) * X[row - 1]
    assert mean == pytest.approx(m.predict(x[None, :], refits.limit)[0][0], abs=1e-12)
