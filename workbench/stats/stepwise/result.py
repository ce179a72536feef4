"""The fitted model of a stepwise search: coefficients, step history, prediction with
confidence or prediction intervals, a text summary and a JSON description."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy import special as _special

from ..design import Encoding, column_labels, design_columns, raw_transform
from ..distributions import t_quantile
from ..terms import Term

__all__ = ["StepwiseFit", "StepwiseWarning"]


class StepwiseWarning(UserWarning):
    """A stepwise search that did not end by its rules: it cycled, or reached the default
    step limit (the fit's :attr:`StepwiseFit.search_warnings` say which model it kept)."""


_INTERVAL_COLUMNS = pd.Index(["mean", "lower", "upper", "mean_se"], dtype=object)
_COEFFICIENT_COLUMNS = pd.Index(["estimate", "se", "t_stat", "p_value"], dtype=object)


def _to_float(frame: pd.DataFrame) -> np.ndarray:
    """Float array of a numeric frame (pandas NA becomes NaN)."""
    try:
        return frame.to_numpy(dtype=float)
    except (TypeError, ValueError):  # nullable dtypes holding pd.NA
        return frame.to_numpy(dtype=float, na_value=np.nan)


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class StepwiseFit:
    """Result of :func:`stepwise`: the selected linear model and how it was found.

    Parameters
    ----------
    terms : tuple of str
        Non-constant terms of the final model in canonical order (``"x1"``, ``"x1:x2"``);
        the intercept is always in the model and listed in :attr:`coefficients`.
    predictor_names : tuple of str
        All predictor columns the search saw (DataFrame columns, or x1..xn).
    response_name : str
        Name of the response (Series name, or ``"y"``).
    criterion : {"sse", "aic", "bic", "rsquared", "adjrsquared"}
        Criterion of the search.
    p_enter, p_remove : float
        Thresholds used.
    n_obs : int
        Observations of the final model: rows with the response and every predictor of the
        final model finite (``missing="candidate"``), or with every predictor of the upper
        model finite (``missing="complete"``).
    dfe : int
        Error degrees of freedom, ``n_obs`` minus the number of coefficients.
    sse : float
        Residual sum of squares. [response unit²]
    rmse : float
        Root mean squared error ``sqrt(sse / dfe)``. [response unit]
    r_squared, adj_r_squared : float
        Coefficient of determination and its adjusted version.
    f_stat, f_p_value : float
        F-test of the model against the constant model (NaN for the constant model).
    log_likelihood, aic, bic : float
        Gaussian log-likelihood and MATLAB's information criteria
        (``-2 logL + 2 k`` and ``-2 logL + k ln n``, k coefficients).
    search_warnings : tuple of str
        Why the search ended other than by its rules (a cycle of models, the default step
        limit), with the model kept; empty when it ended by its rules.

    Notes
    -----
    Properties :attr:`coefficients`, :attr:`steps` and :attr:`skipped` are DataFrames built
    on first access. Coefficients are in raw units of the predictors (one row per design
    column: a categorical term has one row per non-reference level, ``Year_76``).
    Standard errors are ``rmse * sqrt(diag((X'X)^-1))`` and p-values two-sided from
    Student's t with ``dfe`` degrees of freedom. The model is held in the search's
    centred units (:attr:`search_estimates`, :attr:`term_means`,
    :attr:`slope_covariance`), which :meth:`predict` uses; the raw-unit
    :attr:`estimates` and :attr:`standard_errors` are computed from them on first access
    (a sliding forecast that only predicts never needs them).
    """

    terms: tuple[str, ...]
    predictor_names: tuple[str, ...]
    response_name: str
    criterion: str
    p_enter: float
    p_remove: float
    n_obs: int
    dfe: int
    sse: float
    rmse: float
    r_squared: float
    adj_r_squared: float
    f_stat: float
    f_p_value: float
    log_likelihood: float
    aic: float
    bic: float
    model_terms: tuple[Term, ...] = field(repr=False)
    search_estimates: np.ndarray = field(repr=False)
    term_means: np.ndarray = field(repr=False)
    slope_covariance: np.ndarray = field(repr=False)
    step_records: tuple[tuple, ...] = field(repr=False, default=())
    skipped_records: tuple[tuple, ...] = field(repr=False, default=())
    coefficient_names: tuple[str, ...] = field(repr=False, default=())
    coefficient_terms: tuple[Term, ...] = field(repr=False, default=())
    encoding: Encoding | None = field(repr=False, default=None)
    missing: str = "candidate"
    search_warnings: tuple[str, ...] = ()

    # ----------------------------------------------------------------- raw units
    @functools.cached_property
    def _raw_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """(estimates, standard errors) in raw units from the model in centred units.

        With x̄ the term means and V = (X_cᵀX_c)⁻¹ of the centred slope columns, the
        covariance of (intercept, slopes) per σ² is [[1/n + x̄ᵀVx̄, -(Vx̄)ᵀ], [-Vx̄, V]];
        b_raw = A b and Cov_raw = A Cov Aᵀ with A of
        :func:`~workbench.stats.design.raw_transform`.
        """
        covariance = self.slope_covariance
        term_means = self.term_means
        m = term_means.shape[0]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            full = np.empty((m + 1, m + 1))
            full[0, 0] = 1.0 / self.n_obs + float(term_means @ covariance @ term_means)
            full[0, 1:] = full[1:, 0] = -(covariance @ term_means)
            full[1:, 1:] = covariance
            encoding = self.encoding
            transform = None if encoding is None else raw_transform(self.model_terms, encoding)
            if transform is None:  # cannot happen with the hierarchy kept: centred units
                transform = np.eye(m + 1)
            estimates = transform @ self.search_estimates
            raw_covariance = transform @ full @ transform.T
            standard_errors = self.rmse * np.sqrt(np.maximum(np.diagonal(raw_covariance), 0.0))
        return estimates, standard_errors

    @property
    def estimates(self) -> np.ndarray:
        """Coefficients in raw units, intercept first (one per design column)."""
        return self._raw_coefficients[0]

    @property
    def standard_errors(self) -> np.ndarray:
        """Standard errors of :attr:`estimates`. [units of the coefficients]"""
        return self._raw_coefficients[1]

    # ----------------------------------------------------------------- tables
    @functools.cached_property
    def coefficients(self) -> pd.DataFrame:
        """Estimate, standard error, t statistic and two-sided p-value, indexed by term."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_stat = self.estimates / self.standard_errors
        p_value = 2.0 * _special.stdtr(self.dfe, -np.abs(t_stat))
        names = list(self.coefficient_names) or ["(Intercept)", *self.terms]
        return pd.DataFrame(
            np.column_stack([self.estimates, self.standard_errors, t_stat, p_value]),
            columns=_COEFFICIENT_COLUMNS,
            index=pd.Index(names, dtype=object, name="term"),
        )

    @functools.cached_property
    def steps(self) -> pd.DataFrame:
        """Step history: step, action ("add"/"remove"), term, f_stat, p_value.

        For the other criteria two more columns give the criterion of the model after the
        step and its change (``aic``, ``aic_change``; for ``rsquared`` the change is the R²
        gained with the term). Then ``df`` (numerator degrees of freedom: the term's
        columns) and ``n_obs`` (rows of the larger of the two models compared; both models
        of the step's F-test are fitted on these rows).

        A search stopped by the cycle guard ends with a row of action ``"stop"`` whose term
        is the kept model (``"1 + a + b"``), with its F-test against the constant model
        (``df`` its coefficients besides the intercept) on the ``n_obs`` rows complete in
        the variables of every model of the cycle; see :attr:`search_warnings`.
        """
        columns = ["step", "action", "term", "f_stat", "p_value"]
        if self.criterion != "sse":
            columns += [self.criterion, f"{self.criterion}_change"]
        columns += ["df", "n_obs"]
        rows = [record[: len(columns)] for record in self.step_records]
        frame = pd.DataFrame(rows, columns=columns)
        return frame.astype(
            {"step": "int64", "f_stat": float, "p_value": float, "df": "int64", "n_obs": "int64"}
        )

    @functools.cached_property
    def skipped(self) -> pd.DataFrame:
        """Candidates not tested (step, term, reason): collinear, too few observations or
        an exact fit.

        Each (term, reason) pair is listed once, at the first step it occurred.
        """
        return pd.DataFrame(list(self.skipped_records), columns=["step", "term", "reason"])

    @property
    def formula(self) -> str:
        """The final model in Wilkinson notation, e.g. ``"y ~ 1 + x1 + x2"``."""
        return f"{self.response_name} ~ " + " + ".join(["1", *self.terms])

    @functools.cached_property
    def used_predictors(self) -> tuple[str, ...]:
        """Predictor columns appearing in the final model's terms, in column order."""
        used = sorted({i for term in self.model_terms for i in term})
        return tuple(self.predictor_names[i] for i in used)

    # ----------------------------------------------------------------- prediction
    def _predictor_values(self, X) -> tuple[np.ndarray, pd.Index | None]:
        encoding = self.encoding
        if encoding is not None and any(encoding.categorical):
            return self._encoded_values(X)
        if isinstance(X, pd.DataFrame):
            columns = column_labels(X.columns)
            if columns == self.predictor_names:
                # the fitted columns in the fitted order (a sliding forecast's windows): the
                # whole frame as is; columns the model does not use are never read
                try:
                    return _to_float(X), X.index
                except (TypeError, ValueError):
                    pass  # a column the model does not use is not numeric
            needed = self.used_predictors
            if not all(type(name) is str for name in columns):
                columns = [str(name) for name in columns]
            lookup = {name: i for i, name in enumerate(columns)}
            missing = [name for name in needed if name not in lookup]
            if missing:
                raise ValueError(f"X is missing predictor column {missing[0]!r} used by the model")
            values = np.empty((len(X), len(self.predictor_names)))
            values.fill(np.nan)
            if needed:
                positions = [self.predictor_names.index(name) for name in needed]
                source = [lookup[name] for name in needed]
                # one conversion of the whole frame is cheapest (pandas column selection by a
                # list of names costs far more than a small fit); column by column otherwise
                try:
                    block = _to_float(X)[:, source]
                except (TypeError, ValueError):
                    block = np.column_stack(
                        [X.iloc[:, i].to_numpy(dtype=float, na_value=np.nan) for i in source]
                    )
                values[:, positions] = block
            return values, X.index
        return self._predictor_array(X, float), None

    def _predictor_array(self, X, dtype) -> np.ndarray:
        """*X* (not a DataFrame) as rows of the fitted predictor columns; one row if 1-D."""
        values = np.asarray(X, dtype=dtype)
        if values.ndim == 1:
            values = values[None, :] if len(self.predictor_names) > 1 else values[:, None]
        if values.ndim != 2 or values.shape[1] != len(self.predictor_names):
            raise ValueError(
                f"X has shape {np.shape(X)}; the model was fitted on "
                f"{len(self.predictor_names)} predictor columns"
            )
        return values

    def _encoded_values(self, X) -> tuple[np.ndarray, pd.Index | None]:
        """Predictor values with categorical columns as level codes of the fit."""
        encoding = self.encoding
        index = X.index if isinstance(X, pd.DataFrame) else None
        if not isinstance(X, pd.DataFrame):
            array = self._predictor_array(X, object)
            X = pd.DataFrame(array, columns=list(self.predictor_names))
        lookup = {str(name): name for name in X.columns}
        values = np.full((len(X), len(self.predictor_names)), np.nan)
        for name in self.used_predictors:
            if name not in lookup:
                raise ValueError(f"X is missing predictor column {name!r} used by the model")
            j = self.predictor_names.index(name)
            column = X[lookup[name]]
            if encoding.levels[j] is None:
                values[:, j] = pd.to_numeric(column, errors="coerce").to_numpy(dtype=float)
            else:
                values[:, j] = encoding.codes(column, j)
        return values, index

    def predict(
        self,
        X,
        *,
        interval: Literal["confidence", "prediction"] | None = None,
        alpha: float = 0.05,
    ) -> np.ndarray | pd.DataFrame:
        """Predict the response, optionally with two-sided intervals.

        Parameters
        ----------
        X : DataFrame or ndarray
            New predictor values: a DataFrame with (at least) the columns the model uses,
            or an array with the same columns as the fitted one.
        interval : {None, "confidence", "prediction"}
            ``None``: return the predicted means. ``"confidence"``: interval for the mean
            response (MATLAB ``'Prediction','curve'``). ``"prediction"``: interval for a
            new observation (``'observation'``).
        alpha : float
            Intervals have confidence ``1 - alpha``.

        Returns
        -------
        ndarray or DataFrame
            Means (shape ``(n_rows,)``), or a DataFrame with columns ``mean``, ``lower``,
            ``upper`` and ``mean_se``, the standard error of the mean s √h (index of *X*
            when it is a DataFrame). Rows with NaN in a predictor
            the model uses are NaN.

        Notes
        -----
        With x the row of the design matrix, s the RMSE and h = x (X'X)⁻¹ x' its leverage
        (computed as 1/n + (x - x̄)ᵀ (X_cᵀX_c)⁻¹ (x - x̄) with centred columns X_c):
        confidence bounds ŷ ± t s √h, prediction bounds ŷ ± t s √(1 + h), t the
        ``1 - alpha/2`` quantile of Student's t with ``dfe`` degrees of freedom.
        """
        if interval not in (None, "confidence", "prediction"):
            raise ValueError(f"interval={interval!r}: expected None, 'confidence' or 'prediction'")
        if not 0.0 < alpha < 1.0:
            raise ValueError(f"alpha={alpha!r} must lie in (0, 1)")
        values, index = self._predictor_values(X)
        design = design_columns(values, self.model_terms, self.encoding)  # centred units
        mean = design @ self.search_estimates
        if interval is None:
            return mean
        # leverage in centred form, h = 1/n + (x - x̄)ᵀ V (x - x̄), V = (X_cᵀX_c)⁻¹
        centred = design[:, 1:] - self.term_means
        leverage = 1.0 / self.n_obs + np.einsum(
            "ij,ij->i", centred @ self.slope_covariance, centred
        )
        mean_se = self.rmse * np.sqrt(leverage)  # standard error of the mean, s √h
        if interval == "prediction":
            leverage = leverage + 1.0
        half = t_quantile(1.0 - alpha / 2.0, self.dfe) * self.rmse * np.sqrt(leverage)
        # one (4, n) block, handed to pandas transposed: its column layout, no copy
        table = np.empty((4, len(mean)))
        table[0] = mean
        np.subtract(mean, half, out=table[1])
        np.add(mean, half, out=table[2])
        table[3] = mean_se
        return pd.DataFrame(
            table.T,
            columns=_INTERVAL_COLUMNS,
            index=index if index is not None else pd.RangeIndex(len(mean)),
            copy=False,
        )

    def residuals(self, X, y) -> np.ndarray:
        """Observed minus predicted response (NaN where either is missing)."""
        return np.asarray(y, dtype=float).ravel() - self.predict(X)

    # ----------------------------------------------------------------- reporting
    def summary(self) -> str:
        """A text summary in the manner of MATLAB's display of a LinearModel."""
        rows = (
            "each model on the rows complete in its own variables (MATLAB stepwiselm)"
            if self.missing == "candidate"
            else "rows complete in every candidate predictor (MATLAB stepwisefit)"
        )
        lines = [
            f"Stepwise linear regression ({self.criterion}, p_enter={self.p_enter:g}, "
            f"p_remove={self.p_remove:g})",
            f"    {self.formula}",
            f"Missing values: {rows}",
            "F-tests: each step compares its two models on one sample, the rows complete in "
            "the larger model's variables ([n rows] when not the final model's)",
            *(f"Warning: {text}" for text in self.search_warnings),
            "",
        ]
        if len(self.step_records):
            for record in self.step_records:
                step, action, term, f_stat, p_value = record[:5]
                if action == "stop":
                    lines.append(
                        f"{step}. Stopping: the search cycled; kept {self.response_name} ~ "
                        f"{term} (best of the cycle by {self.criterion}, "
                        f"{record[-1]} rows complete in the cycle's variables)"
                    )
                    continue
                verb = "Adding" if action == "add" else "Removing"
                text = f"{step}. {verb} {term}, FStat = {f_stat:.4f}, pValue = {p_value:.6g}"
                if self.criterion != "sse":
                    text += f", {self.criterion} = {record[5]:.4f}"
                df, n_obs = record[-2:]
                if df != 1:
                    text += f" ({df} df)"
                if n_obs != self.n_obs:
                    text += f" [{n_obs} rows]"
                lines.append(text)
            lines.append("")
        table = self.coefficients
        width = max(12, *(len(name) for name in table.index))
        lines.append(f"{'':<{width}} {'Estimate':>12} {'SE':>12} {'tStat':>10} {'pValue':>12}")
        for name, row in table.iterrows():
            lines.append(
                f"{name:<{width}} {row['estimate']:>12.6g} {row['se']:>12.6g} "
                f"{row['t_stat']:>10.4g} {row['p_value']:>12.4g}"
            )
        lines += [
            "",
            f"Number of observations: {self.n_obs}, Error degrees of freedom: {self.dfe}",
            f"Root Mean Squared Error: {self.rmse:.4g}",
            f"R-squared: {self.r_squared:.4g},  Adjusted R-Squared: {self.adj_r_squared:.4g}",
        ]
        if self.terms:
            lines.append(
                f"F-statistic vs. constant model: {self.f_stat:.4g}, p-value = {self.f_p_value:.4g}"
            )
        if len(self.skipped_records):
            lines.append("Candidates not tested:")
            lines += [f"  step {s}: {term}: {reason}" for s, term, reason in self.skipped_records]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable description (non-finite numbers become ``None``)."""

        def number(value):
            value = float(value)
            return value if math.isfinite(value) else None

        coefficients = {
            str(name): {key: number(row[key]) for key in ("estimate", "se", "t_stat", "p_value")}
            for name, row in self.coefficients.iterrows()
        }
        steps = [
            {
                key: (number(value) if isinstance(value, float) else value)
                for key, value in zip(self.steps.columns, record, strict=False)
            }
            for record in self.step_records
        ]
        return {
            "formula": self.formula,
            "response": self.response_name,
            "terms": list(self.terms),
            "predictors": list(self.predictor_names),
            "criterion": self.criterion,
            "missing": self.missing,
            "warnings": list(self.search_warnings),
            "p_enter": number(self.p_enter),
            "p_remove": number(self.p_remove),
            "coefficients": coefficients,
            "steps": steps,
            "skipped": [
                {"step": int(s), "term": term, "reason": reason}
                for s, term, reason in self.skipped_records
            ],
            "n_obs": int(self.n_obs),
            "dfe": int(self.dfe),
            "sse": number(self.sse),
            "rmse": number(self.rmse),
            "r_squared": number(self.r_squared),
            "adj_r_squared": number(self.adj_r_squared),
            "f_stat": number(self.f_stat),
            "f_p_value": number(self.f_p_value),
            "log_likelihood": number(self.log_likelihood),
            "aic": number(self.aic),
            "bic": number(self.bic),
        }
