"""Temperature experiment (workbench.forecasting.run_temperature_experiment): Kalman vs raw
observations, cumulative error pooled over 8 seeds, window and memory model.

Run: python benchmarks/bench_temperature_experiment.py (results:
benchmarks/results/temperature_experiment.txt).
"""

import warnings

from workbench.forecasting import run_temperature_experiment

for model in ("window", "memory"):
    totals = {}
    for seed in range(8):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = run_temperature_experiment(seed=seed, model=model)
        for row in result.evaluation.itertuples():
            ssi, kalman = totals.get(row.mode, (0.0, 0.0))
            totals[row.mode] = (
                ssi + row.ssi_cumulative_error_hz,
                kalman + row.kalman_cumulative_error_hz,
            )
    pooled = {m: 100 * (1 - k / s) for m, (s, k) in sorted(totals.items())}
    print(model, " ".join(f"mode {m}: {v:.1f} %" for m, v in pooled.items()))
