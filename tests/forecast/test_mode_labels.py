"""Mode labels are identifiers: any integer, 0 and negative included (issue 11, item 4)."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import FORECAST, MODAL, ContractError
from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast

START = pd.Timestamp("2024-03-01T00:00:00Z")


def _tables(labels):
    rng = np.random.default_rng(3)
    block = np.arange(40)
    start = START + pd.to_timedelta(block * 300, unit="s")
    predictors = pd.DataFrame(
        {"block": block, "block_start": start, "speed_kn": 10 + rng.normal(0, 1, block.size)}
    )
    rows = [
        {
            "block": b,
            "block_start": start[b],
            "block_end": start[b] + pd.Timedelta(minutes=20),
            "mode": label,
            "frequency_hz": base + rng.normal(0, 0.005),
            "damping_ratio": 0.01,
        }
        for b in block
        for label, base in zip(labels, (3.0, 5.0), strict=True)
    ]
    return pd.DataFrame(rows), predictors


@pytest.mark.parametrize("labels", [(0, 1), (-3, 0), (7, 12)])
def test_any_integer_label_is_accepted_and_kept(labels):
    modal, predictors = _tables(labels)
    MODAL.validate(modal)  # used to refuse 0 ("values outside [1, None]")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        table = sliding_forecast(
            modal, predictors, ForecastOptions(horizon=10, model="window", scheme=1)
        ).table
    FORECAST.validate(table)
    assert sorted(table["mode"].unique()) == sorted(labels)
    # each label's forecast follows its own mode (3 Hz and 5 Hz), not a renumbered one
    level = table.groupby("mode")["kalman_frequency_hz"].mean()
    assert abs(level[labels[0]] - 3.0) < 0.05
    assert abs(level[labels[1]] - 5.0) < 0.05


def test_non_integer_label_is_still_refused():
    modal, _ = _tables((0, 1))
    modal["mode"] = modal["mode"] + 0.5
    with pytest.raises(ContractError) as error:
        MODAL.validate(modal)
    assert "mode" in str(error.value)
