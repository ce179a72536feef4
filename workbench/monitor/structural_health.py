"""The monitor's structural-health chart: the operational model's residuals, charted.

The chart needs a model of how speed, temperatures and fuel move the frequencies that is
frozen before its reference period and honest about its own uncertainty out of sample
(:func:`~workbench.health.fit_operational_model`); the project's rolling stepwise forecast
is neither (5.4 false alarms a day through the chart, ``benchmarks/results/health.txt``).
So the monitor learns in two steps from the first tracked block: the operational model on
``health_train_hours``, then the chart's reference on the next ``reference_hours``, and
charts every block after them. When the ship log carries ``fuel_on_board_t`` (tank
soundings) the model has the fuel mass as a term; without it, the slow rise of the
frequencies as fuel is burned is left to a slowly following baseline of the chart
(``baseline_hours``), which a step change outruns.
"""

from __future__ import annotations

import math
import warnings

import pandas as pd

__all__ = ["FUEL_COLUMN", "operational_health"]

#: The optional ship-log column with the fuel on board (tank soundings). [t]
FUEL_COLUMN = "fuel_on_board_t"


def operational_health(
    tracked: pd.DataFrame, predictors: pd.DataFrame, settings, step_s: float
) -> tuple[pd.DataFrame | None, pd.DataFrame | None, list[str]]:
    """HEALTH and ALARMS tables of the tracked table so far, or (None, None) while the
    model or the reference is still being learned; and notes for the status.

    Parameters
    ----------
    tracked : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors of the tracked blocks (PREDICTORS contract; ``fuel_on_board_t``
        used when present).
    settings : ForecastSettings
        ``health_train_hours``, ``reference_hours``, ``baseline_hours``, ``ewma_lambda``
        and ``false_alarms_per_day`` are read.
    step_s : float
        Block step. [s]
    """
    from ..health import HealthOptions, fit_operational_model, health_chart

    train = int(round(settings.health_train_hours * 3600.0 / step_s))
    reference = int(round(settings.reference_hours * 3600.0 / step_s))
    first = int(tracked["block"].min())
    last = int(tracked["block"].max())
    have = last - first + 1
    if have <= train + reference:
        return (
            None,
            None,
            [
                f"health: learning, {have} of {train + reference + 1} blocks "
                f"({settings.health_train_hours:g} h model, {settings.reference_hours:g} h "
                "reference, then the chart)"
            ],
        )
    has_fuel = FUEL_COLUMN in predictors.columns and predictors[FUEL_COLUMN].notna().any()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # modes too rarely seen: noted, not modelled
        # DEFAULT_TERMS over the columns the log has (the fuel term only with soundings)
        model = fit_operational_model(
            tracked, predictors, train_start_block=first, train_blocks=train
        )
    notes = list(dict.fromkeys(f"health: {w.message}" for w in caught))
    forecast = model.forecast(
        tracked, predictors, reference_start_block=first + train, reference_blocks=reference
    )
    baseline = None if has_fuel else settings.baseline_hours
    if baseline is not None and not math.isfinite(baseline):
        baseline = None
    options = HealthOptions(
        reference_blocks=reference,
        reference_start_block=first + train,
        ewma_lambda=settings.ewma_lambda,
        false_alarms_per_day=settings.false_alarms_per_day,
        baseline_hours=baseline,
    )
    chart = health_chart(forecast, options)
    if not has_fuel:
        notes.append(
            f"health: no {FUEL_COLUMN} in the ship log; the fuel burn is followed by a "
            f"{baseline:g}-h baseline"
            if baseline is not None
            else f"health: no {FUEL_COLUMN} in the ship log and no baseline"
        )
    return chart.table, chart.alarms, notes
