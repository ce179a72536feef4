"""The monitor's cost of taking one newly landed file, against the voyage's length.

Each landed file is placed among the files taken before it (clock jitter and drift,
:func:`~workbench.signals.block_plan.place_files`) and the placed headers are what the
blocks are cut from (``Monitor._placed``); the step that took it then lists the blocks
that are ready (``Monitor._ready_blocks``: the blocks a plan of the files gives that are
not decided yet and whose data can no longer change). This replays the headers of a
voyage of 5-min files at 2048 Hz whose sample clock runs 20 ppm fast with a +-5 ms stamp
jitter (no file is read) through the monitor's own steps and prints, at several voyage
lengths, the median time of taking one file, of listing the ready blocks after it (every
block ending 20 min or more before the newest data decided, as the monitor would have),
and their sum, with its ratio to the first day's. A cost that grows with the voyage makes
a monitor restarted on a long expedition's folder (every file taken again) quadratic in
its files.

Run: ``python benchmarks/bench_monitor_placement.py [--days 1,10,25,51]``; results in
``benchmarks/results/monitor_placement_51.txt`` (``monitor_placement_50.txt``: the take
alone, session 50).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # the tree run is the one importable

from bench_clock_drift import RATE_HZ, T0, _headers  # noqa: E402

from workbench.blocks import BlockGrid  # noqa: E402
from workbench.monitor.core import Monitor  # noqa: E402
from workbench.monitor.watcher import LandedFile  # noqa: E402

FILES_PER_DAY = 288
SAMPLE = 25  # files timed at each day mark
GRID = BlockGrid(T0, 1200.0, 300.0)  # the monitor's default blocks


def _monitor() -> Monitor:
    monitor = Monitor.__new__(Monitor)  # only what the placement and readiness steps use
    try:  # a tree keeping its taken files in a TakenFiles
        from workbench.monitor.taken import TakenFiles

        monitor.files = TakenFiles()
    except ImportError:  # main before it: a list and its placement key
        monitor.files = []
        monitor._placed_files = ((), [], None)
    monitor.voyage = SimpleNamespace(
        rate_hz=RATE_HZ,
        grid=GRID,
        options=SimpleNamespace(max_gap_s=0.0),
        channels=("a",),
        lengths=None,
        per_file=True,
    )
    monitor.options = SimpleNamespace(late_s=900.0)
    monitor.done = set()
    monitor._done_below = 0
    return monitor


def _take(monitor: Monitor, item: LandedFile) -> None:
    """What ``Monitor._take`` does to place a file and keep it."""
    reason, _ = monitor._placed_among(item.info)
    assert not reason, reason
    if hasattr(monitor.files, "add"):
        monitor.files.add(item)
    else:
        monitor.files.append(item)
        monitor.files.sort(key=lambda f: (f.info.start_time, str(f.path)))
    monitor._placed()


def _decide_older(monitor: Monitor, newest: pd.Timestamp) -> None:
    """Every block ending 20 min or more before *newest* decided (not timed)."""
    last = int(((newest - GRID.t0).total_seconds() - 1200.0 - GRID.length_s) // GRID.step_s)
    monitor.done.update(range(getattr(monitor, "_bench_decided", 0), last + 1))
    monitor._bench_decided = max(last + 1, 0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", default="1,10,25,51")
    args = parser.parse_args(argv)
    days = [int(d) for d in args.days.split(",")]
    n = max(days) * FILES_PER_DAY + SAMPLE
    infos = _headers(n, 20.0, 5.0, 0, 0.0)
    landed = pd.Timestamp("2026-03-01T00:00:00Z")
    items = [LandedFile(info, landed, 0, 0) for info in infos]
    monitor = _monitor()
    marks = {d * FILES_PER_DAY: d for d in days}
    take: dict[int, list[float]] = {}
    ready: dict[int, list[float]] = {}
    started = time.perf_counter()
    for k, item in enumerate(items):
        day = next((d for m, d in marks.items() if m <= k < m + SAMPLE), None)
        t = time.perf_counter()
        _take(monitor, item)
        if day is None:
            continue
        take.setdefault(day, []).append(time.perf_counter() - t)
        _decide_older(monitor, item.info.end_time)
        t = time.perf_counter()
        blocks = monitor._ready_blocks(False)
        ready.setdefault(day, []).append(time.perf_counter() - t)
        monitor.done.update(int(b.block) for b in blocks)
    total = time.perf_counter() - started
    first = np.median(take[days[0]]) + np.median(ready[days[0]])
    print(f"{n} files taken in {total:.1f} s (20 ppm, +-5 ms jitter)")
    print(
        "  day   files taken   take s/file   ready blocks s   sum s   ratio to day " + str(days[0])
    )
    for d in days:
        a, b = float(np.median(take[d])), float(np.median(ready[d]))
        print(f"  {d:3d}   {d * FILES_PER_DAY:11d}   {a:11.5f}   {b:14.5f}   {a + b:.5f}"
              f"   {(a + b) / first:6.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
