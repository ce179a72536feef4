"""A time that lacks digits (``2026-03-01T00:1``, ``00:10:5``) is refused with the file,
the column and the line, instead of being read as another time; an unpadded day, month or
hour that another field follows (``1/3/2026 0:05``, as spreadsheets write) is no cut and
reads as before.

Before: pandas' ISO-8601 parser reads a one-digit minute, hour or second as a whole field,
so the ship-log line ``2026-03-01T00:1`` (a minute cut short: 00:10 to 00:19) was read as
00:01 and averaged into the blocks of nine to eighteen minutes earlier, and ``2026-03``
as the first of March; the ``yyyy/mm/dd HH:MM:SS`` forms did the same through
``strptime``. Nothing was said. Now a time of a recognised form must have every digit of
each field it writes; a complete time still reads as before (the documented forms:
ISO-8601 with ``T`` or a space, seconds and fractions optional, ``Z`` or an offset;
``yyyy/mm/dd``, ``dd.mm.yyyy``, ``dd-mmm-yyyy``, slash dates).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from data_contracts import MODAL, ContractError, read_dship
from data_contracts.dship_names import parse_log_times
from workbench.cli import main

HEADER = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\n"


def _log(path: Path, odd: str, fmt: str = "%Y-%m-%dT%H:%M:%S") -> Path:
    """A 1-min log of 30 lines whose 6th data line (line 7) has the time *odd*."""
    times = [f"{t:{fmt}}" for t in pd.date_range("2026-03-01T00:00", periods=30, freq="60s")]
    times[5] = odd
    rows = [f"{t}\t10\t2\t-1\t7\t90" for t in times]
    path.write_text(HEADER + "\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "odd",
    [
        "2026-03-01T00:1",  # a minute cut short: was 00:01
        "2026-03-01T00:05:0",  # a second cut short: was 00:05:00 whatever it was
        "2026-03-01T00",  # the minutes cut off: was 00:00
        "2026-3-01T00:05:00",  # a month of one digit
        "2026-03",  # the day cut off: was the first
        "2026-03-01T00:05:00+1",  # an offset of one digit: was an hour back
    ],
)
def test_a_time_missing_digits_is_refused_with_its_line(tmp_path: Path, odd: str):
    path = _log(tmp_path / "dship.tsv", odd)
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    message = str(caught.value)
    assert str(path) in message
    assert "'Date/Time'" in message and "line 7" in message and repr(odd) in message


def test_validate_says_it_in_one_line_and_exits_1(tmp_path: Path, capsys):
    path = _log(tmp_path / "dship.tsv", "2026-03-01T00:1")
    assert main(["validate", "dship", str(path)]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert str(path) in lines[0] and "line 7" in lines[0] and "'2026-03-01T00:1'" in lines[0]
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("odd", "fmt"),
    [
        ("2026/03/01 00:05:0", "%Y/%m/%d %H:%M:%S"),  # strptime read it as 00:05:00
        ("01.03.2026 00:5:00", "%d.%m.%Y %H:%M:%S"),
        ("1.3.2026 0:0", "%d.%m.%Y %H:%M"),  # the minutes cut short
        ("01-Mar-2026 00:5:00", "%d-%b-%Y %H:%M:%S"),
    ],
)
def test_the_other_recognised_forms_need_their_digits_too(tmp_path: Path, odd: str, fmt: str):
    path = _log(tmp_path / "dship.tsv", odd, fmt)
    with pytest.raises(ContractError, match="line 7"):
        read_dship(path)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2026-03-01T00:05:00", "2026-03-01T00:05:00Z"),
        ("2026-03-01 00:05:00", "2026-03-01T00:05:00Z"),
        ("2026-03-01T00:05", "2026-03-01T00:05:00Z"),
        ("2026-03-01T00:05:00.25Z", "2026-03-01T00:05:00.25Z"),
        ("2026-03-01T01:05:00+01:00", "2026-03-01T00:05:00Z"),
        ("2026-03-01T01:05:00+0100", "2026-03-01T00:05:00Z"),
        ("2026-03-01T01:05:00+01", "2026-03-01T00:05:00Z"),
        ("2026-03-01 00:05:00.000000+00:00", "2026-03-01T00:05:00Z"),
        ("2026-03-01", "2026-03-01T00:00:00Z"),
        ("20260301T000500Z", "2026-03-01T00:05:00Z"),
        ("2026/03/01 00:05:00", "2026-03-01T00:05:00Z"),
        ("01.03.2026 00:05:00.5", "2026-03-01T00:05:00.5Z"),
        ("01-Mar-2026 00:05:00", "2026-03-01T00:05:00Z"),
        ("13/03/2026 00:05:00", "2026-03-13T00:05:00Z"),
        # unpadded fields that another field follows: no cut
        ("2026-03-01T0:10", "2026-03-01T00:10:00Z"),
        ("13/3/2026 0:05", "2026-03-13T00:05:00Z"),
        ("3/13/2026 9:05:00", "2026-03-13T09:05:00Z"),
        ("1.3.2026 0:05:00", "2026-03-01T00:05:00Z"),
        ("1-Mar-2026 0:05:00", "2026-03-01T00:05:00Z"),
    ],
)
def test_complete_times_read_as_before(text: str, expected: str):
    times, _ = parse_log_times(pd.Series([text, text]))
    assert times.tolist() == [pd.Timestamp(expected)] * 2


def test_a_table_time_column_missing_digits_is_refused():
    """The time columns of the contract tables (``block_start`` of a modal or tracked
    table read from CSV) go through the same check."""
    frame = pd.DataFrame({"block_start": ["2026-03-01T00:10:00Z", "2026-03-01T00:1"]})
    with pytest.raises(ContractError) as caught:
        MODAL.validate(frame)
    named = [v for v in caught.value.violations if v.column == "block_start"]
    assert len(named) == 1 and named[0].rows == (1,)


def test_a_start_time_missing_digits_is_refused(tmp_path: Path):
    """The start time of an acceleration record or layout and the grid origin of a modal
    layout: ``pd.Timestamp`` read ``2026-03-01T00:1`` as 00:01 too."""
    import numpy as np

    from data_contracts import AccelerationRecord, validate_accelerations
    from data_contracts.formats import AccelerationLayout
    from data_contracts.modal_layout import _utc

    record = AccelerationRecord(np.zeros((64, 2)), 32.0, "2026-03-01T00:1", ["a", "b"])
    with pytest.raises(ContractError) as caught:
        validate_accelerations(record)
    assert [v.column for v in caught.value.violations] == ["start_time"]
    with pytest.raises(ValueError, match="start_time='2026-03-01T00:1' is not a complete"):
        AccelerationLayout(start_time="2026-03-01T00:1")
    with pytest.raises(ValueError, match="grid_t0='2026-03-01T00:1' is not a complete"):
        _utc("2026-03-01T00:1", "grid_t0")
    assert AccelerationLayout(start_time="2026-03-01T00:10").start_time == "2026-03-01T00:10"
    assert _utc("2026-03-01 00:10:00", "grid_t0") == pd.Timestamp("2026-03-01T00:10Z")
