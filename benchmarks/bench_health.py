"""Benchmark: detection delay and false alarms of the structural-health chart.

Block-level voyages from :func:`workbench.health.simulate_health_voyage` (the demo hull's
modal law driven by the demo operating profile, identification errors correlated as
75 %-overlapping blocks give, 10 % missing estimates, 0.5 % wrong poles). Timeline: the
forecast model trains on the first ``--train-hours`` (36 h, three 12-h operating cycles),
the chart's reference period is the next ``--reference-hours`` (12 h, one full cycle),
then 24 h are monitored. Damage: a step stiffness loss on one mode 12 h into the
monitoring (frequency x sqrt(1 - loss)).

Two operational/environmental models feed the chart:

* ``law``: the hull's own law at the logged predictors (the best any model can do);
* ``stepwise``: the real :func:`workbench.forecast.sliding_forecast`, method 1, trained
  once on the training period (a frozen model).

Printed per model and scenario over ``--seeds`` seeds: alarm episodes per day in the 24 h
without damage (all of them, and before the onset in damaged runs), and the detection
delay (onset to the end of the first alarming block after the onset; "miss" when none)
as median and worst, with the share of seeds already alarming at the onset.

Run: ``python benchmarks/bench_health.py --seeds 10``
"""

from __future__ import annotations

import argparse
import math
import statistics

import numpy as np
import pandas as pd

from workbench.health import (
    HealthOptions,
    detection_delay_hours,
    frozen_forecast,
    health_chart,
    law_forecast,
    simulate_health_voyage,
)


def _episodes_per_day(health: pd.DataFrame, until: pd.Timestamp | None) -> float:
    monitor = health[health["phase"] == "monitor"]
    if until is not None:
        monitor = monitor[monitor["block_start"] + pd.Timedelta(minutes=20) <= until]
    alarm = monitor["alarm"].to_numpy(dtype=bool)
    starts = int(np.count_nonzero(alarm[1:] & ~alarm[:-1]) + (alarm[:1].sum()))
    return starts / (len(monitor) / 288.0) if len(monitor) else math.nan


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--train-hours", type=float, default=36.0)
    parser.add_argument("--reference-hours", type=float, default=12.0)
    parser.add_argument("--mode", type=int, default=3, help="damaged mode (1-7)")
    parser.add_argument("--losses", type=float, nargs="+", default=[0.01, 0.02])
    parser.add_argument("--ewma-lambda", type=float, default=0.1)
    parser.add_argument("--false-alarms-per-day", type=float, default=0.1)
    args = parser.parse_args(argv)

    train = int(round(args.train_hours * 12))
    reference = int(round(args.reference_hours * 12))
    hours = args.train_hours + args.reference_hours + 24.0
    onset = args.train_hours + args.reference_hours + 12.0
    options = HealthOptions(
        reference_blocks=reference,
        reference_start_block=train,
        ewma_lambda=args.ewma_lambda,
        false_alarms_per_day=args.false_alarms_per_day,
    )
    models = {"law": law_forecast, "stepwise": lambda v: frozen_forecast(v, train)}
    print(
        f"{args.seeds} seeds; train {args.train_hours:g} h, reference {args.reference_hours:g} h, "
        f"monitor 24 h; damage on mode {args.mode} at +12 h; lambda {args.ewma_lambda:g}, "
        f"target {args.false_alarms_per_day:g} false alarms/day"
    )
    header = (
        f"{'model':9s} {'stiffness loss':>14s} {'false alarms/day':>17s} "
        f"{'delay median [h]':>17s} {'delay worst [h]':>16s} {'missed':>7s} {'alarming at onset':>18s}"
    )
    print(header)
    print("-" * len(header))
    for name, make in models.items():
        for loss in [0.0, *args.losses]:
            rates, delays, at_onset = [], [], 0
            for seed in range(args.seeds):
                voyage = simulate_health_voyage(
                    hours,
                    seed=seed,
                    damaged_mode=args.mode if loss > 0 else None,
                    stiffness_loss=loss,
                    damage_after_hours=onset if loss > 0 else None,
                )
                result = health_chart(make(voyage), options)
                table = result.table
                until = voyage.damage_time
                rates.append(_episodes_per_day(table, until))
                if loss > 0:
                    delay = detection_delay_hours(voyage, table)
                    delays.append(delay)
                    ends = table["block_start"] + pd.Timedelta(minutes=20)
                    before = table[ends <= until]
                    at_onset += bool(len(before) and before["alarm"].iloc[-1])
            rate = f"{statistics.mean(rates):.2f} (max {max(rates):.1f})"
            if loss > 0:
                found = [d for d in delays if math.isfinite(d)]
                median = f"{statistics.median(delays):.2f}" if found else "miss"
                worst = f"{max(delays):.2f}" if all(map(math.isfinite, delays)) else "miss"
                missed = f"{len(delays) - len(found)}/{len(delays)}"
                onset_share = f"{at_onset}/{len(delays)}"
            else:
                median = worst = missed = onset_share = "-"
            print(
                f"{name:9s} {100 * loss:13.1f}% {rate:>17s} {median:>17s} {worst:>16s} "
                f"{missed:>7s} {onset_share:>18s}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
