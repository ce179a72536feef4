"""Ship logs as DSHIP writes them: dotted channel names, header rows, decimal commas,
day-first dates, user mappings, and the relative wind derived from the true wind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import ContractError, read_dship
from data_contracts.dship_names import parse_column_mapping, relative_wind
from workbench.cli import main

#: A raw DSHIP extraction (Polarstern-style channel names): name row, description row,
#: unit row; ';' separators, decimal commas, day-first dates; true wind only.
RAW = (
    "Date/Time;SYS.STR.PosLat;SYS.STR.PosLon;SYS.STR.SOG;SYS.STR.HDG;SYS.STR.COG;"
    "Weatherstation.PEWDS.Air_temperature;Thermosalinograph.TSG1.Water_temperature;"
    "Weatherstation.PEWDS.Wind_speed_true;Weatherstation.PEWDS.Wind_direction_true\n"
    ";Latitude;Longitude;Speed over ground;Heading;Course over ground;Air temperature;"
    "Water temperature;True wind speed;True wind direction\n"
    ";deg;deg;kn;deg;deg;°C;°C;m/s;deg\n"
    "31.07.2016 14:00:00;80,1000;5,2000;{sog};0,0;0,0;-0,6;1,81;10,0;90,0\n"
    "31.07.2016 14:01:00;80,1010;5,2010;{sog};90,0;90,0;-0,8;1,83;10,0;90,0\n"
)


def write(tmp_path: Path, text: str, name: str = "dship.dat", encoding="utf-8") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


def test_raw_extraction_with_description_and_unit_rows(tmp_path):
    sog_kn = 10.0 * 3600 / 1852  # 10 m/s
    log = read_dship(write(tmp_path, RAW.format(sog=f"{sog_kn:.6f}".replace(".", ","))))
    assert log["time"].tolist() == [
        pd.Timestamp("2016-07-31T14:00Z"),
        pd.Timestamp("2016-07-31T14:01Z"),
    ]
    assert log["air_temp_c"].tolist() == [-0.6, -0.8]
    assert log["water_temp_c"].tolist() == [1.81, 1.83]
    assert log["speed_kn"].to_numpy() == pytest.approx(sog_kn, rel=1e-6)
    # Row 1: wind from the east at 10 m/s, ship steaming north at 10 m/s: the apparent
    # wind comes from 45 deg off the starboard bow at 10*sqrt(2) m/s.
    # Row 2: ship heading and moving east into the east wind: head wind of 20 m/s.
    assert log["wind_dir_rel_deg"].to_numpy() == pytest.approx([45.0, 0.0], abs=1e-4)
    assert log["wind_speed_ms"].to_numpy() == pytest.approx([10 * np.sqrt(2), 20.0], rel=1e-6)
    assert log["wind_speed_true_ms"].tolist() == [10.0, 10.0]
    assert log["sys_str_poslat_deg"].tolist() == [80.1, 80.101]


def test_relative_wind_conventions():
    # Ship at rest: the relative direction is the true one minus the heading.
    direction, speed = relative_wind([30.0, 350.0], [5.0, 5.0], [40.0, 10.0], [0, 0], [0, 0])
    assert direction == pytest.approx([350.0, 340.0])
    assert speed == pytest.approx([5.0, 5.0])
    # Calm: the relative wind is the ship's own motion, from ahead, at the ship's speed,
    # whatever the heading; with drift (course 20 deg off heading) it comes from 20 deg.
    direction, speed = relative_wind([0.0, 0.0], [0.0, 0.0], [100.0, 100.0], [100, 120], [10, 10])
    assert direction == pytest.approx([0.0, 20.0], abs=1e-9)
    assert speed == pytest.approx(10 * 1852 / 3600)


def test_heading_without_course_warns_and_derives_nothing(tmp_path):
    text = (
        "Date/Time\tSYS.STR.SOG [kn]\tSYS.STR.HDG [deg]\tWind_speed [m/s]\tdd [deg]\n"
        "2026-01-01T00:00\t10\t0\t5\t90\n"
    )
    with pytest.warns(UserWarning, match="deriving it needs course_deg"):
        log = read_dship(write(tmp_path, text))
    assert np.isnan(log.loc[0, "wind_dir_rel_deg"])
    assert log.loc[0, "wind_speed_ms"] == 5.0


def test_ambiguous_dotted_names_ask_for_a_mapping(tmp_path):
    text = (
        "Date/Time\tNACOS.GPS1.SOG [kn]\tNACOS.GPS2.SOG [kn]\tTT [°C]\n"
        "2026-01-01T00:00\t10\t10.2\t1\n"
    )
    path = write(tmp_path, text)
    with pytest.raises(ContractError, match=r"several columns could be speed_kn \(NACOS.GPS1"):
        read_dship(path)
    with pytest.warns(UserWarning, match="no column for water_temp_c"):
        log = read_dship(path, mapping={"speed_kn": "NACOS.GPS2.SOG"})
    assert log.loc[0, "speed_kn"] == 10.2


def test_unknown_layout_names_the_columns_found(tmp_path):
    path = write(tmp_path, "Zeitpunkt;Fahrt;Luft\n01.01.2026 00:00;5;1\n")
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    (line,) = caught.value.lines()
    assert (
        "time column is missing" in line and "columns in the file: Zeitpunkt, Fahrt, Luft" in line
    )
    with pytest.raises(ContractError) as caught:
        read_dship(path, mapping={"time": "Zeitpunkt"})
    assert "none of the predictor columns" in str(caught.value)
    assert "columns in the file: Zeitpunkt, Fahrt, Luft" in str(caught.value)
    with pytest.warns(UserWarning, match="no column for water_temp_c, wind_speed_ms"):
        log = read_dship(
            path, mapping={"time": "Zeitpunkt", "speed_kn": "Fahrt", "air_temp_c": "Luft"}
        )
    assert log.loc[0, ["speed_kn", "air_temp_c"]].tolist() == [5.0, 1.0]


def test_unparseable_times_list_the_formats_tried(tmp_path):
    path = write(tmp_path, "Date/Time;Speed [kn]\n07/06/2016 14:00;5\n07/06/2016 14:00;6\n")
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    message = str(caught.value)
    assert "no known time format fits ('07/06/2016 14:00' (2 rows)" in message
    assert message.count("07/06/2016") == 1  # each distinct value once
    assert "no day above 12" in message and "--time-format" in message
    with pytest.warns(UserWarning):
        log = read_dship(path, time_format="%m/%d/%Y %H:%M")
    assert log.loc[0, "time"] == pd.Timestamp("2016-07-06T14:00Z")


def test_slash_dates_whose_days_tell_day_and_month_apart_need_no_format(tmp_path):
    """A day above 12 in the values settles month-first (07/31) and day-first (31/07)."""
    for text in ("07/31/2016 14:00", "31/07/2016 14:00"):
        path = write(tmp_path, f"Date/Time;Speed [kn]\n{text};5\n")
        with pytest.warns(UserWarning):  # the other predictors are missing
            log = read_dship(path)
        assert log.loc[0, "time"] == pd.Timestamp("2016-07-31T14:00Z")


def test_parse_column_mapping():
    assert parse_column_mapping("speed_kn=SYS.STR.SOG, air_temp_c=TT [°C,dry]") == {
        "speed_kn": "SYS.STR.SOG",
        "air_temp_c": "TT [°C,dry]",
    }
    assert parse_column_mapping(["speed_kn=A", "air_temp_c=B"]) == {
        "speed_kn": "A",
        "air_temp_c": "B",
    }
    with pytest.raises(ValueError, match="'speed_kn' is not COLUMN=SOURCE_NAME"):
        parse_column_mapping("speed_kn")


def test_cli_validate_with_dship_columns(tmp_path, capsys):
    path = write(tmp_path, "Date/Time;Fahrt [kn];Luft [°C]\n01.01.2026 00:00;5,5;1\n")
    assert main(["validate", "dship", str(path)]) == 1
    err = capsys.readouterr().err
    assert "columns in the file: Date/Time, Fahrt [kn], Luft [°C]" in err
    code = main(
        ["validate", "dship", str(path), "--dship-columns", "speed_kn=Fahrt,air_temp_c=Luft"]
    )
    out, err = capsys.readouterr()
    assert code == 0 and "1 records" in out
    assert main(["validate", "dship", str(path), "--dship-columns", "speed=Fahrt"]) == 2
    assert "unknown column(s) speed" in capsys.readouterr().err
