"""The monitor's ship log read as it grows (:class:`workbench.monitor.ship_log.LiveShipLog`):
after every append, in pieces that cut lines (and characters) in two, the table and the
warnings equal ``read_dship(path, complete_lines=True)`` over the whole file, while only
the appended lines are parsed; a log rotated, truncated or rewritten in place is read whole.

Before (main): ``outlook._ship_log`` read the whole file again each time it changed
(``benchmarks/results/monitor_costs_51.txt``, ``monitor_costs_52.txt``); the tests of counts
(``appended_reads``) fail there, the class being absent.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from data_contracts import ContractError, read_dship
from workbench.monitor.ship_log import PREFIX_ROWS, LiveShipLog

HEADER = (
    "/* DATA DESCRIPTION:\nParameter(s):\tDATE/TIME\n\tSpeed, ship\n\tShaft speed\n*/\n"
    "Date/Time\tSpeed [kn]\tShaft speed [rpm]\tTTT [°C]\tNote\n"
)
T0 = pd.Timestamp("2026-03-01T00:00:00")


def _lines(n: int, first: int = 0, *, rng=None, air: bool = True) -> list[str]:
    """*n* 1-s lines from second *first*: speed, shaft speed, air temperature, a note."""
    rng = rng or np.random.default_rng(first)
    out = []
    for k in range(first, first + n):
        t = (T0 + pd.Timedelta(seconds=k)).strftime("%Y-%m-%dT%H:%M:%S")
        speed = f"{10 + rng.normal():.2f}"
        rpm = "" if rng.random() < 0.05 else f"{75 + 5 * rng.normal():.1f}"
        temp = f"{2 + rng.normal():.1f}" if air else ""
        out.append(f"{t}\t{speed}\t{rpm}\t{temp}\tok\n")
    return out


def _whole(path) -> tuple[pd.DataFrame | None, list[str], str | None]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            frame = read_dship(path, complete_lines=True)
        except ContractError as error:
            return None, [], str(error)
    return frame, [str(w.message) for w in caught], None


def _live(live: LiveShipLog) -> tuple[pd.DataFrame | None, list[str], str | None]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            frame = live.read()
        except ContractError as error:
            return None, [], str(error)
    return frame, [str(w.message) for w in caught], None


def _same(live: LiveShipLog, path) -> None:
    frame, notes, error = _live(live)
    whole, whole_notes, whole_error = _whole(path)
    assert error == whole_error
    if whole is not None:
        pd.testing.assert_frame_equal(frame, whole, check_exact=True)
        assert notes == whole_notes


def _append_in_pieces(path, data: bytes, cuts: list[int], live: LiveShipLog) -> None:
    cuts = sorted({min(c, len(data)) for c in cuts} | {len(data)})
    done = 0
    for cut in cuts:
        with open(path, "ab") as handle:
            handle.write(data[done:cut])
        # the same size twice: the modification time must tell the reads apart
        os.utime(path, ns=(0, os.stat(path).st_mtime_ns + 1))
        done = cut
        _same(live, path)


def test_a_log_appended_in_pieces_is_read_as_whole(tmp_path):
    path = tmp_path / "dship.tsv"
    start = HEADER + "".join(_lines(200))
    path.write_text(start, encoding="utf-8")
    live = LiveShipLog(path)
    _same(live, path)
    more = "".join(_lines(3000, 200))
    # cut in the middle of lines, of the °C of no line, of a line end
    rng = np.random.default_rng(5)
    cuts = list(np.sort(rng.integers(0, len(more.encode()), 40)))
    _append_in_pieces(path, more.encode("utf-8"), cuts, live)
    assert live.whole_reads == 1  # the first read; every append parsed alone
    assert live.appended_reads >= 35
    assert len(live.read()) == 3200


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    n_first=st.integers(0, 2 * PREFIX_ROWS),
    pieces=st.lists(st.integers(1, 4000), min_size=1, max_size=6),
    fault=st.sampled_from(
        ["none", "back", "duplicate", "text", "air appears", "cut time", "crlf", "latin-1"]
    ),
)
def test_appends_with_faults_equal_the_whole_read(tmp_path_factory, n_first, pieces, fault):
    """Whatever the appended lines hold (a time going back or repeated, text in a column
    of numbers, a value in a column empty so far, a cut time, CRLF line ends, a Latin-1
    byte), the table, warnings and errors are those of the whole read."""
    path = tmp_path_factory.mktemp("log") / "dship.tsv"
    rng = np.random.default_rng(n_first)
    air = fault != "air appears"
    path.write_text(HEADER + "".join(_lines(n_first, rng=rng, air=air)), encoding="utf-8")
    live = LiveShipLog(path)
    _same(live, path)
    lines = _lines(600, n_first, rng=rng, air=air)
    k = len(lines) // 2
    if fault == "back":
        lines[k], lines[k + 1] = lines[k + 1], lines[k]
    elif fault == "duplicate":
        lines.insert(k, lines[k])
    elif fault == "text":
        fields = lines[k].split("\t")
        lines[k] = "\t".join([fields[0], "fast", *fields[2:]])
    elif fault == "air appears":
        lines[k] = lines[k].replace("\t\tok", "\t1.5\tok")
    elif fault == "cut time":
        lines[k] = lines[k][:12] + "\n"
    elif fault == "crlf":
        lines = [line.replace("\n", "\r\n") for line in lines]
    text = "".join(lines)
    if fault == "latin-1":
        data = text.encode("utf-8")
        at = data.index(b"\tok\n", len(data) // 2)
        data = data[:at] + b"\tok\xb0\n" + data[at + 4 :]  # a note's byte not UTF-8
        text = None
    else:
        data = text.encode("utf-8")
    _append_in_pieces(path, data, list(np.cumsum(pieces)), live)
    if n_first < PREFIX_ROWS + 5:  # too short for the log's start: every read whole
        return
    if fault in ("none", "crlf"):
        assert live.whole_reads == 1  # every append parsed alone
    elif fault in ("cut time", "text", "latin-1"):
        # text in the speed is not a number; read as Latin-1, the header's UTF-8 '°C' is not
        # a unit
        assert _live(live)[2] is not None  # refused, as the whole read refuses it
    else:
        assert live.whole_reads >= 2  # the whole read says it (or takes the column out)


def test_rotated_truncated_or_rewritten_logs_are_read_whole(tmp_path):
    path = tmp_path / "dship.tsv"
    path.write_text(HEADER + "".join(_lines(300)), encoding="utf-8")
    live = LiveShipLog(path)
    _same(live, path)
    with open(path, "a", encoding="utf-8") as handle:
        handle.write("".join(_lines(100, 300)))
    _same(live, path)
    assert (live.whole_reads, live.appended_reads) == (1, 1)
    # rotated: a new file under the name, longer than the part read
    other = tmp_path / "new.tsv"
    other.write_text(HEADER + "".join(_lines(500, 7200)), encoding="utf-8")
    os.replace(other, path)
    _same(live, path)
    assert live.whole_reads == 2
    # truncated, then grown past the part read: the same inode, other bytes before its end
    size = path.stat().st_size
    with open(path, "r+", encoding="utf-8") as handle:
        handle.truncate(len(HEADER.encode()) + 1000)
    _same(live, path)
    assert live.whole_reads == 3
    with open(path, "a", encoding="utf-8") as handle:
        handle.write("\n" + "".join(_lines(400, 9000)))
    assert path.stat().st_size > size // 2
    _same(live, path)
    # rewritten in place (a value corrected near the end), then appended to
    text = path.read_text(encoding="utf-8")
    path.write_text(text[:-30] + text[-30:].replace("ok", "OK"), encoding="utf-8")
    with open(path, "a", encoding="utf-8") as handle:
        handle.write("".join(_lines(10, 9400)))
    before = live.whole_reads
    _same(live, path)
    assert live.whole_reads == before + 1


def test_a_short_log_is_read_whole_and_an_unchanged_one_not_again(tmp_path):
    path = tmp_path / "dship.tsv"
    path.write_text(HEADER + "".join(_lines(10)), encoding="utf-8")
    live = LiveShipLog(path)
    _same(live, path)
    first = live.read()
    assert live.read() is first  # unchanged: nothing read, no warning
    with open(path, "a", encoding="utf-8") as handle:
        handle.write("".join(_lines(10, 10)))
    _same(live, path)
    assert (live.whole_reads, live.appended_reads) == (2, 0)
    path.unlink()
    with pytest.raises(FileNotFoundError):
        live.read()


def test_appended_rows_fill_buffers_that_grow_and_earlier_tables_stay(tmp_path, monkeypatch):
    """The appended rows are written into column buffers with room to grow (here 8 rows or
    a quarter more than needed, so they grow again and again), not copied with the whole
    table at each read (``pd.concat`` on main: ``benchmarks/results/monitor_parity_53.txt``):
    every read equals the whole read, a table handed out earlier keeps its rows as
    later ones are appended, and a reader writing to it changes neither the log's next
    tables nor the other tables handed out (pandas copies the column it writes to)."""
    from workbench.monitor import ship_log

    monkeypatch.setattr(ship_log, "GROWTH_MIN_ROWS", 8)
    path = tmp_path / "dship.tsv"
    path.write_text(HEADER + "".join(_lines(100)), encoding="utf-8")
    live = LiveShipLog(path)
    _same(live, path)
    given = [live.read()]
    kept = [given[0].copy()]
    given[0].loc[0, "speed_kn"] = -1.0  # a reader writing to its table
    capacities = set()
    for k in range(30):
        with open(path, "a", encoding="utf-8") as handle:
            handle.write("".join(_lines(50, 100 + 50 * k)))
        _same(live, path)
        frame = live.read()
        given.append(frame)
        kept.append(frame.copy())
        capacities.add(len(live._last.table._whole))
        assert frame["speed_kn"].iloc[0] == kept[1]["speed_kn"].iloc[0] != -1.0
    assert (live.whole_reads, live.appended_reads) == (1, 30)
    assert len(capacities) >= 5  # the buffers grew, the tables stayed
    for frame, copy in zip(given[1:], kept[1:], strict=True):
        pd.testing.assert_frame_equal(frame, copy, check_exact=True)
    assert given[0]["speed_kn"].iloc[0] == -1.0
    pd.testing.assert_frame_equal(given[0].iloc[1:], kept[0].iloc[1:], check_exact=True)


def test_the_monitor_says_a_log_warning_once_as_the_log_grows(tmp_path):
    """A backward time in the growing log is said once by the monitor, not again with
    every read after lines were appended (main: the same 3 warning lines at each of the 4
    reads; a live log is read at every step for weeks)."""
    from types import SimpleNamespace

    from workbench.monitor.core import Monitor
    from workbench.monitor.log_record import ShipLogRecord

    path = tmp_path / "dship.tsv"
    lines = _lines(200)
    path.write_text(HEADER + "".join(lines[:150] + [lines[100]] + [lines[120]]), encoding="utf-8")
    monitor = Monitor.__new__(Monitor)
    monitor.dship = path
    monitor.options = SimpleNamespace(
        forecast=SimpleNamespace(dship_mapping={}, dship_utc_offset=None)
    )
    monitor._log_warnings_said = set()
    monitor.log_record = ShipLogRecord(tmp_path, path, {}, None)
    said, rows = [], []
    for k in range(4):
        if k:
            with open(path, "a", encoding="utf-8") as file:
                file.write(
                    _lines(10, 200 + 10 * k)[0] if k == 1 else "".join(_lines(10, 200 + 10 * k))
                )
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            log = monitor._read_log()
        said += [str(w.message) for w in caught]
        rows.append(len(log))
    assert rows == [150, 151, 161, 171]  # the duplicate kept once, every appended line read
    # no column for water_temp_c ..., time goes back, 2 duplicate time stamps: once each
    assert len(said) == len(set(said)) == 3, said
    assert sum("time goes back" in s or "duplicate time stamp" in s for s in said) == 2
