"""A ship log whose times mix UTC offsets, or mix times with and without an offset.

Before: ``read_dship`` parsed every time with ``utc=True``, so a time without an offset
was taken as UTC next to times carrying ``+02:00`` (a log in local time whose exporter
wrote the offset on some rows only): the naive rows landed two hours off and nothing
said so. Times with two different offsets (a ship whose data system follows the local
zone and changed it on the way) were converted right, but silently.

Now a log mixing times with and without an offset is refused, naming the file, the time
column and the first row of the other kind: a time without an offset cannot be placed
among times that have one (UTC is a guess, the other rows' offset another). A log whose
every time carries an offset, not always the same, is converted to UTC row by row, as
before, and says so in one warning naming the file, the column, the offsets and the line
where the offset first changes.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pandas as pd
import pytest

from data_contracts import ContractError, read_dship
from workbench.cli import main

HEADER = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\n"


def _log(tmp_path: Path, times: list[str]) -> Path:
    path = tmp_path / "dship.tsv"
    rows = [f"{t}\t10.0\t2.0\t-1.0\t7.0\t90" for t in times]
    path.write_text(HEADER + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_times_without_an_offset_among_times_with_one_are_refused_naming_the_first(tmp_path):
    path = _log(
        tmp_path,
        ["2026-03-01T02:00:00+02:00", "2026-03-01T02:00:01+02:00", "2026-03-01T02:00:02"],
    )
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    message = str(caught.value)
    assert str(path) in message
    assert "'Date/Time'" in message and "line 4" in message
    assert "no UTC offset" in message and "line 2" in message


def test_an_offset_among_naive_times_is_refused_too(tmp_path):
    path = _log(tmp_path, ["2026-03-01T00:00:00", "2026-03-01T00:00:01", "2026-03-01T02:00:02Z"])
    with pytest.raises(ContractError, match="line 4") as caught:
        read_dship(path)
    assert "carries a UTC offset (Z)" in str(caught.value)


def test_the_cli_refuses_it_in_one_line_exit_1(tmp_path, capsys):
    path = _log(
        tmp_path,
        ["2026-03-01T02:00:00+02:00", "2026-03-01T02:00:01", "2026-03-01T02:00:02+02:00"],
    )
    status = main(["validate", "dship", str(path)])
    err = capsys.readouterr().err
    assert status == 1
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "dship.tsv" in lines[0] and "line 3" in lines[0], err


def test_two_offsets_are_each_converted_to_utc_and_named(tmp_path):
    # the data system switched from +01:00 to +02:00 between two readings one second apart
    path = _log(
        tmp_path,
        ["2026-03-29T01:59:58+01:00", "2026-03-29T01:59:59+01:00", "2026-03-29T03:00:00+02:00"],
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_dship(path)
    assert log["time"].tolist() == list(pd.date_range("2026-03-29T00:59:58Z", periods=3, freq="1s"))
    notes = [str(w.message) for w in caught if "offset" in str(w.message)]
    assert notes == [
        f"{path}: column 'Date/Time' mixes UTC offsets (+01:00, +02:00; +02:00 from line 4); "
        "each time was converted to UTC with its own offset"
    ]


def test_one_offset_throughout_says_nothing(tmp_path):
    path = _log(
        tmp_path,
        ["2026-03-01T02:00:00+02:00", "2026-03-01T02:00:01+0200", "2026-03-01T02:00:02+02"],
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_dship(path)
    assert log["time"].iloc[0] == pd.Timestamp("2026-03-01T00:00:00Z")
    assert not [w for w in caught if "offset" in str(w.message)]
