"""What a forecast returns: the table, the warnings and the model of every window, with
its summary, figure, evaluation and saving."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import pandas as pd

from data_contracts import FORECAST, MODAL

from ..results import StageResult, read_any_table, shown_once, table_path, write_frame
from .evaluate import evaluate_forecast
from .options import ForecastOptions

__all__ = ["ForecastResult", "ForecastWarning", "WindowModel", "combined"]


class ForecastWarning(UserWarning):
    """A forecast went on with a fallback (constant or last good model, predict-only steps)."""


@dataclass(frozen=True)
class WindowModel:
    """The model used for one mode over one training window.

    Parameters
    ----------
    mode : int
        Mode label.
    window_start_block, window_end_block : int
        First and last block of the training window.
    kind : {"stepwise", "constant", "last_good"}
        Stepwise fit of this window; constant model (mean of the window's targets);
        the last good stepwise model of an earlier window, reused.
    terms : tuple of str
        Model terms (empty for the constant model).
    coefficients : dict
        Term -> estimate on normalised predictors (intercept included as the fit names it).
    n_train : int
        Training targets available in the window.
    rmse_hz : float
        Residual standard deviation of the fit (constant model: of the targets). [Hz]
    measurement_variance : float
        R, scatter of the measurements about the model in the window. [Hz²]
    process_variance : float
        Q of the Kalman filter for the blocks this window predicts. [Hz²]
    normalisation : dict
        Predictor -> (mean, standard deviation) of the window, used to z-score.
    warning : str
        Why a fallback was used ("" when none).
    """

    mode: int
    window_start_block: int
    window_end_block: int
    kind: Literal["stepwise", "constant", "last_good"]
    terms: tuple[str, ...]
    coefficients: Mapping[str, float]
    n_train: int
    rmse_hz: float
    measurement_variance: float
    process_variance: float
    normalisation: Mapping[str, tuple[float, float]]
    warning: str = ""


@dataclass(frozen=True)
class ForecastResult(StageResult):
    """A forecast: of :func:`~workbench.forecasting.sliding_forecast` and of the forecast
    stage (:func:`workbench.stages.forecast`, ``wb.forecast``).

    Parameters
    ----------
    table : DataFrame
        FORECAST contract table, one row per block, mode and option (SSI, model and Kalman
        estimates with bounds), plus ``warning`` (str, "" when none) and, for option B,
        ``selected_model_order`` (Int64), ``selected_damping_ratio`` and ``selected_mac``
        (MAC of the chosen pole's shape with the mode's reference shape; NaN when no pole
        was chosen or shapes were not used).
    options : ForecastOptions
        The settings the forecast ran with.
    warnings : tuple of str
        Distinct warnings with their counts, also issued as :class:`ForecastWarning` (the
        stage collects them instead, each led by its option: ``option A: ...``).
    models : tuple of WindowModel
        The model of every mode and training window, in order.
    lines : tuple of str
        Further lines of the summary (the stage's: modes left out, what was forecast).
    """

    table: pd.DataFrame
    options: ForecastOptions
    warnings: tuple[str, ...] = ()
    models: tuple[WindowModel, ...] = ()
    lines: tuple[str, ...] = ()
    title = "forecast"

    def evaluate(self, truth: pd.DataFrame | str | os.PathLike, *, phase="forecast"):
        """This forecast against the true modal table *truth* (DataFrame or file, MODAL
        contract): :func:`~workbench.forecasting.evaluate.evaluate_forecast`, as the
        evaluate stage."""
        truth = read_any_table(truth, MODAL, name="truth")
        return evaluate_forecast(self.table, truth, phase=phase)

    def plot(self, mode: int | None = None, *, truth: pd.DataFrame | None = None, option=None):
        """Forecast figure of *mode* (default the first): SSI, model with bounds, Kalman
        (:func:`~workbench.forecasting.plot.plot_forecast_mode`)."""
        from .plot import plot_forecast_mode  # matplotlib only when drawing

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
            from .plot import write_forecast_figures

            for path in write_forecast_figures(self.table, figures, truth_modal=truth):
                paths[path.stem] = path
        return paths


def combined(
    results: Iterable[ForecastResult], options: ForecastOptions, **fields
) -> ForecastResult:
    """One result of forecasts run apart (options, modes): their tables one after the
    other, their warnings and models in order; *fields* replace any of the result's."""
    results = list(results)
    if len(results) == 1:
        return replace(results[0], options=options, **fields)
    joined = ForecastResult(
        table=pd.concat([r.table for r in results], ignore_index=True),
        options=options,
        warnings=tuple(w for r in results for w in r.warnings),
        models=tuple(m for r in results for m in r.models),
    )
    return replace(joined, **fields)
