"""Health stage: control chart (per-mode CUSUM or MEWMA) of a forecast's frequency
residuals."""

from __future__ import annotations

import math
import os
from dataclasses import replace

import pandas as pd

from data_contracts import FORECAST

from ..results import read_any_table
from ..shm import HealthBaseline, HealthOptions, HealthResult, health_chart

__all__ = ["HealthOptions", "HealthResult", "health"]


def health(
    forecast: pd.DataFrame | str | os.PathLike,
    *,
    options: HealthOptions | None = None,
    reference_hours: float | None = None,
    baseline: HealthBaseline | None = None,
) -> HealthResult:
    """Structural-health chart of a forecast's standardised frequency residuals.

    Parameters
    ----------
    forecast : DataFrame
        Forecast table (FORECAST contract), best with a model frozen before the reference
        period (method 1).
    options : HealthOptions, optional
    reference_hours : float, optional
        Length of the reference period in hours; sets ``options.reference_blocks`` from
        the forecast's block step.
    baseline : HealthBaseline, optional
        An earlier voyage's chart (its options and reference, limits included): every
        block of *forecast* is charted, from the first (*forecast* should be the
        baseline's model's, :meth:`HealthBaseline.forecast`).
    """
    forecast = read_any_table(forecast, FORECAST, name="forecast")
    if baseline is not None:
        return baseline.chart(forecast)
    options = options or HealthOptions()
    if reference_hours is not None:
        if not (math.isfinite(reference_hours) and reference_hours > 0):
            raise ValueError(
                f"reference_hours={reference_hours!r} must be a positive number of hours"
            )
        step = forecast["block_start"].drop_duplicates().sort_values().diff().median()
        blocks = int(round(reference_hours * 3600 / step.total_seconds()))
        options = replace(options, reference_blocks=blocks)
    return health_chart(forecast, options)
