"""The monitor checks the ship log's clock as ``identify --dship`` does.

Before, only identify checked it: on the bridge, where the log is read as it grows, a log
kept in local time without a UTC offset moved every predictor of the monitor hours off its
blocks, and nothing said so. Now the monitor runs identify's check
(:mod:`workbench.predictors.clock`) on the blocks it has identified, first at 24 blocks
(the check's own minimum), then every 12 blocks until it has decided (warned once, or found
the log as read to agree), and says the warning once, as a note.

The voyage is the monitor tests' (the demo simulator, 6 channels), 3 h long (33 blocks of
20 min, 36 of varying length), its log also written by a clock 2 h ahead of UTC without an
offset; the files land one by one and the log grows with them.
"""

from __future__ import annotations

import logging
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor

from .conftest import FORECAST, IDENTIFY, MONITOR_FAST, ShipLog, cli, file_end, land, write_voyage

WARNING = (
    "the hull's vibration level follows the log's speed best with the log's times taken as "
    "UTC+02:00 (rank correlation {:.2f}, against 0.00 as read, UTC+00:00): if its times are "
    "local time without an offset, give --dship-utc-offset +02:00"
)


@pytest.fixture(scope="module")
def long_voyage(tmp_path_factory) -> Path:
    """The monitor tests' voyage for 3 h, with ``dship_local.tsv``: its log as a clock
    2 h ahead of UTC writes it, without an offset."""
    source = write_voyage(tmp_path_factory.mktemp("clock_voyage"), hours=3.0)
    lines = (source / "dship.tsv").read_text(encoding="utf-8").split("\n")
    start = next(i for i, line in enumerate(lines) if line.startswith("Date/Time")) + 1
    for i in range(start, len(lines)):
        if lines[i]:
            time, rest = lines[i].split("\t", 1)
            moved = datetime.fromisoformat(time) + timedelta(hours=2)
            lines[i] = f"{moved:%Y-%m-%dT%H:%M:%S}\t{rest}"
    (source / "dship_local.tsv").write_text("\n".join(lines), encoding="utf-8")
    return source


def _live(source: Path, run: Path, log_name: str, ahead_h: float, *extra) -> tuple:
    """The files landed one by one, the log (*log_name*, its clock *ahead_h* ahead of UTC)
    written up to each file's end as they land; the monitor stepped after each. Returns the
    monitor (closed) and, per note about the log's clock, the blocks identified when it was
    made."""
    watch, state, log = run / "watch", run / "state", run / "dship.tsv"
    watch.mkdir(parents=True)
    growing = ShipLog(source / f"{log_name}.tsv", log)
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", log]
    argv += [*IDENTIFY, *FORECAST, *MONITOR_FAST, "--foreground", "--settle", "0", *extra]
    monitor = prepare_monitor(parse_arguments([str(a) for a in argv]))
    said = []

    def step(flush: bool = False) -> None:
        monitor.step(flush=flush)
        notes = sum("vibration level" in m for m in monitor.messages)
        said.extend([monitor.identified_here] * (notes - len(said)))

    try:
        for path in sorted((source / "accelerations").glob("*.npz")):
            growing.until(file_end(path) + pd.Timedelta(hours=ahead_h))
            land(path, watch)
            step()
        growing.until(None)
        step(flush=True)  # the input has ended: the last blocks
    finally:
        monitor.close()
    return monitor, said


def test_the_monitor_warns_once_on_a_local_log_as_the_blocks_come(long_voyage, tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="workbench")
    monitor, said = _live(long_voyage, tmp_path, "dship_local", 2.0)
    line = f"{tmp_path / 'dship.tsv'}: {WARNING.format(0.98)}"
    # at the first check, with 24 blocks identified (2 h of data): said once, as a note
    # (notes.txt) and on the log, not again over the 9 blocks after it
    assert monitor.clock_check.checked_blocks == [24] and said == [24]
    assert [m for m in monitor.messages if "vibration" in m] == [line]
    notes = (tmp_path / "state" / "notes.txt").read_text(encoding="utf-8").splitlines()
    assert [n.split(" ", 1)[1] for n in notes if "vibration" in n] == [line]
    assert [r.getMessage() for r in caplog.records if "vibration" in r.getMessage()] == [line]
    assert monitor.identified_here == 33


def test_the_correct_log_is_checked_once_and_not_warned_about(long_voyage, tmp_path):
    monitor, said = _live(long_voyage, tmp_path, "dship", 0.0)
    # the log as read follows the level best (rank correlation 0.8 at least): decided at
    # the first check, not checked again
    assert said == [] and monitor.clock_check.checked_blocks == [24]
    assert monitor.clock_check.decided and monitor.clock_check.warning is None
    assert not any("vibration" in m for m in monitor.messages)


def test_the_local_log_placed_by_its_offset_is_not_warned_about(long_voyage, tmp_path, capsys):
    # --dship-utc-offset reaches the monitor's reading of the log for the check too
    local = long_voyage / "dship_local.tsv"
    for name, extra in (("placed", ["--dship-utc-offset", "+02:00"]), ("as_read", [])):
        assert cli(
            "monitor", "--watch", long_voyage / "accelerations", "--state", tmp_path / name,
            "--dship", local, *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once", *extra,
        ) == 0  # fmt: skip
        printed = [line for line in capsys.readouterr().out.splitlines() if "vibration" in line]
        if name == "placed":
            assert printed == []
    # read as UTC, --once checks once, over all 33 blocks
    assert printed == [f"note: {local}: {WARNING.format(0.96)}"]


def test_blocks_of_varying_length_are_checked_on_their_own_spans(long_voyage, tmp_path):
    monitor, said = _live(long_voyage, tmp_path, "dship_local", 2.0, "--block-minutes", "auto")
    # 36 blocks of 5-35 min; at 24, the log's 10-min gap (01:39-01:49) leaves two of them
    # (01:35-01:50, 01:45-01:50) without half their own span logged: 22 blocks with a
    # speed at +2 h, too few to judge; said at the next check, 12 blocks later
    assert monitor.clock_check.checked_blocks == [24, 36] and said == [36]
    assert [m for m in monitor.messages if "vibration" in m] == [
        f"{tmp_path / 'dship.tsv'}: {WARNING.format(0.98)}"
    ]


def test_a_check_reads_the_newest_day_of_blocks_and_runs_every_12_blocks():
    from workbench.monitor.log_clock import LiveClockCheck

    # 30 h of 20-min blocks every 5 min at rest (one speed: never decided), 3 channels
    t0 = pd.Timestamp("2024-03-01T00:00:00Z")
    starts = t0 + pd.Timedelta(minutes=5) * np.arange(360)
    log = pd.DataFrame(
        {"time": t0 + pd.Timedelta(seconds=10) * np.arange(31 * 360), "speed_kn": 0.1}
    )
    check = LiveClockCheck()
    rng = np.random.default_rng(1)
    for block, start in enumerate(starts):
        rms = rng.uniform(0.5, 2.0, 3)
        channels = pd.DataFrame(
            {"block": block, "block_start": start, "channel": ["a", "b", "c"], "rms": rms}
        )
        check.add(channels, 1200.0)
        if check.due():
            assert check.check(log, "log") is None
    assert not check.decided
    # from 24 blocks, then every 12 added: 24, 36, ..., 360
    assert check.checked_blocks == list(range(24, 361, 12))
    # the blocks starting in the newest 24 h are kept (360 - 72 + 1 = 289), the older let go
    assert check.n_blocks == 289 and check.n_added == 360
