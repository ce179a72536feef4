"""The monitor's per-block costs that could grow with the voyage, as ratios day N / day 1.

A synthetic voyage of 20-min blocks every 5 min (288 a day): each block's selected modes
(four structural modes with fixed shapes and a shaft harmonic following a slowly varying
shaft speed, 4 channels) and a ship log at 1 min with ``shaft_rpm`` and ``speed_kn``
covering the blocks decided so far (the newest block's marks pending, as a live log that
lags). Each block is fed to the monitor's own tracking step (``Monitor._advance_tracking``:
the tracker, the harmonic marks, the tracked table and ``tracked.parquet``,
``harmonics.parquet``, ``harmonic_tracks.parquet``, ``labels.json``); at each day mark
the median time of the next ``SAMPLE`` blocks is printed. Also timed, apart: the store's
check of one new landed file (``BlockStore.check_inputs``, one new fingerprint among the
voyage's files so far) and the decided-block scans of a step (``_note_too_late``,
``given_up``, ``_write_status``, ``_write_data_health``) with one data-health row per block.
With a 1-s ship log at ``--dship-days``: reading the log after it grew by 5 min (``--only
dship``; session 51: read again whole) and the marks of a new block (``--only marking``;
session 51: the log's checks run over all of it).

Run: ``python benchmarks/bench_monitor_costs.py [--days 1,10,25,51] [--only
tracking,store,scans,dship,marking] [--dship-days 1,5]`` (default: ``--days``); results in
``benchmarks/results/monitor_costs_51.txt``, ``monitor_costs_52.txt`` (dship, marking).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the tree run is the one importable

from workbench.blocks import BlockGrid  # noqa: E402
from workbench.monitor.core import Monitor  # noqa: E402
from workbench.monitor.notes import NoteList  # noqa: E402
from workbench.monitor.tracking import IncrementalTracking  # noqa: E402
from workbench.sid.harmonics import HarmonicOptions  # noqa: E402
from workbench.sid.tracking import TrackingOptions  # noqa: E402
from workbench.store import BlockStore  # noqa: E402

BLOCKS_PER_DAY = 288
SAMPLE = 15  # blocks timed at each day mark
T0 = pd.Timestamp("2026-03-01T00:00:00Z")
GRID = BlockGrid(T0, 1200.0, 300.0)
UNITS = {
    "tracking": f"block, median of {SAMPLE}",
    "store": f"new file, median of {SAMPLE}",
    "scans": f"block, median of {SAMPLE}",
    "dship": "read after 5 min appended, median of 3",
    "marking": "block (1-s log), median of 3",
}
CHANNELS = ("a", "b", "c", "d")
MODES_HZ = (0.8, 1.6, 2.9, 4.1)


def _shaft_rpm(minutes: np.ndarray) -> np.ndarray:
    """Shaft speed, 90 +- 30 rpm over a 3-day cycle. [rpm]"""
    return 90.0 + 30.0 * np.sin(2 * np.pi * minutes / (3 * 1440.0))


def _log(days: int) -> pd.DataFrame:
    minutes = np.arange(days * 1440 + 60, dtype=float)
    rpm = _shaft_rpm(minutes)
    return pd.DataFrame(
        {
            "time": T0 + pd.to_timedelta(minutes, unit="min"),
            "shaft_rpm": rpm,
            "speed_kn": rpm / 7.5,
        }
    )


def _selected(block: int, rng: np.random.Generator) -> pd.DataFrame:
    """A block's selected modes: MODES_HZ with their shapes and shaft order 1."""
    start = GRID.start(block)
    mid = (start - T0).total_seconds() / 60.0 + 10.0
    frequency = [f * (1 + 0.003 * rng.standard_normal()) for f in MODES_HZ]
    frequency.append(float(_shaft_rpm(np.array([mid]))[0]) / 60.0)
    shapes = np.array(
        [[1, 0.5, -0.3, 0.2], [0.2, 1, 0.6, -0.5], [-0.4, 0.1, 1, 0.7], [0.6, -0.7, 0.2, 1],
         [0.5, 0.5, 0.5, 0.5]]
    ) + 0.01 * rng.standard_normal((5, 4))  # fmt: skip
    frame = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": GRID.end(block),
            "frequency_hz": frequency,
            "damping_ratio": 0.01 + 0.001 * rng.standard_normal(5),
            "model_order": np.arange(5) * 2 + 20,
        }
    )
    for j, c in enumerate(CHANNELS):
        frame[f"shape_re_{c}"] = shapes[:, j]
    for c in CHANNELS:
        frame[f"shape_im_{c}"] = 0.0
    return frame


def _tracking_monitor(state: Path, log: pd.DataFrame) -> Monitor:
    monitor = Monitor.__new__(Monitor)  # only what the tracking step uses
    monitor.state = state
    monitor.voyage = None
    monitor.done = set()
    monitor.options = SimpleNamespace(harmonics=HarmonicOptions())
    monitor.tracking = IncrementalTracking(TrackingOptions())
    monitor._labels_lost = None
    monitor._marks_pending, monitor._shaft_logged = False, False
    monitor._marks, monitor._marks_kept = np.empty((0, 3)), np.zeros(0, bool)
    monitor._harmonic_marks = {}  # main before the marks were kept as arrays
    monitor._block_shaft = {}
    monitor._marked = None
    monitor._tracked = None
    monitor._speed_test = None
    monitor._log_now = log
    monitor._read_log = lambda: monitor._log_now
    monitor._live_shaft, monitor._log_generation = None, lambda: 0  # the log only grows
    return monitor


def bench_tracking(days: list[int], folder: Path) -> dict[int, float]:
    full = _log(max(days))
    times = pd.DatetimeIndex(full["time"]).asi8
    monitor = _tracking_monitor(folder, full)
    rng = np.random.default_rng(1)
    marks = {d * BLOCKS_PER_DAY: d for d in days}
    out: dict[int, list[float]] = {}
    n = max(days) * BLOCKS_PER_DAY + SAMPLE + 1
    for block in range(n):
        monitor.tracking.add(block, _selected(block, rng))
        monitor.done.add(block)
        day = next((d for m, d in marks.items() if m < block <= m + SAMPLE), None)
        # the log covers the blocks before the newest one
        end = GRID.start(block).value
        monitor._log_now = full.iloc[: int(np.searchsorted(times, end, side="right"))]
        if day is None and block not in marks:
            monitor.tracking.advance(monitor.done)  # fed, the table not built
            continue
        t = time.perf_counter()
        monitor._advance_tracking()
        if day is not None:
            out.setdefault(day, []).append(time.perf_counter() - t)
    return {d: float(np.median(v)) for d, v in out.items()}


def _fingerprint(k: int) -> dict:
    start = T0 + pd.Timedelta(minutes=5 * k)
    return {
        "path": f"/data/voyage/file_{k:06d}.h5",
        "start": start.isoformat(),
        "end": (start + pd.Timedelta(minutes=5)).isoformat(),
        "size": 10_000_000,
        "mtime_ns": 1_700_000_000_000_000_000 + k,
        "sha256": f"{k:064x}",
    }


def bench_store(days: list[int], folder: Path) -> dict[int, float]:
    out = {}
    for d in days:
        root = folder / f"store_{d}"
        n = d * BLOCKS_PER_DAY
        with BlockStore.open(root, {"bench": 1}) as store:
            store.check_inputs([_fingerprint(k) for k in range(n)])
        with BlockStore.open(root, {"bench": 1}) as store:  # a monitor's store
            store.check_inputs([_fingerprint(0)])
            taken = []
            for k in range(n, n + SAMPLE):
                t = time.perf_counter()
                store.check_inputs([_fingerprint(k)])
                taken.append(time.perf_counter() - t)
        out[d] = float(np.median(taken))
    return out


def _health_row(block: int) -> dict:
    """Every 50th block skipped for a gap, the others identified."""
    skipped = block % 50 == 7
    return {
        "block": block,
        "block_start": GRID.start(block),
        "n_channels": 0 if skipped else 4,
        "dropped_channels": "",
        "gap_seconds": 2.0 if skipped else 0.0,
        "last_file_landed": GRID.end(block),
        "identified_at": GRID.end(block),
        "latency_s": 60.0,
        "status": "skipped" if skipped else "ok",
        "reason": "gap of 2.0 s" if skipped else "",
    }


def bench_scans(days: list[int], folder: Path) -> dict[int, float]:
    from workbench.monitor.taken import TakenFiles
    from workbench.monitor.watcher import LandedFile

    out = {}
    for d in days:
        state = folder / f"scans_{d}"
        state.mkdir()
        monitor = Monitor.__new__(Monitor)
        monitor.state = state
        monitor.watch = state
        monitor.voyage = SimpleNamespace(grid=GRID, options=SimpleNamespace(max_gap_s=0.0))
        monitor.messages = NoteList(state / "notes.txt")
        n = d * BLOCKS_PER_DAY
        monitor._health_rows = [_health_row(b) for b in range(n)]
        monitor.done = set(range(n))
        monitor.tracking = SimpleNamespace(tracked_through=n - 1)
        monitor.files = TakenFiles()
        monitor._given_up = ((-1, -1), [])
        monitor._missing_scan = ({}, None, 0)
        monitor._health_schedule = ""
        monitor._health_rows_all, monitor._health_rows_from = True, None
        monitor._write_data_health()  # every part once
        item = SimpleNamespace(
            info=SimpleNamespace(start_time=GRID.start(n), end_time=GRID.start(n + 1)),
            path=Path("new.h5"),
        )
        _ = LandedFile
        taken = []
        for k in range(SAMPLE):
            monitor._health_rows.append(_health_row(n + k))  # a decided block
            monitor.done.add(n + k)
            monitor.tracking.tracked_through = n + k
            monitor._health_rows_from = n + k
            t = time.perf_counter()
            monitor._note_too_late(item)
            monitor.given_up()
            monitor._write_data_health()
            monitor._write_status("running")
            taken.append(time.perf_counter() - t)
        out[d] = float(np.median(taken))
    return out


def _dship_text(seconds: np.ndarray) -> str:
    """Lines of a 1-s ship log with the speed and shaft speed at *seconds*."""
    times = (T0.tz_convert(None) + pd.to_timedelta(seconds, unit="s")).strftime("%Y-%m-%dT%H:%M:%S")
    rpm = _shaft_rpm(seconds / 60.0)
    body = pd.DataFrame({"t": times, "kn": np.round(rpm / 7.5, 1), "rpm": np.round(rpm, 1)})
    return body.to_csv(sep="\t", header=False, index=False)


def bench_dship(days: list[int], folder: Path) -> dict[int, float]:
    """Reading the 1-s ship log after it grew by 5 min (``outlook._ship_log``, what
    ``Monitor._read_log`` does each step while the log is written): the log of *d* days
    read once, then 3 times 300 lines appended and the log read; the median of the 3."""
    from workbench.monitor.outlook import _ship_log

    header = (
        "/* DATA DESCRIPTION:\nParameter(s):\tDATE/TIME * SHORT_NAME: Date/Time\n"
        "\tSpeed, ship * SHORT_NAME: Speed * UNIT: kn\n"
        "\tShaft speed * SHORT_NAME: Shaft speed * UNIT: rpm\n*/\n"
        "Date/Time\tSpeed [kn]\tShaft speed [rpm]\n"
    )
    out = {}
    for d in days:
        path = folder / f"dship_{d}.tsv"
        path.write_text(header + _dship_text(np.arange(d * 86400)), "utf-8")
        _ship_log(path, None, None)  # the monitor's first read: the whole log
        taken = []
        for k in range(3):
            seconds = d * 86400 + 300 * k + np.arange(300)
            with open(path, "a", encoding="utf-8") as handle:
                handle.write(_dship_text(seconds))
            t = time.perf_counter()
            log = _ship_log(path, None, None)
            taken.append(time.perf_counter() - t)
            assert len(log) == d * 86400 + 300 * (k + 1)
        out[d] = float(np.median(taken))
        path.unlink()
    return out


def _marking_monitor() -> Monitor:
    """A monitor holding only what its harmonic marking uses (tests/monitor/conftest.py's
    marking_monitor)."""
    monitor = Monitor.__new__(Monitor)
    monitor._marks, monitor._marks_kept = np.empty((0, 3)), np.zeros(0, bool)
    monitor._marks_pending, monitor._shaft_logged = False, False
    monitor._block_shaft_rpm, monitor._shaft_rpm_of_block = {}, {}
    monitor._speed_test, monitor._speed_index, monitor._block_speed = None, np.empty(0, int), {}
    monitor._shaft_hz_per_kn, monitor._speed_of_block = np.nan, {}
    monitor._shaft_log_note, monitor._shaft_rows, monitor.messages = None, {}, []
    monitor._orders_at, monitor._orders_kept = np.zeros(0, bool), np.zeros(0, bool)
    monitor._judge_pending = False
    monitor.options = SimpleNamespace(harmonics=HarmonicOptions())
    # the log only grows (one read generation): its rows are taken once (session 52)
    monitor._live_shaft, monitor._log_generation = None, lambda: 0
    return monitor


def bench_marking(days: list[int], folder: Path) -> dict[int, float]:
    """The harmonic marks of a new block from a 1-s ship log with the shaft speed
    (``Monitor._mark_harmonics``, the tracking step's marks: the new block's and those of
    the blocks the log, 5 min behind, does not cover yet): the 8 blocks before day *d*
    marked once, then 3 blocks each with the log grown by 5 min; the median of the 3."""
    out = {}
    for d in days:
        seconds = np.arange(d * 86400 + 3600)
        rpm = _shaft_rpm(seconds / 60.0)
        full = pd.DataFrame(
            {"time": T0 + pd.to_timedelta(seconds, unit="s"), "shaft_rpm": rpm,
             "speed_kn": rpm / 7.5}
        )  # fmt: skip
        times = pd.DatetimeIndex(full["time"]).asi8
        n = d * BLOCKS_PER_DAY
        rng = np.random.default_rng(1)
        parts = {k: _selected(k, rng) for k in range(n - 8, n + 4)}
        monitor = _marking_monitor()
        taken = []
        for k, block in enumerate(range(n, n + 4)):
            end = GRID.start(block).value
            log = full.iloc[: int(np.searchsorted(times, end, side="right"))]
            monitor._read_log = lambda log=log: log
            frame = pd.concat([parts[b] for b in range(n - 8, block + 1)], ignore_index=True)
            t = time.perf_counter()
            monitor._mark_harmonics(frame)
            if k:  # the first: every row marked
                taken.append(time.perf_counter() - t)
        out[d] = float(np.median(taken))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", default="1,10,25,51")
    parser.add_argument("--only", default="tracking,store,scans")
    parser.add_argument(
        "--dship-days",
        default=None,
        help="days of 1-s ship log (--only dship,marking; default: --days)",
    )
    args = parser.parse_args(argv)
    days = [int(d) for d in args.days.split(",")]
    wanted = args.only.split(",")
    benches = {
        "tracking": bench_tracking,
        "store": bench_store,
        "scans": bench_scans,
        "dship": bench_dship,
        "marking": bench_marking,
    }
    warnings.simplefilter("ignore")  # the 1-s log's missing columns, said at each read
    with tempfile.TemporaryDirectory() as tmp:
        for name in wanted:
            folder = Path(tmp) / name
            folder.mkdir()
            started = time.perf_counter()
            log_days = [int(d) for d in (args.dship_days or args.days).split(",")]
            marks = log_days if name in ("dship", "marking") else days
            result = benches[name](marks, folder)
            print(f"{name}: s per {UNITS[name]}"
                  f" [{time.perf_counter() - started:.0f} s in all]")  # fmt: skip
            first = result[marks[0]]
            for d in marks:
                print(f"  day {d:3d}   {result[d]:.5f} s   ratio to day {marks[0]} "
                      f"{result[d] / first:7.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
