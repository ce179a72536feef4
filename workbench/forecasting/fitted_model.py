"""Fitted window models and the helpers the window and memory forecasts share.

A fitted model ready to predict (:class:`_Model`: a stepwise fit or a constant model with
the normalisation of its window), its predictions with prediction bounds
(:func:`_predict`, :func:`_constant_prediction` for the constant model ȳ ± t s sqrt(1 + 1/n)),
the z-scoring of predictors (:func:`_z_scores`), the plausibility band of a mode's frequency
(:func:`_plausible`) and the robust white-scatter estimate of the measurement variance R
(:func:`_white_scatter_variance`). Used by :mod:`workbench.forecasting.window.model`,
:mod:`workbench.forecasting.window.noise`, :mod:`workbench.forecasting.window.kalman` and the
memory forecast (:mod:`workbench.forecasting.memory.forecast`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ..stats.distributions import t_quantile

#: A mode's frequency is plausible within a factor of this of its first window's median.
_PLAUSIBLE_FACTOR = 2.0
#: Fewest successive differences for the robust scatter estimate of R.
_MIN_DIFFERENCES = 5
#: Relative floor on the measurement standard deviation, sqrt(R) >= this x frequency. [-]
_MIN_RELATIVE_STD = 1e-5
#: Relative measurement standard deviation assumed when a window has too little data to
#: estimate the scatter and no earlier estimate exists. [-]
_DEFAULT_RELATIVE_STD = 5e-3


@dataclass
class _Model:
    """A fitted window model ready to predict (internal)."""

    kind: str
    fit: Any  # stepwise fit or None (constant)
    columns: tuple[str, ...]  # predictor columns the fit saw
    mean: np.ndarray  # normalisation of those columns
    scale: np.ndarray
    level: float = math.nan  # constant model: mean of targets
    spread: float = math.nan  # constant model: std of targets
    n_train: int = 0
    n_params: int = 1
    rmse: float = math.nan
    used: frozenset = frozenset()  # predictor columns named in the model's terms

    def terms(self) -> tuple[str, ...]:
        return tuple(getattr(self.fit, "terms", ())) if self.fit is not None else ()


def _constant_prediction(
    level: float, spread: float, n: int, n_rows: int, alpha: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant model ȳ ± t s sqrt(1 + 1/n): mean, lower, upper, mean-prediction variance."""
    mean = np.full(n_rows, level)
    t = t_quantile(1 - alpha / 2, max(n - 1, 1))
    half = t * spread * math.sqrt(1.0 + 1.0 / max(n, 1))
    return mean, mean - half, mean + half, np.full(n_rows, spread**2 / max(n, 1))


def _z_scores(rows: np.ndarray, mean: np.ndarray, scale: np.ndarray, limit: float) -> np.ndarray:
    """z = (x - mean) / scale, clipped to ±limit (NaN stays NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.clip((rows - mean) / scale, -limit, limit)


def _predict(
    model: _Model,
    rows: np.ndarray,
    alpha: float,
    limit: float,
    frame: pd.DataFrame | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, lower, upper (prediction interval) and mean-prediction variance on raw *rows*.

    *frame*, when given, holds *rows* already z-scored (and clipped to ±*limit*) with the
    model's normalisation. Rows the model cannot predict (a predictor it uses is NaN) are
    NaN.
    """
    n_rows = rows.shape[0]
    if model.fit is None:
        return _constant_prediction(model.level, model.spread, model.n_train, n_rows, alpha)
    if frame is None:
        z = _z_scores(rows, model.mean, model.scale, limit)
        frame = pd.DataFrame(z, columns=list(model.columns))
    try:
        out = model.fit.predict(frame, interval="prediction", alpha=alpha)
        mean = np.array(out["mean"], dtype=float)
        lower = np.array(out["lower"], dtype=float)
        upper = np.array(out["upper"], dtype=float)
        mean_variance = np.array(out["mean_se"], dtype=float) ** 2  # se² of the mean
    except Exception:  # a fit that cannot predict these rows: fall back per row
        nan = np.full(n_rows, np.nan)
        return nan, nan.copy(), nan.copy(), nan.copy()
    return mean, lower, upper, mean_variance


def _plausible(frequency: np.ndarray, reference: np.ndarray | float) -> np.ndarray:
    """f > 0 and, where a reference level is known, ref / c < f < c ref (c = 2)."""
    f = np.asarray(frequency, dtype=float)
    ref = np.asarray(reference, dtype=float)
    with np.errstate(invalid="ignore"):
        band = (f > ref / _PLAUSIBLE_FACTOR) & (f < ref * _PLAUSIBLE_FACTOR)
        return (f > 0) & np.where(np.isfinite(ref), band, True)


def _white_scatter_variance(residuals: np.ndarray) -> float:
    """Variance of the white part of *residuals*, robustly, from successive differences.

    Notes
    -----
    For r_k = e_k + v_k with e slowly varying (model error) and v white (SSI scatter),
    Δr_k ≈ Δv_k has variance 2 σ_v². With the MAD as a robust standard deviation,
    σ_v² = (1.4826 MAD(Δr))² / 2; differencing removes the model error, the MAD ignores
    the odd mis-selected pole. Falls back to the mean square when the MAD is zero.
    """
    differences = np.diff(residuals)
    mad = float(np.median(np.abs(differences - np.median(differences))))
    if mad > 0:
        return (1.4826 * mad) ** 2 / 2.0
    return float(np.mean(residuals**2))


def _used_columns(fit, names: Sequence[str]) -> frozenset:
    """Predictor columns named in the fit's terms (e.g. "speed_kn:water_temp_c")."""
    tokens: set[str] = set()
    for term in getattr(fit, "terms", ()):
        tokens.update(re.split(r"[^0-9A-Za-z_]+", str(term)))
    return frozenset(name for name in names if name in tokens)


def _coefficients(model: _Model) -> dict[str, float]:
    if model.fit is None:
        return {"const": float(model.level)}
    table = getattr(model.fit, "coefficients", None)
    if isinstance(table, pd.DataFrame) and "estimate" in table.columns:
        names = table.index.tolist()
        values = table["estimate"].to_numpy(dtype=float).tolist()
        return dict(zip(map(str, names), values, strict=True))
    return {}
