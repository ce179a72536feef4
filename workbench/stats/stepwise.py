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

from .design import Encoding, column_names, design_columns, encode, raw_transform, term_width
from .distributions import t_quantile
from .terms import Term, is_square, parents, parse_terms, term_name

__all__ = ["StepwiseFit", "StepwiseRegressor", "stepwise"]

Criterion = Literal["sse", "aic", "bic", "rsquared", "adjrsquared"]
MissingRule = Literal["candidate", "complete"]

#: Default thresholds per criterion (MATLAB ``stepwiselm``): (p_enter, p_remove).
DEFAULT_THRESHOLDS = {
    "sse": (0.05, 0.10),
    "aic": (0.0, 0.01),
    "bic": (0.0, 0.01),
    "rsquared": (0.1, 0.05),
    "adjrsquared": (0.0, -0.05),
}

#: A model fits exactly (zero noise up to round-off) when its SSE is at most this fraction
#: of the total sum of squares; no term is added after that, since every F-test would
#: compare round-off with round-off.
EXACT_FIT_TOLERANCE = 1e-12

#: A candidate is collinear with the model (never added) when the fraction of its centred
#: sum of squares left unexplained by the model's terms, 1 - R²_j, is at most this.
COLLINEARITY_TOLERANCE = 1e-10

_INTERVAL_COLUMNS = pd.Index(["mean", "lower", "upper", "mean_se"], dtype=object)
_COEFFICIENT_COLUMNS = pd.Index(["estimate", "se", "t_stat", "p_value"], dtype=object)


def _f_sf(f: np.ndarray | float, df_num: float, df_den: float) -> np.ndarray:
    """Upper tail P(F > f) of the F(df_num, df_den) distribution."""
    return _special.fdtrc(df_num, df_den, f)


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

    Notes
    -----
    Properties :attr:`coefficients`, :attr:`steps` and :attr:`skipped` are DataFrames built
    on first access. Coefficients are in raw units of the predictors (one row per design
    column: a categorical term has one row per non-reference level, ``Year_76``).
    Standard errors are ``rmse * sqrt(diag((X'X)^-1))`` and p-values two-sided from
    Student's t with ``dfe`` degrees of freedom. Internally the model is held in the
    search's centred units (:attr:`search_estimates`), which :meth:`predict` uses.
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
    coefficient_names: tuple[str, ...] = field(repr=False, default=())
    coefficient_terms: tuple[Term, ...] = field(repr=False, default=())
    search_estimates: np.ndarray | None = field(repr=False, default=None)
    encoding: Encoding | None = field(repr=False, default=None)
    missing: str = "candidate"

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
        columns) and ``n_obs`` (rows of the larger of the two models compared).
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

    @property
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

    def _encoded_values(self, X) -> tuple[np.ndarray, pd.Index | None]:
        """Predictor values with categorical columns as level codes of the fit."""
        encoding = self.encoding
        index = X.index if isinstance(X, pd.DataFrame) else None
        if not isinstance(X, pd.DataFrame):
            array = np.asarray(X, dtype=object)
            if array.ndim == 1:
                array = array[None, :] if len(self.predictor_names) > 1 else array[:, None]
            if array.ndim != 2 or array.shape[1] != len(self.predictor_names):
                raise ValueError(
                    f"X has shape {np.shape(X)}; the model was fitted on "
                    f"{len(self.predictor_names)} predictor columns"
                )
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
            "",
        ]
        if len(self.step_records):
            for record in self.step_records:
                step, action, term, f_stat, p_value = record[:5]
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
    lower="constant",
    criterion: Criterion = "sse",
    p_enter: float | None = None,
    p_remove: float | None = None,
    max_steps: int | None = None,
    missing: MissingRule = "candidate",
    categorical: Sequence[str | int] | None = None,
) -> StepwiseFit:
    """Stepwise linear regression between a start and an upper model (MATLAB ``stepwiselm``).

    Parameters
    ----------
    X : DataFrame or ndarray, shape (n_obs, n_predictors)
        Predictors. DataFrame column names become term names (interactions ``a:b``,
        squares ``a^2``); array columns are named ``x1..xn``. Categorical, bool and string
        columns enter as categorical predictors (MATLAB's reference coding, see
        :mod:`workbench.stats.design`).
    y : array-like, shape (n_obs,)
        Response. Rows with NaN in *y* are left out; for NaN in predictors see *missing*.
    start : {"constant", "linear", "interactions", "purequadratic", "quadratic"}, formula \
str or sequence of str
        Model the search starts from, e.g. ``"y ~ x1 + x2"`` or ``["x1", "x2"]``. Formula
        text is parsed, never evaluated. Must lie inside *upper*, contain *lower* and keep
        the hierarchy (an interaction or square with its main effects).
    upper : model specification (as *start*)
        Largest model considered: ``"interactions"`` (default) is the intercept, every main
        effect and every two-way interaction; ``"quadratic"`` adds the squares of the
        numeric predictors.
    lower : model specification (as *start*)
        Terms that are never removed (MATLAB ``'Lower'``); default the intercept only.
    criterion : {"sse", "aic", "bic", "rsquared", "adjrsquared"}
        ``"sse"``: partial F-test p-values. ``"aic"``/``"bic"``: change of the information
        criterion when a term is added (negative = better). ``"rsquared"``/
        ``"adjrsquared"``: increase of R² or adjusted R² when a term is added.
    p_enter : float, optional
        A candidate enters when its p-value (``"sse"``) or criterion change
        (``"aic"``/``"bic"``) is strictly below *p_enter*, or its R² increase
        (``"rsquared"``/``"adjrsquared"``) strictly above. Defaults (MATLAB's): 0.05, 0, 0,
        0.1, 0.
    p_remove : float, optional
        A term leaves when its p-value or criterion change (of adding it back) is strictly
        above *p_remove*, or its R² increase strictly below. Defaults: 0.10, 0.01, 0.01,
        0.05, -0.05.
    max_steps : int, optional
        Most steps taken; default no limit.
    missing : {"candidate", "complete"}
        Rows with NaN in a predictor. ``"candidate"`` (default, MATLAB ``stepwiselm``): each
        model, and each candidate model of a step, is fitted on the rows complete in the
        variables it uses, so a NaN in a predictor that is never selected costs no row.
        ``"complete"`` (MATLAB ``stepwisefit``): rows with a NaN in any predictor of the
        upper model are left out of the whole search.
    categorical : sequence of str or int, optional
        Further predictor columns (names or positions) to treat as categorical, e.g. a
        numeric operating-case code.

    Returns
    -------
    StepwiseFit
        Final model, coefficient table (raw units), step history and the
        :meth:`~StepwiseFit.predict` method.

    Raises
    ------
    ValueError
        Bad options or model specifications, a predictor of the upper model without a
        finite value (named), fewer complete rows than the start model needs, or a start
        model whose terms are collinear.

    Notes
    -----
    Each step first tries to add the candidate with the best score (smallest p-value,
    strictly below *p_enter*); only when none enters is the term with the worst score
    removed (largest p-value, strictly above *p_remove*). Terms are ordered intercept, main
    effects in column order, interactions, then squares; ties go to the first. The
    intercept and the *lower* terms are never removed. An interaction or a square enters
    only when its main effects are in the model, and a main effect does not leave while a
    term containing it is in. The term just added is not removed in the next step, nor the
    one just removed added back. Collinear candidates are never added; when adding a term
    would leave no error degrees of freedom the candidates are skipped; after an exact fit
    (SSE at most ``EXACT_FIT_TOLERANCE`` times the total sum of squares, i.e. zero up to
    round-off) no term is added, because every F-test would divide round-off by round-off.
    All three are recorded in :attr:`StepwiseFit.skipped`.

    A categorical predictor with L levels is one term of L - 1 columns, tested with L - 1
    numerator degrees of freedom. For a candidate of d columns added to a model of k
    coefficients fitted on n rows:

    .. math:: F = \\frac{(SSE_{small} - SSE_{large}) / d}{SSE_{large} / (n - k - d)},
              \\quad p = P(F_{d, n - k - d} > F)

    Numeric predictors are centred before products are formed (see
    :mod:`workbench.stats.design`): the models and tests are the same, but a large offset
    in raw units cannot make an interaction look collinear with its main effects. The
    coefficients are reported in raw units.

    The search sweeps [1]_ the cross-product matrix of the centred, unit-norm candidate
    columns and the centred response. With the model's columns swept in, a candidate
    column c has residual cross-products c⊥ᵀc⊥ (= 1 - R² of c on the model; at most
    ``COLLINEARITY_TOLERANCE`` means collinear) and c⊥ᵀr, and adding it lowers the SSE by
    (c⊥ᵀr)² / c⊥ᵀc⊥ (a term of several columns: the columns swept in turn). Removing term
    T raises it by b_Tᵀ [(XᵀX)⁻¹]_TT⁻¹ b_T. AIC = -2 logL + 2k and BIC = -2 logL + k ln n
    with logL = -n/2 (ln(2π SSE/n) + 1), so the change from adding d columns is
    n ln(SSE_new/SSE) + 2d (AIC) or + d ln n (BIC). The final model's statistics are
    computed from its residuals.

    References
    ----------
    .. [1] J. H. Goodnight, "A tutorial on the SWEEP operator", The American Statistician
       33(3), 149-158, 1979. doi:10.1080/00031305.1979.10482685
    .. [2] N. R. Draper, H. Smith, *Applied Regression Analysis*, 3rd ed., Wiley, 1998,
       ch. 15 (selecting the "best" regression equation). doi:10.1002/9781118625590
    .. [3] The MathWorks, "stepwiselm" and "LinearModel.step", Statistics and Machine
       Learning Toolbox documentation (step rules, criteria, the Hald and carsmall
       examples).
    """
    if criterion not in DEFAULT_THRESHOLDS:
        raise ValueError(
            f"criterion={criterion!r}: expected one of " + ", ".join(map(repr, DEFAULT_THRESHOLDS))
        )
    if missing not in ("candidate", "complete"):
        raise ValueError(f"missing={missing!r}: expected 'candidate' or 'complete'")
    default_enter, default_remove = DEFAULT_THRESHOLDS[criterion]
    p_enter = _check_threshold("p_enter", p_enter, default_enter)
    p_remove = _check_threshold("p_remove", p_remove, default_remove)
    if criterion == "sse" and not (0.0 < p_enter <= p_remove < 1.0):
        raise ValueError(
            f"p_enter={p_enter:g}, p_remove={p_remove:g}: need 0 < p_enter <= p_remove < 1"
        )
    if criterion in ("aic", "bic") and p_enter > p_remove:
        raise ValueError(f"p_enter={p_enter:g} must not exceed p_remove={p_remove:g}")
    if criterion in ("rsquared", "adjrsquared") and p_enter < p_remove:
        raise ValueError(
            f"p_enter={p_enter:g} must not be below p_remove={p_remove:g} for {criterion}"
        )
    if max_steps is not None:
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)):
            raise TypeError(f"max_steps={max_steps!r} is not an integer")
        if max_steps < 0:
            raise ValueError(f"max_steps={max_steps} must be >= 0")

    values, encoding = encode(X, categorical)
    names = encoding.names
    response_name = str(y.name) if isinstance(y, pd.Series) and y.name is not None else "y"
    y_values = np.asarray(y, dtype=float)
    if y_values.ndim == 2 and 1 in y_values.shape:
        y_values = y_values.ravel()
    if y_values.ndim != 1 or y_values.shape[0] != values.shape[0]:
        raise ValueError(
            f"y has shape {np.shape(y)}; expected ({values.shape[0]},) to match X's rows"
        )
    squarable = [not flag for flag in encoding.categorical]
    models = {}
    for parameter, spec in (("upper", upper), ("start", start), ("lower", lower)):
        terms = parse_terms(spec, names, parameter=parameter, squarable=squarable)
        for term in terms if any(encoding.categorical) else ():
            if is_square(term) and encoding.categorical[term[0]]:
                raise ValueError(
                    f"{parameter} term {term_name(term, names)!r}: a categorical predictor "
                    "cannot be squared"
                )
        models[parameter] = terms
    upper_terms = tuple(models["upper"])
    start_terms, lower_terms = models["start"], models["lower"]
    position = {term: k for k, term in enumerate(upper_terms)}
    outside = [t for t in start_terms if t not in position]
    if outside:
        raise ValueError(f"start term {term_name(outside[0], names)!r} is not in the upper model")
    absent = [t for t in lower_terms if t not in start_terms]
    if absent:
        raise ValueError(
            f"lower term {term_name(absent[0], names)!r} is not in the start model; the start "
            "model must contain the lower model"
        )
    for term in start_terms:
        for parent in parents(term):
            if parent not in start_terms:
                raise ValueError(
                    f"start term {term_name(term, names)!r} needs {term_name(parent, names)!r} "
                    "in the start model (hierarchy)"
                )

    layout = _layout(upper_terms, names, encoding.levels)
    used_columns = layout.used_columns
    valid = np.isfinite(y_values)
    if not valid.any():
        raise ValueError(f"response {response_name!r} has no finite value")
    finite = np.isfinite(values)
    usable = (finite[:, used_columns] & valid[:, None]).any(axis=0)
    if not usable.all():
        column = used_columns[int(np.argmin(usable))]
        where = "" if finite[:, column].any() else " (all NaN)"
        raise ValueError(
            f"X column {names[column]!r} has no finite value where the response "
            f"{response_name!r} is finite{where}"
        )
    if missing == "complete" and used_columns:
        valid &= finite[:, used_columns].all(axis=1)
    if not valid.all():
        values = values[valid]
        y_values = y_values[valid]
        finite = finite[valid]
    n = int(y_values.shape[0])
    start_columns = sorted({c for t in start_terms for c in t})
    start_rows = int(finite[:, start_columns].all(axis=1).sum()) if start_columns else n
    width = sum(layout.widths[position[t]] for t in start_terms)
    if start_rows < width + 1:
        raise ValueError(
            f"stepwise needs at least {width + 1} complete rows for the start model "
            f"({width} coefficients), got {start_rows}"
        )
    # numeric predictors enter centred (their mean over the usable rows)
    centres = np.zeros(len(names))
    numeric = [c for c in used_columns if encoding.levels[c] is None]
    has_missing = bool(used_columns) and not finite[:, used_columns].all()
    if numeric:
        block = values[:, numeric]
        centres[numeric] = np.nanmean(block, axis=0) if has_missing else block.mean(axis=0)
    encoding = encoding.with_centres(centres)
    with np.errstate(invalid="ignore"):
        candidates = design_columns(values, upper_terms, encoding, widths=layout.widths)
    search = _Search(
        candidates=candidates,
        y=y_values,
        finite=finite if has_missing else None,
        layout=layout,
        criterion=criterion,
        p_enter=p_enter,
        p_remove=p_remove,
    )
    start_index = [position[t] for t in start_terms]
    lower_index = {position[t] for t in lower_terms}
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        search.run(start_index, lower_index, max_steps)
        return search.result(encoding, response_name, missing)


@dataclass(frozen=True)
class _Layout:
    """Columns, names and hierarchy of an upper model's terms (cached per model)."""

    terms: tuple[Term, ...]
    widths: tuple[int, ...]
    columns: tuple[np.ndarray, ...]  # design columns of each term
    display: tuple[str, ...]
    column_names: tuple[str, ...]
    parent_count: np.ndarray  # parents each term needs (hierarchy)
    parents: np.ndarray  # parents[k, p]: term p is a parent of term k
    missing_parent: np.ndarray  # a parent is not in the upper model: never eligible
    is_intercept: np.ndarray
    predictors: tuple[tuple[int, ...], ...]  # predictor columns of each term
    used_columns: list[int]
    single: bool  # every term has one design column
    first_column: np.ndarray  # first design column of each term
    parent_a: np.ndarray  # the parents of a term; n_terms: none, or absent from upper
    parent_b: np.ndarray
    has_parents: np.ndarray


@functools.lru_cache(maxsize=256)
def _layout(upper_terms: tuple[Term, ...], names: tuple[str, ...], levels: tuple) -> _Layout:
    encoding = Encoding(names, levels, np.zeros(len(names)))
    n_terms = len(upper_terms)
    position = {term: k for k, term in enumerate(upper_terms)}
    widths = tuple(term_width(t, encoding) for t in upper_terms)
    starts = np.concatenate([[0], np.cumsum(widths)])
    columns = tuple(np.arange(starts[k], starts[k + 1]) for k in range(n_terms))
    parent_matrix = np.zeros((n_terms, n_terms), dtype=bool)
    missing_parent = np.zeros(n_terms, dtype=bool)
    parent_a = np.full(n_terms, n_terms)
    parent_b = np.full(n_terms, n_terms)
    for k, term in enumerate(upper_terms):
        term_parents = parents(term)
        for parent in term_parents:
            if parent in position:
                parent_matrix[k, position[parent]] = True
            else:
                missing_parent[k] = True
        if term_parents:
            parent_a[k] = position.get(term_parents[0], n_terms)
            parent_b[k] = position.get(term_parents[-1], n_terms)
    out = _Layout(
        terms=upper_terms,
        widths=widths,
        columns=columns,
        display=tuple(term_name(t, names) for t in upper_terms),
        column_names=tuple(column_names(upper_terms, encoding)),
        parent_count=parent_matrix.sum(axis=1),
        parents=parent_matrix,
        missing_parent=missing_parent,
        is_intercept=np.array([not t for t in upper_terms]),
        predictors=tuple(tuple(sorted(set(t))) for t in upper_terms),
        used_columns=sorted({i for t in upper_terms for i in t}),
        single=all(w == 1 for w in widths),
        first_column=starts[:-1].astype(int),
        parent_a=parent_a,
        parent_b=parent_b,
        has_parents=np.array([len(parents(t)) > 0 for t in upper_terms], dtype=bool),
    )
    for array in (
        out.parent_count,
        out.parents,
        out.missing_parent,
        out.is_intercept,
        out.first_column,
    ):
        array.setflags(write=False)
    return out


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
    """Centred and scaled candidate columns and their cross-product matrix (one per row set)."""

    n: int
    centred: np.ndarray  # candidate columns minus their means (n x m; column 0 intercept: 0)
    means: np.ndarray  # column means (m,)
    scale: np.ndarray  # norms of the centred columns, 1 where a column is constant
    y_mean: float
    y_centred: np.ndarray
    sst: float
    cross: np.ndarray  # [[ZᵀZ, Zᵀy_c], [y_cᵀZ, y_cᵀy_c]] with Z = centred / scale


def _problem(candidates: np.ndarray, y: np.ndarray) -> _Problem:
    n = y.shape[0]
    means = candidates.sum(axis=0) / n
    centred = candidates - means
    scale = np.sqrt(np.einsum("ij,ij->j", centred, centred))
    # a column constant up to rounding carries no information beyond the intercept; a
    # column with NaN on these rows is never a candidate here (zeroed)
    flat = ~(scale > 1e-13 * np.maximum(np.abs(means) * math.sqrt(n), 1e-300))
    flat[0] = True  # the intercept is handled by the centring
    scale = np.where(flat, 1.0, scale)
    y_mean = float(y.sum() / n)
    y_centred = y - y_mean
    augmented = np.empty((n, candidates.shape[1] + 1))
    np.divide(centred, scale, out=augmented[:, :-1])
    augmented[:, :-1][:, flat] = 0.0
    augmented[:, -1] = y_centred
    cross = augmented.T @ augmented
    sst = float(cross[-1, -1])
    return _Problem(n, centred, means, scale, y_mean, y_centred, sst, cross)


class _Search:
    """State of one stepwise search (see :func:`stepwise`, Notes)."""

    def __init__(self, *, candidates, y, finite, layout, criterion, p_enter, p_remove):
        self.candidates = candidates
        self.y = y
        self.finite = finite  # None: no NaN in any used predictor
        self.layout = layout
        self.criterion = criterion
        self.p_enter, self.p_remove = p_enter, p_remove
        negated = criterion in ("rsquared", "adjrsquared")
        # every score is "smaller is better for adding": R² gains are negated
        self.enter_threshold = -p_enter if negated else p_enter
        self.remove_threshold = -p_remove if negated else p_remove
        self.y_slot = candidates.shape[1]
        self.problems: dict[bytes | None, tuple[_Problem, np.ndarray | None]] = {}
        self.steps: list[tuple] = []
        self.skipped: dict[tuple[str, str], int] = {}
        self.model: list[int] = []
        self.swept: dict[int, list[int]] = {}  # term -> its columns swept into the model
        self._columns_cache: list[int] | None = None

    # ----------------------------------------------------------------- row sets
    def _rows(self, terms) -> np.ndarray | None:
        if self.finite is None:
            return None
        columns = sorted({c for t in terms for c in self.layout.predictors[t]})
        if not columns:
            return np.ones(self.finite.shape[0], dtype=bool)
        return self.finite[:, columns].all(axis=1)

    def _problem_for(self, rows: np.ndarray | None) -> _Problem:
        key = None if rows is None or rows.all() else rows.tobytes()
        if key not in self.problems:
            if key is None:
                problem = _problem(self.candidates, self.y)
            else:
                problem = _problem(self.candidates[rows], self.y[rows])
            self.problems[key] = (problem, rows)
        return self.problems[key][0]

    def _swept_matrix(self, problem: _Problem, model_columns) -> tuple[np.ndarray, int]:
        matrix = problem.cross.copy()
        count = 0
        for column in model_columns:
            if matrix[column, column] > COLLINEARITY_TOLERANCE:
                _sweep(matrix, column)
                count += 1
        return matrix, count

    def _model_columns(self) -> list[int]:
        if self._columns_cache is None:
            self._columns_cache = [c for t in self.model for c in self.swept.get(t, [])]
        return self._columns_cache

    # ----------------------------------------------------------------- statistics
    def _score_add(self, n, k, sse, sst, decrease, df):
        """F, p and score of adding terms with SSE decrease *decrease* and *df* columns."""
        dfe_new = n - k - df
        sse_new = np.maximum(sse - decrease, 0.0)
        f_stat = (decrease / df) / (sse_new / dfe_new)
        p_value = _f_sf(f_stat, df, dfe_new)
        criterion = self.criterion
        if criterion == "sse":
            score = p_value
            value = p_value  # not recorded for "sse"
        elif criterion in ("aic", "bic"):
            penalty = 2.0 if criterion == "aic" else np.log(n)
            score = n * np.log(sse_new / sse) + penalty * df
            value = n * (np.log(2 * np.pi * sse_new / n) + 1.0) + penalty * (k + df)
        elif criterion == "rsquared":
            value = 1.0 - sse_new / sst
            score = -(decrease / sst)
        else:
            value = 1.0 - (sse_new / dfe_new) / (sst / (n - 1))
            score = -(value - (1.0 - (sse / (n - k)) / (sst / (n - 1))))
        return f_stat, p_value, score, value

    def _gains(self, matrix: np.ndarray, terms: np.ndarray):
        """SSE decrease, degrees of freedom and columns of adding each term to the model
        swept into *matrix* (collinear columns of a term are left out)."""
        layout = self.layout
        y = self.y_slot
        decrease = np.zeros(len(terms))
        df = np.zeros(len(terms))
        columns: list[list[int]] = []
        if layout.single:
            index = layout.first_column[terms]
            unexplained = matrix[index, index]
            ok = unexplained > COLLINEARITY_TOLERANCE
            if ok.all():
                decrease = matrix[index, y] ** 2 / unexplained
                df.fill(1.0)
            else:
                decrease[ok] = matrix[index[ok], y] ** 2 / unexplained[ok]
                df[ok] = 1.0
            return decrease, df, None  # columns: the term's one column
        for position, term in enumerate(terms):
            cols = [int(c) for c in layout.columns[term]]
            if len(cols) == 1:
                u = matrix[cols[0], cols[0]]
                if u > COLLINEARITY_TOLERANCE:
                    decrease[position] = matrix[cols[0], y] ** 2 / u
                    df[position] = 1.0
                    columns.append(cols)
                else:
                    columns.append([])
                continue
            index = [*cols, y]
            small = matrix[np.ix_(index, index)].copy()
            kept = []
            for j in range(len(cols)):
                if small[j, j] > COLLINEARITY_TOLERANCE:
                    _sweep(small, j)
                    kept.append(cols[j])
            decrease[position] = matrix[y, y] - small[-1, -1]
            df[position] = len(kept)
            columns.append(kept)
        return decrease, df, columns

    # ----------------------------------------------------------------- the search
    def run(self, start: list[int], lower: set[int], max_steps: int | None) -> None:
        layout = self.layout
        display = layout.display
        n_terms = len(layout.terms)
        self.model = sorted(start)
        rows = self._rows(self.model)
        problem = self._problem_for(rows)
        matrix = problem.cross.copy()
        for term in self.model:
            if layout.is_intercept[term]:
                continue
            kept = []
            for column in layout.columns[term]:
                if matrix[column, column] > COLLINEARITY_TOLERANCE:
                    _sweep(matrix, int(column))
                    kept.append(int(column))
            if not kept:
                raise ValueError(
                    f"start model is rank deficient: term {display[term]!r} is collinear with "
                    "the terms before it"
                )
            self.swept[term] = kept
        self._columns_cache = None
        in_model = np.zeros(n_terms, dtype=bool)
        in_model[self.model] = True
        in_extended = np.zeros(n_terms + 1, dtype=bool)
        protected = np.zeros(n_terms, dtype=bool)
        protected[list(lower)] = True
        protected |= layout.is_intercept
        just_added = just_removed = -1
        step = 0
        while max_steps is None or step < max_steps:
            k = 1 + len(self._model_columns())
            n = problem.n
            dfe = n - k
            sse = max(float(matrix[self.y_slot, self.y_slot]), 0.0)
            sst = problem.sst
            acted = False

            # ---- try to add: not in the model, hierarchy satisfied, not just removed
            # hierarchy: both parents in the model (slot n_terms: no such parent, False)
            in_extended[:n_terms] = in_model
            eligible = ~in_model & (
                ~layout.has_parents | (in_extended[layout.parent_a] & in_extended[layout.parent_b])
            )
            if just_removed >= 0:
                eligible[just_removed] = False
            eligible_index = np.flatnonzero(eligible)
            exact = sse <= EXACT_FIT_TOLERANCE * sst
            if eligible_index.size and exact:
                reason = (
                    f"exact fit: SSE/SST <= {EXACT_FIT_TOLERANCE:g} (round-off), "
                    "F-tests are meaningless"
                )
                for index in eligible_index.tolist():
                    self.skipped.setdefault((display[index], reason), step + 1)
            elif eligible_index.size:
                best = self._best_addition(eligible_index, matrix, problem, rows, step)
                if best is not None:
                    index, record, columns, new_rows = best
                    if record[0] < self.enter_threshold:
                        self.steps.append((step + 1, "add", display[index], *record[1:]))
                        self.model = sorted([*self.model, index])
                        self.swept[index] = columns
                        self._columns_cache = None
                        in_model[index] = True
                        if new_rows is not None and not np.array_equal(new_rows, rows):
                            rows = new_rows
                            problem = self._problem_for(rows)
                            matrix, _ = self._swept_matrix(problem, self._model_columns())
                        else:
                            for column in columns:
                                _sweep(matrix, column)
                        just_added, just_removed = index, -1
                        acted = True

            # ---- otherwise try to remove: not protected, not just added, no child in model
            if not acted and dfe >= 1:
                terms = np.array(self.model)
                has_child = (layout.parents[:, terms] & in_model[:, None]).any(axis=0)
                removable = ~protected[terms] & ~has_child
                if just_added >= 0:
                    removable &= terms != just_added
                if removable.any():
                    worst = self._worst_removal(terms, removable, matrix, n, k, sse, sst)
                    if worst is not None and worst[1][0] > self.remove_threshold:
                        index, record = worst
                        self.steps.append((step + 1, "remove", display[index], *record[1:]))
                        self.model = [t for t in self.model if t != index]
                        self.swept.pop(index, None)
                        self._columns_cache = None
                        in_model[index] = False
                        rows = self._rows(self.model)
                        problem = self._problem_for(rows)
                        # afresh: no drift from sweeping back
                        matrix, _ = self._swept_matrix(problem, self._model_columns())
                        just_added, just_removed = -1, index
                        acted = True
            if not acted:
                break
            step += 1
        self.final = (problem, matrix, rows)

    def _best_addition(self, eligible_index, matrix, problem, rows, step):
        """Best candidate: (term, record, columns, rows) or None when none is testable."""
        display = self.layout.display
        groups: dict[bytes | None, list[int]] = {}
        group_rows: dict[bytes | None, np.ndarray | None] = {}
        if self.finite is None:
            groups[None] = eligible_index
            group_rows[None] = None
        else:
            for term in eligible_index.tolist():
                candidate_rows = self._rows([*self.model, term])
                key = None if np.array_equal(candidate_rows, rows) else candidate_rows.tobytes()
                groups.setdefault(key, []).append(term)
                group_rows[key] = rows if key is None else candidate_rows
        k = 1 + len(self._model_columns())
        best = None
        for key, terms in groups.items():
            if key is None:
                group_problem, group_matrix, group_k = problem, matrix, k
            else:
                candidate_rows = group_rows[key]
                if candidate_rows.sum() < 2:
                    for term in terms:
                        self.skipped.setdefault(
                            (display[term], "no complete rows with the model's variables"),
                            step + 1,
                        )
                    continue
                group_problem = self._problem_for(candidate_rows)
                group_matrix, swept = self._swept_matrix(group_problem, self._model_columns())
                group_k = 1 + swept
            terms_array = np.asarray(terms)
            n = group_problem.n
            sse = max(float(group_matrix[self.y_slot, self.y_slot]), 0.0)
            decrease, df, columns = self._gains(group_matrix, terms_array)
            collinear = df == 0
            short = ~collinear & (n - group_k - df < 1)
            ok = ~collinear & ~short
            if not ok.all():
                for term in terms_array[collinear].tolist():
                    self.skipped.setdefault(
                        (display[term], "collinear with the model's terms"), step + 1
                    )
                for term in terms_array[short].tolist():
                    reason = f"too few observations: n={n} leaves no error degrees of freedom"
                    self.skipped.setdefault((display[term], reason), step + 1)
                if not ok.any():
                    continue
                terms_array, decrease, df = terms_array[ok], decrease[ok], df[ok]
                if columns is not None:
                    columns = [c for c, good in zip(columns, ok, strict=True) if good]
            f_stat, p_value, score, value = self._score_add(
                n, group_k, sse, group_problem.sst, decrease, df
            )
            score = np.where(score != score, np.inf, score)  # NaN (0/0) never enters
            j = int(np.argmin(score))  # terms in canonical order: ties go to the first
            term = int(terms_array[j])
            candidate = (float(score[j]), term)
            if best is None or candidate < best[0]:
                change = score[j] if self.criterion in ("aic", "bic") else -score[j]
                record = self._record(f_stat[j], p_value[j], value[j], change, df[j], n)
                chosen = [int(self.layout.first_column[term])] if columns is None else columns[j]
                best = (candidate, term, (float(score[j]), *record), chosen, group_rows[key])
        if best is None:
            return None
        _, term, record, columns, new_rows = best
        return term, record, columns, new_rows

    def _record(self, f_stat, p_value, value, change, df, n) -> tuple:
        record = [float(f_stat), float(p_value)]
        if self.criterion != "sse":
            record += [float(value), float(change)]
        return (*record, int(df), int(n))

    def _worst_removal(self, terms, removable, matrix, n, k, sse, sst):
        y = self.y_slot
        increase = np.full(len(terms), np.nan)
        df = np.zeros(len(terms))
        if self.layout.single and all(self.swept.get(t) for t in terms.tolist()[1:]):
            # one column per term: SSE_small - SSE_large = b_j² / [(XᵀX)⁻¹]_jj
            columns = self.layout.first_column[terms[removable]]
            increase[removable] = matrix[columns, y] ** 2 / -matrix[columns, columns]
            df[removable] = 1.0
            terms_loop: list[int] = []
        else:
            terms_loop = terms.tolist()
        for position, term in enumerate(terms_loop):
            if not removable[position]:
                continue
            cols = self.swept.get(term, [])
            if not cols:
                continue
            if len(cols) == 1:
                c = cols[0]
                increase[position] = matrix[c, y] ** 2 / -matrix[c, c]
            else:
                b = matrix[cols, y]
                inverse_block = -matrix[np.ix_(cols, cols)]  # [(XᵀX)⁻¹]_TT
                increase[position] = float(b @ np.linalg.solve(inverse_block, b))
            df[position] = len(cols)
        dfe = n - k
        f_stat = (increase / np.maximum(df, 1)) / (sse / dfe)
        p_value = _f_sf(f_stat, np.maximum(df, 1), dfe)
        criterion = self.criterion
        if criterion == "sse":
            score = p_value
            value = np.full_like(p_value, np.nan)
            change = score
        elif criterion in ("aic", "bic"):
            penalty = 2.0 if criterion == "aic" else math.log(n)
            score = n * np.log(sse / (sse + increase)) + penalty * df  # Δ of adding it back
            value = n * (np.log(2 * np.pi * (sse + increase) / n) + 1.0) + penalty * (k - df)
            change = score
        elif criterion == "rsquared":
            score = -(increase / sst)
            value = 1.0 - (sse + increase) / sst
            change = -score
        else:
            with_term = 1.0 - (sse / dfe) / (sst / (n - 1))
            value = 1.0 - ((sse + increase) / (dfe + df)) / (sst / (n - 1))
            score = -(with_term - value)
            change = -score
        valid = removable & ~np.isnan(score) & (df > 0)
        if not valid.any():
            return None
        score = np.where(valid, score, -np.inf)
        worst = int(np.argmax(score))  # model is in canonical order: ties go first
        record = self._record(
            f_stat[worst], p_value[worst], value[worst], change[worst], df[worst], n
        )
        return int(terms[worst]), (float(score[worst]), *record)

    # ----------------------------------------------------------------- the result
    def result(self, encoding: Encoding, response_name: str, missing: str) -> StepwiseFit:
        layout = self.layout
        problem, matrix, rows = self.final
        model = self.model
        n = problem.n
        model_columns = [int(c) for t in model for c in layout.columns[t]]
        swept = self._model_columns()
        k = 1 + len(swept)
        dfe = n - k
        slope_columns = model_columns[1:]  # model_columns[0] is the intercept
        m = len(slope_columns)
        scale = problem.scale[swept]
        # back from centred-scaled columns: b = b_z / s, V = (X_cᵀX_c)⁻¹ = V_z / (s sᵀ)
        swept_slopes = matrix[swept, self.y_slot] / scale
        swept_covariance = -matrix[swept][:, swept] / np.outer(scale, scale)
        if swept == slope_columns:
            slopes, covariance = swept_slopes, swept_covariance
        else:  # columns left out as collinear: estimate 0 (MATLAB's rank-deficient fit)
            position = {c: j for j, c in enumerate(slope_columns)}
            swept_position = [position[c] for c in swept]
            slopes = np.zeros(m)
            covariance = np.zeros((m, m))
            slopes[swept_position] = swept_slopes
            covariance[np.ix_(swept_position, swept_position)] = swept_covariance
        term_means = problem.means[slope_columns]
        intercept = problem.y_mean - float(term_means @ slopes)
        residual = problem.y_centred - problem.centred[:, slope_columns] @ slopes
        sse = float(residual @ residual)
        sst = problem.sst
        mse = sse / dfe if dfe > 0 else math.nan
        rmse = math.sqrt(mse) if mse == mse else math.nan
        # full covariance of (intercept, slopes) in the search's centred units, per σ²
        full = np.empty((m + 1, m + 1))
        full[0, 0] = 1.0 / n + float(term_means @ covariance @ term_means)
        full[0, 1:] = full[1:, 0] = -(covariance @ term_means)
        full[1:, 1:] = covariance
        search_estimates = np.concatenate([[intercept], slopes])
        terms = [layout.terms[t] for t in model]
        transform = raw_transform(terms, encoding)
        if transform is None:  # cannot happen with the hierarchy kept; stay in search units
            transform = np.eye(m + 1)
        estimates = transform @ search_estimates
        raw_covariance = transform @ full @ transform.T
        standard_errors = rmse * np.sqrt(np.maximum(np.diagonal(raw_covariance), 0.0))
        r_squared = 1.0 - sse / sst if sst > 0 else math.nan
        adj_r_squared = 1.0 - (sse / dfe) / (sst / (n - 1)) if sst > 0 and dfe > 0 else math.nan
        if k > 1 and dfe > 0 and mse > 0:
            f_stat = ((sst - sse) / (k - 1)) / mse
            f_p_value = float(_f_sf(f_stat, k - 1, dfe))
        else:
            f_stat = f_p_value = math.nan
        log_likelihood = -0.5 * n * (math.log(2 * math.pi * sse / n) + 1.0) if sse > 0 else math.inf
        names = [layout.column_names[c] for c in model_columns]
        return StepwiseFit(
            terms=tuple(layout.display[t] for t in model[1:]),
            predictor_names=encoding.names,
            response_name=response_name,
            criterion=self.criterion,
            p_enter=self.p_enter,
            p_remove=self.p_remove,
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
            model_terms=tuple(terms),
            estimates=estimates,
            standard_errors=standard_errors,
            term_means=term_means,
            slope_covariance=covariance,
            step_records=tuple(self.steps),
            skipped_records=tuple((s, term, reason) for (term, reason), s in self.skipped.items()),
            coefficient_names=tuple(names),
            coefficient_terms=tuple(layout.terms[t] for t in model for _ in layout.columns[t]),
            search_estimates=search_estimates,
            encoding=encoding,
            missing=missing,
        )


# --------------------------------------------------------------------------- scikit-learn
class StepwiseRegressor(RegressorMixin, BaseEstimator):
    """Scikit-learn estimator around :func:`stepwise` (usable in ``cross_val_score``).

    Parameters
    ----------
    start, upper, lower, criterion, p_enter, p_remove, max_steps, missing
        As for :func:`stepwise` (the estimator sees numeric arrays only).

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
        lower="constant",
        criterion: Criterion = "sse",
        p_enter: float | None = None,
        p_remove: float | None = None,
        max_steps: int | None = None,
        missing: MissingRule = "candidate",
    ):
        self.start = start
        self.upper = upper
        self.lower = lower
        self.missing = missing
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
            lower=self.lower,
            criterion=self.criterion,
            p_enter=self.p_enter,
            p_remove=self.p_remove,
            max_steps=self.max_steps,
            missing=self.missing,
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
