"""The stepwise regression function: options, model specifications and data checked, the
numeric predictors centred, the search run (:mod:`.search`)."""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from ..design import design_columns, encode
from ..terms import is_square, parents, parse_terms, term_name
from .layout import _layout
from .result import StepwiseFit, StepwiseWarning
from .search import _Search

__all__ = ["DEFAULT_THRESHOLDS", "stepwise"]

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
        Most steps taken (MATLAB ``'NSteps'``). Default: ``STEPS_PER_TERM`` (4) per term of
        the upper model plus 10, a guard the search is not expected to reach; reaching it
        warns (:class:`StepwiseWarning`).
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

    Every search ends. Each F-test compares its two models on one sample, the rows complete
    in the variables of the larger model (so with ``missing="candidate"`` the candidates of
    one step may be tested on different rows, as MATLAB does). Because the rows change with
    the model, a search over data with gaps can return to a model it has visited (add a,
    add b, remove a, remove b, add a...). The cycle guard stops it there: the models of
    the cycle are fitted on one sample, the rows complete in all their variables, and the
    best by the criterion is kept (``"sse"``: the smallest p-value of the model's F-test
    against the constant model, which scores *p_enter*; ``"aic"``/``"bic"``: the smallest
    criterion; ``"rsquared"``/``"adjrsquared"``: the largest), fitted on its own rows. The
    stop is the last row of :attr:`StepwiseFit.steps` (action ``"stop"``), and a
    :class:`StepwiseWarning` and :attr:`StepwiseFit.search_warnings` say why. A default
    step limit is the second guard.

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

    # floating-point exceptions of the search are expected (0/0 of an exact fit, a column
    # of NaN): silenced once for the whole fit
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        fit = _fit(
            X, y, start, upper, lower, criterion, p_enter, p_remove, max_steps, missing, categorical
        )
    for message in fit.search_warnings:
        warnings.warn(message, StepwiseWarning, stacklevel=2)
    return fit


def _fit(
    X, y, start, upper, lower, criterion, p_enter, p_remove, max_steps, missing, categorical
) -> StepwiseFit:
    """The search of :func:`stepwise` with its options checked: data and model
    specifications checked, numeric predictors centred, the search run."""
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
    models = _models(upper, start, lower, names, encoding.levels)
    upper_terms, layout = models.upper_terms, models.layout
    used_columns = layout.used_columns
    # complete data (the common case) needs none of the row bookkeeping below; a finite
    # total means that every value is finite (NaN and inf propagate; a sum that overflows
    # only takes the longer way)
    total = float(values.sum()) + float(y_values.sum()) if y_values.shape[0] else math.nan
    complete = math.isfinite(total)
    finite = None
    if not complete:
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
    start_columns = list(models.start_columns)
    start_rows = (
        int(finite[:, start_columns].all(axis=1).sum()) if start_columns and not complete else n
    )
    width = models.start_width
    if start_rows < width + 1:
        raise ValueError(
            f"stepwise needs at least {width + 1} complete rows for the start model "
            f"({width} coefficients), got {start_rows}"
        )
    # numeric predictors enter centred (their mean over the usable rows)
    centres = np.zeros(len(names))
    numeric = models.numeric
    has_missing = not complete and bool(used_columns) and not finite[:, used_columns].all()
    if numeric.size:
        block = values[:, numeric]
        # sum / n: the value of block.mean(axis=0) without its overhead
        if has_missing:  # over the finite values: ±inf is missing as NaN is (rows above)
            block = np.where(finite[:, numeric], block, np.nan)
            centres[numeric] = np.nanmean(block, axis=0)
        else:
            centres[numeric] = block.sum(axis=0) / n
    encoding = encoding.with_centres(centres)
    candidates = design_columns(values, upper_terms, encoding, widths=layout.widths)
    search = _Search(
        candidates=candidates,
        y=y_values,
        finite=finite if has_missing else None,
        layout=layout,
        criterion=criterion,
        p_enter=p_enter,
        p_remove=p_remove,
        response_name=response_name,
    )
    search.run(models.start_index, models.lower_index, max_steps)
    return search.result(encoding, response_name, missing)


@dataclass(frozen=True, eq=False)
class _Models:
    """The upper, start and lower models of a search, checked, with what the search needs
    of them (cached per specification and predictors: a sliding fit repeats them)."""

    upper_terms: tuple
    layout: object
    start_columns: tuple[int, ...]  # predictor columns of the start model
    start_width: int  # design columns of the start model
    numeric: np.ndarray  # numeric predictor columns used by the upper model
    start_index: tuple[int, ...]
    lower_index: frozenset[int]


def _read_only(values) -> np.ndarray:
    out = np.array(values, dtype=int)
    out.setflags(write=False)
    return out


def _hashable(spec):
    """*spec* as a cache key: text as is, a sequence as a tuple, otherwise None."""
    if isinstance(spec, str):
        return spec
    if isinstance(spec, (list, tuple)) and all(isinstance(item, str) for item in spec):
        return tuple(spec)
    return None


def _models(upper, start, lower, names: tuple[str, ...], levels: tuple) -> _Models:
    keys = (_hashable(upper), _hashable(start), _hashable(lower))
    if None in keys:
        return _check_models(upper, start, lower, names, levels)
    return _cached_models(*keys, names, levels)


@functools.lru_cache(maxsize=256)
def _cached_models(upper, start, lower, names, levels) -> _Models:
    return _check_models(upper, start, lower, names, levels)


def _check_models(upper, start, lower, names: tuple[str, ...], levels: tuple) -> _Models:
    """Parse and check the model specifications (see :func:`stepwise`, Raises)."""
    categorical = [level is not None for level in levels]
    squarable = [not flag for flag in categorical]
    models = {}
    for parameter, spec in (("upper", upper), ("start", start), ("lower", lower)):
        terms = parse_terms(spec, names, parameter=parameter, squarable=squarable)
        for term in terms if any(categorical) else ():
            if is_square(term) and categorical[term[0]]:
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

    layout = _layout(upper_terms, names, levels)
    return _Models(
        upper_terms=upper_terms,
        layout=layout,
        start_columns=tuple(sorted({c for t in start_terms for c in t})),
        start_width=sum(layout.widths[position[t]] for t in start_terms),
        numeric=_read_only([c for c in layout.used_columns if levels[c] is None]),
        start_index=tuple(position[t] for t in start_terms),
        lower_index=frozenset(position[t] for t in lower_terms),
    )
