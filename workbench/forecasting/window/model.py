"""Window model of the reference forecast: candidates, stepwise fit, prediction.

Step 1 of :func:`~workbench.forecasting.window.forecast.window_forecast` for one window: which
predictors the window can use (:func:`candidate_columns`), the model of each mode
(:func:`fit_window_model`: stepwise, else the last good model, else a constant model) and
its predictions with 95 % bounds over the window's training and forecast rows
(:func:`predict_window`, with the fallbacks for NaN predictors and implausible values).
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..fitted_model import (
    _DEFAULT_RELATIVE_STD,
    _PLAUSIBLE_FACTOR,
    _constant_prediction,
    _Model,
    _plausible,
    _predict,
    _used_columns,
    _z_scores,
)

__all__ = ["WindowFrame", "candidate_columns", "fit_window_model", "predict_window"]


class WindowFrame:
    """The z-scored candidate predictors of one window (training then forecast rows)."""

    def __init__(self, X_all: np.ndarray, columns: Sequence[str], w0: int, w1: int, f1: int):
        self.w0, self.w1, self.f1 = w0, w1, f1
        self.use: list[int] = []
        self.X_train = X_all[w0:w1]
        self.columns = list(columns)
        self._X_all = X_all
        self._frame: pd.DataFrame | None = None

    def select(self, min_train: int, notes: Counter) -> None:
        """Candidate predictors of the window: enough valid values, not constant."""
        self.use = candidate_columns(self.X_train, self.columns, min_train, notes)
        self.names = tuple(self.columns[c] for c in self.use)
        Xw = self.X_train[:, self.use]
        self.mean = np.nanmean(Xw, axis=0) if self.use else np.empty(0)
        self.scale = np.nanstd(Xw, axis=0, ddof=1) if self.use else np.empty(0)
        self.z_train = pd.DataFrame((Xw - self.mean) / self.scale, columns=list(self.names))

    def frame(self, limit: float) -> pd.DataFrame:
        """Rows [w0, f1) z-scored with this window's normalisation (built once)."""
        if self._frame is None:
            rows = self._X_all[self.w0 : self.f1][:, self.use]
            self._frame = pd.DataFrame(
                _z_scores(rows, self.mean, self.scale, limit), columns=list(self.names)
            )
        return self._frame


def candidate_columns(
    X_train: np.ndarray, columns: Sequence[str], min_train: int, notes: Counter
) -> list[int]:
    """Positions of the predictors with >= *min_train* valid values that are not constant."""
    use = []
    for c, name in enumerate(columns):
        values = X_train[:, c]
        valid = np.isfinite(values)
        if valid.sum() < min_train:
            notes[f"predictor '{name}' left out: fewer than {min_train} valid values"] += 1
            continue
        v = values[valid]
        if np.ptp(v) <= 1e-12 * max(1.0, float(np.abs(v).max())):
            notes[f"predictor '{name}' left out: constant in the window"] += 1
            continue
        use.append(c)
    return use


def fit_window_model(run, j: int, window: WindowFrame, y: np.ndarray):
    """The model of mode *j* for one window, the fallback reason and the targets counted.

    Stepwise on the window's z-scored candidates when the window has at least
    ``min_train`` targets; a failing fit reuses the mode's last good model; with no usable
    model a constant model (the window's mean ± its spread; a mode without targets in the
    window but a running filter: its estimate, counted as one target). Returns
    ``(model, reason, n_valid)``, model None when the mode has no data yet.
    """
    from workbench.stats import stepwise  # optional stage

    valid_y = np.isfinite(y)
    n_valid = int(valid_y.sum())
    model: _Model | None = None
    reason = ""
    if not np.isfinite(run.reference_hz[j]) and n_valid >= 1:
        run.reference_hz[j] = float(np.median(y[valid_y]))
    if n_valid >= run.min_train and window.use:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fit = stepwise(window.z_train, y, **run.stepwise_options)
            rmse = float(fit.rmse)
            n_params = len(getattr(fit, "coefficients", ())) or 1
            if not np.isfinite(rmse):
                raise ValueError("non-finite rmse")
            model = _Model(
                "stepwise",
                fit,
                window.names,
                window.mean,
                window.scale,
                n_train=n_valid,
                n_params=n_params,
                rmse=rmse,
                used=_used_columns(fit, window.names),
            )
            run.last_good[j] = model
        except Exception as error:  # rank deficiency, singular fits...
            reason = f"stepwise fit failed ({type(error).__name__})"
    elif n_valid < run.min_train:
        reason = f"too few valid blocks ({n_valid} < {run.min_train})"
    else:
        reason = "no usable predictor"
    if model is None and n_valid >= run.min_train and not window.use:
        model = None  # constant model below is the right model here
    elif model is None and run.last_good[j] is not None:
        model = run.last_good[j]
        model = _Model(**{**model.__dict__, "kind": "last_good"})
        reason += ": last good model"
    if model is None:
        if n_valid >= 1:
            level = float(np.mean(y[valid_y]))
            spread = float(np.std(y[valid_y], ddof=1)) if n_valid >= 2 else math.nan
        elif run.started[j]:
            level, spread = float(run.bank.state[j]), math.nan
            n_valid = 1
        else:
            level = math.nan
        if not np.isfinite(level):
            run.warn_rows([], j, "", f"mode {run.mode_labels[j]}: no data yet, no forecast")
            return None, "", n_valid
        if not np.isfinite(spread) or spread <= 0:
            spread = (
                math.sqrt(run.last_r[j])
                if np.isfinite(run.last_r[j])
                else _DEFAULT_RELATIVE_STD * abs(level)
            )
        model = _Model(
            "constant",
            None,
            (),
            np.empty(0),
            np.empty(0),
            level=level,
            spread=spread,
            n_train=max(n_valid, 1),
            n_params=1,
            rmse=spread,
        )
        if reason:
            reason += ": constant model"
    return model, reason, n_valid


def predict_window(run, j: int, model: _Model, window: WindowFrame, y: np.ndarray, n_valid: int):
    """Mean, lower, upper and mean-prediction variance of mode *j* on rows [w0, f1).

    Rows whose needed predictor is NaN, and non-physical values (outside the plausibility
    band), get the window's constant model; clipped, NaN and implausible rows carry row
    warnings (from the first reported row on).
    """
    w0, f0, f1 = window.w0, window.w1, window.f1
    is_first = w0 == run.first
    limit = run.extrapolation_limit
    pred_rows = np.arange(w0, f1)
    valid_y = np.isfinite(y)
    if model.kind == "stepwise":  # this window's normalisation: shared frame
        rows_X = run.X_all[w0:f1][:, window.use]
        mean_p, lower_p, upper_p, mvar = _predict(
            model, rows_X, run.alpha, limit, window.frame(limit)
        )
    else:
        rows_X = run.X_all[w0:f1][:, [run.columns.index(c) for c in model.columns]]
        mean_p, lower_p, upper_p, mvar = _predict(model, rows_X, run.alpha, limit)
    if model.fit is not None:
        used = [c for c, name in enumerate(model.columns) if name in model.used]
        if used:
            with np.errstate(invalid="ignore", divide="ignore"):
                far = np.abs((rows_X[:, used] - model.mean[used]) / model.scale[used])
            clipped = pred_rows[(far > limit).any(axis=1)]
            clipped = clipped[clipped >= (w0 if is_first else f0)]
            if clipped.size:
                run.warn_rows(
                    clipped.tolist(),
                    j,
                    f"predictors beyond ±{limit:g} sd of the window: clipped",
                    "blocks with predictors far outside the training window (clipped)",
                )
    with np.errstate(invalid="ignore"):
        implausible = np.isfinite(mean_p) & ~_plausible(mean_p, run.reference_hz[j])
    mean_p[implausible] = np.nan  # non-physical: constant model below
    bad = ~np.isfinite(mean_p)
    if bad.any():
        # needed predictor NaN in these blocks: constant model of the window
        if n_valid >= 1:
            level = float(np.mean(y[valid_y]))
            spread = float(np.std(y[valid_y], ddof=1)) if n_valid >= 2 else model.rmse
        elif run.started[j]:
            level, spread = float(run.bank.state[j]), model.rmse
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                level, spread = float(np.nanmean(mean_p)), model.rmse
        cm, cl, cu, cv = _constant_prediction(
            level,
            spread if spread > 0 else model.rmse,
            max(n_valid, 1),
            int(bad.sum()),
            run.alpha,
        )
        mean_p[bad], lower_p[bad], upper_p[bad], mvar[bad] = cm, cl, cu, cv
        shown_from = w0 if is_first else f0
        for mask, message, kind in (
            (
                bad & ~implausible,
                "predictor NaN: constant-model prediction",
                "blocks predicted by the constant model (a needed predictor is NaN)",
            ),
            (
                implausible,
                "model implausible: constant-model prediction",
                "blocks predicted by the constant model (model value outside "
                f"{1 / _PLAUSIBLE_FACTOR:g}-{_PLAUSIBLE_FACTOR:g} x the mode's level)",
            ),
        ):
            shown = pred_rows[mask]
            shown = shown[shown >= shown_from]
            if shown.size:
                run.warn_rows(shown.tolist(), j, message, kind)
    return mean_p, lower_p, upper_p, mvar
