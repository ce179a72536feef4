"""Operational and environmental model of the modal frequencies, fitted for the health chart.

The health chart needs a model frozen before its reference period whose residuals are
honest out of sample. :func:`fit_operational_model` fits, per mode, a robust least-squares
regression of the log frequency on physics-motivated terms of the ship log (speed and its
square for the added mass, water and air temperature for the stiffness, their interaction,
the fuel on board when the log has tank soundings); :meth:`OperationalModel.forecast` writes a FORECAST table whose 95 %
bounds carry both the identification scatter and the model's own parameter uncertainty
(Newey-West, because 75 %-overlapping blocks have correlated errors), so extrapolating
outside the training range widens them instead of raising alarms.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from data_contracts import FORECAST, MODAL

from ..errors import PredictorError

if TYPE_CHECKING:
    from ..simulate.health_voyage import HealthVoyage

__all__ = [
    "DEFAULT_TERMS",
    "MIN_TRAIN_BLOCKS",
    "OperationalModel",
    "fit_operational_model",
    "frozen_forecast",
]

#: The fewest training blocks the operational model is fitted on (its default terms and
#: the Newey-West covariance need a dozen blocks at least).
MIN_TRAIN_BLOCKS = 12

#: Terms of the default model: added mass (speed, speed²), stiffness (water and air
#: temperature), the speed x water interaction of the hull-water coupling, and the fuel on
#: board (``fuel_on_board_t``, the tank soundings' sum: burning fuel lowers the mass).
#: Terms whose columns the log lacks are left out; without the fuel, the chart's slowly
#: following baseline takes the fuel burn (``HealthOptions.baseline_hours``): a straight
#: line in elapsed hours cannot follow a burn rate that falls as the tanks empty (false
#: alarms every day: model ``ols-time`` in ``benchmarks/results/health.txt``).
DEFAULT_TERMS: tuple[str, ...] = (
    "speed_kn",
    "speed_kn^2",
    "water_temp_c",
    "air_temp_c",
    "speed_kn*water_temp_c",
    "fuel_on_board_t",
)
_Z975 = 1.959963984540054
_TERM = re.compile(r"^(?P<a>[A-Za-z_][A-Za-z0-9_]*)(?:(?P<op>[*^])(?P<b>[A-Za-z0-9_]+))?$")


def _parse(term: str) -> tuple[str, ...]:
    match = _TERM.match(term.replace(" ", ""))
    if match is None:
        raise ValueError(f"terms: {term!r} is not 'column', 'column^2' or 'column*column'")
    a, op, b = match["a"], match["op"], match["b"]
    if op is None:
        return (a,)
    if op == "^":
        if b != "2":
            raise ValueError(f"terms: {term!r}: only squares ('^2') are supported")
        return (a, a)
    return (a, b)


@dataclass(frozen=True)
class OperationalModel:
    """Per-mode regression of log frequency on terms of the ship log.

    Parameters
    ----------
    terms : tuple of str
        Model terms (``'speed_kn'``, ``'speed_kn^2'``, ``'speed_kn*water_temp_c'``).
    modes : tuple of int
        Modes fitted, in the order of the arrays below.
    centre, spread : dict
        Training mean and standard deviation of each column (predictors are standardised
        before the products are formed, for conditioning).
    coefficients : ndarray, shape (n_modes, 1 + n_terms)
        Intercept and term coefficients of log f. [log Hz]
    covariance : ndarray, shape (n_modes, 1 + n_terms, 1 + n_terms)
        Newey-West (lag 3) covariance of the coefficients.
    residual_std : ndarray, shape (n_modes,)
        Robust (1.4826 MAD) standard deviation of the training residuals of log f. [-]
    train_start_block, train_end_block : int
        Training window.
    n_used : ndarray, shape (n_modes,)
        Blocks used per mode (after dropping missing estimates and wrong poles).
    """

    terms: tuple[str, ...]
    modes: tuple[int, ...]
    centre: dict[str, float]
    spread: dict[str, float]
    coefficients: np.ndarray
    covariance: np.ndarray
    residual_std: np.ndarray
    train_start_block: int
    train_end_block: int
    n_used: np.ndarray

    def design(self, predictors: pd.DataFrame) -> np.ndarray:
        """Design matrix [1, terms...] of *predictors* (NaN rows where a column is missing)."""
        return _design(predictors, self.terms, self.centre, self.spread)

    def reference_design(
        self, predictors: pd.DataFrame, start_block: int, blocks: int
    ) -> np.ndarray:
        """Mean design row [1, terms...] over the reference blocks *start_block* ..
        *start_block* + *blocks* - 1 of *predictors* (x̄_ref of :meth:`forecast`).

        Raises
        ------
        PredictorError
            When no reference block is in *predictors*.
        """
        stop = start_block + int(blocks) - 1
        inside = predictors["block"].between(start_block, stop).to_numpy()
        if not inside.any():
            raise PredictorError(
                f"the predictor table holds none of the reference blocks {start_block} to {stop}",
                parameter="reference_start_block",
                value=start_block,
            )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmean(self.design(predictors)[inside], axis=0)

    def predict_log(self, predictors: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Predicted log frequency and its standard error from the coefficients alone.

        Returns arrays of shape (n_blocks, n_modes). [log Hz], [-]
        """
        x = self.design(predictors)
        mean = x @ self.coefficients.T
        parameter_var = np.einsum("bi,mij,bj->bm", x, self.covariance, x)
        return mean, np.sqrt(np.maximum(parameter_var, 0.0))

    def forecast(
        self,
        modal: pd.DataFrame,
        predictors: pd.DataFrame,
        *,
        reference_start_block: int | None = None,
        reference_blocks: int | None = None,
        reference_design: np.ndarray | None = None,
        same_voyage: bool = True,
    ) -> pd.DataFrame:
        """FORECAST table (option A) of this model on the blocks of *predictors*.

        ``model_frequency_hz`` = exp(prediction); the 95 % bounds are exp(prediction ±
        1.96 s) with s² = residual variance + parameter variance at the block's predictors;
        phase 'train' inside the training window, 'forecast' elsewhere. There is no Kalman
        blending: ``kalman_frequency_hz`` is the model prediction and ``kalman_std_hz`` its
        standard deviation.

        With the health chart's reference period (*reference_start_block*,
        *reference_blocks*), the table also has ``model_shift_std``: the standard deviation
        of the model's error at the block minus its mean error over the reference blocks,
        √((x - x̄_ref)ᵀ C (x - x̄_ref)) with C the coefficients' covariance. [-] (relative)
        The chart learns the reference's mean error away; what is left is persistent
        (the EWMA does not average it out), so the chart adds it to its covariance.
        *reference_design* gives x̄_ref directly (the reference period of an earlier
        voyage, :meth:`reference_design`), instead of the reference blocks.

        With *same_voyage* False (a model saved from an earlier voyage), no block of
        *predictors* is a training block: every row is in the 'forecast' phase.
        """
        modal = MODAL.validate(modal)
        grid = predictors.sort_values("block").reset_index(drop=True)
        blocks = grid["block"].to_numpy()
        mean, parameter_std = self.predict_log(grid)
        shift_std = None
        if reference_design is None and reference_start_block is not None:
            if reference_blocks is not None:
                reference_design = self.reference_design(
                    grid, reference_start_block, reference_blocks
                )
        if reference_design is not None:
            dx = self.design(grid) - np.asarray(reference_design, dtype=float)
            shift_std = np.sqrt(
                np.maximum(np.einsum("bi,mij,bj->bm", dx, self.covariance, dx), 0.0)
            )
        std = np.sqrt(self.residual_std[None, :] ** 2 + parameter_std**2)
        measured = (
            modal[modal["mode"].isin(self.modes)]
            .pivot_table(index="block", columns="mode", values="frequency_hz", aggfunc="first")
            .reindex(index=blocks, columns=list(self.modes))
            .to_numpy(dtype=float)
        )
        n_blocks, n_modes = mean.shape
        block = np.repeat(blocks, n_modes)
        inside = (block >= self.train_start_block) & (block <= self.train_end_block)
        inside &= same_voyage
        frequency = np.exp(mean)
        table = pd.DataFrame(
            {
                "block": block,
                "block_start": np.repeat(grid["block_start"].to_numpy(), n_modes),
                "mode": np.tile(self.modes, n_blocks),
                "phase": np.where(inside, "train", "forecast"),
                "ssi_frequency_hz": measured.ravel(),
                "model_frequency_hz": frequency.ravel(),
                "model_lower_hz": np.exp(mean - _Z975 * std).ravel(),
                "model_upper_hz": np.exp(mean + _Z975 * std).ravel(),
                "kalman_frequency_hz": frequency.ravel(),
                "kalman_std_hz": (frequency * std).ravel(),
                "option": "A",
                "window_start_block": self.train_start_block,
                "window_end_block": self.train_end_block,
            }
        )
        if shift_std is not None:
            table["model_shift_std"] = shift_std.ravel()
        table = table[np.isfinite(table["model_frequency_hz"])]
        return FORECAST.validate(table.reset_index(drop=True))


def _design(
    predictors: pd.DataFrame,
    terms: Sequence[str],
    centre: dict[str, float],
    spread: dict[str, float],
) -> np.ndarray:
    columns = [np.ones(len(predictors))]
    for term in terms:
        factors = _parse(term)
        value = np.ones(len(predictors))
        for name in factors:
            value = value * (predictors[name].to_numpy(dtype=float) - centre[name]) / spread[name]
        columns.append(value)
    return np.column_stack(columns)


def _default_terms(
    predictors: pd.DataFrame, train_start_block: int, train_blocks: int
) -> tuple[str, ...]:
    """:data:`DEFAULT_TERMS` whose columns *predictors* holds with a value in the training
    window; warns naming the columns present without one and the terms they leave out."""
    stop = train_start_block + int(train_blocks) - 1
    window = predictors[predictors["block"].between(train_start_block, stop)]
    present = [t for t in DEFAULT_TERMS if all(c in predictors.columns for c in _parse(t))]
    empty = sorted(
        {c for t in present for c in _parse(t) if not window[c].notna().any()},
        key=list(predictors.columns).index,
    )
    left_out = [t for t in present if set(_parse(t)) & set(empty)]
    if empty and len(window):
        warnings.warn(
            f"the predictor table holds no value of {', '.join(empty)} in the training "
            f"window (blocks {train_start_block}-{stop}): the operational model leaves out "
            f"{', '.join(left_out)}",
            stacklevel=3,
        )
    return tuple(t for t in present if t not in left_out)


def _newey_west(x: np.ndarray, residual: np.ndarray, lags: int) -> np.ndarray:
    """HAC covariance (X'X)⁻¹ S (X'X)⁻¹ with Bartlett weights (Newey and West 1987)."""
    bread = np.linalg.pinv(x.T @ x)
    score = x * residual[:, None]
    meat = score.T @ score
    for lag in range(1, lags + 1):
        weight = 1.0 - lag / (lags + 1.0)
        cross = score[lag:].T @ score[:-lag]
        meat += weight * (cross + cross.T)
    return bread @ meat @ bread


def fit_operational_model(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    train_start_block: int = 0,
    train_blocks: int,
    terms: Sequence[str] | None = None,
    outlier_sigma: float = 4.0,
    hac_lags: int = 3,
) -> OperationalModel:
    """Fit the operational/environmental model of each mode on a training window.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors with a ``block`` column and the columns the terms name.
    train_start_block : int
        First block of the training window.
    train_blocks : int
        Length of the training window. It should span the operating range the ship will
        be monitored in (an extrapolated model is honest about it through wider bounds,
        but the chart then sees less). [blocks]
    terms : sequence of str, optional
        Model terms; default :data:`DEFAULT_TERMS` restricted to the columns present
        with a value in the training window (a column present without any, e.g. a
        sensor dead from the start, is left out with a warning naming it).
    outlier_sigma : float
        Estimates further than this many robust standard deviations from the fit (wrong
        poles, swapped labels) are dropped and the fit repeated (three passes). [-]
    hac_lags : int
        Lags of the Newey-West covariance: 3 for 20-min blocks every 5 min, whose errors
        correlate up to lag 3. [blocks]

    Returns
    -------
    OperationalModel

    Notes
    -----
    With f = f₀ √(k/m), log f = ½ log k - ½ log m is nearly linear in the stiffness and
    mass changes the terms stand for, so the model is linear in log f. Predictors are
    standardised with the training mean and standard deviation before squares and
    products are formed.

    References
    ----------
    .. [1] F. Magalhães, Á. Cunha, E. Caetano, "Vibration based structural health
       monitoring of an arch bridge: from automated OMA to damage detection", Mechanical
       Systems and Signal Processing 28, 2012. doi:10.1016/j.ymssp.2011.06.011
    .. [2] W. K. Newey, K. D. West, "A simple, positive semi-definite, heteroskedasticity
       and autocorrelation consistent covariance matrix", Econometrica 55(3), 1987.
       doi:10.2307/1913610
    """
    if int(train_blocks) != train_blocks or train_blocks < MIN_TRAIN_BLOCKS:
        raise ValueError(f"train_blocks={train_blocks!r} must be an integer >= {MIN_TRAIN_BLOCKS}")
    modal = MODAL.validate(modal)
    if "block" not in predictors.columns:
        raise PredictorError("the predictor table has no column 'block'")
    if terms is None:
        terms = _default_terms(predictors, train_start_block, train_blocks)
    terms = tuple(terms)
    names = sorted({c for t in terms for c in _parse(t)})
    missing = [c for c in names if c not in predictors.columns]
    if missing:
        raise PredictorError(
            f"the predictor table has no column {', '.join(map(repr, missing))}",
            parameter="terms",
            value=terms,
        )
    grid = predictors.sort_values("block").reset_index(drop=True)
    stop = train_start_block + int(train_blocks) - 1
    window = grid[(grid["block"] >= train_start_block) & (grid["block"] <= stop)]
    if len(window) < train_blocks:
        raise PredictorError(
            f"the predictor table holds only {len(window)} of the {train_blocks} blocks of "
            f"the training window from block {train_start_block}",
            parameter="train_blocks",
            value=train_blocks,
        )
    centre, spread = {}, {}
    for name in names:
        values = window[name].to_numpy(dtype=float)
        centre[name] = float(np.nanmean(values))
        sd = float(np.nanstd(values))
        spread[name] = sd if sd > 0 else 1.0
    x_all = _design(window, terms, centre, spread)
    modes = tuple(int(m) for m in sorted(modal["mode"].unique()))
    wide = (
        modal.pivot_table(index="block", columns="mode", values="frequency_hz", aggfunc="first")
        .reindex(index=window["block"].to_numpy(), columns=list(modes))
        .to_numpy(dtype=float)
    )
    n_coef = x_all.shape[1]
    kept, coefficients, covariances, scales, counts = [], [], [], [], []
    for j, mode in enumerate(modes):
        with np.errstate(invalid="ignore", divide="ignore"):
            y = np.log(wide[:, j])
        use = np.isfinite(y) & np.all(np.isfinite(x_all), axis=1)
        if use.sum() < 4 * n_coef:
            warnings.warn(
                f"mode {mode}: only {int(use.sum())} training blocks for {n_coef} "
                "coefficients; not modelled",
                stacklevel=2,
            )
            continue
        finite = use.copy()
        for _ in range(3):
            beta, *_ = np.linalg.lstsq(x_all[use], y[use], rcond=None)
            residual = np.where(finite, y - x_all @ np.where(np.isfinite(beta), beta, 0), np.nan)
            scale = 1.4826 * float(np.nanmedian(np.abs(residual[finite])))
            use = finite & (np.abs(residual) <= outlier_sigma * max(scale, 1e-12))
        beta, *_ = np.linalg.lstsq(x_all[use], y[use], rcond=None)
        # HAC over the used blocks in time order, dropped blocks counted as zero scores
        full_residual = np.where(use, y - x_all @ beta, 0.0)
        x_used = np.where(use[:, None], x_all, 0.0)
        covariance = _newey_west(x_used, full_residual, hac_lags)
        kept.append(mode)
        coefficients.append(beta)
        covariances.append(covariance)
        scales.append(1.4826 * float(np.median(np.abs(y[use] - x_all[use] @ beta))))
        counts.append(int(use.sum()))
    if not kept:
        raise ValueError("no mode has enough training blocks for the operational model")
    return OperationalModel(
        terms=terms,
        modes=tuple(kept),
        centre=centre,
        spread=spread,
        coefficients=np.array(coefficients),
        covariance=np.array(covariances),
        residual_std=np.array(scales),
        train_start_block=int(window["block"].iloc[0]),
        train_end_block=int(window["block"].iloc[-1]),
        n_used=np.array(counts),
    )


#: Stepwise options of the frozen model (see :func:`frozen_forecast`).
STEPWISE = {"start": "linear"}
#: Predictor clipping of the frozen model, in training-window standard deviations: high
#: enough that the fuel-burn trend extrapolates over the monitoring period.
EXTRAPOLATION_LIMIT = 100.0
#: Predictors of the stepwise model of :func:`frozen_forecast` (the log as the forecast
#: stage reads it: elapsed hours stand for the fuel state).
STEPWISE_PREDICTORS = ("speed_kn", "water_temp_c", "air_temp_c", "elapsed_hours")


def frozen_forecast(
    voyage: HealthVoyage,
    train_blocks: int,
    *,
    predictor_columns: tuple[str, ...] = STEPWISE_PREDICTORS,
) -> pd.DataFrame:
    """FORECAST table of a model trained once on the first *train_blocks* blocks.

    :func:`workbench.forecasting.sliding_forecast`, scheme 1 (single window: one forward
    prediction to the end of the voyage) on a voyage of
    :func:`~workbench.simulate.simulate_health_voyage`, option A, every linear term in the start model
    (``stepwise_options=STEPWISE``; interactions are left to the stepwise
    search), so the fuel-burn trend is part of the model even when 24 h show it weakly.
    Forecast warnings are silenced (they are kept in the table's ``warning`` column).
    """
    from ..forecasting import sliding_forecast
    from ..forecasting.options import ForecastOptions

    horizon = len(voyage.predictors) - int(train_blocks)
    if horizon < 1:
        raise ValueError(
            f"train_blocks={train_blocks} leaves no block to forecast "
            f"(voyage has {len(voyage.predictors)})"
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        options = ForecastOptions(
            model="window",
            scheme="single_window",
            options=("A",),
            train_blocks=int(train_blocks),
            horizon=horizon,
            stepwise_options=STEPWISE,
            extrapolation_limit=EXTRAPOLATION_LIMIT,
            predictor_columns=list(predictor_columns),
        )
        result = sliding_forecast(voyage.modal, voyage.predictors, options)
    return result.table
