"""Tests for faulty ship-log sensors (workbench.predictors.flag_faulty)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from data_contracts import read_dship
from workbench.predictors import LogFaultOptions, flag_faulty
from workbench.simulate import simulate_voyage


def _log(n: int, seed: int = 0) -> pd.DataFrame:
    """Clean 10-s log: a slow trend plus Gaussian noise, directions wandering across 0°."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    return pd.DataFrame(
        {
            "time": pd.date_range("2024-01-01", periods=n, freq="10s", tz="UTC"),
            "speed_kn": 8.0 + 2.0 * np.sin(2 * np.pi * t / 2000) + 0.1 * rng.standard_normal(n),
            "water_temp_c": 2.0 + t / n + 0.02 * rng.standard_normal(n),
            "air_temp_c": -2.0 + 0.1 * rng.standard_normal(n),
            "wind_speed_ms": 8.0 + 0.4 * rng.standard_normal(n),
            "wind_dir_rel_deg": np.mod(
                20 * np.sin(2 * np.pi * t / 3000) + 4 * rng.standard_normal(n), 360
            ),
        }
    )


def test_clean_log_has_no_spikes():
    """Gaussian noise: with z = 7 no false spike is expected among 5 x 20 000 samples."""
    flags = flag_faulty(_log(20_000))
    assert flags.n_spikes == dict.fromkeys(flags.spikes.columns, 0)
    assert not flags.stretches["faulty"].any()
    assert not flags.columns["faulty"].any()
    # kurtosis of the residuals of Gaussian noise is about 3: 360 samples per hour give an
    # estimator sd of sqrt(24 / 360) = 0.26
    kurtosis = flags.stretches.loc[flags.stretches["column"] == "air_temp_c", "kurtosis"]
    assert kurtosis.median() == pytest.approx(3.0, abs=0.3)
    assert kurtosis.max() < 5.0


def test_spikes_are_found_and_removed():
    log = _log(20_000, seed=1)
    rng = np.random.default_rng(2)
    spiky = rng.choice(20_000, 30, replace=False)
    log.loc[spiky, "air_temp_c"] += rng.choice([-1, 1], 30) * rng.uniform(2, 30, 30)
    direction_spikes = np.array([500, 9000])
    log.loc[direction_spikes, "wind_dir_rel_deg"] = np.mod(
        log.loc[direction_spikes, "wind_dir_rel_deg"] + 150, 360
    )
    flags = flag_faulty(log)
    np.testing.assert_array_equal(np.flatnonzero(flags.spikes["air_temp_c"]), np.sort(spiky))
    np.testing.assert_array_equal(
        np.flatnonzero(flags.spikes["wind_dir_rel_deg"]), direction_spikes
    )
    assert flags.n_spikes["speed_kn"] == 0
    cleaned = flags.apply(log)
    assert cleaned["air_temp_c"].isna().sum() == 30
    assert np.isnan(cleaned.loc[spiky, "air_temp_c"]).all()
    assert log["air_temp_c"].notna().all()  # input untouched


def test_faulty_stretch_and_column():
    log = _log(3 * 360, seed=3)  # three hours of 10-s rows
    rng = np.random.default_rng(4)
    second_hour = np.arange(360, 720)
    bad = rng.choice(second_hour, 60, replace=False)  # 17 % spikes in hour 2
    log.loc[bad, "wind_speed_ms"] += rng.uniform(15, 30, 60)
    flags = flag_faulty(log, columns=["wind_speed_ms", "air_temp_c"])
    wind = flags.stretches[flags.stretches["column"] == "wind_speed_ms"]
    assert wind["faulty"].tolist() == [False, True, False]
    assert wind["reason"].iloc[1] == "spike fraction 16.7 % > 5 %"
    assert wind["start"].iloc[1] == pd.Timestamp("2024-01-01T01:00Z")
    assert flags.spikes["wind_speed_ms"].sum() == 60
    # blanking the faulty stretch removes the whole hour of that column only
    blanked = flags.apply(log, drop_faulty_stretches=True)
    assert blanked.loc[second_hour, "wind_speed_ms"].isna().all()
    assert blanked["wind_speed_ms"].notna().sum() == 720
    assert blanked["air_temp_c"].notna().all()
    # a column faulty in most of its stretches is a faulty column
    log.loc[rng.random(len(log)) < 0.2, "air_temp_c"] += 40.0
    columns = flag_faulty(log, columns=["air_temp_c"]).columns
    assert columns["faulty"].item()
    assert columns["reason"].item() == "faulty in 3 of 3 stretches"


def test_heavy_tails_flag_a_stretch_by_kurtosis():
    log = _log(720, seed=5)
    rng = np.random.default_rng(6)
    # Student-t noise with 3 degrees of freedom: infinite kurtosis, few 6-sigma spikes
    log["air_temp_c"] = -2.0 + 0.1 * rng.standard_t(3, len(log))
    flags = flag_faulty(log, columns=["air_temp_c"], options=LogFaultOptions(kurtosis_limit=6.0))
    assert flags.stretches["faulty"].any()
    reasons = flags.stretches.loc[flags.stretches["faulty"], "reason"]
    assert reasons.str.contains("kurtosis").any()


def test_options_are_checked():
    log = _log(100)
    with pytest.raises(ValueError, match="odd"):
        flag_faulty(log, options=LogFaultOptions(window=20))
    with pytest.raises(ValueError, match="not in the log"):
        flag_faulty(log, columns=["heave_m"])


def test_demo_voyage_air_temperature_spikes(tmp_path):
    """Every spike the simulator injected is found, nothing else (seed 0, 12 h)."""
    voyage = simulate_voyage(tmp_path, seed=0, accelerations=False)
    defects = json.loads(voyage.summary_json.read_text())["defects"]
    log = read_dship(voyage.dship_log)
    flags = flag_faulty(log)
    assert flags.n_spikes == {
        "speed_kn": 0,
        "water_temp_c": 0,
        "air_temp_c": defects["air_temp_spikes"],
        "wind_speed_ms": 0,
        "wind_dir_rel_deg": 0,
    }
    faulty = flags.stretches[flags.stretches["faulty"]]
    assert set(faulty["column"]) == {"air_temp_c"}
    start, end = (pd.Timestamp(t) for t in defects["air_temp_faulty"])
    # the faulty hours overlap the defect span (07:12-09:36 for 12 h)
    assert (faulty["end"] > start).all() and (faulty["start"] < end).all()
