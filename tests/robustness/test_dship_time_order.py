"""A ship log whose time goes back mid-file (the data system's clock reset, two exports
joined out of order) is named with the line where it goes back.

Before: "time stamps are not sorted; rows were sorted by time": nothing said where, so
a log whose clock jumped back ten minutes (its readings then interleaved with those of
the ten minutes before, and averaged together into the blocks) could not be found and
checked. Now the warning counts the steps back and names the first: its line, how far
back, and the two times.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pandas as pd

from data_contracts import read_dship

HEADER = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\n"


def test_the_first_step_back_is_named_with_its_line(tmp_path: Path):
    first = pd.date_range("2026-03-01T00:00:00", periods=20, freq="60s")
    again = pd.date_range("2026-03-01T00:09:30", periods=20, freq="60s")  # clock reset
    rows = [f"{t:%Y-%m-%dT%H:%M:%S}\t10\t2\t-1\t7\t90" for t in [*first, *again]]
    path = tmp_path / "dship.tsv"
    path.write_text(HEADER + "\n".join(rows) + "\n", encoding="utf-8")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_dship(path)
    assert log["time"].is_monotonic_increasing and len(log) == 40
    notes = [str(w.message) for w in caught if "back" in str(w.message)]
    assert notes == [
        f"{path}: time goes back 1 time(s), first at line 22 (570 s before line 21: "
        "2026-03-01T00:19:00Z then 2026-03-01T00:09:30Z); rows were sorted by time"
    ]


def test_a_row_shorter_than_the_header_reads_its_missing_cells_as_empty(tmp_path: Path):
    """Before: the cells a short row lacks (an exporter leaving out trailing empty fields,
    or the line being written at the end of a live log) were refused as "column 'TTT
    [°C]', line 3: not a number", a number that was not there at all."""
    rows = [
        "2026-03-01T00:00:00\t10\t2\t-1\t7\t90",
        "2026-03-01T00:00:01\t10.5\t2",
        "2026-03-01T00:00:02\t11\t2\t-1\t7\t90",
    ]
    path = tmp_path / "dship.tsv"
    path.write_text(HEADER + "\n".join(rows), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_dship(path)
    assert log["speed_kn"].tolist() == [10.0, 10.5, 11.0]
    assert log["air_temp_c"].isna().tolist() == [False, True, False]
