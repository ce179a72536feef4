"""Forecast stage: sliding model per mode, Kalman-blended with SSI, for each option."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from data_contracts import FORECAST, MODAL, POLES, PREDICTORS, recorded_grid, set_grid

from ..forecasting import ForecastWarning, sliding_forecast
from ..forecasting.options import ForecastOptions
from ..parallel import process_map
from ..results import StageResult, read_any_table, shown_once, table_path, write_frame
from ..sid.presence import persistent_modes

__all__ = ["ForecastOptions", "ForecastStageResult", "forecast", "forecast_modes"]


#: Descriptive names of the forecast schemes (the reference work's methods 1 and 2).
SCHEME_NAMES = {1: "single-window", 2: "rolling"}


@dataclass
class ForecastStageResult(StageResult):
    """The forecast table (FORECAST contract) of every option, and its notes.

    Attributes
    ----------
    table : DataFrame
        One row per block, mode and option: SSI, model and Kalman estimates with bounds.
    options : ForecastOptions
    """

    table: pd.DataFrame
    options: ForecastOptions
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "forecast"

    def evaluate(self, truth: pd.DataFrame | str | os.PathLike, *, phase="forecast"):
        """:func:`~workbench.stages.evaluate` of this forecast against the true modal
        table *truth*."""
        from .evaluation import evaluate

        return evaluate(self.table, truth, phase=phase)

    def plot(self, mode: int | None = None, *, truth: pd.DataFrame | None = None, option=None):
        """Forecast figure of *mode* (default the first): SSI, model with bounds, Kalman."""
        from ..reporting.forecast_plot import plot_forecast_mode

        mode = int(self.table["mode"].min()) if mode is None else int(mode)
        return shown_once(plot_forecast_mode(self.table, mode, truth_modal=truth, option=option))

    def save(
        self,
        out: str | os.PathLike,
        *,
        figures: str | os.PathLike | None = None,
        truth: pd.DataFrame | None = None,
    ) -> dict[str, Path]:
        """The table (``out`` a .csv/.parquet file, or a folder: forecast.csv) and, with
        *figures* (a folder), one figure per mode (the *truth* drawn beside)."""
        paths = {"forecast": write_frame(self.table, table_path(out, "forecast.csv"), FORECAST)}
        if figures is not None:
            from ..reporting.forecast_plot import write_forecast_figures

            for path in write_forecast_figures(self.table, figures, truth_modal=truth):
                paths[path.stem] = path
        return paths


def _forecast_part(modal, predictors, options, modes, poles, cases):
    """One process's share of :func:`forecast_modes` (module level: picklable)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ForecastWarning)
        result = sliding_forecast(modal, predictors, options, modes=modes, poles=poles, cases=cases)
    messages = [str(w.message) for w in caught if issubclass(w.category, ForecastWarning)]
    return result.table, messages


def forecast_modes(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    options: ForecastOptions,
    *,
    modes=None,
    poles: pd.DataFrame | None = None,
    cases=None,
    progress: bool = False,
) -> tuple[pd.DataFrame, list[str]]:
    """:func:`~workbench.forecasting.sliding_forecast` with the modes spread over
    ``options.n_workers`` processes.

    Modes of the window model are independent (one model and one Kalman filter each), so
    the table equals that of a single call, whatever the number of workers. The memory
    model pools the excitation sensitivity of SSI's bias (a property of the excitation, not
    of a mode; :mod:`workbench.forecasting.excitation`) over the modes forecast together,
    so its modes run in one call (one process) and the table is again that of a single
    call. Returns the forecast table (sorted by block, mode) and the forecast warnings'
    messages.
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
    table = pd.concat([p[0] for p in parts], ignore_index=True)
    keys = [c for c in ("block", "mode", "option") if c in table.columns]
    table = table.sort_values(keys, kind="stable").reset_index(drop=True)
    return table, [m for p in parts for m in p[1]]


def forecast(
    modal: pd.DataFrame | str | os.PathLike,
    predictors: pd.DataFrame | str | os.PathLike,
    *,
    poles: pd.DataFrame | str | os.PathLike | None = None,
    cases=None,
    options: ForecastOptions | None = None,
    progress: bool = False,
) -> ForecastStageResult:
    """Sliding forecasts of every persistent mode, for each measurement option.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors (PREDICTORS contract); their blocks are the forecast's grid.
    poles : DataFrame, optional
        Pole table (POLES contract), needed for option B; poles marked as shaft or
        blade-pass harmonics (``harmonic`` column) are left out.
    cases : None, "derive", path or DataFrame
        Each window forecasts with the model of the current operating case.
    options : ForecastOptions, optional
        Every setting, down to the filter (:class:`~workbench.forecasting.options.ForecastOptions`).
    progress : bool
        Progress bar on stderr.

    Modes measured in fewer than ``options.min_presence`` of the blocks (short-lived
    tracks: a shaft harmonic passing by, spurious poles) are not forecast; a line says which.
    """
    options = options or ForecastOptions()
    modal = read_any_table(modal, MODAL, name="modal")
    predictors = read_any_table(predictors, PREDICTORS, name="predictors")
    if poles is not None:
        poles = read_any_table(poles, POLES, name="poles")
        if "harmonic" in poles.columns:
            # option B measures the pole nearest the prediction: never a shaft harmonic's
            poles = poles[poles["harmonic"].isna()].reset_index(drop=True)
    if "B" in options.options and poles is None:
        raise ValueError("option B needs the pole table (poles=...)")
    kept, lines = persistent_modes(
        modal, options.min_presence, n_blocks=predictors["block"].nunique()
    )
    modes = sorted(int(m) for m in kept["mode"].unique())
    result = ForecastStageResult(table=pd.DataFrame(), options=options, lines=list(lines))
    frames = []
    for option in options.options:
        table, messages = forecast_modes(
            modal,
            predictors,
            replace(options, options=(option,)),
            modes=modes,
            poles=poles,
            cases=cases,
            progress=progress,
        )
        result.warnings += [f"option {option}: {m}" for m in messages]
        frames.append(table)
    result.table = pd.concat(frames, ignore_index=True)
    set_grid(result.table, recorded_grid(modal) or recorded_grid(predictors))
    result.lines.append(
        f"forecast of {result.table['mode'].nunique()} modes over "
        f"{result.table['block'].nunique()} blocks, option(s) {'/'.join(options.options)}, "
        f"scheme {SCHEME_NAMES[options.scheme]}, train {options.train_blocks}"
    )
    return result
