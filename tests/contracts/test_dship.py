"""Parsing raw DSHIP / PANGAEA ship logs into the canonical log table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import ContractError, read_dship

#: The sample PANGAEA export of ../shared/reference, shipped with the tests (a clean clone
#: has no ../shared).
REFERENCE = Path(__file__).resolve().parents[1] / "reference" / "dship_pangaea_example.tsv"

HEADER = (
    "/* DATA DESCRIPTION:\nCitation:\tsynthetic\n*/\n"
    "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\tdd [deg]\n"
)


def write(tmp_path: Path, text: str, name: str = "log.tab", encoding: str = "utf-8") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


def test_reference_pangaea_export():
    log = read_dship(REFERENCE)
    assert len(log) == 120
    assert log["time"].iloc[0] == pd.Timestamp("2016-07-31T14:00Z")
    assert log["time"].is_monotonic_increasing
    assert log.loc[
        0, ["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"]
    ].tolist() == [5.0, 1.81, -0.6, 8.4, 45.0]
    # empty cells are missing values, extra numeric columns are kept
    assert np.isnan(log.loc[17, "water_temp_c"])
    assert {"latitude", "longitude"} <= set(log.columns)


def test_header_block_units_and_extras(tmp_path):
    text = (
        HEADER + "2026-01-01T00:00\t5.0\t2.0\t-1.0\t7.0\t350\t120\n"
        "2026-01-01T00:01\t\t2.1\t-1.1\t7.5\t10\t125\n"
    )
    log = read_dship(write(tmp_path, text))
    assert list(log.columns) == [
        "time",
        "speed_kn",
        "water_temp_c",
        "air_temp_c",
        "wind_speed_ms",
        "wind_dir_rel_deg",
        "dd_deg",
    ]
    assert np.isnan(log.loc[1, "speed_kn"])
    assert log["time"].dt.tz is not None and str(log["time"].dt.tz) == "UTC"


def test_offsets_are_converted_to_utc(tmp_path):
    text = HEADER + "2026-01-01T02:00+02:00\t5\t2\t-1\t7\t10\t1\n"
    log = read_dship(write(tmp_path, text))
    assert log.loc[0, "time"] == pd.Timestamp("2026-01-01T00:00Z")


def test_latin1_encoding(tmp_path):
    text = HEADER + "2026-01-01T00:00\t5\t2\t-1\t7\t10\t1\n"
    log = read_dship(write(tmp_path, text, encoding="latin-1"))
    assert log.loc[0, "water_temp_c"] == 2.0


def test_unsorted_and_duplicate_timestamps_warn_and_are_resolved(tmp_path):
    text = HEADER + (
        "2026-01-01T00:02\t7\t2\t-1\t7\t10\t1\n"
        "2026-01-01T00:00\t5\t2\t-1\t7\t10\t1\n"
        "2026-01-01T00:01\t6\t2\t-1\t7\t10\t1\n"
        "2026-01-01T00:01\t9\t2\t-1\t7\t10\t1\n"
    )
    with pytest.warns(UserWarning) as caught:
        log = read_dship(write(tmp_path, text))
    messages = " ".join(str(w.message) for w in caught)
    assert "time goes back 1 time(s), first at line 6" in messages
    assert "1 duplicate time stamp" in messages
    assert log["speed_kn"].tolist() == [5.0, 6.0, 7.0]


def test_semicolon_separated_three_header_rows_with_unit_conversion(tmp_path):
    text = (
        "Date/Time;SOG;Water temp;TTT;ff;RelWindDir\n"
        ";GPS;Thermosalinograph;Met;Met;Met\n"
        ";m/s;K;°C;kn;deg\n"
        "2026-01-01T00:00:00;5.14444;275.15;-1;10;90\n"
    )
    log = read_dship(write(tmp_path, text, "raw.dat"))
    assert log.loc[0, "speed_kn"] == pytest.approx(10.0, rel=1e-5)
    assert log.loc[0, "water_temp_c"] == pytest.approx(2.0)
    assert log.loc[0, "wind_speed_ms"] == pytest.approx(5.14444, rel=1e-5)


def test_custom_mapping(tmp_path):
    text = "Date/Time\tv_ship [kn]\tSST [°C]\n2026-01-01T00:00\t4\t3\n"
    with pytest.warns(UserWarning, match="no column for air_temp_c, wind_speed_ms"):
        log = read_dship(write(tmp_path, text), mapping={"speed_kn": "v_ship"})
    assert log.loc[0, ["speed_kn", "water_temp_c"]].tolist() == [4.0, 3.0]


def test_canonical_names_need_no_mapping(tmp_path):
    # a log written with the project's own column names (a CSV exported from a notebook)
    # was refused: "none of the predictor columns was found ... pass a column mapping"
    text = (
        "time,speed_kn,water_temp_c,air_temp_c,wind_speed_ms,wind_dir_rel_deg,shaft_rpm\n"
        "2026-01-01T00:00:00Z,4.5,1.5,-3,7,120,96\n"
    )
    log = read_dship(write(tmp_path, text, "log.csv"))
    row = log.loc[0, ["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms"]]
    assert row.tolist() == [4.5, 1.5, -3.0, 7.0]
    assert log.loc[0, "wind_dir_rel_deg"] == 120.0
    assert log.loc[0, "shaft_rpm"] == 96.0
    # the ship's own name comes first; a user's entry replaces the canonical name too
    both = "time,speed_kn,SOG\n2026-01-01T00:00:00Z,1,2\n"
    with pytest.warns(UserWarning, match="no column for water_temp_c"):
        assert read_dship(write(tmp_path, both, "both.csv")).loc[0, "speed_kn"] == 2.0
    # (the log's speed_kn is not taken for it: the name mapped is not there, refused)
    with pytest.raises(ContractError, match="'v_ship': not in the file, named by the column"):
        read_dship(write(tmp_path, both, "both.csv"), mapping={"speed_kn": "v_ship"})


def test_bad_cells_are_reported_by_file_column_and_line(tmp_path):
    text = HEADER + (
        "2026-01-01T00:00\t5\t2\t-1\t7\t10\t1\n"
        "yesterday\t5\t2\t-1\t7\t10\t1\n"
        "2026-01-01T00:02\tfast\t2\t-1\t7\t10\t1\n"
    )
    path = write(tmp_path, text)
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    lines = caught.value.lines()
    assert lines == [
        f"{path}: column 'Date/Time', line 6: not an ISO-8601 time: 'yesterday' (1 row)",
        f"{path}: column 'Speed [kn]', line 7: not a number",
    ]


def test_out_of_range_values_name_file_lines(tmp_path):
    text = HEADER + "2026-01-01T00:00\t5\t2\t-1\t7\t10\t1\n2026-01-01T00:01\t5\t2\t-1\t-7\t10\t1\n"
    path = write(tmp_path, text)
    with pytest.raises(
        ContractError, match=r"wind_speed_ms', line 6: values outside \[0.0, 100.0\]"
    ):
        read_dship(path)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("/* never closed\nDate/Time\tSpeed [kn]\n", "never closed"),
        ("Speed [kn]\tTTT [°C]\n5\t1\n", "time column is missing"),
        ("Date/Time\tSpeed [furlong/fortnight]\n2026-01-01T00:00\t5\n", "cannot be converted"),
        ("Date/Time\tLatitude\n2026-01-01T00:00\t80.1\n", "none of the predictor columns"),
    ],
)
def test_malformed_files(tmp_path, text, reason):
    with pytest.raises(ContractError, match=reason):
        read_dship(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(ContractError, match="cannot read file"):
        read_dship(tmp_path / "nope.tab")
