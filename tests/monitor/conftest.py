"""A short simulated voyage, its batch results, and a feeder that replays it into a folder.

The voyage is the demo's simulator (7 hull modes, shaft harmonic, dropouts, a dead
channel) for 1.5 h, reduced to 6 of its 19 channels so that SSI takes a fraction of a
second per block. The batch reference is what a user runs: ``workbench identify`` +
``track`` + ``forecast`` over the complete folder, with the same settings as the monitor.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations

HOURS = 1.5
KEEP = ("acc01", "acc04", "acc08", "acc12", "acc15", "acc18")
IDENTIFY = ["--block-rows", "8", "--max-order", "20", "--band", "2", "12"]
FORECAST = ["--train-blocks", "6"]  # the batch forecast with the monitor's default model
MONITOR_FAST = ["--poll", "0.05", "--settle", "0.2"]


def cli(*argv) -> int:
    from workbench.cli import main

    return main([str(a) for a in argv])


def write_voyage(
    root: Path, *, rate_hz: float = 64.0, seed: int = 11, hours: float = HOURS, shaft=None
) -> Path:
    """The reduced voyage in *root*/source: accelerations/ and dship.tsv (*shaft*: the
    simulator's ShaftHarmonics, default its own)."""
    from workbench.simulate import simulate_voyage

    full = root / "full"
    simulate_voyage(full, seed=seed, hours=hours, sampling_rate_hz=rate_hz, shaft=shaft)
    source = root / "source"
    (source / "accelerations").mkdir(parents=True)
    for path in sorted((full / "accelerations").glob("*.npz")):
        record = read_accelerations(path)
        columns = [record.channels.index(c) for c in KEEP]
        write_accelerations(
            AccelerationRecord(
                record.acceleration[:, columns], record.sampling_rate_hz, record.start_time, KEEP
            ),
            source / "accelerations" / path.name,
        )
    shutil.copy(full / "dship.tsv", source / "dship.tsv")
    shutil.rmtree(full)
    return source


def batch_run(source: Path, out: Path, identify=IDENTIFY) -> dict[str, pd.DataFrame]:
    """identify + track + forecast over the complete folder (the reference)."""
    out.mkdir(parents=True, exist_ok=True)
    common = ["--scheduler", "synchronous", "--quiet"]
    # the ship log's shaft speed marks the harmonics, as the monitor's does
    dship = ["--dship", source / "dship.tsv"]
    assert (
        cli("identify", source / "accelerations", "--out", out / "id", *identify, *dship, *common)
        == 0
    )
    assert cli("track", out / "id" / "selected.parquet", "--out", out / "tracked.parquet") == 0
    assert (
        cli(
            "forecast",
            "--modal",
            out / "tracked.parquet",
            "--dship",
            source / "dship.tsv",
            *FORECAST,
            "--out",
            out / "forecast.parquet",
            "--quiet",
        )
        == 0
    )
    return {
        "tracked": pd.read_parquet(out / "tracked.parquet"),
        "forecast": pd.read_parquet(out / "forecast.parquet"),
        "blocks": pd.read_csv(out / "id" / "blocks.csv"),
    }


@pytest.fixture(scope="session")
def voyage(tmp_path_factory):
    return write_voyage(tmp_path_factory.mktemp("monitor_voyage"))


@pytest.fixture(scope="session")
def batch(voyage, tmp_path_factory):
    return batch_run(voyage, tmp_path_factory.mktemp("monitor_batch"))


class ShipLog:
    """The ship log written as it grows: header first, then the rows up to a time."""

    def __init__(self, source: Path, target: Path):
        lines = source.read_text(encoding="utf-8").splitlines(keepends=True)
        end = next(i for i, line in enumerate(lines) if line.startswith("*/"))
        self.header = lines[: end + 2]
        self.rows = lines[end + 2 :]
        self.times = pd.to_datetime([r.split("\t", 1)[0] for r in self.rows], utc=True)
        self.target = target
        self.written = 0
        target.write_text("".join(self.header), encoding="utf-8")

    def until(self, time: pd.Timestamp | None) -> None:
        """Append the rows before *time* (all with None)."""
        stop = len(self.rows) if time is None else int(np.searchsorted(self.times, time))
        if stop > self.written:
            with open(self.target, "a", encoding="utf-8") as handle:
                handle.writelines(self.rows[self.written : stop])
            self.written = stop


def land(path: Path, folder: Path) -> Path:
    """Put *path* into *folder* as a recorder does: a hidden temporary name, then rename."""
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".{path.name}.part"
    shutil.copyfile(path, tmp)
    final = folder / path.name
    os.replace(tmp, final)
    return final


def land_slowly(path: Path, folder: Path, pieces: int = 4, pause_s: float = 0.05) -> Path:
    """Write *path* into *folder* in place, in *pieces* with pauses (a writer appending)."""
    data = path.read_bytes()
    final = folder / path.name
    size = -(-len(data) // pieces)
    with open(final, "wb") as handle:
        for k in range(pieces):
            handle.write(data[k * size : (k + 1) * size])
            handle.flush()
            time.sleep(pause_s)
    return final


def file_end(path: Path) -> pd.Timestamp:
    from workbench.signals.block_plan import read_file_info

    return read_file_info(path).end_time


def assert_same_tables(state: Path, batch: dict[str, pd.DataFrame], min_rows: int = 20) -> None:
    tracked = pd.read_parquet(state / "tracked.parquet")
    forecast = pd.read_parquet(state / "forecast.parquet")
    # not vacuous: several modes over the blocks, forecast rows after the training window
    # (the memory model starts forecasting later than the 6-block window on this short voyage;
    # with the shaft harmonics left out, 40 rows of modes over the 15 blocks)
    assert len(batch["tracked"]) >= 2 * min_rows and len(batch["forecast"]) > min_rows // 2
    assert batch["forecast"]["kalman_frequency_hz"].notna().sum() > min_rows // 2
    pd.testing.assert_frame_equal(tracked, batch["tracked"])
    pd.testing.assert_frame_equal(forecast, batch["forecast"])


def marked_frame(monitor, frame: pd.DataFrame) -> pd.DataFrame:
    """*frame* with the harmonic columns of the monitor's marks (``Monitor._mark_harmonics``:
    an array, a row per row of *frame*), as ``identify --dship`` writes them."""
    marks = monitor._mark_harmonics(frame)
    return frame.assign(
        harmonic=marks[:, 0], harmonic_frequency_hz=marks[:, 1], harmonic_checked=marks[:, 2] > 0.5
    )


def marking_monitor(log, harmonics=None):
    """A :class:`~workbench.monitor.core.Monitor` holding only what its harmonic marking
    uses (``_mark_harmonics``, ``_mark_from_speed``), reading *log* as its ship log, with
    *harmonics* (``HarmonicOptions``; default: the defaults)."""
    from types import SimpleNamespace

    from workbench.monitor.core import Monitor
    from workbench.sid.harmonics import HarmonicOptions

    monitor = Monitor.__new__(Monitor)
    monitor._marks, monitor._marks_kept = np.empty((0, 3)), np.zeros(0, bool)
    monitor._marks_pending, monitor._shaft_logged = False, False
    monitor._block_shaft_rpm, monitor._shaft_rpm_of_block = {}, {}
    monitor._speed_test, monitor._speed_index, monitor._block_speed = None, np.empty(0, int), {}
    monitor._shaft_hz_per_kn, monitor._speed_of_block = np.nan, {}
    monitor._shaft_log_note, monitor._shaft_rows, monitor.messages = None, {}, []
    monitor._orders_at, monitor._orders_kept = np.zeros(0, bool), np.zeros(0, bool)
    monitor._judge_pending = False
    monitor.options = SimpleNamespace(harmonics=harmonics or HarmonicOptions())
    monitor._read_log = lambda: log
    # the log as given each time (tests of the marks as the log grows give its generation)
    monitor._live_shaft, monitor._log_generation = None, lambda: None
    return monitor
