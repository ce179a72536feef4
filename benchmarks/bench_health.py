"""Benchmark: detection delay and false alarms of the structural-health chart.

Block-level voyages from :func:`workbench.simulate.simulate_health_voyage` (the demo hull's
modal law driven by the demo operating profile, identification errors correlated as
75 %-overlapping blocks give, 10 % missing estimates, 0.5 % wrong poles). Timeline: the
operational model trains on the first ``--train-hours``, the chart's reference period is
the next ``--reference-hours``, then 24 h are monitored. Scenarios:

* ``none``: no damage;
* ``regime``: no damage; 4 h into the monitoring the ship leaves its operating cycle for a
  transit into colder water (12 kn, water to -1.7 °C, air 10 °C colder: all outside the
  training range), the main false-alarm risk in practice;
* ``<loss>@<mode>`` (e.g. ``0.02@3``): a step stiffness loss on one mode 12 h into the
  monitoring (frequency x sqrt(1 - loss)); ``<loss>@<mode>/<ramp>h`` (``0.02@3/12h``):
  the loss grows linearly over the ramp from that time on.

Operational/environmental models feeding the chart:

* ``law``: the hull's own law at the logged predictors (the best any model can do);
* ``stepwise``: the project's :func:`workbench.forecasting.sliding_forecast`, method 1,
  trained once on the training period (elapsed hours as the fuel proxy);
* ``ols``: :func:`workbench.shm.fit_operational_model` on the training period (speed,
  speed², temperatures, speed x water, logged fuel used), with its parameter uncertainty
  relative to the reference period (``model_shift_std``);
* ``ols-time``: the same with elapsed hours instead of the logged fuel on board;
* ``ols-baseline``: the same without any fuel term, the chart's baseline following slow
  drifts (``--baseline-hours``, :attr:`HealthOptions.baseline_hours`).

Chart settings: ``after`` (the current :class:`~workbench.shm.HealthOptions` defaults)
or ``before`` (the previous defaults: upcrossing-calibrated limit, full covariance,
4-block bootstrap, no model uncertainty, two-sided EWMA).

Printed per model and scenario over ``--seeds`` seeds: alarm episodes per day in the
monitored hours before any damage (mean, max), seeds without any false alarm, and the
detection delay (onset to the end of the first alarming block after it; "miss" when
none) as median and worst. Last, per model, the share of monitored days without damage
(scenarios ``none`` and ``regime``) with a false alarm, beside the limit's design
1 - exp(-rate) (a day passes without one with probability exp(-rate)).

Run: ``python benchmarks/bench_health.py --seeds 10`` (results: benchmarks/results/health.txt)
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import warnings

import numpy as np
import pandas as pd

from workbench.shm import (
    DEFAULT_TERMS,
    HealthOptions,
    fit_operational_model,
    frozen_forecast,
    health_chart,
)
from workbench.simulate import detection_delay_hours, law_forecast, simulate_health_voyage

#: The chart settings before this benchmark's second round (kept to measure against).
BEFORE = {
    "limit_method": "upcrossings",
    "covariance": "full",
    "bootstrap_block_length": 4,
    "model_uncertainty": False,
    "decrease_only": False,
    "statistic": "mewma",
}


def _episodes_per_day(health: pd.DataFrame, until: pd.Timestamp | None) -> float:
    monitor = health[health["phase"] == "monitor"]
    if until is not None:
        monitor = monitor[monitor["block_start"] + pd.Timedelta(minutes=20) <= until]
    alarm = monitor["alarm"].to_numpy(dtype=bool)
    starts = int(np.count_nonzero(alarm[1:] & ~alarm[:-1]) + (alarm[:1].sum()))
    return starts / (len(monitor) / 288.0) if len(monitor) else math.nan


def _forecast(name: str, voyage, train: int, reference: int) -> pd.DataFrame:
    if name == "law":
        return law_forecast(voyage)
    if name == "stepwise":
        return frozen_forecast(voyage, train)
    predictors = voyage.predictors
    terms = None  # the default terms over the columns present
    if name in ("ols-time", "ols-baseline"):
        predictors = predictors.drop(columns="fuel_on_board_t")  # a log without soundings
    if name == "ols-time":
        terms = [*DEFAULT_TERMS[:-1], "elapsed_hours"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_operational_model(voyage.modal, predictors, train_blocks=train, terms=terms)
    return model.forecast(
        voyage.modal, predictors, reference_start_block=train, reference_blocks=reference
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--train-hours", type=float, default=72.0)
    parser.add_argument("--reference-hours", type=float, default=24.0)
    parser.add_argument(
        "--models",
        nargs="+",
        default=["ols"],
        choices=["law", "stepwise", "ols", "ols-time", "ols-baseline"],
    )
    parser.add_argument(
        "--scenarios",
        nargs="+",
        default=["none", "regime", "0.01@3", "0.02@3", "0.02@1", "0.02@6"],
        help="none, regime, or LOSS@MODE",
    )
    parser.add_argument("--chart", choices=["after", "before"], default="after")
    parser.add_argument("--ewma-lambda", type=float, default=HealthOptions.ewma_lambda)
    parser.add_argument(
        "--false-alarms-per-day", type=float, default=HealthOptions.false_alarms_per_day
    )
    parser.add_argument("--statistic", choices=["cusum", "mewma"], default=HealthOptions.statistic)
    parser.add_argument("--detect-shift", type=float, default=HealthOptions.detect_shift)
    parser.add_argument("--model-error-sigma", type=float, default=HealthOptions.model_error_sigma)
    parser.add_argument(
        "--baseline-hours",
        type=float,
        default=24.0,
        help="time constant of the following baseline of the ols-baseline model [h]",
    )
    parser.add_argument("--per-seed", action="store_true", help="also print each seed's numbers")
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
        statistic=args.statistic,
        detect_shift=args.detect_shift,
        model_error_sigma=args.model_error_sigma,
    )
    if args.chart == "before":
        options = dataclasses.replace(options, **BEFORE)
    print(
        f"{args.seeds} seeds from {args.first_seed}; train {args.train_hours:g} h, reference "
        f"{args.reference_hours:g} h, monitor 24 h; damage at +12 h, regime change at +4 h; "
        f"chart '{args.chart}': lambda {options.ewma_lambda:g}, target "
        f"{options.false_alarms_per_day:g} false alarms/day, statistic {options.statistic}"
        + (
            f" (detect shift {options.detect_shift:g}, model error sigma "
            f"{options.model_error_sigma:g}, ols-baseline {args.baseline_hours:g} h)"
            if options.statistic == "cusum"
            else f" (limit {options.limit_method}, covariance {options.covariance}, "
            f"bootstrap blocks {options.bootstrap_block_length}, model uncertainty "
            f"{options.model_uncertainty}, decrease only {options.decrease_only})"
        )
    )
    header = (
        f"{'model':9s} {'scenario':>9s} {'false alarms/day':>17s} {'no false alarm':>15s} "
        f"{'delay median [h]':>17s} {'delay worst [h]':>16s} {'missed':>7s}"
    )
    print(header)
    print("-" * len(header))
    in_control: dict[str, list[float]] = {}  # model: false alarms/day of undamaged voyages
    for name in args.models:
        for scenario in args.scenarios:
            loss, mode, regime, ramp = 0.0, None, None, 0.0
            if scenario == "regime":
                regime = args.train_hours + args.reference_hours + 4.0
            elif scenario != "none":
                text_loss, text_mode = scenario.split("@")
                if "/" in text_mode:  # LOSS@MODE/RAMPh: a loss growing over RAMP hours
                    text_mode, text_ramp = text_mode.split("/")
                    ramp = float(text_ramp.rstrip("h"))
                loss, mode = float(text_loss), int(text_mode)
            rates, delays = [], []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                voyage = simulate_health_voyage(
                    hours,
                    seed=seed,
                    damaged_mode=mode,
                    stiffness_loss=loss,
                    damage_after_hours=onset if mode else None,
                    regime_change_after_hours=regime,
                    damage_ramp_hours=ramp,
                )
                chart_options = options
                if name == "ols-baseline":
                    chart_options = dataclasses.replace(options, baseline_hours=args.baseline_hours)
                forecast = _forecast(name, voyage, train, reference)
                table = health_chart(forecast, chart_options).table
                rates.append(_episodes_per_day(table, voyage.damage_time))
                if not mode:
                    in_control.setdefault(name, []).append(rates[-1])
                if mode:
                    delays.append(detection_delay_hours(voyage, table))
            rate = f"{statistics.mean(rates):.2f} (max {max(rates):.1f})"
            clean = f"{sum(r == 0 for r in rates)}/{len(rates)}"
            if mode:
                found = [d for d in delays if math.isfinite(d)]
                median = f"{statistics.median(delays):.2f}" if found else "miss"
                if median == "inf":
                    median = "miss"
                worst = f"{max(delays):.2f}" if len(found) == len(delays) else "miss"
                missed = f"{len(delays) - len(found)}/{len(delays)}"
            else:
                median = worst = missed = "-"
            print(
                f"{name:9s} {scenario:>9s} {rate:>17s} {clean:>15s} {median:>17s} "
                f"{worst:>16s} {missed:>7s}",
                flush=True,
            )
            if args.per_seed:
                shown = delays if mode else rates
                what = "delays [h]" if mode else "false alarms/day"
                print(f"{'':19s} per seed {what}: " + " ".join(f"{v:.2f}" for v in shown))
    # the limit's design: a day passes without a false alarm with probability exp(-rate)
    design = 1.0 - math.exp(-options.false_alarms_per_day)
    for name, rates in in_control.items():
        days = sum(r > 0 for r in rates)
        print(
            f"{name}: a false alarm on {days} of {len(rates)} monitored days without damage "
            f"({days / len(rates):.1%}; design {design:.1%})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
