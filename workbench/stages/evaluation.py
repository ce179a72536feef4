"""Evaluate stage: SSI-only, model-only and Kalman estimates against the true frequencies."""

from __future__ import annotations

import os

import pandas as pd

from data_contracts import FORECAST, MODAL

from ..forecasting.evaluate import EvaluateResult, evaluate_forecast
from ..results import read_any_table

__all__ = ["EvaluateResult", "evaluate"]


def evaluate(
    forecast: pd.DataFrame | str | os.PathLike,
    truth: pd.DataFrame | str | os.PathLike,
    *,
    phase: str | None = "forecast",
) -> EvaluateResult:
    """Compare SSI-only, model-only and Kalman estimates with the true frequencies
    (:func:`~workbench.forecasting.evaluate.evaluate_forecast` of the tables read).

    Parameters
    ----------
    forecast : DataFrame or path
        Forecast table (FORECAST contract).
    truth : DataFrame or path
        True modal table (MODAL contract), e.g. of a simulated voyage.
    phase : {"forecast", "train", None}
        Rows compared: forecast blocks, training blocks, or all (None).
    """
    forecast = read_any_table(forecast, FORECAST, name="forecast")
    truth = read_any_table(truth, MODAL, name="truth")
    return evaluate_forecast(forecast, truth, phase=phase)
