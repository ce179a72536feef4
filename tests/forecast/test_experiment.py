"""The 5-DOF temperature experiment, the evaluation and the forecast figure."""

from __future__ import annotations

import math

import matplotlib
import pytest

from workbench.forecasting import (
    run_temperature_experiment,
)

matplotlib.use("Agg")

#: Seeds pooled for the reference comparison (sum of cumulative errors over the seeds).
SEEDS = range(8)


def _pooled_improvement(trust):
    totals = {}
    for seed in SEEDS:
        result = run_temperature_experiment(seed=seed, trust=trust)
        for row in result.evaluation.itertuples():
            ssi, kalman = totals.get(row.mode, (0.0, 0.0))
            totals[row.mode] = (
                ssi + row.ssi_cumulative_error_hz,
                kalman + row.kalman_cumulative_error_hz,
            )
    return {mode: 100 * (1 - kalman / ssi) for mode, (ssi, kalman) in totals.items()}


@pytest.mark.filterwarnings("ignore::workbench.forecasting.ForecastWarning")
def test_reference_experiment_improvement_matches_or_beats_85_and_89_percent():
    # Reference: 85 % (mode 3) and 89 % (mode 4) lower cumulative absolute error of the
    # Kalman estimates than of the raw observations over 20 noisy observations per mode.
    # Here: model trained on one day of noisy observations (288 blocks), 20 forecast
    # blocks blended, data-driven Q/R (trust=None), errors pooled over 8 seeds. The
    # expected improvement is about 1 - sqrt(2/288)/0.8 ≈ 90 %; measured 93-95 %.
    improvement = _pooled_improvement(None)
    assert improvement[3] >= 85.0
    assert improvement[4] >= 89.0
    assert min(improvement.values()) >= 85.0


@pytest.mark.filterwarnings("ignore::workbench.forecasting.ForecastWarning")
def test_fixed_trust_is_bounded_by_the_white_noise_limit():
    # A fixed gain K on white noise keeps an error σ sqrt(K/(2-K)) even with a perfect
    # model: for K = 0.65 the expected improvement is at most 1 - sqrt(0.65/1.35) = 30.6 %.
    # 160 pooled observations per mode scatter the measured value by a few points
    # (observed 28-35 %); the data-driven setting of the test above does three times better.
    limit = 100 * (1 - math.sqrt(0.65 / 1.35))
    improvement = _pooled_improvement(0.65)
    for value in improvement.values():
        assert limit - 8.0 < value < limit + 6.0


@pytest.mark.filterwarnings("ignore::workbench.forecasting.ForecastWarning")
def test_forecast_figures_written_and_closed(tmp_path):
    import matplotlib.pyplot as plt

    from workbench.forecasting.plot import write_forecast_figures

    result = run_temperature_experiment(seed=0, n_train=40, n_observations=20, period_blocks=40)
    before = len(plt.get_fignums())
    paths = write_forecast_figures(result.forecast.table, tmp_path, truth_modal=result.data.truth)
    assert [p.name for p in paths] == [f"forecast_mode{m}.png" for m in range(1, 6)]
    for path in paths:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert path.stat().st_size > 10_000
    assert len(plt.get_fignums()) == before
