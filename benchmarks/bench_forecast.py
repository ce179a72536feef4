"""Benchmark: sliding forecast of a 51-day voyage (about 15 000 blocks, 7 modes).

Target (issue 6): under 60 s on 2 cores for method 2 (predict 4 blocks, Kalman-filter,
slide, refit on a 20-block window) with option A. The voyage's tracked modal table and block
predictors come from the demo simulator (``--data DIR`` reuses a simulated voyage; without
it one is simulated first, which takes about 1.5 minutes and 6 GB of memory and is not
timed). Printed: wall time with modes spread over 1 and over 2 processes (median of
``--repeats`` runs each), the speed-up, and the ratio of the 2-process time to the 60 s
target. The two runs must give identical tables. ``--model memory`` times the model with
memory (``model="memory"``) instead of the reference window model; ``--model window memory``
times both back to back in the same run and prints the ratio.

Run: ``python benchmarks/bench_forecast.py --data /tmp/voy51 --model window memory``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from data_contracts import MODAL, PREDICTORS, read_table
from workbench.forecasting import ForecastOptions
from workbench.stages import forecast_modes

TARGET_S = 60.0


def _load(data: Path | None, days: float):
    if data is None or not (data / "tracked_modal.csv").is_file():
        from workbench.simulate import simulate_voyage

        data = data or Path(tempfile.mkdtemp(prefix="bench_forecast_"))
        print(f"simulating a {days:g}-day voyage into {data} (not timed) ...", flush=True)
        simulate_voyage(data, seed=0, hours=24 * days, accelerations=False)
    modal = read_table(data / "tracked_modal.csv", MODAL)
    predictors = read_table(data / "truth_predictors.csv", PREDICTORS)
    return modal, predictors[
        [
            "block",
            "block_start",
            "block_end",
            "speed_kn",
            "water_temp_c",
            "air_temp_c",
            "wind_speed_ms",
            "wind_dir_rel_deg",
        ]
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, help="folder of a simulated voyage")
    parser.add_argument("--days", type=float, default=51.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--model",
        nargs="+",
        choices=("window", "memory"),
        default=["window"],
        help="predictive model(s) to time; several: back to back in the same run",
    )
    args = parser.parse_args(argv)
    models = list(dict.fromkeys(args.model))
    modal, predictors = _load(args.data, args.days)
    n_blocks, n_modes = predictors["block"].nunique(), modal["mode"].nunique()
    print(f"{n_blocks} blocks, {n_modes} modes, method 2, option A, train 20, horizon 4")
    times = {(m, jobs): [] for m in models for jobs in (1, 2)}
    tables: dict[tuple[str, int], pd.DataFrame] = {}
    for _ in range(args.repeats):
        for name in models:
            for jobs in (1, 2):
                start = time.perf_counter()
                table = forecast_modes(
                    modal,
                    predictors,
                    ForecastOptions(
                        options=("A",),
                        scheme=2,
                        train_blocks=20,
                        horizon=4,
                        trust=None,
                        model=name,
                        n_workers=jobs,
                    ),
                ).table
                times[name, jobs].append(time.perf_counter() - start)
                tables[name, jobs] = table
    status = 0
    for name in models:
        one = statistics.median(times[name, 1])
        two = statistics.median(times[name, 2])
        print(f"model={name}")
        print(f"  1 process : {one:7.1f} s (median of {args.repeats})")
        print(f"  2 processes: {two:7.1f} s (median of {args.repeats}); speed-up {one / two:.2f}x")
        print(
            f"  2 processes / 60 s target = {two / TARGET_S:.2f} "
            f"({'meets' if two < TARGET_S else 'MISSES'} the target)"
        )
        pd.testing.assert_frame_equal(tables[name, 1], tables[name, 2], check_exact=True)
        print("  tables of the 1- and 2-process runs are identical")
        status |= int(two >= TARGET_S)
    if len(models) > 1:
        base = statistics.median(times[models[0], 2])
        for name in models[1:]:
            ratio = statistics.median(times[name, 2]) / base
            print(f"2 processes, model={name} / model={models[0]}: {ratio:.2f}")
    return status


if __name__ == "__main__":
    sys.exit(main())
