"""The monitor's structural-health chart: the operational model's residuals, charted.

The chart needs a model of how speed, temperatures and fuel move the frequencies that is
frozen before its reference period and honest about its own uncertainty out of sample
(:func:`~workbench.shm.fit_operational_model`); the project's rolling stepwise forecast
is neither (false alarms every day through the chart: model ``stepwise`` in
``benchmarks/results/health.txt``).
So the monitor learns in two steps from the first tracked block: the operational model on
``health_train_hours``, then the chart's reference on the next ``reference_hours``, and
charts every block after them. When the ship log carries ``fuel_on_board_t`` (tank
soundings) the model has the fuel mass as a term; without it, the slow rise of the
frequencies as fuel is burned is left to a slowly following baseline of the chart
(``baseline_hours``), which a step change outruns.

With a saved baseline (``ForecastSettings.health_baseline``, ``workbench monitor
--baseline FILE``) the model and the chart's reference and limits are an earlier voyage's
(:class:`~workbench.shm.HealthBaseline`) and every block is charted from the first;
a baseline whose modes are not this voyage's tracked modes, or whose model needs a column
the ship log lacks, is refused (a note) and the chart learns its own as above.
:func:`charting_starts` says from which block (and when) the chart draws.
"""

from __future__ import annotations

import math
import warnings

import pandas as pd

__all__ = ["FUEL_COLUMN", "charting_starts", "load_baseline", "operational_health"]

#: The optional ship-log column with the fuel on board (tank soundings). [t]
FUEL_COLUMN = "fuel_on_board_t"


_BASELINES: dict[str, tuple[tuple[int, int], object]] = {}


def load_baseline(path: str):
    """The :class:`~workbench.shm.HealthBaseline` in *path*, read again only when the
    file changed. Raises :class:`~workbench.shm.BaselineError` (one line)."""
    import os

    from ..shm import HealthBaseline

    stat = os.stat(path)
    key = (stat.st_size, stat.st_mtime_ns)
    cached = _BASELINES.get(path)
    if cached is None or cached[0] != key:
        cached = (key, HealthBaseline.load(path))
        _BASELINES.clear()
        _BASELINES[path] = cached
    return cached[1]


def charting_starts(first_block: int, settings, step_s: float) -> int:
    """First block the chart monitors (alarms possible): the first tracked block with a
    baseline, else the first after the model's training and the reference hours."""
    if settings.health_baseline is not None:
        return int(first_block)
    hours = settings.health_train_hours + settings.reference_hours
    return int(first_block) + int(round(hours * 3600.0 / step_s))


def learning_notes(
    tracked: pd.DataFrame, settings, step_s: float, first: int, have: int
) -> list[str]:
    """The notes of a health chart still learning this voyage's own model: when it will
    start and how far the learning is, after *have* blocks from block *first*."""
    train = int(round(settings.health_train_hours * 3600.0 / step_s))
    reference = int(round(settings.reference_hours * 3600.0 / step_s))
    start = first + train + reference
    return [
        f"health: the chart starts at block {start} ({_at(tracked, start, step_s)}), after "
        f"this voyage's {settings.health_train_hours:g}-h model and "
        f"{settings.reference_hours:g}-h reference; with a saved baseline (monitor "
        "--baseline) it starts at the first block",
        f"health: learning, {have} of {train + reference + 1} blocks",
    ]


def operational_health(
    tracked: pd.DataFrame, predictors: pd.DataFrame, settings, step_s: float
) -> tuple[pd.DataFrame | None, pd.DataFrame | None, list[str]]:
    """HEALTH and ALARMS tables of the tracked table so far, or (None, None) while the
    model or the reference is still being learned; and notes for the status, the first of
    which says from which block (and time) the chart monitors.

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
    from ..shm import BaselineError, HealthOptions, fit_operational_model, health_chart

    train = int(round(settings.health_train_hours * 3600.0 / step_s))
    reference = int(round(settings.reference_hours * 3600.0 / step_s))
    first = int(tracked["block"].min())
    last = int(tracked["block"].max())
    have = last - first + 1
    refused = ""
    if settings.health_baseline is not None:
        try:
            baseline = load_baseline(settings.health_baseline)
            baseline.check_predictors(predictors, "the ship log")
            baseline.check_modes(tracked, "the tracked modes")
            chart = baseline.chart(baseline.forecast(tracked, predictors))
        except (BaselineError, OSError) as error:
            refused = f"health: baseline refused: {error}; learning this voyage's own model"
        else:
            model = baseline.model
            return (
                chart.table,
                chart.alarms,
                [
                    f"health: charting from block {first} ({_at(tracked, first, step_s)}) with "
                    f"the baseline {settings.health_baseline} (model of blocks "
                    f"{model.train_start_block}-{model.train_end_block} of the voyage from "
                    f"{baseline.source.get('first_block_start', '?')})"
                ],
            )
    start = first + train + reference
    if have <= train + reference:
        notes = learning_notes(tracked, settings, step_s, first, have)
        return None, None, [n for n in (*notes, refused) if n]
    has_fuel = FUEL_COLUMN in predictors.columns and predictors[FUEL_COLUMN].notna().any()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # modes too rarely seen: noted, not modelled
        # DEFAULT_TERMS over the columns the log has (the fuel term only with soundings)
        model = fit_operational_model(
            tracked, predictors, train_start_block=first, train_blocks=train
        )
    notes = [
        f"health: charting from block {start} ({_at(tracked, start, step_s)}), after this "
        f"voyage's {settings.health_train_hours:g}-h model and {settings.reference_hours:g}-h "
        "reference"
    ]
    notes += [n for n in (refused,) if n]
    notes += list(dict.fromkeys(f"health: {w.message}" for w in caught))
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


def _at(tracked: pd.DataFrame, block: int, step_s: float) -> str:
    """UTC start of *block* on the grid of *tracked* ('YYYY-MM-DD HH:MMZ')."""
    first = tracked.loc[tracked["block"].idxmin()]
    when = pd.Timestamp(first["block_start"]) + pd.Timedelta(
        seconds=(block - int(first["block"])) * step_s
    )
    return f"{when.tz_convert('UTC'):%Y-%m-%d %H:%MZ}"
