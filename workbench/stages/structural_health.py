"""Health stage: control chart (per-mode CUSUM or MEWMA) of a forecast's frequency
residuals."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from data_contracts import FORECAST

from ..shm import HealthBaseline, HealthOptions, HealthResult, health_chart
from ._base import StageResult, Summary, read_any_table, shown_once

__all__ = ["HealthStageResult", "health"]


@dataclass
class HealthStageResult(StageResult):
    """The HEALTH table (statistic, limit, alarm per block) and the alarm episodes.

    Attributes
    ----------
    table : DataFrame
        HEALTH contract (and each mode's contribution).
    alarms : DataFrame
        ALARMS contract, one row per episode.
    chart : HealthResult
        Everything the chart learned (reference period, limit).
    """

    table: pd.DataFrame
    alarms: pd.DataFrame
    chart: HealthResult
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "structural health"

    def summary(self) -> Summary:
        return Summary(self.title, [*self.chart.summary().splitlines(), *self.lines])

    def save(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """health.csv and alarms.csv in *out_dir*."""
        return self.chart.save(out_dir)

    def plot(self, ax=None):
        """The chart: statistic per block, the control limit, alarming blocks marked."""
        import matplotlib.pyplot as plt

        drawn_here = ax is None
        if ax is None:
            _, ax = plt.subplots(figsize=(9, 4), layout="constrained")
        table = self.table
        ax.plot(table["block"], table["statistic"], "-", lw=0.8, color="0.3", label="statistic")
        ax.plot(table["block"], table["limit"], "--", color="tab:red", lw=1, label="limit")
        alarm = table["alarm"].astype(bool)
        ax.plot(table.loc[alarm, "block"], table.loc[alarm, "statistic"], ".", color="tab:red")
        ax.set_xlabel("block")
        ax.set_ylabel("CUSUM max S/H" if self.chart.reference.statistic == "cusum" else "MEWMA T²")
        ax.legend(fontsize=8)
        return shown_once(ax.figure) if drawn_here else ax.figure


def health(
    forecast: pd.DataFrame | str | os.PathLike,
    *,
    options: HealthOptions | None = None,
    reference_hours: float | None = None,
    baseline: HealthBaseline | None = None,
) -> HealthStageResult:
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
        chart = baseline.chart(forecast)
        return HealthStageResult(table=chart.table, alarms=chart.alarms, chart=chart)
    options = options or HealthOptions()
    if reference_hours is not None:
        step = forecast["block_start"].drop_duplicates().sort_values().diff().median()
        blocks = int(round(reference_hours * 3600 / step.total_seconds()))
        options = replace(options, reference_blocks=blocks)
    chart = health_chart(forecast, options)
    return HealthStageResult(table=chart.table, alarms=chart.alarms, chart=chart)
