"""Benchmark: the monitor's hand-on step (alarm hook + daily key indicators) late in a
long expedition against its first day.

After each forecast/health update the monitor reads the alarm episodes and rewrites the
key indicators of the days with new blocks (:meth:`workbench.monitor.Monitor.hand_on`).
Its cost must not grow with the voyage (issue 29: constant cost per block). A state
folder is synthesised with 7 modes on a 5-min block grid (tracked and forecast tables as
the monitor writes them) for day 1 and for day N, and the step is timed after one new
block, repeatedly; printed: median and worst per step, and day N / day 1.

Run: ``python benchmarks/bench_shore.py --days 51 --repeats 20``
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from data_contracts import ALARMS, FORECAST, write_table
from data_contracts.parts import PartWriter
from workbench.blocks import BlockGrid
from workbench.monitor import Monitor, MonitorOptions
from workbench.monitor.outlook import empty_table
from workbench.monitor.state_format import FORMAT_FILE, STATE_FORMAT

STEP_S = 300.0
MODES = 7


def _state(folder: Path, n_blocks: int, seed: int) -> tuple[BlockGrid, pd.DataFrame]:
    rng = np.random.default_rng(seed)
    grid = BlockGrid(pd.Timestamp("2026-03-01T00:00:00Z"), 1200.0, STEP_S)
    blocks = np.repeat(np.arange(n_blocks), MODES)
    modes = np.tile(np.arange(1, MODES + 1), n_blocks)
    start = grid.t0 + pd.to_timedelta(blocks * STEP_S, unit="s")
    frequency = 2.0 + modes + 0.01 * rng.standard_normal(blocks.size)
    tracked = pd.DataFrame(
        {
            "block": blocks,
            "block_start": start,
            "block_end": start + pd.Timedelta(seconds=1200),
            "mode": modes,
            "frequency_hz": frequency,
            "damping_ratio": 0.01 + 0.001 * rng.standard_normal(blocks.size) ** 2,
            "mac": 0.99,
        }
    )
    folder.mkdir(parents=True)
    # the state folder's layout (workbench.monitor.state_format): growing tables a day per part
    per_day = int(round(86400 / STEP_S))
    (folder / FORMAT_FILE).write_text(json.dumps({"schema": STATE_FORMAT}), encoding="utf-8")
    PartWriter(folder / "tracked.parquet", None, part_blocks=per_day).write(tracked)
    model = 2.0 + modes
    forecast = pd.DataFrame(
        {
            "block": blocks,
            "block_start": start,
            "mode": modes,
            "phase": "forecast",
            "ssi_frequency_hz": frequency,
            "model_frequency_hz": model,
            "model_lower_hz": model - 0.02,
            "model_upper_hz": model + 0.02,
            "kalman_frequency_hz": frequency,
            "kalman_std_hz": 0.005,
            "option": "A",
            "window_start_block": np.maximum(blocks - 20, 0),
            "window_end_block": np.maximum(blocks - 1, 0),
            "warning": "",
        }
    )
    PartWriter(folder / "forecast.parquet", FORECAST, part_blocks=per_day).write(forecast)
    write_table(empty_table(ALARMS), folder / "alarms.parquet", ALARMS)
    return grid, tracked


def time_step(n_blocks: int, repeats: int, root: Path) -> list[float]:
    state, watch = root / f"state-{n_blocks}", root / "watch"
    watch.mkdir(exist_ok=True)
    grid, tracked = _state(state, n_blocks, seed=n_blocks)
    seconds = []
    with Monitor(watch, state, options=MonitorOptions()) as monitor:
        monitor.voyage = SimpleNamespace(grid=grid)
        monitor._tracked = tracked  # as written by its last tracking step
        monitor.tracking.tracked_through = n_blocks - 1
        monitor.hand_on()  # after a restart: every day once
        for _ in range(repeats):
            monitor._indicators_through = n_blocks - 2  # one new block
            started = time.perf_counter()
            monitor.hand_on()
            seconds.append(time.perf_counter() - started)
        monitor.voyage = None  # nothing of a real voyage to close
    return seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=51.0, help="day N of the expedition")
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args(argv)
    per_day = int(round(86400 / STEP_S))
    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for label, n_blocks in (
            ("day 1", per_day),
            (f"day {args.days:g}", int(args.days * per_day)),
        ):
            seconds = time_step(n_blocks, args.repeats, Path(tmp))
            results[label] = seconds
            print(
                f"{label:>8} ({n_blocks:6d} blocks): median {1000 * statistics.median(seconds):7.1f} ms, "
                f"worst {1000 * max(seconds):7.1f} ms per hand-on step"
            )
        first, last = (statistics.median(v) for v in results.values())
        print(f"ratio day {args.days:g} / day 1: {last / first:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
