"""Forecast stage: sliding model per mode, Kalman-blended with SSI, for each option."""

from __future__ import annotations

import os
import warnings
from dataclasses import replace

import numpy as np
import pandas as pd

from data_contracts import (
    MODAL,
    POLES,
    PREDICTORS,
    column_log_coverage_name,
    recorded_grid,
    set_grid,
)

from ..forecasting import ForecastResult, ForecastWarning, sliding_forecast
from ..forecasting.measurement import measurable_poles
from ..forecasting.options import ForecastOptions
from ..forecasting.results import combined
from ..parallel import process_map
from ..predictors.directions import direction_source
from ..results import read_any_table
from ..sid.presence import persistent_modes

__all__ = ["ForecastOptions", "ForecastResult", "forecast", "forecast_modes", "partial_log_lines"]


#: The predictor table's per-column share of a block: ``log_coverage_<column>``.
COLUMN_COVERAGE_PREFIX = column_log_coverage_name("")

#: Descriptive names of the forecast schemes (the reference work's methods 1 and 2).
SCHEME_NAMES = {1: "single-window", 2: "rolling"}


def _forecast_part(modal, predictors, options, modes, poles, cases):
    """One process's share of :func:`forecast_modes` (module level: picklable); its
    warnings are in the result, not issued."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        return sliding_forecast(modal, predictors, options, modes=modes, poles=poles, cases=cases)


def forecast_modes(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    options: ForecastOptions,
    *,
    modes=None,
    poles: pd.DataFrame | None = None,
    cases=None,
    progress: bool = False,
) -> ForecastResult:
    """:func:`~workbench.forecasting.sliding_forecast` with the modes spread over
    ``options.n_workers`` processes.

    Modes of the window model are independent (one model and one Kalman filter each), so
    the table equals that of a single call, whatever the number of workers. The memory
    model pools the excitation sensitivity of SSI's bias (a property of the excitation, not
    of a mode; :mod:`workbench.forecasting.excitation`) over the modes forecast together,
    so its modes run in one call (one process) and the table is again that of a single
    call. Returns that forecast, its table sorted by block and mode and its warnings
    collected (not issued).
    """
    modes = sorted(int(m) for m in (modal["mode"].unique() if modes is None else modes))
    n_workers = max(1, min(int(options.n_workers), len(modes)))
    if options.model == "memory":
        n_workers = 1
    if n_workers == 1:  # one call: the windows' normalisation is shared by all modes
        calls = [(modal, predictors, options, modes, poles, cases)]
        sizes = [len(modes)]
    else:
        calls = [
            (modal[modal["mode"] == mode], predictors, options, [mode], poles, cases)
            for mode in modes
        ]
        sizes = None
    parts = process_map(
        _forecast_part,
        calls,
        n_workers=n_workers,
        progress=progress,
        description="forecast",
        unit="mode",
        sizes=sizes,
    )
    result = combined(parts, options)
    keys = [c for c in ("block", "mode", "option") if c in result.table.columns]
    return replace(
        result, table=result.table.sort_values(keys, kind="stable").reset_index(drop=True)
    )


def partial_log_lines(
    table: pd.DataFrame, predictors: pd.DataFrame | None = None, models=()
) -> list[str]:
    """A run note on the forecast rows whose block the ship log covers only partly
    (``log_coverage`` below 1; none when the table has no such column or row).

    ``log_coverage`` is the least share over the log's columns, so one column out (a dead
    wind-direction sensor) marks every block: with the predictor table's per-column shares
    (``log_coverage_<column>``) the note says how many of those blocks each column covers
    only partly, and which of the columns no model of the run (*models*, their ``terms``)
    uses, so such a column is not taken for an outage of the predictors forecast from.
    """
    if "log_coverage" not in table.columns or table.empty:
        return []
    rows = table[(table["phase"] == "forecast") & (table["log_coverage"] < 1.0)]
    if rows.empty:
        return []
    blocks = np.unique(rows["block"].to_numpy())
    by_column = ""
    if predictors is not None:
        shares = predictors.drop_duplicates("block", keep="last").set_index("block")
        shares = shares.reindex(blocks)
        # a direction's cosine is the direction's column (its coverage)
        used = {
            direction_source(name)
            for model in models
            for term in model.terms
            for name in term.split(":")
        }
        parts = []
        for name in (c for c in shares.columns if c.startswith(COLUMN_COVERAGE_PREFIX)):
            column = name[len(COLUMN_COVERAGE_PREFIX) :]
            n = int((shares[name].to_numpy(dtype=float, na_value=np.nan) < 1.0).sum())
            if n:
                unused = " (in no model)" if models and column not in used else ""
                parts.append((n, f"{column} in {n}{unused}"))
        if parts:
            by_column = "; " + ", ".join(text for _, text in sorted(parts, key=lambda p: -p[0]))
    return [
        f"ship log: {blocks.size} forecast block(s) covered only partly (log_coverage below "
        f"1, the first block {int(blocks[0])}{by_column}): their predictors are means of the "
        "logged part, or filled where too little of the block is logged"
    ]


def forecast(
    modal: pd.DataFrame | str | os.PathLike,
    predictors: pd.DataFrame | str | os.PathLike,
    *,
    poles: pd.DataFrame | str | os.PathLike | None = None,
    cases=None,
    options: ForecastOptions | None = None,
    progress: bool = False,
) -> ForecastResult:
    """Sliding forecasts of every persistent mode, for each measurement option.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors (PREDICTORS contract); their blocks are the forecast's grid.
    poles : DataFrame, optional
        Pole table (POLES contract), needed for option B; poles marked as shaft or
        blade-pass harmonics (``harmonic`` column) are left out, but for option B's in the
        column of a mode's tracked pole of their block
        (:func:`~workbench.forecasting.measurement.measurable_poles`).
    cases : None, "derive", path or DataFrame
        Each window forecasts with the model of the current operating case.
    options : ForecastOptions, optional
        Every setting, down to the filter (:class:`~workbench.forecasting.options.ForecastOptions`).
    progress : bool
        Progress bar on stderr.

    Modes measured in fewer than ``options.min_presence`` of the blocks with data (the
    modal table's: a hole in the accelerations takes no mode out; short-lived tracks, a
    shaft harmonic passing by, spurious poles, are left out) are not forecast; a line says
    which. The forecast runs over every block of *predictors*, through such a hole too.
    """
    options = options or ForecastOptions()
    modal = read_any_table(modal, MODAL, name="modal")
    predictors = read_any_table(predictors, PREDICTORS, name="predictors")
    if poles is not None:
        poles = read_any_table(poles, POLES, name="poles")
        if "B" in options.options and poles.empty:
            raise ValueError("option B needs poles: the pole table has no rows")
    if "B" in options.options and poles is None:
        raise ValueError("option B needs the pole table (poles=...)")
    kept, lines = persistent_modes(modal, options.min_presence)
    modes = sorted(int(m) for m in kept["mode"].unique())
    parts, messages = [], []
    for option in options.options:
        read = poles
        if poles is not None and "harmonic" in poles.columns:
            # option B measures the pole nearest the prediction: never a shaft harmonic's,
            # but a mode's own column where an order sits on it (measurable_poles); judged
            # over every mode here, so the per-mode calls (n_workers) read the same poles
            read = measurable_poles(poles, modal, option).drop(columns="harmonic")
            if option == "B" and read.empty:
                raise ValueError(
                    "option B needs poles: every pole of the table is marked as a shaft "
                    "harmonic (column harmonic)"
                )
        part = forecast_modes(
            modal,
            predictors,
            replace(options, options=(option,)),
            modes=modes,
            poles=read,
            cases=cases,
            progress=progress,
        )
        messages += [f"option {option}: {m}" for m in part.warnings]
        parts.append(part)
    table = pd.concat([p.table for p in parts], ignore_index=True)
    set_grid(table, recorded_grid(modal) or recorded_grid(predictors))
    models = [m for p in parts for m in p.models]
    lines = (*lines, *partial_log_lines(table, predictors, models))
    done = (
        f"forecast of {table['mode'].nunique()} modes over {table['block'].nunique()} blocks, "
        f"option(s) {'/'.join(options.options)}, scheme {SCHEME_NAMES[options.scheme]}, "
        f"train {options.train_blocks}"
    )
    return combined(parts, options, table=table, warnings=tuple(messages), lines=(*lines, done))
