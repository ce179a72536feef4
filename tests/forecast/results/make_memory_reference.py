"""Record the memory forecast of a small synthetic voyage (tests/forecast/test_memory_speed.py).

Run from the repository root, with the code whose results are the reference:
``python tests/forecast/results/make_memory_reference.py``. The reference in
memory_reference.csv was first written by the memory path before it was vectorised (commit
301f99c), so the test checks that the speed-up did not change the results; it was
re-recorded when the method changed on purpose (issue 11: a run of large innovations must
reach a block that shares no data with its first before it counts as a model error; then
the model-error variance floored by the out-of-sample residuals, noise.model_error_floor,
and model variance added where the innovations are inconsistent, innovation_consistency;
issue 27: the identification error capped by noise.identification_error_bound, and the
estimate weighed against a model-free filter, model_trust, whose weight is the new
model_probability column; then the model-free filter under the blend's persistence rule and a
prior probability of 0.2 that the model explains a mode before it has predicted unseen blocks;
then the innovation-consistency tests with their own clip, 1.5, and the inverted variance factor:
kalman_frequency_hz moved by at most 0.019 Hz, and the forecast's cumulative error against the
case's true frequencies went from +69.9 % to +69.3 % better than SSI; then kalman_std_hz as
the posterior std of the whole blended estimate, var(δ + c) with the model term's variance,
issue 27d: only that column moved, new / old median 1.08, 0.92 .. 39; then the noise split
averaged over the grid points that fit as well as the best and the model switch at 0.02, issue
27m/27n: kalman_frequency_hz moved by at most 0.032 Hz, and the cumulative error against the
true frequencies went from +69.3 % to +65.1 % better than SSI; then the model variance
raised where the predictors leave the range the model's refit saw,
MemoryRefits.extrapolation_variance: kalman_frequency_hz moved by at most 0.024 Hz, and the
cumulative error went from +65.1 % to +65.8 % better than SSI; then the model-free filters'
hull-wide change test, model_trust.ModelTrust._change_step: on at blocks 90-103 (the first
switch from 5 to 13 kn, which the model, fitted at 5 kn, extrapolates for all three modes),
there kalman_frequency_hz moved by at most 0.035 Hz and model_probability is 0; the
cumulative error went from +65.8 % to +65.7 % better than SSI; then the band where a mode is
not measured widened by the prior on the predictors beyond the model's range,
MemoryRefits.extrapolation_prior: only kalman_std_hz moved, in 130 of the 2700 rows, all
without a measurement, new / old 1.00 .. 3.53).
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

COLUMNS = [
    "model_frequency_hz",
    "model_lower_hz",
    "model_upper_hz",
    "ssi_frequency_hz",
    "kalman_frequency_hz",
    "kalman_std_hz",
    "model_probability",
]


def case() -> tuple[pd.DataFrame, pd.DataFrame]:
    """Three modes, speed / temperatures / wind, 900 blocks (3 days of 5-minute blocks)."""
    rng = np.random.default_rng(11)
    n = 900
    block = np.arange(n)
    start = pd.Timestamp("2025-01-01T00:00:00Z") + pd.to_timedelta(block * 300, unit="s")
    speed = np.where((block // 90) % 2 == 0, 5.0, 13.0) + 3 * np.sin(block / 70.0)
    speed += rng.normal(0, 0.3, n)
    water = 12 + 2 * np.sin(block / 300.0) + rng.normal(0, 0.05, n)
    air = 15 + 4 * np.sin(block / 144.0) + rng.normal(0, 0.3, n)
    wind = 8 + 3 * np.cos(block / 50.0) + rng.normal(0, 0.5, n)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": air,
            "wind_speed_ms": wind,
        }
    )
    rows = []
    for mode, f0 in ((1, 2.1), (2, 4.7), (3, 7.9)):
        truth = f0 * (1 - 0.0015 * speed + 0.0004 * (water - 12) - 1e-5 * speed * wind)
        err = np.empty(n)
        err[0] = 0.0
        for k in range(1, n):
            err[k] = 0.6 * err[k - 1] + math.sqrt(1 - 0.36) * rng.normal(0, 0.003 * f0)
        z = truth + err
        z[rng.random(n) < 0.1] = np.nan
        keep = np.isfinite(z)
        rows.append(
            pd.DataFrame(
                {
                    "block": block[keep],
                    "block_start": start[keep],
                    "mode": mode,
                    "frequency_hz": z[keep],
                }
            )
        )
    return pd.concat(rows, ignore_index=True), predictors


def forecast() -> pd.DataFrame:
    from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast

    modal, predictors = case()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        table = sliding_forecast(modal, predictors, ForecastOptions(scheme=2, model="memory")).table
    return table[["block", "mode", "phase", *COLUMNS]].reset_index(drop=True)


if __name__ == "__main__":
    out = Path(__file__).with_name("memory_reference.csv")
    forecast().to_csv(out, index=False, float_format="%.17g")
    print(f"wrote {out}", file=sys.stderr)
