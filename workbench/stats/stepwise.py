"""Stepwise linear regression with two-way interactions, following MATLAB ``stepwiselm``.

:func:`stepwise` searches between a start model and an upper model by partial F-tests
(criterion ``"sse"``) or by the change in AIC/BIC, with MATLAB's rules: add first, remove
only when nothing enters, hierarchy in both directions, no immediate undo, intercept kept.
It returns a :class:`StepwiseFit` (coefficients, step history, goodness of fit,
``predict`` with confidence or prediction intervals). :class:`StepwiseRegressor` wraps it as
a scikit-learn estimator.

The search works on the cross-product matrix of the centred and scaled candidate columns
and the response, built once per fit, with Goodnight's sweep operator: after sweeping the
model's terms the matrix holds every candidate's residual cross-products (so each candidate's
residual sum of squares costs a division) and, for the model's terms, the coefficients and
(X'X)⁻¹. A step costs O(m²) for m candidate terms, independent of the number of rows; a
20-row search over 5 predictors and their 10 interactions takes a few hundred microseconds,
which matters because the sliding forecast refits a model for every mode and window.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy import special as _special
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from .terms import Term, parse_terms, term_name

__all__ = ["StepwiseFit", "StepwiseRegressor", "stepwise"]

Criterion = Literal["sse", "aic", "bic"]

#: Default thresholds per criterion (MATLAB ``stepwiselm``): (p_enter, p_remove).
DEFAULT_THRESHOLDS = {"sse": (0.05, 0.10), "aic": (0.0, 0.01), "bic": (0.0, 0.01)}

#: A candidate is collinear with the model (never added) when the fraction of its centred
#: sum of squares left unexplained by the model's terms, 1 - R²_j, is at most this.
COLLINEARITY_TOLERANCE = 1e-10

_INTERVAL_COLUMNS = pd.Index(["mean", "lower", "upper", "mean_se"], dtype=object)
_COEFFICIENT_COLUMNS = pd.Index(["estimate", "se", "t_stat", "p_value"], dtype=object)


def _f_sf(f: np.ndarray | float, df_num: float, df_den: float) -> np.ndarray:
    """Upper tail P(F > f) of the F(df_num, df_den) distribution."""
    return _special.fdtrc(df_num, df_den, f)


@functools.lru_cache(maxsize=1024)
def _t_quantile(probability: float, dof: int) -> float:
    """Student-t quantile (cached: every window of a sliding forecast asks for the same)."""
    return float(_special.stdtrit(dof, probability))


# --------------------------------------------------------------------------- design matrix
def _design(values: np.ndarray, terms: Sequence[Term]) -> np.ndarray:
    """Design matrix with one column per term (intercept ones, main effects, products)."""
    out = np.empty((values.shape[0], len(terms)))
    for k, term in enumerate(terms):
        if not term:
            out[:, k] = 1.0
        elif len(term) == 1:
            out[:, k] = values[:, term[0]]
        else:
            np.multiply(values[:, term[0]], values[:, term[1]], out=out[:, k])
    return out


def _to_float(frame: pd.DataFrame) -> np.ndarray:
    """Float array of a numeric frame (pandas NA becomes NaN)."""
    try:
        return frame.to_numpy(dtype=float)
    except (TypeError, ValueError):  # nullable dtypes holding pd.NA
        return frame.to_numpy(dtype=float, na_value=np.nan)


def _as_matrix(X, parameter: str = "X") -> tuple[np.ndarray, tuple[str, ...]]:
    """Float matrix and column names of a DataFrame or array (names x1..xn for arrays)."""
    if isinstance(X, pd.DataFrame):
        names = tuple(X.columns.tolist())
        if not all(type(name) is str for name in names):
            names = tuple(map(str, names))
        if len(set(names)) != len(names):
            raise ValueError(f"{parameter} has duplicate column names: {list(names)}")
        bad = [c for c in names if ":" in c]
        if bad:
            raise ValueError(f"{parameter} column {bad[0]!r}: ':' is reserved for interactions")
        try:
            values = _to_float(X)
        except (TypeError, ValueError) as error:
            numeric = set(X.select_dtypes("number").columns.map(str))
            other = [c for c in names if c not in numeric]
            raise TypeError(
                f"{parameter} column {other[0] if other else '?'!r} is not numeric"
            ) from error
        return values, names
    values = np.asarray(X, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2:
        raise ValueError(
            f"{parameter} must be 2-D (observations x predictors), got {values.ndim}-D"
        )
    return values, tuple(f"x{i + 1}" for i in range(values.shape[1]))


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
    criterion : {"sse", "aic", "bic"}
        Criterion of the search.
    p_enter, p_remove : float
        Thresholds used.
    n_obs : int
        Observations used (rows without NaN in the response or a predictor of the upper
        model).
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

    Notes
    -----
    Properties :attr:`coefficients`, :attr:`steps` and :attr:`skipped` are DataFrames built
    on first access. Coefficient standard errors are ``rmse * sqrt(diag((X'X)^-1))`` and
    p-values two-sided from Student's t with ``dfe`` degrees of freedom.
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
    estimates: np.ndarray = field(repr=False)
    standard_errors: np.ndarray = field(repr=False)
    term_means: np.ndarray = field(repr=False)
    slope_covariance: np.ndarray = field(repr=False)
    step_records: tuple[tuple, ...] = field(repr=False, default=())
    skipped_records: tuple[tuple, ...] = field(repr=False, default=())

    # ----------------------------------------------------------------- tables
    @functools.cached_property
    def coefficients(self) -> pd.DataFrame:
        """Estimate, standard error, t statistic and two-sided p-value, indexed by term."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_stat = self.estimates / self.standard_errors
        p_value = 2.0 * _special.stdtr(self.dfe, -np.abs(t_stat))
        names = ["(Intercept)", *self.terms]
        return pd.DataFrame(
            np.column_stack([self.estimates, self.standard_errors, t_stat, p_value]),
            columns=_COEFFICIENT_COLUMNS,
            index=pd.Index(names, dtype=object, name="term"),
        )

    @functools.cached_property
    def steps(self) -> pd.DataFrame:
        """Step history: step, action ("add"/"remove"), term, f_stat, p_value.

        For criterion ``"aic"``/``"bic"`` two more columns give the criterion of the model
        after the step and its change (``aic``, ``aic_change``).
        """
        columns = ["step", "action", "term", "f_stat", "p_value"]
        if self.criterion != "sse":
            columns += [self.criterion, f"{self.criterion}_change"]
        rows = [record[: len(columns)] for record in self.step_records]
        frame = pd.DataFrame(rows, columns=columns)
        return frame.astype({"step": "int64", "f_stat": float, "p_value": float})

    @functools.cached_property
    def skipped(self) -> pd.DataFrame:
        """Candidates not tested (step, term, reason): collinear or too few observations.

        Each (term, reason) pair is listed once, at the first step it occurred.
        """
        return pd.DataFrame(list(self.skipped_records), columns=["step", "term", "reason"])

    @property
    def formula(self) -> str:
        """The final model in Wilkinson notation, e.g. ``"y ~ 1 + x1 + x2"``."""
        return f"{self.response_name} ~ " + " + ".join(["1", *self.terms])

    @property
    def used_predictors(self) -> tuple[str, ...]:
        """Predictor columns appearing in the final model's terms, in column order."""
        used = sorted({i for term in self.model_terms for i in term})
        return tuple(self.predictor_names[i] for i in used)

    # ----------------------------------------------------------------- prediction
    def _predictor_values(self, X) -> tuple[np.ndarray, pd.Index | None]:
        if isinstance(X, pd.DataFrame):
            needed = self.used_predictors
            columns = X.columns.tolist()
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
        values = np.asarray(X, dtype=float)
        if values.ndim == 1:
            values = values[None, :] if len(self.predictor_names) > 1 else values[:, None]
        if values.ndim != 2 or values.shape[1] != len(self.predictor_names):
            raise ValueError(
                f"X has shape {np.shape(X)}; the model was fitted on "
                f"{len(self.predictor_names)} predictor columns"
            )
        return values, None

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
        design = _design(values, self.model_terms)
        mean = design @ self.estimates
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
        half = _t_quantile(1.0 - alpha / 2.0, self.dfe) * self.rmse * np.sqrt(leverage)
        return pd.DataFrame(
            np.column_stack([mean, mean - half, mean + half, mean_se]),
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
        lines = [
            f"Stepwise linear regression ({self.criterion}, p_enter={self.p_enter:g}, "
            f"p_remove={self.p_remove:g})",
            f"    {self.formula}",
            "",
        ]
        if len(self.step_records):
            for record in self.step_records:
                step, action, term, f_stat, p_value = record[:5]
                verb = "Adding" if action == "add" else "Removing"
                text = f"{step}. {verb} {term}, FStat = {f_stat:.4f}, pValue = {p_value:.6g}"
                if self.criterion != "sse":
                    text += f", {self.criterion.upper()} = {record[5]:.4f}"
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


# --------------------------------------------------------------------------- search
def _check_threshold(name: str, value, default: float) -> float:
    if value is None:
        return default
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name}={value!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{name}={value!r} must be finite")
    return value


def stepwise(
    X,
    y,
    *,
    start="constant",
    upper="interactions",
    criterion: Criterion = "sse",
    p_enter: float | None = None,
    p_remove: float | None = None,
    max_steps: int | None = None,
) -> StepwiseFit:
    """Stepwise linear regression between a start and an upper model (MATLAB ``stepwiselm``).

    Parameters
    ----------
    X : DataFrame or ndarray, shape (n_obs, n_predictors)
        Predictors. DataFrame column names become term names (interactions ``a:b``);
        array columns are named ``x1..xn``.
    y : array-like, shape (n_obs,)
        Response. Rows with NaN in *y* or in a predictor of the upper or start model are
        left out (:attr:`StepwiseFit.n_obs` counts the rows used).
    start : {"constant", "linear", "interactions"}, formula str or sequence of str
        Model the search starts from, e.g. ``"y ~ x1 + x2"`` or ``["x1", "x2"]``. Formula
        text is parsed, never evaluated. Must lie inside *upper*.
    upper : {"constant", "linear", "interactions"}, formula str or sequence of str
        Largest model considered: ``"interactions"`` (default) is the intercept, every main
        effect and every two-way interaction.
    criterion : {"sse", "aic", "bic"}
        ``"sse"``: partial F-test p-values. ``"aic"``/``"bic"``: change of the information
        criterion when a term is added (negative = better).
    p_enter : float, optional
        A candidate enters when its p-value (``"sse"``) or criterion change
        (``"aic"``/``"bic"``) is strictly below *p_enter*. Default 0.05 for ``"sse"``,
        0 for ``"aic"``/``"bic"``.
    p_remove : float, optional
        A term leaves when its p-value or criterion change (of adding it back) is strictly
        above *p_remove*. Default 0.10 for ``"sse"``, 0.01 for ``"aic"``/``"bic"``.
    max_steps : int, optional
        Most steps taken; default no limit.

    Returns
    -------
    StepwiseFit
        Final model, coefficient table, step history and the :meth:`~StepwiseFit.predict`
        method.

    Raises
    ------
    ValueError
        Bad options or model specifications, fewer complete rows than the start model
        needs, or a start model whose terms are collinear.

    Notes
    -----
    Each step first tries to add the candidate with the smallest p-value (strictly below
    *p_enter*); only when none enters is the term with the largest p-value removed (strictly
    above *p_remove*). Terms are ordered intercept, main effects in column order, then
    interactions; ties go to the first. The intercept is never removed. An interaction
    enters only when both its main effects are in the model, and a main effect does not
    leave while an interaction containing it is in. The term just added is not removed in
    the next step, nor the one just removed added back. Collinear candidates are never
    added, and when adding a term would leave no error degrees of freedom the candidates
    are skipped; both are recorded in :attr:`StepwiseFit.skipped`.

    For a model with k coefficients, residual sum of squares SSE_k and n observations, the
    partial F-statistic of one term is always computed against the larger model's error:

    .. math:: F = \\frac{SSE_{small} - SSE_{large}}{SSE_{large} / (n - k_{large})},
              \\quad p = P(F_{1, n - k_{large}} > F)

    The search sweeps [1]_ the cross-product matrix of the centred, unit-norm candidate
    columns and the centred response. With the model's terms swept in, a candidate c has
    residual cross-products c⊥ᵀc⊥ (= 1 - R² of c on the model; at most
    ``COLLINEARITY_TOLERANCE`` means collinear) and c⊥ᵀr, and adding it lowers the SSE by
    (c⊥ᵀr)² / c⊥ᵀc⊥. Removing term j raises it by b_j² / [(XᵀX)⁻¹]_jj (the squared
    t-statistic times s²). AIC = -2 logL + 2k and BIC = -2 logL + k ln n with
    logL = -n/2 (ln(2π SSE/n) + 1), so the change from adding a term is
    n ln(SSE_new/SSE) + 2 (AIC) or + ln n (BIC). The final model's statistics are computed
    from its residuals.

    References
    ----------
    .. [1] J. H. Goodnight, "A tutorial on the SWEEP operator", The American Statistician
       33(3), 149-158, 1979. doi:10.1080/00031305.1979.10482685
    .. [2] N. R. Draper, H. Smith, *Applied Regression Analysis*, 3rd ed., Wiley, 1998,
       ch. 15 (selecting the "best" regression equation). doi:10.1002/9781118625590
    .. [3] The MathWorks, "stepwiselm" and "LinearModel.step", Statistics and Machine
       Learning Toolbox documentation (step rules and the Hald cement example).
    """
    if criterion not in DEFAULT_THRESHOLDS:
        raise ValueError(f"criterion={criterion!r}: expected 'sse', 'aic' or 'bic'")
    default_enter, default_remove = DEFAULT_THRESHOLDS[criterion]
    p_enter = _check_threshold("p_enter", p_enter, default_enter)
    p_remove = _check_threshold("p_remove", p_remove, default_remove)
    if criterion == "sse" and not (0.0 < p_enter <= p_remove < 1.0):
        raise ValueError(
            f"p_enter={p_enter:g}, p_remove={p_remove:g}: need 0 < p_enter <= p_remove < 1"
        )
    if criterion != "sse" and p_enter > p_remove:
        raise ValueError(f"p_enter={p_enter:g} must not exceed p_remove={p_remove:g}")
    if max_steps is not None:
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)):
            raise TypeError(f"max_steps={max_steps!r} is not an integer")
        if max_steps < 0:
            raise ValueError(f"max_steps={max_steps} must be >= 0")

    values, names = _as_matrix(X)
    response_name = str(y.name) if isinstance(y, pd.Series) and y.name is not None else "y"
    y_values = np.asarray(y, dtype=float)
    if y_values.ndim == 2 and 1 in y_values.shape:
        y_values = y_values.ravel()
    if y_values.ndim != 1 or y_values.shape[0] != values.shape[0]:
        raise ValueError(
            f"y has shape {np.shape(y)}; expected ({values.shape[0]},) to match X's rows"
        )
    upper_terms = tuple(parse_terms(upper, names, parameter="upper"))
    start_terms = parse_terms(start, names, parameter="start")
    outside = [t for t in start_terms if t not in upper_terms]
    if outside:
        raise ValueError(f"start term {term_name(outside[0], names)!r} is not in the upper model")

    # rows: complete in y and in every predictor the upper model uses
    used_columns = _structure(upper_terms, names).used_columns
    valid = np.isfinite(y_values)
    if len(used_columns) == values.shape[1]:
        valid &= np.isfinite(values).all(axis=1)
    elif used_columns:
        valid &= np.isfinite(values[:, used_columns]).all(axis=1)
    if not valid.all():
        values = values[valid]
        y_values = y_values[valid]
    n = int(y_values.shape[0])
    if n < len(start_terms) + 1:
        raise ValueError(
            f"stepwise needs at least {len(start_terms) + 1} complete rows for the start model "
            f"({len(start_terms)} coefficients), got {n}"
        )

    candidates = _design(values, upper_terms)  # every upper term's column, built once
    problem = _problem(candidates, y_values)
    start_index = [upper_terms.index(t) for t in start_terms]
    model, matrix, steps, skipped = _search(
        problem, upper_terms, start_index, names, criterion, p_enter, p_remove, max_steps
    )
    return _final_fit(
        problem,
        model,
        matrix,
        steps,
        skipped,
        upper_terms,
        names,
        response_name,
        criterion,
        p_enter,
        p_remove,
    )


@dataclass(frozen=True)
class _Structure:
    """Names and hierarchy of an upper model's terms (cached per term list and names)."""

    display: tuple[str, ...]
    parent_a: np.ndarray  # main-effect parents of interactions; n_terms = absent/none
    parent_b: np.ndarray
    is_interaction: np.ndarray
    is_intercept: np.ndarray
    children: np.ndarray  # children[i, k]: interaction k contains main effect i
    used_columns: list[int]  # predictor columns appearing in any term


@functools.lru_cache(maxsize=256)
def _structure(upper_terms: tuple[Term, ...], names: tuple[str, ...]) -> _Structure:
    n_terms = len(upper_terms)
    position = {term: k for k, term in enumerate(upper_terms)}
    # parents point at n_terms ("absent from upper") for terms without parents: in the
    # search that slot of in_model is always False
    sentinel = n_terms
    parent_a = np.full(n_terms, sentinel)
    parent_b = np.full(n_terms, sentinel)
    is_interaction = np.zeros(n_terms, dtype=bool)
    children = np.zeros((n_terms, n_terms), dtype=bool)
    for k, term in enumerate(upper_terms):
        if len(term) == 2:
            is_interaction[k] = True
            parent_a[k] = position.get((term[0],), sentinel)
            parent_b[k] = position.get((term[1],), sentinel)
            for parent in (parent_a[k], parent_b[k]):
                if parent < n_terms:
                    children[parent, k] = True
    for array in (parent_a, parent_b, is_interaction, children):
        array.setflags(write=False)
    is_intercept = np.array([not term for term in upper_terms])
    is_intercept.setflags(write=False)
    display = tuple(term_name(term, names) for term in upper_terms)
    used_columns = sorted({i for term in upper_terms for i in term})
    return _Structure(
        display, parent_a, parent_b, is_interaction, is_intercept, children, used_columns
    )


def _sweep(matrix: np.ndarray, pivot: int) -> None:
    """Sweep the symmetric *matrix* in place on *pivot* (Goodnight 1979; Dempster's SWP).

    With a = A[:, k] and d = A[k, k]: A ← A - a aᵀ / d, then A[:, k] = A[k, :] = a / d and
    A[k, k] = -1 / d. Sweeping the model's columns of [[XᵀX, Xᵀy], [yᵀX, yᵀy]] leaves the
    residual cross-products of the other columns, the coefficients in the pivot rows of the
    last column, -(XᵀX)⁻¹ in the pivot block and the residual sum of squares in the corner.
    """
    column = matrix[:, pivot].copy()
    scaled = column / column[pivot]
    matrix -= np.outer(column, scaled)
    matrix[:, pivot] = scaled
    matrix[pivot, :] = scaled
    matrix[pivot, pivot] = -1.0 / column[pivot]


@dataclass
class _Problem:
    """Centred and scaled candidate columns and their cross-product matrix (one per fit)."""

    n: int
    centred: np.ndarray  # candidate columns minus their means (n x m; column 0 intercept: 0)
    means: np.ndarray  # column means (m,)
    scale: np.ndarray  # norms of the centred columns, 1 where a column is constant
    y_mean: float
    y_centred: np.ndarray
    cross: np.ndarray  # [[ZᵀZ, Zᵀy_c], [y_cᵀZ, y_cᵀy_c]] with Z = centred / scale


def _problem(candidates: np.ndarray, y: np.ndarray) -> _Problem:
    n = y.shape[0]
    means = candidates.sum(axis=0) / n
    centred = candidates - means
    scale = np.sqrt(np.einsum("ij,ij->j", centred, centred))
    # a column constant up to rounding carries no information beyond the intercept
    flat = scale <= 1e-13 * np.maximum(np.abs(means) * math.sqrt(n), 1e-300)
    flat[0] = True  # the intercept is handled by the centring
    scale = np.where(flat, 1.0, scale)
    y_mean = float(y.sum() / n)
    y_centred = y - y_mean
    augmented = np.empty((n, candidates.shape[1] + 1))
    np.divide(centred, scale, out=augmented[:, :-1])
    augmented[:, :-1][:, flat] = 0.0
    augmented[:, -1] = y_centred
    cross = augmented.T @ augmented
    return _Problem(n, centred, means, scale, y_mean, y_centred, cross)


def _swept(problem: _Problem, model: list[int]) -> np.ndarray:
    """Cross-product matrix with the model's (non-intercept) terms swept in."""
    matrix = problem.cross.copy()
    for index in model:
        if index:
            _sweep(matrix, index)
    return matrix


def _search(
    problem: _Problem,
    upper_terms: tuple[Term, ...],
    start_index: list[int],
    names: tuple[str, ...],
    criterion: str,
    p_enter: float,
    p_remove: float,
    max_steps: int | None,
) -> tuple[list[int], np.ndarray, list[tuple], dict[tuple[str, str], int]]:
    """The stepwise search (see :func:`stepwise`, Notes); returns the model's term indices,
    the swept cross-product matrix, the step records and the skipped candidates."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _search_steps(
            problem, upper_terms, start_index, names, criterion, p_enter, p_remove, max_steps
        )


def _search_steps(
    problem: _Problem,
    upper_terms: tuple[Term, ...],
    start_index: list[int],
    names: tuple[str, ...],
    criterion: str,
    p_enter: float,
    p_remove: float,
    max_steps: int | None,
) -> tuple[list[int], np.ndarray, list[tuple], dict[tuple[str, str], int]]:
    n = problem.n
    n_terms = len(upper_terms)
    structure = _structure(upper_terms, names)
    display = structure.display
    parent_a, parent_b = structure.parent_a, structure.parent_b
    is_interaction, is_intercept = structure.is_interaction, structure.is_intercept
    children = structure.children
    y_slot = n_terms  # last row/column of the cross-product matrix

    model = sorted(start_index)
    matrix = problem.cross.copy()
    for index in model:
        if not index:
            continue
        if matrix[index, index] <= COLLINEARITY_TOLERANCE:  # 1 - R² of the term on the others
            raise ValueError(
                f"start model is rank deficient: term {display[index]!r} is collinear with "
                "the terms before it"
            )
        _sweep(matrix, index)
    in_model = np.zeros(n_terms + 1, dtype=bool)  # last slot: "absent parent", always False
    in_model[model] = True
    steps: list[tuple] = []
    skipped: dict[tuple[str, str], int] = {}
    just_added = just_removed = -1
    penalty = 2.0 if criterion == "aic" else math.log(n)
    use_p_value = criterion == "sse"

    def information(sse: float, k: int) -> float:
        if sse <= 0:
            return -math.inf
        return n * (math.log(2 * math.pi * sse / n) + 1.0) + penalty * k  # -2 logL + pen k

    step = 0
    while max_steps is None or step < max_steps:
        k = len(model)
        dfe = n - k
        sse = max(float(matrix[y_slot, y_slot]), 0.0)
        acted = False

        # ---- try to add: not in the model, hierarchy satisfied, not just removed
        eligible = ~in_model[:n_terms] & (
            ~is_interaction | (in_model[parent_a] & in_model[parent_b])
        )
        if just_removed >= 0:
            eligible[just_removed] = False
        eligible_index = np.flatnonzero(eligible)
        if eligible_index.size and dfe - 1 < 1:
            reason = f"too few observations: n={n} leaves no error degrees of freedom"
            for index in eligible_index.tolist():
                skipped.setdefault((display[index], reason), step + 1)
        elif eligible_index.size:
            # 1 - R²_j of each candidate on the model (scaled columns: c⊥ᵀc⊥)
            unexplained = matrix[eligible_index, eligible_index]
            collinear = unexplained <= COLLINEARITY_TOLERANCE
            if collinear.any():
                for index in eligible_index[collinear].tolist():
                    skipped.setdefault(
                        (display[index], "collinear with the model's terms"), step + 1
                    )
                eligible_index = eligible_index[~collinear]
                unexplained = unexplained[~collinear]
            if eligible_index.size:
                dfe_new = dfe - 1
                # SSE - SSE_new = (c⊥ᵀr)² / c⊥ᵀc⊥;  F = (SSE - SSE_new) / (SSE_new / dfe_new)
                decrease = matrix[eligible_index, y_slot] ** 2 / unexplained
                sse_new = np.maximum(sse - decrease, 0.0)
                f_stat = decrease * dfe_new / sse_new
                p_value = _f_sf(f_stat, 1.0, dfe_new)
                if use_p_value:
                    score = p_value
                else:
                    score = n * np.log(sse_new / sse) + penalty  # Δ criterion of adding
                score[score != score] = np.inf  # NaN (0/0 on a perfect fit) never enters
                best = int(np.argmin(score))
                if score[best] < p_enter:
                    index = int(eligible_index[best])
                    record = [
                        step + 1,
                        "add",
                        display[index],
                        float(f_stat[best]),
                        float(p_value[best]),
                    ]
                    if not use_p_value:
                        record += [information(float(sse_new[best]), k + 1), float(score[best])]
                    steps.append(tuple(record))
                    _sweep(matrix, index)
                    model = sorted([*model, index])
                    in_model[index] = True
                    just_added, just_removed = index, -1
                    acted = True

        # ---- otherwise try to remove: not the intercept, not just added, no child in model
        if not acted and dfe >= 1:
            terms = np.array(model)
            removable = ~is_intercept[terms] & ~children[terms][:, in_model[:n_terms]].any(axis=1)
            if just_added >= 0:
                removable &= terms != just_added
            if removable.any():
                # SSE_small - SSE_large = b_j² / [(XᵀX)⁻¹]_jj; the swept block holds -(XᵀX)⁻¹
                estimates = matrix[terms, y_slot]
                increase = estimates**2 / -matrix[terms, terms]
                f_stat = increase / (sse / dfe)
                p_value = _f_sf(f_stat, 1.0, dfe)
                if use_p_value:
                    score = p_value
                else:  # Δ criterion of adding the term back: large = better without
                    score = n * np.log(sse / (sse + increase)) + penalty
                score = np.where(removable & ~np.isnan(score), score, -np.inf)
                worst = int(np.argmax(score))  # model is in canonical order: ties go first
                if score[worst] > p_remove:
                    index = int(terms[worst])
                    record = [
                        step + 1,
                        "remove",
                        display[index],
                        float(f_stat[worst]),
                        float(p_value[worst]),
                    ]
                    if not use_p_value:
                        record += [
                            information(sse + float(increase[worst]), k - 1),
                            float(score[worst]),
                        ]
                    steps.append(tuple(record))
                    model = [i for i in model if i != index]
                    matrix = _swept(problem, model)  # afresh: no drift from sweeping back
                    in_model[index] = False
                    just_added, just_removed = -1, index
                    acted = True
        if not acted:
            break
        step += 1
    return model, matrix, steps, skipped


def _final_fit(
    problem: _Problem,
    model: list[int],
    matrix: np.ndarray,
    steps: list[tuple],
    skipped: dict[tuple[str, str], int],
    upper_terms: tuple[Term, ...],
    names: tuple[str, ...],
    response_name: str,
    criterion: str,
    p_enter: float,
    p_remove: float,
) -> StepwiseFit:
    n = problem.n
    k = len(model)
    dfe = n - k
    slopes_index = model[1:]  # model[0] is the intercept
    y_slot = len(upper_terms)
    scale = problem.scale[slopes_index]
    # back from centred-scaled columns: b = b_z / s, V = (X_cᵀX_c)⁻¹ = V_z / (s sᵀ)
    slopes = matrix[slopes_index, y_slot] / scale
    covariance = -matrix[slopes_index][:, slopes_index] / np.outer(scale, scale)
    term_means = problem.means[slopes_index]
    intercept = problem.y_mean - float(term_means @ slopes)
    residual = problem.y_centred - problem.centred[:, slopes_index] @ slopes
    sse = float(residual @ residual)
    sst = float(problem.y_centred @ problem.y_centred)
    mse = sse / dfe if dfe > 0 else math.nan
    rmse = math.sqrt(mse) if mse == mse else math.nan
    # se(b) = s √diag(V); se(intercept) = s √(1/n + x̄ᵀ V x̄)
    variances = np.empty(k)
    variances[0] = 1.0 / n + float(term_means @ covariance @ term_means)
    variances[1:] = np.diagonal(covariance)
    standard_errors = rmse * np.sqrt(np.maximum(variances, 0.0))
    r_squared = 1.0 - sse / sst if sst > 0 else math.nan
    adj_r_squared = 1.0 - (sse / dfe) / (sst / (n - 1)) if sst > 0 and dfe > 0 else math.nan
    if k > 1 and dfe > 0 and mse > 0:
        f_stat = ((sst - sse) / (k - 1)) / mse
        f_p_value = float(_f_sf(f_stat, k - 1, dfe))
    else:
        f_stat = f_p_value = math.nan
    log_likelihood = -0.5 * n * (math.log(2 * math.pi * sse / n) + 1.0) if sse > 0 else math.inf
    display = _structure(upper_terms, names).display
    return StepwiseFit(
        terms=tuple(display[i] for i in slopes_index),
        predictor_names=names,
        response_name=response_name,
        criterion=criterion,
        p_enter=p_enter,
        p_remove=p_remove,
        n_obs=int(n),
        dfe=int(dfe),
        sse=sse,
        rmse=float(rmse),
        r_squared=float(r_squared),
        adj_r_squared=float(adj_r_squared),
        f_stat=float(f_stat),
        f_p_value=float(f_p_value),
        log_likelihood=float(log_likelihood),
        aic=float(-2.0 * log_likelihood + 2.0 * k),
        bic=float(-2.0 * log_likelihood + math.log(n) * k),
        model_terms=tuple(upper_terms[i] for i in model),
        estimates=np.concatenate([[intercept], slopes]),
        standard_errors=standard_errors,
        term_means=term_means,
        slope_covariance=covariance,
        step_records=tuple(steps),
        skipped_records=tuple((s, term, reason) for (term, reason), s in skipped.items()),
    )


# --------------------------------------------------------------------------- scikit-learn
class StepwiseRegressor(RegressorMixin, BaseEstimator):
    """Scikit-learn estimator around :func:`stepwise` (usable in ``cross_val_score``).

    Parameters
    ----------
    start, upper, criterion, p_enter, p_remove, max_steps
        As for :func:`stepwise`.

    Attributes
    ----------
    result_ : StepwiseFit
        The fitted model.
    feature_names_in_ : ndarray of str
        Column names when fitted on a DataFrame.
    n_features_in_ : int
        Number of predictor columns.
    """

    def __init__(
        self,
        *,
        start="constant",
        upper="interactions",
        criterion: Criterion = "sse",
        p_enter: float | None = None,
        p_remove: float | None = None,
        max_steps: int | None = None,
    ):
        self.start = start
        self.upper = upper
        self.criterion = criterion
        self.p_enter = p_enter
        self.p_remove = p_remove
        self.max_steps = max_steps

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True  # rows with NaN are left out of the fit
        return tags

    def _frame(self, values: np.ndarray):
        """Predictor values with the fitted column names (term names follow them)."""
        names = getattr(self, "feature_names_in_", None)
        if names is None:
            return values
        return pd.DataFrame(values, columns=[str(name) for name in names])

    def fit(self, X, y):
        """Run the stepwise search on (*X*, *y*); returns ``self``."""
        response = y.name if isinstance(y, pd.Series) and y.name is not None else None
        values, target = validate_data(
            self,
            X,
            y,
            dtype=float,
            ensure_all_finite="allow-nan",
            ensure_min_samples=2,
            y_numeric=True,
        )
        self.result_ = stepwise(
            self._frame(values),
            pd.Series(target, name=response) if response is not None else target,
            start=self.start,
            upper=self.upper,
            criterion=self.criterion,
            p_enter=self.p_enter,
            p_remove=self.p_remove,
            max_steps=self.max_steps,
        )
        return self

    @property
    def terms_(self) -> tuple[str, ...]:
        """Non-constant terms of the fitted model."""
        check_is_fitted(self, "result_")
        return self.result_.terms

    @property
    def coef_(self) -> pd.Series:
        """Estimates indexed by term, intercept included."""
        check_is_fitted(self, "result_")
        return self.result_.coefficients["estimate"]

    def predict(self, X) -> np.ndarray:
        """Predicted means for the rows of *X* (NaN where a used predictor is NaN)."""
        check_is_fitted(self, "result_")
        values = validate_data(self, X, reset=False, dtype=float, ensure_all_finite="allow-nan")
        return np.asarray(self.result_.predict(self._frame(values)), dtype=float)
