"""Tests for block averaging of the ship log (workbench.predictors.block_predictors).

The main reference is the demo voyage's ``truth_predictors.csv``: block means of the
simulator's *true* 1-s predictors, while ``dship.tsv`` holds the logged values (see
workbench/simulate/profile.py, ``write_dship_log``): speed every 1 s (noise 0.1 kn, made
positive with abs, rounded to 0.1 kn), water and air temperature every 60 s (noise 0.02 and
0.1 °C), wind speed and relative direction every 10 s (noise 0.4 m/s and 4°), a 10-min row
outage, water and wind outages, and 15 % air-temperature spikes of ±(20-35) °C over 20 %
of the voyage. Tolerances for fully covered blocks (after despiking):

* speed 0.08 kn: abs() folds the noise at rest, biasing the mean by up to
  0.1·sqrt(2/π) = 0.08 kn; the noise of a 1200-sample mean is only 0.003 kn;
* water 0.05 °C: 20 readings (sd of mean 0.005 °C) of a wandering temperature rounded to
  0.01 °C; observed max 0.03 °C over seeds 0-3;
* air 0.1 °C: 20 readings, sd of the mean 0.1/sqrt(20) = 0.022 °C, so 4.5 sd;
* wind 0.2 m/s: 120 readings, sd 0.4/sqrt(120) = 0.037 m/s, 5 sd;
* direction 2°: 120 readings, sd 4°/sqrt(120) = 0.37° plus 1° rounding, 5 sd.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import CANONICAL_PREDICTORS, PREDICTOR_KEYS, PREDICTORS, read_dship, read_table
from workbench.blocks import BlockGrid
from workbench.predictors import (
    PredictorWarning,
    block_coverage,
    block_predictors,
    circular_mean_deg,
    flag_faulty,
)
from workbench.simulate import simulate_voyage

TOLERANCE = {
    "speed_kn": 0.08,
    "water_temp_c": 0.05,
    "air_temp_c": 0.1,
    "wind_speed_ms": 0.2,
    "wind_dir_rel_deg": 2.0,
}


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    return simulate_voyage(tmp_path_factory.mktemp("voyage"), seed=0, accelerations=False)


@pytest.fixture(scope="module")
def log(voyage):
    return read_dship(voyage.dship_log)


@pytest.fixture(scope="module")
def predictors(voyage, log):
    injected = json.loads(voyage.summary_json.read_text())["defects"]["air_temp_spikes"]
    # every spike the simulator injected into the faulty air-temperature sensor is found
    with pytest.warns(PredictorWarning, match=f"{injected} air_temp_c samples"):
        return block_predictors(log)


def test_block_means_reproduce_the_truth(voyage, log, predictors):
    truth = read_table(voyage.truth_predictors, PREDICTORS)
    assert predictors["block"].tolist() == truth["block"].tolist()  # 141 blocks
    assert (predictors["block_start"] == truth["block_start"]).all()
    assert (predictors["block_end"] == truth["block_end"]).all()
    coverage = block_coverage(flag_faulty(log).apply(log))
    for column, tolerance in TOLERANCE.items():
        full = coverage[column].to_numpy() >= 0.999
        assert full.sum() >= 80, column  # enough blocks for the comparison to mean much
        error = (predictors[column] - truth[column]).to_numpy()[full]
        if column == "wind_dir_rel_deg":
            error = np.mod(error + 180.0, 360.0) - 180.0
        assert np.abs(error).max() < tolerance, (column, np.abs(error).max())


def test_coverage_threshold_on_the_voyage(log, predictors):
    coverage = block_coverage(flag_faulty(log).apply(log))
    for column in TOLERANCE:
        missing = predictors[column].isna().to_numpy()
        np.testing.assert_array_equal(missing, coverage[column].to_numpy() < 0.5, column)
    # the 10-min row outage 06:36-06:46 leaves half of block 78 (06:30-06:50) and 14 of the
    # 20 minutes of block 80 (06:40-07:00) with 1-s speed readings
    by_block = coverage.set_index("block")["speed_kn"]
    assert by_block[78] == pytest.approx(0.5)
    assert by_block[80] == pytest.approx(0.7)
    # the 40-min water outage empties whole blocks
    assert predictors["water_temp_c"].isna().sum() >= 5


def test_despiking_matters(voyage, log):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PredictorWarning)
        raw = block_predictors(log, despike=False)
    truth = read_table(voyage.truth_predictors, PREDICTORS)
    assert np.nanmax(np.abs(raw["air_temp_c"] - truth["air_temp_c"])) > 1.0


def test_circular_mean():
    assert circular_mean_deg(np.array([350.0, 10.0])) == 0.0
    assert circular_mean_deg(np.array([350.0, 10.0, np.nan])) == 0.0
    assert circular_mean_deg(np.array([90.0, 180.0])) == pytest.approx(135.0)
    assert circular_mean_deg(np.array([300.0, 320.0])) == pytest.approx(310.0)
    assert np.isnan(circular_mean_deg(np.array([0.0, 180.0])))  # no mean direction
    np.testing.assert_allclose(
        circular_mean_deg(np.array([[350.0, 10.0], [170.0, 190.0]]), axis=1), [0.0, 180.0]
    )


def _minute_log(hours: float = 2.0, **columns) -> pd.DataFrame:
    n = int(hours * 60)
    frame = pd.DataFrame({"time": pd.date_range("2024-01-01", periods=n, freq="min", tz="UTC")})
    for name in ("speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"):
        frame[name] = columns.get(name, np.full(n, 1.0))
    return frame


def test_directions_across_north_average_to_north():
    n = 120
    log = _minute_log(wind_dir_rel_deg=np.where(np.arange(n) % 2 == 0, 350.0, 10.0))
    result = block_predictors(log, despike=False)
    assert len(result) == 21  # (120 - 20) / 5 + 1 blocks of 20 min in 2 h
    np.testing.assert_allclose(result["wind_dir_rel_deg"], 0.0, atol=1e-9)
    assert ((result["wind_dir_rel_deg"] >= 0) & (result["wind_dir_rel_deg"] < 360)).all()


def test_coverage_threshold_with_a_hole():
    n = 120
    speed = np.arange(n, dtype=float) / 10.0
    log = _minute_log(speed_kn=speed)
    log = log[(log.index < 25) | (log.index >= 40)].reset_index(drop=True)  # 00:25-00:40 gone
    coverage = block_coverage(log).set_index("block")["speed_kn"]
    # block 4 = 00:20-00:40: 5 of 20 minutes; block 5 = 00:25-00:45: 5 of 20; block 3: 10/20
    assert coverage[3] == pytest.approx(0.5) and coverage[4] == pytest.approx(0.25)
    result = block_predictors(log, despike=False).set_index("block")
    assert np.isnan(result.loc[4, "speed_kn"])
    assert result.loc[3, "speed_kn"] == pytest.approx(speed[15:25].mean())  # partial mean
    strict = block_predictors(log, despike=False, min_coverage=0.8).set_index("block")
    assert np.isnan(strict.loc[3, "speed_kn"])
    assert strict.loc[0, "speed_kn"] == pytest.approx(speed[:20].mean())


def test_blocks_follow_a_modal_table_and_block_numbers():
    log = _minute_log(hours=3.0, speed_kn=np.arange(180, dtype=float) / 20)
    grid = BlockGrid(pd.Timestamp("2024-01-01T00:00Z"))
    modal = grid.frame([7, 2, 2, 40])  # long format: repeated blocks; 40 is past the log
    result = block_predictors(log, blocks=modal, despike=False)
    assert result["block"].tolist() == [2, 7, 40]
    assert result.loc[0, "speed_kn"] == pytest.approx(np.arange(10, 30).mean() / 20)
    assert np.isnan(result.loc[2, "speed_kn"])
    numbers = block_predictors(log, grid=grid, blocks=[7, 2], despike=False)
    pd.testing.assert_frame_equal(numbers, result.iloc[:2].reset_index(drop=True))
    with pytest.raises(ValueError, match="contradicts"):
        block_predictors(log, grid=grid, length_s=600)


def test_log_coverage_is_the_least_over_the_canonical_columns_the_log_has():
    """A 15-min hole in the speed only (00:25-00:40): blocks 2-7 (00:10-00:30 to
    00:35-00:55) lose 5-15 of their 20 minutes; a wind sensor without any reading, and an
    extra column's hole, mark nothing."""
    n = 120
    log = _minute_log()
    log.loc[25:39, "speed_kn"] = np.nan  # 00:25-00:40
    log["wind_speed_ms"] = np.nan  # never read: not a hole of this voyage
    log["latitude"] = np.where((log.index >= 60) & (log.index < 80), np.nan, 78.0)
    result = block_predictors(log, despike=False).set_index("block")
    speed = block_coverage(log).set_index("block")["speed_kn"]
    np.testing.assert_allclose(result["log_coverage"], speed.reindex(result.index))
    minutes_lost = {1: 0, 2: 5, 3: 10, 4: 15, 5: 15, 6: 10, 7: 5, 8: 0, 12: 0}
    for block, lost in minutes_lost.items():
        assert result.loc[block, "log_coverage"] == pytest.approx(1 - lost / 20), block
    assert len(result) == (n - 20) // 5 + 1
    only_extras = log[["time", "latitude"]]
    with pytest.warns(PredictorWarning):
        extras = block_predictors(only_extras, despike=False).set_index("block")
    assert extras.loc[12, "log_coverage"] == pytest.approx(0.0)  # 01:00-01:20 all gone
    assert extras.loc[0, "log_coverage"] == pytest.approx(1.0)


def test_each_canonical_column_has_its_own_log_coverage():
    """The speed out 00:25-00:40 and the water temperature 00:30-00:35: each column's
    coverage counts its own minutes (block 4, 00:20-00:40, keeps 5 of the speed's 20
    minutes and 15 of the water temperature's), ``log_coverage`` is their least, and a
    value is the mean of the column's logged part (block 2's speed: 00:10-00:25); a column
    without any reading (the wind speed) or not in the log (the air temperature) has NaN."""
    log = _minute_log(speed_kn=np.arange(120) / 10).drop(columns=["air_temp_c"])
    log.loc[25:39, "speed_kn"] = np.nan  # 00:25-00:40
    log.loc[30:34, "water_temp_c"] = np.nan  # 00:30-00:35
    log["wind_speed_ms"] = np.nan
    with pytest.warns(PredictorWarning, match="air_temp_c"):
        result = block_predictors(log, despike=False).set_index("block")
    speed_lost = {1: 0, 2: 5, 3: 10, 4: 15, 5: 15, 6: 10, 7: 5, 8: 0}
    water_lost = {1: 0, 2: 0, 3: 5, 4: 5, 5: 5, 6: 5, 7: 0, 8: 0}
    for block in speed_lost:
        row = result.loc[block]
        assert row["log_coverage_speed_kn"] == pytest.approx(1 - speed_lost[block] / 20), block
        assert row["log_coverage_water_temp_c"] == pytest.approx(1 - water_lost[block] / 20)
        assert row["log_coverage"] == pytest.approx(1 - speed_lost[block] / 20)
    assert result.loc[2, "speed_kn"] == pytest.approx(np.arange(10, 25).mean() / 10)
    assert result["log_coverage_wind_speed_ms"].isna().all()
    assert result["log_coverage_air_temp_c"].isna().all()
    assert result["log_coverage_wind_dir_rel_deg"].eq(1.0).all()
    # not predictors: the block keys of the contract
    assert {f"log_coverage_{c.name}" for c in CANONICAL_PREDICTORS} <= set(PREDICTOR_KEYS)


def test_extra_columns_and_missing_canonical():
    log = _minute_log().drop(columns=["wind_speed_ms"])
    log["latitude"] = 78.0 + np.arange(len(log)) / 1000
    with pytest.warns(PredictorWarning, match="wind_speed_ms"):
        result = block_predictors(log, despike=False)
    assert list(result.columns[3:]) == [
        "log_coverage",
        "log_coverage_speed_kn",
        "log_coverage_water_temp_c",
        "log_coverage_air_temp_c",
        "log_coverage_wind_speed_ms",
        "log_coverage_wind_dir_rel_deg",
        "speed_kn",
        "water_temp_c",
        "air_temp_c",
        "wind_speed_ms",
        "wind_dir_rel_deg",
        "latitude",
    ]
    assert result["wind_speed_ms"].isna().all()
    assert result.loc[0, "latitude"] == pytest.approx(78.0 + np.arange(20).mean() / 1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PredictorWarning)
        assert "latitude" not in block_predictors(log, columns=[], despike=False).columns


def test_one_day_of_1_s_rows_against_a_direct_computation():
    """86 400 rows: the vectorised means equal per-block means computed directly."""
    rng = np.random.default_rng(4)
    n = 86_400
    time = pd.date_range("2024-01-01", periods=n, freq="s", tz="UTC")
    speed = 10 + np.cumsum(rng.standard_normal(n)) * 0.01
    speed[rng.random(n) < 0.1] = np.nan
    direction = np.mod(rng.standard_normal(n) * 30, 360)
    log = pd.DataFrame(
        {
            "time": time,
            "speed_kn": speed,
            "water_temp_c": 2.0,
            "air_temp_c": -1.0,
            "wind_speed_ms": 5.0,
            "wind_dir_rel_deg": direction,
        }
    )
    result = block_predictors(log, despike=False)
    assert len(result) == (86_400 - 1200) // 300 + 1
    for k in (0, 1, 137, len(result) - 1):
        window = slice(300 * k, 300 * k + 1200)
        assert result.loc[k, "speed_kn"] == pytest.approx(np.nanmean(speed[window]), rel=1e-12)
        assert result.loc[k, "wind_dir_rel_deg"] == pytest.approx(
            circular_mean_deg(direction[window]), abs=1e-9
        )
