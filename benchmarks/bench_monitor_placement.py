"""The monitor's cost of taking one newly landed file, against the voyage's length.

Each landed file is placed among the files taken before it (clock jitter and drift,
:func:`~workbench.signals.block_plan.place_files`) and the placed headers are what the
blocks are cut from (``Monitor._placed``). This replays the headers of a voyage of 5-min
files at 2048 Hz whose sample clock runs 20 ppm fast with a +-5 ms stamp jitter (no file
is read) through the monitor's own placement steps and prints the median time of taking
one file at several voyage lengths, and its ratio to the first day's. A cost that grows
with the voyage makes a monitor restarted on a long expedition's folder (every file taken
again) quadratic in its files.

Run: ``python benchmarks/bench_monitor_placement.py [--days 1,10,25,51]``; results in
``benchmarks/results/monitor_placement_50.txt``.
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

from bench_clock_drift import _headers  # noqa: E402

from workbench.monitor.core import Monitor  # noqa: E402
from workbench.monitor.watcher import LandedFile  # noqa: E402

FILES_PER_DAY = 288
SAMPLE = 25  # files timed at each day mark


def _monitor() -> Monitor:
    monitor = Monitor.__new__(Monitor)  # only what the placement steps use
    monitor.files = []
    monitor._placed_files = ((), [], None)
    monitor.voyage = SimpleNamespace(rate_hz=2048.0)
    return monitor


def _take(monitor: Monitor, item: LandedFile) -> None:
    """What ``Monitor._take`` does to place a file and keep it."""
    if hasattr(monitor, "_placed_among") and callable(getattr(Monitor, "_placed_among", None)):
        reason, _ = monitor._placed_among(item.info)
    else:  # a tree with the module-level function only
        from workbench.monitor.core import _placed_among

        reason, _ = _placed_among(item.info, [f.info for f in monitor.files])
    assert not reason, reason
    monitor.files.append(item)
    monitor.files.sort(key=lambda f: (f.info.start_time, str(f.path)))
    monitor._placed()


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
    seconds: dict[int, list[float]] = {}
    started = time.perf_counter()
    for k, item in enumerate(items):
        day = next((d for m, d in marks.items() if m <= k < m + SAMPLE), None)
        t = time.perf_counter()
        _take(monitor, item)
        if day is not None:
            seconds.setdefault(day, []).append(time.perf_counter() - t)
    total = time.perf_counter() - started
    first = np.median(seconds[days[0]])
    print(f"{n} files taken in {total:.1f} s (20 ppm, +-5 ms jitter)")
    print("  day   files taken   median s per file   ratio to day " + str(days[0]))
    for d in days:
        med = float(np.median(seconds[d]))
        print(f"  {d:3d}   {d * FILES_PER_DAY:11d}   {med:17.5f}   {med / first:6.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
