"""What a forecast returns: the table, the warnings and the model of every window."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import pandas as pd

__all__ = ["ForecastResult", "ForecastWarning", "WindowModel"]


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
class ForecastResult:
    """Output of :func:`sliding_forecast`.

    Parameters
    ----------
    table : DataFrame
        FORECAST contract table plus ``warning`` (str, "" when none) and, for option B,
        ``selected_model_order`` (Int64), ``selected_damping_ratio`` and ``selected_mac``
        (MAC of the chosen pole's shape with the mode's reference shape; NaN when no pole
        was chosen or shapes were not used).
    warnings : tuple of str
        Distinct warnings with their counts, also issued as :class:`ForecastWarning`.
    models : tuple of WindowModel
        The model of every mode and training window, in order.
    """

    table: pd.DataFrame
    warnings: tuple[str, ...] = ()
    models: tuple[WindowModel, ...] = field(default=())
