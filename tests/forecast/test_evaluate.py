"""Evaluation against ground truth and the 5-DOF chain (no regression needed)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from workbench.forecasting import evaluate_against_truth
from workbench.simulate.experiment import chain_natural_frequencies, simulate_temperature_experiment


def test_chain_frequencies_match_closed_form():
    # n equal masses and springs, fixed-free: ω_j = 2 sqrt(k/m) sin((2j-1)π / (2(2n+1)))
    n, m, k = 5, 1.0e6, 4.0e8
    j = np.arange(1, n + 1)
    expected = 2 * math.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1))) / (2 * np.pi)
    assert np.allclose(
        chain_natural_frequencies(np.full(n, m), np.full(n, k)), expected, rtol=1e-12
    )


def test_experiment_frequencies_scale_with_sqrt_modulus():
    data = simulate_temperature_experiment(seed=1, n_train=50, n_observations=10)
    truth = data.truth.pivot(index="block", columns="mode", values="frequency_hz").to_numpy()
    temperature = data.predictors["temperature_c"].to_numpy()
    ratio = np.sqrt(1 - 2.5e-4 * (temperature - 10.0))  # f ∝ sqrt(E), E = E0(1 + α(T - T0))
    assert np.allclose(truth / truth[[0]] * ratio[0], ratio[:, None], rtol=1e-12)


def test_evaluate_against_truth_hand_computed():
    forecast = pd.DataFrame(
        {
            "block": [0, 1, 2, 3],
            "mode": 1,
            "phase": ["train", "forecast", "forecast", "forecast"],
            "option": "A",
            "ssi_frequency_hz": [9.0, 2.2, np.nan, 1.6],
            "model_frequency_hz": [9.0, 2.1, 3.3, 1.9],
            "kalman_frequency_hz": [9.0, 2.05, 3.1, 2.1],
        }
    )
    truth = pd.DataFrame({"block": [0, 1, 2, 3], "mode": 1, "frequency_hz": [1.0, 2.0, 3.0, 2.0]})
    row = evaluate_against_truth(forecast, truth).iloc[0]
    assert row["n_blocks"] == 3 and row["n_ssi"] == 2
    assert row["ssi_cumulative_error_hz"] == pytest.approx(0.2 + 0.4)
    assert row["model_cumulative_error_hz"] == pytest.approx(0.1 + 0.1)
    assert row["kalman_cumulative_error_hz"] == pytest.approx(0.05 + 0.1)
    assert row["kalman_cumulative_error_all_hz"] == pytest.approx(0.05 + 0.1 + 0.1)
    assert row["improvement_vs_ssi_pct"] == pytest.approx(100 * (1 - 0.15 / 0.6))
    assert row["improvement_vs_model_pct"] == pytest.approx(100 * (1 - 0.15 / 0.2))
