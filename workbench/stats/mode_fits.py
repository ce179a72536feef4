"""One stepwise regression per tracked mode on the block predictors.

:func:`fit_modes` fits every mode's frequency (or damping ratio) on the predictors of the
same blocks with :func:`~workbench.stats.stepwise`, and attaches the residual diagnostics;
:func:`coefficient_table` lines the models up (one row per mode, one column per term, 0
where a mode's model leaves a term out) and :func:`fit_statistics_table` gives their
goodness of fit. The report with figures is
:func:`workbench.stages.fit` (written by
:func:`workbench.reporting.diagnostics_plot.write_fit_report`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from ..errors import PredictorError
from .correlation import joined_blocks
from .diagnostics import ResidualDiagnostics, residual_diagnostics
from .stepwise import StepwiseFit, stepwise
from .stepwise.sweep import COLLINEARITY_TOLERANCE
from .terms import term_key

__all__ = [
    "ModeFit",
    "StatsWarning",
    "coefficient_table",
    "fit_modes",
    "fit_statistics_table",
]


class StatsWarning(UserWarning):
    """A mode or predictor was left out of a statistical analysis (the reason is given)."""


@dataclass(frozen=True)
class ModeFit:
    """Stepwise model of one mode with its data and residual diagnostics.

    Parameters
    ----------
    mode : int
        Mode label.
    quantity : str
        Modelled column of the modal table (``frequency_hz`` or ``damping_ratio``).
    fit : StepwiseFit
        The selected model.
    blocks : ndarray of int
        Blocks the fit used (the response and the final model's predictors finite), in
        order.
    observed, fitted, residuals : ndarray
        Response, model values and residuals on those blocks. [quantity unit]
    diagnostics : ResidualDiagnostics
        Durbin-Watson and normality tests of the residuals in block order (Durbin-Watson
        within runs of consecutive blocks).
    """

    mode: int
    quantity: str
    fit: StepwiseFit
    blocks: np.ndarray
    observed: np.ndarray
    fitted: np.ndarray
    residuals: np.ndarray
    diagnostics: ResidualDiagnostics

    def to_dict(self) -> dict:
        """JSON-serialisable model and diagnostics."""
        return {
            "mode": int(self.mode),
            "quantity": self.quantity,
            "model": self.fit.to_dict(),
            "diagnostics": self.diagnostics.to_dict(),
            "blocks": [int(b) for b in self.blocks],
        }


def _usable_predictors(
    joined: pd.DataFrame, names: Sequence[str], explicit: bool, missing: str = "candidate"
) -> list[str]:
    """Predictor columns fit to enter a model.

    An all-NaN, constant or collinear column is a :class:`~workbench.errors.
    PredictorError` (a ValueError) naming it when the caller chose the predictors
    (*explicit*), and is left out with a :class:`StatsWarning` when they were taken by
    default (every numeric column of the table); none left is a PredictorError too.
    """

    def reject(message: str) -> None:
        if explicit:
            raise PredictorError(message)
        warnings.warn(f"{message}; left out of the models", StatsWarning, stacklevel=4)

    kept: list[str] = []
    for name in names:
        finite = joined[name].to_numpy(dtype=float)
        finite = finite[np.isfinite(finite)]
        if finite.size == 0:
            reject(f"predictor {name!r} has no finite value in any block")
        elif np.ptp(finite) <= 1e-12 * max(1.0, float(np.abs(finite).max())):
            reject(f"predictor {name!r} is constant ({finite[0]:g}) in every block")
        else:
            kept.append(name)
    if not kept:
        raise PredictorError("no usable predictor column (all NaN or constant)")
    values = joined[kept].to_numpy(dtype=float)
    complete = np.isfinite(values).all(axis=1)
    if complete.sum() <= len(kept):
        if missing == "candidate":
            # each model uses its own complete rows: collinearity is judged by the search
            return kept
        raise ValueError(
            f"only {int(complete.sum())} blocks have every predictor finite; "
            f"{len(kept) + 1} are needed for {len(kept)} predictors ({', '.join(kept)})"
        )
    centred = values[complete] - values[complete].mean(axis=0)
    centred /= np.linalg.norm(centred, axis=0)
    independent: list[int] = []
    for j, name in enumerate(kept):
        # 1 - R² of column j on the columns kept before it (unit-norm, centred columns)
        basis = centred[:, independent]
        residual = centred[:, j] - basis @ np.linalg.lstsq(basis, centred[:, j], rcond=None)[0]
        if float(residual @ residual) <= COLLINEARITY_TOLERANCE:
            others = ", ".join(repr(kept[i]) for i in independent)
            reject(
                f"predictors are rank deficient: {name!r} is a linear combination of "
                f"{others or 'a constant'}"
            )
        else:
            independent.append(j)
    return [kept[i] for i in independent]


def fit_modes(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    quantity: str = "frequency_hz",
    predictors_used: Sequence[str] | None = None,
    modes: Sequence[int] | None = None,
    errors: Literal["raise", "warn"] = "raise",
    alpha: float = 0.05,
    **stepwise_options,
) -> dict[int, ModeFit]:
    """Fit a stepwise regression per mode of *quantity* on the block predictors.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract): ``block``, ``mode``, *quantity*.
    predictors : DataFrame
        Block predictors (PREDICTORS contract, extra numeric columns allowed), already on
        the modal table's blocks.
    quantity : str
        Modal column modelled: ``frequency_hz`` [Hz] or ``damping_ratio`` [-].
    predictors_used : sequence of str, optional
        Candidate predictors; default every numeric predictor column except keys and times
        (of those, all-NaN, constant and collinear columns are left out with a
        :class:`StatsWarning`). They enter in raw units (coefficients per unit of each
        column).
    modes : sequence of int, optional
        Modes to fit; default every mode of *modal*.
    errors : {"raise", "warn"}
        A mode without enough data: raise a ValueError naming it, or leave it out with a
        :class:`StatsWarning`.
    alpha : float
        Level of the residual normality flag.
    **stepwise_options
        Passed to :func:`~workbench.stats.stepwise` (``upper``, ``p_enter``, ``criterion``...).

    Returns
    -------
    dict of int -> ModeFit
        In mode order.

    Raises
    ------
    ValueError
        Missing columns, an all-NaN, constant or collinear predictor among
        *predictors_used*, or (with ``errors="raise"``) a mode with no finite *quantity* or
        too few complete blocks.
    """
    if errors not in ("raise", "warn"):
        raise ValueError(f"errors={errors!r}: expected 'raise' or 'warn'")
    for column in ("block", "mode", quantity):
        if column not in modal.columns:
            raise ValueError(f"modal table has no column {column!r}")
    joined, mode_columns, names = joined_blocks(
        modal, predictors, quantities=(quantity,), predictors_used=predictors_used
    )
    missing = stepwise_options.get("missing", "candidate")
    names = _usable_predictors(joined, names, explicit=predictors_used is not None, missing=missing)
    available = {int(c[len("mode") : -len(quantity) - 1]): c for c in mode_columns}
    wanted = sorted(available) if modes is None else [int(m) for m in modes]
    X = joined[names]
    blocks = joined.index.to_numpy()
    fits: dict[int, ModeFit] = {}
    for mode in wanted:
        try:
            if mode not in available:
                raise ValueError(f"mode {mode}: not in the modal table")
            y = joined[available[mode]].to_numpy(dtype=float)
            if not np.isfinite(y).any():
                raise ValueError(f"mode {mode}: no finite {quantity} in any predictor block")
            finite_x = np.isfinite(X.to_numpy(dtype=float))
            if missing == "complete":
                complete = np.isfinite(y) & finite_x.all(axis=1)
                needed = "every predictor finite"
            else:
                complete = np.isfinite(y) & finite_x.any(axis=1)
                needed = "a finite predictor"
            if complete.sum() < 3:
                raise ValueError(
                    f"mode {mode}: only {int(complete.sum())} blocks with {quantity} and "
                    f"{needed}; at least 3 are needed"
                )
            fit = stepwise(X, pd.Series(y, name=f"mode{mode}_{quantity}"), **stepwise_options)
        except ValueError as error:
            if errors == "raise":
                raise
            warnings.warn(f"{error}; mode left out", StatsWarning, stacklevel=2)
            continue
        # the blocks of the final model: the response and the predictors it uses finite
        used = [names.index(name) for name in fit.used_predictors]
        complete = np.isfinite(y) & finite_x[:, used].all(axis=1)
        if missing == "complete":
            complete &= finite_x.all(axis=1)
        fitted = np.asarray(fit.predict(X[complete]), dtype=float)
        observed = y[complete]
        residuals = observed - fitted
        fits[mode] = ModeFit(
            mode=mode,
            quantity=quantity,
            fit=fit,
            blocks=blocks[complete],
            observed=observed,
            fitted=fitted,
            residuals=residuals,
            diagnostics=residual_diagnostics(residuals, alpha=alpha, blocks=blocks[complete]),
        )
    return fits


def _as_fits(fits: Mapping[int, ModeFit | StepwiseFit]) -> dict[int, StepwiseFit]:
    return {int(m): (f.fit if isinstance(f, ModeFit) else f) for m, f in fits.items()}


def coefficient_table(fits: Mapping[int, ModeFit | StepwiseFit]) -> pd.DataFrame:
    """Estimates of every mode's model side by side: 0 where a term is not in a model.

    Parameters
    ----------
    fits : mapping of int -> ModeFit or StepwiseFit
        Output of :func:`fit_modes` (or stepwise fits keyed by mode).

    Returns
    -------
    DataFrame
        Index ``mode``; columns ``(Intercept)`` then every coefficient selected for any mode
        in canonical term order (main effects in predictor order, interactions, squares;
        a categorical term has one column per non-reference level). [quantity unit per
        predictor unit]
    """
    stepwise_fits = _as_fits(fits)
    if not stepwise_fits:
        return pd.DataFrame(index=pd.Index([], name="mode", dtype="int64"))
    order: dict[str, tuple] = {}
    for fit in stepwise_fits.values():
        for position, (name, term) in enumerate(
            zip(fit.coefficient_names, fit.coefficient_terms, strict=True)
        ):
            order.setdefault(name, (term_key(term), position))
    columns = sorted(order, key=order.__getitem__)
    table = pd.DataFrame(0.0, index=pd.Index(sorted(stepwise_fits), name="mode"), columns=columns)
    for mode, fit in stepwise_fits.items():
        estimates = fit.coefficients["estimate"]
        table.loc[mode, list(estimates.index)] = estimates.to_numpy()
    return table


def fit_statistics_table(fits: Mapping[int, ModeFit]) -> pd.DataFrame:
    """Goodness of fit and residual diagnostics, one row per mode.

    Columns: ``formula``, ``n_obs``, ``dfe``, ``rmse``, ``r_squared``, ``adj_r_squared``,
    ``f_stat``, ``f_p_value``, ``aic``, ``bic``, ``durbin_watson``, ``normality_p_value``,
    ``steps``.
    """
    rows = []
    for mode, item in sorted(fits.items()):
        fit = item.fit if isinstance(item, ModeFit) else item
        diagnostics = item.diagnostics if isinstance(item, ModeFit) else None
        rows.append(
            {
                "mode": int(mode),
                "formula": fit.formula,
                "n_obs": fit.n_obs,
                "dfe": fit.dfe,
                "rmse": fit.rmse,
                "r_squared": fit.r_squared,
                "adj_r_squared": fit.adj_r_squared,
                "f_stat": fit.f_stat,
                "f_p_value": fit.f_p_value,
                "aic": fit.aic,
                "bic": fit.bic,
                "durbin_watson": diagnostics.durbin_watson if diagnostics else np.nan,
                "normality_p_value": diagnostics.normality_p_value if diagnostics else np.nan,
                "steps": len(fit.step_records),
            }
        )
    return pd.DataFrame(rows).set_index("mode") if rows else pd.DataFrame()
