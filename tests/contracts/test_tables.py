"""Block-table contracts: acceptance, every kind of violation, exact CSV/Parquet round trips."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from data_contracts import (
    FORECAST,
    MODAL,
    POLES,
    PREDICTORS,
    ContractError,
    read_table,
    shapes_from_frame,
    shapes_to_frame,
    write_table,
)

T0 = pd.Timestamp("2026-03-01T00:00:00Z")
STEP = pd.Timedelta("5min")
LENGTH = pd.Timedelta("20min")


def modal_frame(n_blocks: int = 3, n_modes: int = 2) -> pd.DataFrame:
    rows = []
    for block in range(n_blocks):
        for mode in range(1, n_modes + 1):
            rows.append(
                {
                    "block": block,
                    "block_start": T0 + block * STEP,
                    "block_end": T0 + block * STEP + LENGTH,
                    "mode": mode,
                    "frequency_hz": 2.9 * mode + 0.01 * block,
                    "damping_ratio": 0.012,
                    "mac": 0.97,
                    "model_order": 40,
                }
            )
    frame = pd.DataFrame(rows)
    shapes = np.exp(1j * np.linspace(0, 1, 3))[None, :] * np.ones((len(frame), 1))
    return pd.concat([frame, shapes_to_frame(["acc01", "acc02", "acc03"], shapes)], axis=1)


def forecast_frame() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "block": [20, 21],
            "block_start": [T0 + 20 * STEP, T0 + 21 * STEP],
            "mode": [1, 1],
            "phase": ["forecast", "forecast"],
            "ssi_frequency_hz": [2.91, np.nan],
            "model_frequency_hz": [2.90, 2.905],
            "model_lower_hz": [2.88, 2.88],
            "model_upper_hz": [2.92, 2.93],
            "kalman_frequency_hz": [2.906, 2.905],
            "kalman_std_hz": [0.004, 0.006],
            "option": ["A", "A"],
            "window_start_block": [0, 0],
            "window_end_block": [19, 19],
        }
    )


def test_valid_modal_table_is_coerced_to_canonical_dtypes():
    frame = modal_frame()
    frame["block_start"] = frame["block_start"].astype(str)  # as read from a CSV
    checked = MODAL.validate(frame)
    assert checked["block_start"].dtype == "datetime64[ns, UTC]"
    assert checked["block"].dtype == np.int64
    assert checked["model_order"].dtype == "Int64"
    assert checked.loc[0, "block_start"] == T0


def test_every_violation_is_reported_at_once():
    frame = modal_frame().drop(columns=["block_end"])
    frame.loc[1, "frequency_hz"] = -1.0
    frame.loc[[2, 3], "damping_ratio"] = 1.5  # a percentage mistaken for a fraction
    frame["mode"] = frame["mode"].astype(float)
    frame.loc[4, "mode"] = 1.5  # labels are any integer (0 included), but integers
    with pytest.raises(ContractError) as caught:
        MODAL.validate(frame, source="tracked.csv")
    lines = caught.value.lines()
    assert len(lines) == 4
    assert "tracked.csv: column 'block_end': required column is missing" in lines[0]
    assert any("'frequency_hz', row 1: values outside (0.0" in line for line in lines)
    assert any("'damping_ratio', rows 2, 3" in line and "0.012" in line for line in lines)
    assert any("'mode', row 4" in line for line in lines)


def test_duplicate_key_and_unparseable_values_are_named():
    frame = modal_frame()
    frame.loc[3, ["block", "mode"]] = [frame.loc[0, "block"], frame.loc[0, "mode"]]
    frame["frequency_hz"] = frame["frequency_hz"].astype(object)
    frame.loc[5, "frequency_hz"] = "abc"
    with pytest.raises(ContractError) as caught:
        MODAL.validate(frame)
    text = str(caught.value)
    assert "column 'frequency_hz', row 5: values cannot be read as float" in text
    assert "duplicate (block, mode)" in text


def test_block_end_must_follow_start_and_non_integral_blocks_fail():
    frame = modal_frame()
    frame.loc[0, "block_end"] = frame.loc[0, "block_start"]
    with pytest.raises(ContractError, match="block_end must be after block_start"):
        MODAL.validate(frame)
    frame = modal_frame()
    frame["block"] = frame["block"].astype(float)
    frame.loc[2, "block"] = 1.5
    with pytest.raises(ContractError, match=r"'block', row 2: values cannot be read as int"):
        MODAL.validate(frame)


def test_forecast_interval_must_contain_model_and_phase_is_closed_set():
    frame = forecast_frame()
    assert len(FORECAST.validate(frame)) == 2
    frame.loc[1, "model_upper_hz"] = 2.9
    frame.loc[0, "phase"] = "predict"
    with pytest.raises(ContractError) as caught:
        FORECAST.validate(frame)
    text = str(caught.value)
    assert "'phase', row 0: values not in {'train', 'forecast'}" in text
    # table-level checks run only once the columns are sound
    assert "prediction interval" not in text
    frame.loc[0, "phase"] = "forecast"
    with pytest.raises(ContractError, match="row 1: prediction interval must contain"):
        FORECAST.validate(frame)


def test_predictor_units_are_checked_with_a_hint():
    frame = pd.DataFrame(
        {
            "block": [0, 1],
            "block_start": [T0, T0 + STEP],
            "block_end": [T0 + LENGTH, T0 + STEP + LENGTH],
            "speed_kn": [5.0, 6.0],
            "water_temp_c": [275.1, 275.3],
            "air_temp_c": [np.nan, 1.0],
            "wind_speed_ms": [3.0, 4.0],
            "wind_dir_rel_deg": [10.0, 350.0],
        }
    )
    with pytest.raises(ContractError, match=r"water_temp_c.*not K"):
        PREDICTORS.validate(frame)


def test_per_column_log_coverage_is_a_share_and_not_a_predictor(tmp_path):
    from workbench.forecasting.predictor_grid import block_column_coverage, predictor_matrix

    frame = pd.DataFrame(
        {
            "block": [0, 1, 2],
            "block_start": [T0, T0 + STEP, T0 + 2 * STEP],
            "block_end": [T0 + LENGTH, T0 + STEP + LENGTH, T0 + 2 * STEP + LENGTH],
            "log_coverage": [1.0, 0.5, 0.25],
            "log_coverage_speed_kn": [1.0, 0.75, 0.25],
            "log_coverage_water_temp_c": [1.0, 0.5, np.nan],
            "speed_kn": [5.0, 6.0, np.nan],
            "water_temp_c": [3.0, 3.1, np.nan],
            "air_temp_c": [1.0, 1.0, 1.0],
            "wind_speed_ms": [3.0, 4.0, 5.0],
            "wind_dir_rel_deg": [10.0, 350.0, 20.0],
        }
    )
    table = PREDICTORS.validate(frame)
    _, _, _, columns, _ = predictor_matrix(table, None)
    assert columns == [
        "speed_kn",
        "water_temp_c",
        "air_temp_c",
        "wind_speed_ms",
        "wind_dir_rel_cos",  # the direction enters models as its cosine
    ]
    # each column's own share; NaN where the table has none (not known)
    np.testing.assert_array_equal(
        block_column_coverage(table, [*columns[:3], "elapsed_hours"]),
        [[1.0, 1.0, np.nan, np.nan], [0.75, 0.5, np.nan, np.nan], [0.25, np.nan, np.nan, np.nan]],
    )
    assert block_column_coverage(table.drop(columns="log_coverage"), columns) is None
    path = tmp_path / "predictors.csv"
    write_table(table, path, PREDICTORS)
    pd.testing.assert_frame_equal(read_table(path, PREDICTORS), table)
    bad = frame.assign(log_coverage_speed_kn=[1.0, 1.5, 0.25])
    with pytest.raises(ContractError, match=r"log_coverage_speed_kn.*row 1") as error:
        PREDICTORS.validate(bad)
    assert "log_coverage_water_temp_c" not in str(error.value)


def test_poles_stable_flag_reads_text_booleans():
    frame = pd.DataFrame(
        {
            "block": [0, 0],
            "model_order": [10, 12],
            "frequency_hz": [2.9, 2.9],
            "damping_ratio": [0.01, 0.011],
            "stable": ["False", "True"],
        }
    )
    checked = POLES.validate(frame)
    assert checked["stable"].tolist() == [False, True]
    frame.loc[0, "stable"] = "maybe"
    with pytest.raises(ContractError, match="'stable', row 0: values cannot be read as bool"):
        POLES.validate(frame)


def test_shapes_round_trip_through_columns():
    rng = np.random.default_rng(1)
    shapes = rng.normal(size=(4, 5)) + 1j * rng.normal(size=(4, 5))
    channels = [f"acc{j:02d}" for j in range(1, 6)]
    frame = shapes_to_frame(channels, shapes)
    names, back = shapes_from_frame(frame)
    assert names == channels
    np.testing.assert_array_equal(back, shapes)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_write_then_read_is_identity(tmp_path, suffix):
    frame = MODAL.validate(modal_frame())
    path = write_table(frame, tmp_path / f"modal{suffix}", MODAL)
    back = read_table(path, MODAL)
    pd.testing.assert_frame_equal(back, frame)
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind


def test_unreadable_and_missing_files_are_contract_errors(tmp_path):
    bad = tmp_path / "broken.parquet"
    bad.write_bytes(b"not parquet at all")
    with pytest.raises(ContractError, match=r"broken.parquet: cannot read PARQUET file"):
        read_table(bad, MODAL)
    with pytest.raises(ContractError, match="missing.csv: file not found"):
        read_table(tmp_path / "missing.csv", MODAL)
    with pytest.raises(ValueError, match="unknown table format"):
        read_table(tmp_path / "x.xlsx", MODAL)


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, width=64)


@st.composite
def forecast_tables(draw):
    n = draw(st.integers(1, 12))
    blocks = draw(st.lists(st.integers(0, 10_000), min_size=n, max_size=n, unique=True))
    model = np.array(draw(st.lists(st.floats(0.1, 50.0), min_size=n, max_size=n)))
    half = np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
    ssi = draw(st.lists(st.one_of(st.just(np.nan), st.floats(0.0, 100.0)), min_size=n, max_size=n))
    offsets = draw(st.lists(st.integers(0, 10**15), min_size=n, max_size=n))
    return pd.DataFrame(
        {
            "block": blocks,
            "block_start": [T0 + pd.Timedelta(int(o), "ns") for o in offsets],
            "mode": draw(st.lists(st.integers(1, 9), min_size=n, max_size=n)),
            "phase": draw(st.lists(st.sampled_from(["train", "forecast"]), min_size=n, max_size=n)),
            "ssi_frequency_hz": ssi,
            "model_frequency_hz": model,
            "model_lower_hz": model - half,
            "model_upper_hz": model + half,
            "kalman_frequency_hz": draw(st.lists(st.floats(0.0, 100.0), min_size=n, max_size=n)),
            "kalman_std_hz": draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)),
            "option": draw(st.lists(st.sampled_from(["A", "B"]), min_size=n, max_size=n)),
            "window_start_block": [0] * n,
            "window_end_block": [b + 1 for b in blocks],
            "extra_score": draw(st.lists(finite, min_size=n, max_size=n)),
        }
    )


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(table=forecast_tables())
@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_forecast_tables_round_trip_exactly(tmp_path, suffix, table):
    frame = FORECAST.validate(table)
    path = write_table(frame, tmp_path / f"forecast{suffix}", FORECAST)
    pd.testing.assert_frame_equal(read_table(path, FORECAST), frame, check_exact=True)
