"""Benchmark: a new voyage charted from its first block with a saved health baseline.

An earlier voyage of the ship (:func:`workbench.simulate.simulate_health_voyage`, seed 1)
gives the baseline: the operational model fitted on its first ``--train-hours`` and the
chart's reference on the next 6 h (:class:`workbench.shm.HealthBaseline`, written to
JSON and read back, as ``workbench health --save-model`` / ``--baseline`` do). New 12-h
voyages (seeds 2..) lose 2 % of mode 3's stiffness ``--damage-hours`` in; quiet 24-h
voyages with the same seeds count false alarms. Without a baseline the voyage's own
chart starts after 12 h + 6 h, so a loss before then is learned into the model.

Usage::

    python benchmarks/bench_health_baseline.py --earlier-hours 48 --train-hours 36
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

from workbench.shm import HealthBaseline, HealthOptions, fit_operational_model, health_chart
from workbench.simulate import detection_delay_hours, simulate_health_voyage


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--earlier-hours", type=float, default=48.0)
    parser.add_argument("--train-hours", type=float, default=36.0)
    parser.add_argument("--damage-hours", type=float, default=6.0)
    parser.add_argument("--seeds", type=int, default=8)
    args = parser.parse_args(argv)
    earlier = simulate_health_voyage(args.earlier_hours, seed=1)
    train, reference = int(round(args.train_hours * 12)), 72
    model = fit_operational_model(earlier.modal, earlier.predictors, train_blocks=train)
    forecast = model.forecast(
        earlier.modal, earlier.predictors, reference_start_block=train, reference_blocks=72
    )
    chart = health_chart(
        forecast, HealthOptions(reference_blocks=reference, reference_start_block=train)
    )
    saved = HealthBaseline.from_chart(earlier.modal, earlier.predictors, model, chart, step_s=300)
    with tempfile.TemporaryDirectory() as folder:
        baseline = HealthBaseline.load(saved.save(Path(folder) / "baseline.json"))
    print(
        f"baseline: {args.earlier_hours:g}-h voyage (seed 1), model on {args.train_hours:g} h, "
        f"reference 6 h; 2 % stiffness loss of mode 3 at {args.damage_hours:g} h"
    )
    delays, false_alarms = [], []
    for seed in range(2, 2 + args.seeds):
        damaged = simulate_health_voyage(
            12, seed=seed, damaged_mode=3, stiffness_loss=0.02,
            damage_after_hours=args.damage_hours,
        )  # fmt: skip
        result = baseline.chart(baseline.forecast(damaged.modal, damaged.predictors))
        first = int(result.table["block"].min())
        delay = detection_delay_hours(damaged, result.table)
        before = result.table["alarm"] & (result.table["block_start"] < damaged.damage_time)
        quiet = simulate_health_voyage(24, seed=seed)
        episodes = len(baseline.chart(baseline.forecast(quiet.modal, quiet.predictors)).alarms)
        delays.append(delay)
        false_alarms.append(episodes)
        print(
            f"seed {seed}: first block charted {first}, delay {delay:.2f} h, alarms before "
            f"the loss {int(before.sum())}, false alarm episodes in a quiet day {episodes}"
        )
    finite = [d for d in delays if math.isfinite(d)]
    print(
        f"found {len(finite)} of {len(delays)}; delay median {np.median(delays):.2f} h, "
        f"worst {max(delays):.2f} h; false alarms {sum(false_alarms)} in {len(delays)} days"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
