"""The ship log's coverage of each block: carried from the predictor table to the forecast's
rows and its run notes, and never taken for a predictor by the stages that pick their
predictors themselves."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import FORECAST, PREDICTORS
from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast
from workbench.forecasting.predictor_grid import predictor_matrix
from workbench.predictors import block_predictors
from workbench.stages.forecasting import forecast, partial_log_lines
from workbench.stats.correlation import joined_blocks, predictor_columns

START = pd.Timestamp("2024-03-01T00:00:00Z")


def _voyage(n_blocks=60, seed=0):
    """Two modes linear in the water temperature; the log's coverage follows the first
    mode's frequency exactly, so any stage that took it for a predictor would pick it."""
    rng = np.random.default_rng(seed)
    block = np.arange(n_blocks)
    start = START + pd.to_timedelta(block * 300, unit="s")
    water = 5.0 + 2.0 * np.sin(2 * np.pi * block / 30.0)
    truth = np.array([3.0, 5.0])[None, :] * (1.0 - 0.004 * (water[:, None] - 5.0))
    observed = truth + rng.normal(0, 0.002, truth.shape)
    coverage = np.clip(0.5 + (observed[:, 0] - observed[:, 0].min()) * 10, 0.5, 1.0)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "log_coverage": coverage,
            "speed_kn": 10.0 + rng.normal(0, 1.0, n_blocks),
            "water_temp_c": water,
            "air_temp_c": np.nan,
            "wind_speed_ms": np.nan,
            "wind_dir_rel_deg": np.nan,
        }
    )
    b = np.repeat(block, 2)
    m = np.tile(np.arange(2), n_blocks)
    modal = pd.DataFrame(
        {
            "block": b,
            "block_start": start[b],
            "block_end": start[b] + pd.Timedelta(minutes=20),
            "mode": m + 1,
            "frequency_hz": observed[b, m],
            "damping_ratio": 0.01,
        }
    )
    return modal, PREDICTORS.validate(predictors)


def test_coverage_is_no_predictor_of_the_forecast_or_the_correlation():
    modal, predictors = _voyage()
    canonical = ["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"]
    _, _, _, columns, X = predictor_matrix(predictors, None)
    assert columns == [*canonical[:4], "wind_dir_rel_cos"]  # the direction's cosine
    assert X.shape == (60, 5)
    assert predictor_columns(predictors) == canonical
    _, _, names = joined_blocks(modal, predictors)
    assert "log_coverage" not in names


@pytest.mark.parametrize("model", ["window", "memory"])
def test_each_forecast_row_carries_its_blocks_coverage(model):
    modal, predictors = _voyage()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        result = sliding_forecast(
            modal, predictors, ForecastOptions(model=model, options=("A",), train_blocks=20)
        )
        without = sliding_forecast(
            modal,
            predictors.drop(columns="log_coverage"),
            ForecastOptions(model=model, options=("A",), train_blocks=20),
        )
    table = FORECAST.validate(result.table)
    expected = predictors.set_index("block")["log_coverage"].reindex(table["block"])
    np.testing.assert_array_equal(table["log_coverage"].to_numpy(), expected.to_numpy())
    assert "log_coverage" not in without.table.columns
    # the mark changes no estimate
    pd.testing.assert_frame_equal(result.table.drop(columns="log_coverage"), without.table)


def test_the_forecast_stage_notes_the_partly_logged_forecast_blocks():
    modal, predictors = _voyage()
    predictors["log_coverage"] = 1.0
    predictors.loc[predictors["block"].isin([10, 41, 42, 43]), "log_coverage"] = 0.75
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        result = forecast(modal, predictors, options=ForecastOptions(options=("A",)))
    notes = [line for line in result.lines if line.startswith("ship log:")]
    # block 10 lies in the training window: not a forecast block
    assert notes == [
        "ship log: 3 forecast block(s) covered only partly (log_coverage below 1, the first "
        "block 41): their predictors are means of the logged part, or filled where too "
        "little of the block is logged"
    ]
    predictors["log_coverage"] = 1.0
    assert partial_log_lines(result.table.assign(log_coverage=1.0)) == []


def test_a_log_hole_reaches_the_forecast_rows_of_its_blocks():
    """From the log to the forecast: a 15-min outage of every column (00:25-00:40) marks
    blocks 2-7 with the share of them still logged."""
    times = pd.date_range(START, periods=6 * 60, freq="min")
    log = pd.DataFrame(
        {
            "time": times,
            "speed_kn": 10.0,
            "water_temp_c": 5.0,
            "air_temp_c": 0.0,
            "wind_speed_ms": 5.0,
            "wind_dir_rel_deg": 90.0,
        }
    )
    log = log[
        (log["time"] < START + pd.Timedelta(minutes=25))
        | (log["time"] >= START + pd.Timedelta(minutes=40))
    ]
    table = block_predictors(log, despike=False).set_index("block")
    np.testing.assert_allclose(
        table.loc[1:8, "log_coverage"], [1.0, 0.75, 0.5, 0.25, 0.25, 0.5, 0.75, 1.0]
    )
    assert np.isnan(table.loc[4, "speed_kn"])  # a quarter logged: below the 0.5 minimum
    assert table.loc[3, "speed_kn"] == pytest.approx(10.0)


def test_the_note_names_the_columns_that_make_blocks_partly_logged():
    """A dead wind-direction sensor (no reading from block 30 on) makes log_coverage, the
    least over the log's columns, 0 in every later block: the note says that column alone
    marks most of them and that no model of the run uses it (main: only '30 forecast
    block(s) covered only partly', as if the predictors forecast from were out)."""
    modal, predictors = _voyage()
    shares = {c: np.ones(60) for c in ("speed_kn", "water_temp_c", "wind_dir_rel_deg")}
    shares["wind_dir_rel_deg"][30:] = 0.0
    shares["water_temp_c"][[41, 42, 43]] = 0.75
    for column, share in shares.items():
        predictors[f"log_coverage_{column}"] = share
    predictors["log_coverage"] = np.minimum.reduce(list(shares.values()))
    predictors["wind_dir_rel_deg"] = np.where(np.arange(60) < 30, 90.0, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        result = forecast(modal, predictors, options=ForecastOptions(options=("A",)))
    terms = {name for m in result.models for t in m.terms for name in t.split(":")}
    assert terms == {"water_temp_c"}  # the modes follow the water temperature alone
    notes = [line for line in result.lines if line.startswith("ship log:")]
    assert notes == [
        "ship log: 30 forecast block(s) covered only partly (log_coverage below 1, the first "
        "block 30; wind_dir_rel_deg in 30 (in no model), water_temp_c in 3): their predictors "
        "are means of the logged part, or filled where too little of the block is logged"
    ]
