"""Benchmark: the monitor's forecast/health update over a 51-day expedition, block level (issue 29).

The live monitor's background worker updates the forecast and the health chart after
every block (:func:`workbench.monitor.outlook.update_outlook`). This replays a whole
expedition at block level - tracked-modal rows and block predictors, not 2048-Hz files,
so that 14 700 blocks (51 days of 5-minute blocks) take minutes, not days:

1. a block-level voyage of ``--blocks`` blocks (``benchmarks/forecast_regimes.py``,
   ``--regime``, seed 0: the demo hull's modes following speed and temperatures, SSI-like
   correlated errors, missing estimates) is simulated (not timed);
2. the blocks are fed in order into a state folder the way the monitor's worker sees
   them: the tracked table's changed parts are written (``tracked.parquet/``, a parted
   table, :mod:`data_contracts.parts`: the parts from 3 blocks before the new ones, as
   the monitor writes them from its tracker's first changed block), then one update reads
   the tracked rows it needs (from ``inputs_from``) and the per-mode counts of the index,
   runs :class:`~workbench.monitor.incremental.IncrementalOutlook` with the block
   predictors it needs, writes the changed parts of ``forecast.parquet/`` and
   ``health.parquet/``, ``alarms.parquet`` and saves the state (``outlook/``), exactly the
   worker's update minus averaging the ship log (the predictors are given);
3. around day 1, 10, 25 and 51 every block is one update (``--sample`` consecutive
   blocks at the end of the day, the newest block's predictors provisional, the block
   before final); between them the blocks are fed a day at a time. Latency = wall time of
   one update, CPU = its process time; the parts (tracked table written, update, tables
   written, state saved) are timed separately;
4. before: the update as it was (``forecast_table`` + ``operational_health`` over the whole
   tables, what ``update_outlook`` recomputed at every block) at day 1 and day 10
   (``--before-days``);
5. at the end, the resumed tables are compared with the batch tables over the whole voyage
   (``--no-check`` skips the batch run, a minute or more).

Written to ``benchmarks/results/monitor_constant_cost.txt``. The machine is shared (2
cores, other sessions): compare the ratios of one run; the load average is printed.

Run: ``python benchmarks/bench_monitor_blocks.py --blocks 14700`` (``--blocks 2000`` for a
quick look).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

BLOCKS_PER_DAY = 288
STEP_S = 300.0


def _voyage(n_blocks: int, regime: str):
    from forecast_regimes import make_regime

    from data_contracts import MODAL, PREDICTORS

    data = make_regime(regime, 0, n_blocks=n_blocks, shapes=False)
    predictors = PREDICTORS.validate(data.predictors)
    tracked = data.tracked.merge(predictors[["block", "block_end"]], on="block")
    tracked = tracked.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)
    return MODAL.validate(tracked), predictors


class Replay:
    """The state folder and the worker's resumed outlook, fed block by block."""

    def __init__(self, state: Path, tracked: pd.DataFrame, predictors: pd.DataFrame):
        from workbench.monitor.incremental import IncrementalOutlook
        from workbench.monitor.outlook import ForecastSettings

        self.state = state
        self.tracked = tracked
        self.predictors = predictors
        self.settings = ForecastSettings()
        self.outlook = IncrementalOutlook(self.settings, STEP_S)
        self.tracked_blocks = tracked["block"].to_numpy()
        self.tracked_through: int | None = None
        self.full_updates = 0

    def update(self, last: int) -> dict[str, float]:
        """Blocks up to *last* landed: write the tracked table, then one worker update."""
        from data_contracts import ALARMS, FORECAST, HEALTH, MODAL, write_table
        from workbench.monitor.incremental import NeedsFullHistory
        from workbench.monitor.outlook import (
            empty_table,
            part_writer,
            read_tracked,
            tracked_summary,
        )

        times = {}
        wall, cpu = time.perf_counter(), time.process_time()
        stop = int(np.searchsorted(self.tracked_blocks, last, side="right"))
        # the monitor's write: the parts from the tracker's first changed block on (the
        # blocks new since the last write, and 3 before them: a late assignment)
        since = None if self.tracked_through is None else max(0, self.tracked_through - 3)
        part_start = 0 if since is None else since // BLOCKS_PER_DAY * BLOCKS_PER_DAY
        first = int(np.searchsorted(self.tracked_blocks, part_start))  # a part's rows whole
        tracked_path = self.state / "tracked.parquet"
        part_writer(tracked_path, MODAL, STEP_S).write(
            self.tracked.iloc[first:stop], since_block=since
        )
        self.tracked_through = last
        times["tracked_written_s"] = time.perf_counter() - wall
        started, cpu_update = time.perf_counter(), time.process_time()
        start = self.outlook.inputs_from
        summary = tracked_summary(tracked_path)
        tracked = read_tracked(tracked_path, since_block=start)
        part = self.predictors[self.predictors["block"] <= last]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                found = self.outlook.update(
                    tracked,
                    part if start is None else part[part["block"] >= start],
                    first_block=0,
                    final_through=last - 1,
                    mode_blocks=summary["mode_blocks"],
                    tracked_blocks=summary["blocks"],
                    tails=True,
                )
            except NeedsFullHistory:
                self.full_updates += 1
                found = self.outlook.update(
                    read_tracked(tracked_path),
                    part,
                    first_block=0,
                    final_through=last - 1,
                    tails=True,
                )
        times["update_s"] = time.perf_counter() - started
        written = time.perf_counter()
        health = found.health if found.health is not None else empty_table(HEALTH)
        alarms = found.alarms if found.alarms is not None else empty_table(ALARMS)
        part_writer(self.state / "forecast.parquet", FORECAST, STEP_S).write(
            found.forecast, since_block=found.forecast_from
        )
        part_writer(self.state / "health.parquet", HEALTH, STEP_S).write(
            health, since_block=found.health_from if found.health is not None else None
        )
        write_table(alarms, self.state / "alarms.parquet", ALARMS)
        times["tables_written_s"] = time.perf_counter() - written
        saved = time.perf_counter()
        self.outlook.save(self.state / "outlook")
        times["state_saved_s"] = time.perf_counter() - saved
        times["worker_s"] = time.perf_counter() - started
        times["worker_cpu_s"] = time.process_time() - cpu_update
        times["total_s"] = time.perf_counter() - wall
        times["total_cpu_s"] = time.process_time() - cpu
        self.found = found
        return times


def _tracking_costs(tracked: pd.DataFrame, days: list[int], sample: int) -> list[str]:
    """The monitor process's own per-block work (tracking the block, the tracked table
    rebuilt and written, the data-health table written) at the last blocks of *days*.

    The selected modes are the simulated tracked rows with cosine mode shapes on 8
    channels (1 % noise), so the tracker follows the same modes."""
    from data_contracts import MODAL, shapes_to_frame
    from workbench.monitor.data_health import data_health_frame
    from workbench.monitor.outlook import part_writer
    from workbench.monitor.tracking import IncrementalTracking
    from workbench.sid.tracking import TrackingOptions

    rng = np.random.default_rng(1)
    channels = [f"c{k:02d}" for k in range(8)]
    x = (np.arange(8) + 0.5) / 8
    shapes = np.array([np.cos(m * np.pi * x) for m in tracked["mode"].to_numpy()]).astype(complex)
    shapes += 0.01 * (rng.normal(size=shapes.shape) + 1j * rng.normal(size=shapes.shape))
    selected = pd.concat(
        [
            tracked[["block", "block_start", "block_end", "frequency_hz", "damping_ratio"]]
            .assign(model_order=40)
            .reset_index(drop=True),
            shapes_to_frame(channels, shapes),
        ],
        axis=1,
    )
    parts = dict(tuple(selected.groupby("block", sort=True)))
    ends = {min(d * BLOCKS_PER_DAY, int(tracked["block"].max()) + 1) - 1: d for d in days}
    timed: dict[int, list[tuple[float, float, float]]] = {d: [] for d in days}
    tracking = IncrementalTracking(TrackingOptions())
    rows: list[dict] = []
    root = Path(tempfile.mkdtemp(prefix="bench_tracking_"))
    health_since = None  # the data-health rows written up to this block
    try:
        done: set[int] = set()
        for block in range(int(tracked["block"].max()) + 1):
            day = next((d for end, d in ends.items() if end - sample < block <= end), None)
            started = time.perf_counter()
            if block in parts:
                tracking.add(block, parts[block])
            done.add(block)
            tracking.advance(done)
            advanced = time.perf_counter()
            rows.append(
                {
                    "block": block,
                    "block_start": pd.Timestamp("2026-01-01T00:00Z")
                    + pd.Timedelta(seconds=STEP_S * block),
                    "n_channels": 8,
                    "dropped_channels": "",
                    "gap_seconds": 0.0,
                    "last_file_landed": pd.Timestamp("2026-01-01T00:00Z"),
                    "identified_at": pd.Timestamp("2026-01-01T00:00Z"),
                    "latency_s": 1.0,
                    "status": "ok",
                    "reason": "",
                }
            )
            if day is None:
                continue
            table = tracking.table()
            # as the monitor writes them: the parts whose rows changed
            part_writer(root / "tracked.parquet", MODAL, STEP_S).write(
                table, since_block=tracking.changed_from
            )
            written = time.perf_counter()
            health_writer = part_writer(root / "data_health.parquet", None, STEP_S)
            blocks = health_writer.part_blocks
            first = 0 if health_since is None else health_since // blocks * blocks
            health_writer.write(
                data_health_frame([r for r in rows if r["block"] >= first]),
                since_block=health_since,
            )
            health_since = block + 1
            timed[day].append(
                (advanced - started, written - advanced, time.perf_counter() - written)
            )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    lines = [
        "monitor process per block (tracker fed, tracked table rebuilt + written, "
        "data_health written), median seconds over the day's last blocks:"
    ]
    for day in days:
        a, b, c = np.median(np.array(timed[day]), axis=0)
        lines.append(
            f"  day {day:3d}: tracker {a:.3f}, tracked table rebuilt + written {b:.3f}, "
            f"data_health written {c:.3f}, total {a + b + c:.3f}"
        )
    return lines


def _before(tracked, predictors, last: int) -> tuple[float, float]:
    """Wall and CPU seconds of the update as it was: both stages over the whole tables."""
    from workbench.monitor.outlook import ForecastSettings, forecast_table
    from workbench.monitor.structural_health import operational_health
    from workbench.predictors.tables import canonical_predictors

    settings = ForecastSettings()
    tracked = tracked[tracked["block"] <= last]
    predictors = predictors[predictors["block"] <= last]
    wall, cpu = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        forecast_table(tracked, canonical_predictors(predictors), settings)
        operational_health(tracked, predictors, settings, STEP_S)
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=14700)
    parser.add_argument("--regime", default="alternating_speed")
    parser.add_argument("--sample", type=int, default=24, help="per-block updates per day shown")
    parser.add_argument("--days", default="1,10,25,51", help="days whose last blocks are timed")
    parser.add_argument("--before-days", default="1,10", help="days the old update is timed at")
    parser.add_argument("--no-check", action="store_true", help="skip the batch comparison")
    parser.add_argument(
        "--tracking", action="store_true", help="also time the monitor process's own work"
    )
    parser.add_argument(
        "--tracking-only", action="store_true", help="time only the monitor process's work"
    )
    parser.add_argument("--out", type=Path, help="report file")
    args = parser.parse_args()
    out = args.out or Path(__file__).parent / "results" / "monitor_constant_cost.txt"

    made = time.perf_counter()
    tracked, predictors = _voyage(args.blocks, args.regime)
    lines = [
        f"monitor forecast/health update, block-level replay of {args.blocks} blocks "
        f"({args.blocks / BLOCKS_PER_DAY:.1f} days of 5-min blocks), regime {args.regime} "
        f"seed 0, {tracked['mode'].nunique()} tracked modes, {len(tracked)} tracked rows "
        f"(simulated in {time.perf_counter() - made:.0f} s, not timed)",
        "settings: the monitor's defaults (memory model, rolling, option A, operational "
        "health model 12 h + 6 h reference, CUSUM)",
    ]
    days = [int(d) for d in args.days.split(",")]
    if args.tracking or args.tracking_only:
        lines += _tracking_costs(tracked, days, args.sample)
        print("\n".join(lines), flush=True)
        if args.tracking_only:
            out.write_text("\n".join(lines) + "\n", encoding="utf-8")
            return
    ends = {d: min(d * BLOCKS_PER_DAY, args.blocks) - 1 for d in days}
    root = Path(tempfile.mkdtemp(prefix="bench_monitor_blocks_"))
    try:
        replay = Replay(root, tracked, predictors)
        sampled: dict[int, list[dict]] = {d: [] for d in days}
        fed = 24  # the first update: the forecast's first window needs 21 blocks
        cpu_all, wall_all = time.process_time(), time.perf_counter()
        updates = 0
        for day in days:
            end = ends[day]
            first_sampled = max(fed, end - args.sample + 1)
            while fed < first_sampled:  # a day at a time up to the sampled blocks
                fed = min(fed + BLOCKS_PER_DAY, first_sampled)
                replay.update(fed - 1)
                updates += 1
            for last in range(fed, end + 1):
                sampled[day].append(replay.update(last))
                updates += 1
            fed = end + 1
            median = np.median([t["total_s"] for t in sampled[day]])
            print(f"day {day}: {len(sampled[day])} updates, median {median:.3f} s", flush=True)
        wall_all = time.perf_counter() - wall_all
        cpu_all = time.process_time() - cpu_all
        lines.append(
            f"replay: {updates} updates in {wall_all:.0f} s (CPU {cpu_all:.0f} s), "
            f"{replay.full_updates} update(s) from the first block, forecast rollbacks "
            f"{replay.outlook.forecast.rollbacks}, restarts {replay.outlook.restarts}"
        )
        lines.append("")
        lines.append(
            "after (resumed), one update per block over the day's last blocks, median "
            "[worst] seconds:"
        )
        header = (
            "  day  block  updates  latency   [worst]   CPU     tracked written  update   "
            "tables written  state saved"
        )
        lines.append(header)
        medians = {}
        for day in days:
            frame = pd.DataFrame(sampled[day])
            med = frame.median()
            medians[day] = med
            lines.append(
                f"  {day:3d}  {ends[day]:5d}  {len(frame):7d}  {med['total_s']:7.3f}  "
                f"[{frame['total_s'].max():6.3f}]  {med['total_cpu_s']:6.3f}  "
                f"{med['tracked_written_s']:15.3f}  {med['update_s']:6.3f}  "
                f"{med['tables_written_s']:14.3f}  {med['state_saved_s']:11.3f}"
            )
        first, last_day = days[0], days[-1]
        ratio = medians[last_day]["total_s"] / medians[first]["total_s"]
        lines.append(
            f"latency day {last_day} / day {first}: {ratio:.2f} (target <= 1.5), day "
            f"{last_day} {medians[last_day]['total_s']:.3f} s (target < 5 s); CPU per "
            f"update day {first} {medians[first]['total_cpu_s']:.3f} s, day {last_day} "
            f"{medians[last_day]['total_cpu_s']:.3f} s"
        )
        lines.append("")
        lines.append("before (forecast + health recomputed over the whole tables at every update):")
        for day in [int(d) for d in args.before_days.split(",") if d]:
            end = min(day * BLOCKS_PER_DAY, args.blocks) - 1
            wall, cpu = _before(tracked, predictors, end)
            lines.append(
                f"  day {day:3d} (block {end}): {wall:.2f} s (CPU {cpu:.2f} s), "
                f"{1000 * cpu / (end + 1):.1f} ms CPU per block of history; after "
                f"{medians[day]['total_s']:.3f} s"
                if day in medians
                else ""
            )
            print(lines[-1], flush=True)
        if not args.no_check:
            from data_contracts import read_table

            wall = time.perf_counter()
            replay.update(args.blocks - 1)
            from workbench.monitor.outlook import ForecastSettings, forecast_table
            from workbench.monitor.structural_health import operational_health
            from workbench.predictors.tables import canonical_predictors

            settings = ForecastSettings()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                batch_forecast, _ = forecast_table(
                    tracked, canonical_predictors(predictors), settings
                )
                batch_health, batch_alarms, _ = operational_health(
                    tracked, predictors, settings, STEP_S
                )
            from data_contracts import ALARMS, FORECAST, HEALTH

            verdict = []
            for name, contract, batch in (
                ("forecast", FORECAST, batch_forecast),
                ("health", HEALTH, batch_health),
                ("alarms", ALARMS, batch_alarms),
            ):
                live = read_table(root / f"{name}.parquet", contract)
                try:
                    pd.testing.assert_frame_equal(
                        live.reset_index(drop=True),
                        contract.validate(batch).reset_index(drop=True),
                        rtol=1e-9,
                    )
                    verdict.append(f"{name} equal ({len(live)} rows)")
                except AssertionError as error:
                    verdict.append(f"{name} DIFFERENT: {str(error).splitlines()[0]}")
            lines.append("")
            lines.append(
                f"resumed tables vs the batch stages over all {args.blocks} blocks "
                f"(rtol 1e-9; batch {time.perf_counter() - wall:.0f} s): " + "; ".join(verdict)
            )
        lines.append(f"machine: 2 cores shared, load average at the end {os.getloadavg()}")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    text = "\n".join(line for line in lines if line is not None) + "\n"
    print(text)
    out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
