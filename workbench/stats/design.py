"""Predictor encoding and design columns of a linear model (MATLAB ``fitlm`` coding).

A predictor is *numeric* or *categorical*. A categorical predictor with L levels enters
as L - 1 indicator (dummy) columns, the first level being the reference (MATLAB's
reference coding): pandas ``Categorical`` keeps its category order, ``bool`` has levels
``0, 1`` (false first), strings and columns named in ``categorical=`` are sorted. A term
is the product of its factors' columns: numeric x numeric one column, categorical (L
levels) x numeric L - 1 columns, categorical x categorical (L - 1)(M - 1) columns, and a
numeric square one column. A categorical predictor cannot be squared.

Numeric predictors enter the search centred (``x - centre``, the mean over the rows with
a finite response): with the hierarchy the model spaces are the same, but products of
centred columns keep interactions and squares well conditioned when a predictor has a
large offset (a temperature in kelvin, a time stamp). Coefficients are mapped back to raw
units for reporting (:func:`raw_transform`).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .terms import Term, is_square

__all__ = ["Encoding", "encode", "design_columns", "column_names", "raw_transform"]


@dataclass(frozen=True, eq=False)
class Encoding:
    """How each predictor column enters the design.

    Parameters
    ----------
    names : tuple of str
        Predictor names.
    levels : tuple of (tuple of str or None)
        Category labels of a categorical predictor (first = reference); ``None`` for
        a numeric one.
    centres : ndarray
        Subtracted from a numeric predictor before it enters a term (0 for categorical).
    """

    names: tuple[str, ...]
    levels: tuple[tuple[str, ...] | None, ...]
    centres: np.ndarray
    #: Per predictor, whether it is categorical (from *levels*; set on construction, which
    #: costs less than a cached property's first access on the encoding of every fit).
    categorical: tuple[bool, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "categorical", tuple(level is not None for level in self.levels))

    def width(self, predictor: int) -> int:
        """Design columns of the predictor's main effect."""
        level = self.levels[predictor]
        return 1 if level is None else len(level) - 1

    def with_centres(self, centres: np.ndarray) -> Encoding:
        return Encoding(self.names, self.levels, np.asarray(centres, dtype=float))

    def codes(self, column: pd.Series, predictor: int, parameter: str = "X") -> np.ndarray:
        """Level codes (float, NaN where missing) of a new column of a categorical predictor;
        a level not seen in the fit is a ValueError naming the column."""
        labels = self.levels[predictor]
        assert labels is not None
        text = _labels(column)
        lookup = {label: k for k, label in enumerate(labels)}
        out = np.full(len(text), np.nan)
        for row, value in enumerate(text):
            if value is None:
                continue
            if value not in lookup:
                raise ValueError(
                    f"{parameter} column {self.names[predictor]!r}: level {value!r} was not in "
                    f"the fitted data (levels: {', '.join(labels)})"
                )
            out[row] = lookup[value]
        return out


def _labels(column: pd.Series) -> list[str | None]:
    """Text labels of a column's values (None where missing); bools become "0"/"1"."""
    out: list[str | None] = []
    for value in column.tolist():
        if value is None or (isinstance(value, float) and value != value) or value is pd.NA:
            out.append(None)
        elif isinstance(value, (bool, np.bool_)):
            out.append("1" if value else "0")
        elif isinstance(value, (float, np.floating)) and float(value).is_integer():
            out.append(str(int(value)))
        else:
            out.append(str(value))
    return out


def _is_categorical(column: pd.Series) -> bool:
    dtype = column.dtype
    return (
        isinstance(dtype, pd.CategoricalDtype)
        or pd.api.types.is_bool_dtype(dtype)
        or pd.api.types.is_object_dtype(dtype)
        or pd.api.types.is_string_dtype(dtype)
    )


def column_labels(columns: pd.Index) -> tuple:
    """The labels of a frame's *columns* as Python objects.

    A column index of pandas' Arrow-backed string dtype is converted through its Arrow
    array, which costs a fraction of ``Index.tolist()`` (a noticeable share of a small
    stepwise fit); any other index, or one with a missing label (None from Arrow, which
    ``tolist()`` gives as NaN), through ``tolist()``. Missing labels are looked for in the
    converted tuple: ``Index.hasnans`` of a new index costs more than the conversion.
    """
    array = columns.array
    if isinstance(array, pd.arrays.ArrowStringArray):
        labels = tuple(array.__arrow_array__().to_pylist())
        if None not in labels:
            return labels
    return tuple(columns.tolist())


def _all_numeric(frame: pd.DataFrame) -> bool:
    """Every column numeric and not bool (checked on the frame's blocks when possible:
    ``frame.dtypes`` builds a Series, which costs more than a small stepwise fit)."""
    manager = getattr(frame, "_mgr", None)
    blocks = getattr(manager, "blocks", None)
    if blocks is not None and len(blocks) == 1 and getattr(blocks[0].dtype, "kind", "") in "fiu":
        return True
    return all(
        pd.api.types.is_numeric_dtype(dtype) and not pd.api.types.is_bool_dtype(dtype)
        for dtype in frame.dtypes
    )


@functools.lru_cache(maxsize=256)
def _name_problem(names: tuple[str, ...]) -> str | None:
    """What is wrong with predictor *names* (duplicates, reserved characters), or None
    (cached: a sliding fit checks the same names for every window)."""
    if len(set(names)) != len(names):
        return f"has duplicate column names: {list(names)}"
    bad = [c for c in names if ":" in c or "^" in c]
    if bad:
        return f"column {bad[0]!r}: ':' and '^' are reserved for terms"
    return None


def encode(
    X, categorical: Sequence[str | int] | None = None, parameter: str = "X"
) -> tuple[np.ndarray, Encoding]:
    """Float matrix (numeric values, or level codes of categorical columns) and encoding.

    Parameters
    ----------
    X : DataFrame or ndarray
        Predictors; arrays are numeric with names ``x1..xn``.
    categorical : sequence of str or int, optional
        Further columns (names or positions) to treat as categorical, e.g. a model year
        stored as integers (MATLAB ``CategoricalVars``).
    """
    if isinstance(X, pd.DataFrame):
        names = column_labels(X.columns)
        if not all(type(name) is str for name in names):
            names = tuple(map(str, names))
        frame = X
    else:
        values = np.asarray(X)
        if values.ndim == 1:
            values = values[:, None]
        if values.ndim != 2:
            raise ValueError(
                f"{parameter} must be 2-D (observations x predictors), got {values.ndim}-D"
            )
        names = tuple(f"x{i + 1}" for i in range(values.shape[1]))
        if not categorical:
            try:
                matrix = values.astype(float)
            except (TypeError, ValueError):
                raise TypeError(f"{parameter} is not numeric") from None
            return matrix, Encoding(names, (None,) * len(names), np.zeros(len(names)))
        frame = pd.DataFrame(values, columns=list(names))
    problem = _name_problem(names)
    if problem is not None:
        raise ValueError(f"{parameter} {problem}")
    if not categorical and _all_numeric(frame):
        # one conversion of the whole frame (the common, fast case)
        try:
            matrix = frame.to_numpy(dtype=float)
        except (TypeError, ValueError):  # nullable dtypes holding pd.NA
            matrix = frame.to_numpy(dtype=float, na_value=np.nan)
        return matrix, Encoding(names, (None,) * len(names), np.zeros(len(names)))
    chosen: set[int] = set()
    for item in categorical or ():
        if isinstance(item, (int, np.integer)) and not isinstance(item, bool):
            if not 0 <= item < len(names):
                raise ValueError(f"categorical={item!r}: no such column (X has {len(names)})")
            chosen.add(int(item))
        elif str(item) in names:
            chosen.add(names.index(str(item)))
        else:
            raise ValueError(
                f"categorical={item!r}: no such column; available: " + ", ".join(map(repr, names))
            )
    matrix = np.empty((len(frame), len(names)))
    levels: list[tuple[str, ...] | None] = []
    for j, name in enumerate(names):
        column = frame.iloc[:, j]
        if j in chosen or _is_categorical(column):
            if isinstance(column.dtype, pd.CategoricalDtype):
                labels = tuple(_labels(pd.Series(column.cat.categories)))
            else:
                text = _labels(column)
                present = {t for t in text if t is not None}
                if pd.api.types.is_bool_dtype(column.dtype):
                    labels = ("0", "1")
                elif pd.api.types.is_numeric_dtype(column.dtype):
                    labels = tuple(sorted(present, key=float))
                else:
                    labels = tuple(sorted(present))
            lookup = {label: k for k, label in enumerate(labels)}
            codes = [lookup.get(t, np.nan) if t is not None else np.nan for t in _labels(column)]
            matrix[:, j] = codes
            levels.append(labels)
        else:
            try:
                matrix[:, j] = column.to_numpy(dtype=float, na_value=np.nan)
            except (TypeError, ValueError):
                raise TypeError(f"{parameter} column {name!r} is not numeric") from None
            levels.append(None)
    return matrix, Encoding(names, tuple(levels), np.zeros(len(names)))


def _factor_blocks(values: np.ndarray, encoding: Encoding, predictor: int) -> np.ndarray:
    """Columns of one factor: the centred numeric column, or the L - 1 dummies."""
    labels = encoding.levels[predictor]
    column = values[:, predictor]
    if labels is None:
        return (column - encoding.centres[predictor])[:, None]
    out = np.empty((values.shape[0], len(labels) - 1))
    for k in range(1, len(labels)):
        out[:, k - 1] = column == k
    out[np.isnan(column)] = np.nan
    return out


def term_width(term: Term, encoding: Encoding) -> int:
    """Design columns of *term*."""
    if not term:
        return 1
    if is_square(term):
        return 1
    width = 1
    for predictor in term:
        width *= encoding.width(predictor)
    return width


def design_columns(
    values: np.ndarray,
    terms: Sequence[Term],
    encoding: Encoding,
    widths: Sequence[int] | None = None,
) -> np.ndarray:
    """Design matrix of *terms* (intercept ones, centred numeric factors, dummies)."""
    simple = not any(encoding.categorical)
    if simple:
        intercept, single, pair_a, pair_b, canonical = _numeric_plan(tuple(terms))
        out = np.empty((values.shape[0], len(terms)))
        if canonical is not None and values.shape[1] == canonical[0]:
            # intercept, every main effect in column order, then products (MATLAB's order
            # for "interactions"): slices instead of scattered columns, the same numbers
            p = canonical[0]
            out[:, 0] = 1.0
            centred = np.subtract(values, encoding.centres, out=out[:, 1 : p + 1])
            np.multiply(centred[:, pair_a[1]], centred[:, pair_b], out=out[:, p + 1 :])
            return out
        centred = values - encoding.centres
        out[:, intercept] = 1.0
        out[:, single[0]] = centred[:, single[1]]
        out[:, pair_a[0]] = centred[:, pair_a[1]] * centred[:, pair_b]
        return out
    if widths is None:
        widths = [term_width(t, encoding) for t in terms]
    out = np.empty((values.shape[0], sum(widths)))
    position = 0
    centres = encoding.centres
    for term, width in zip(terms, widths, strict=True):
        block = out[:, position : position + width]
        if not term:
            block.fill(1.0)
        elif simple and len(term) == 1:
            np.subtract(values[:, term[0]], centres[term[0]], out=block[:, 0])
        elif simple:
            a = values[:, term[0]] - centres[term[0]]
            b = values[:, term[1]] - centres[term[1]]
            np.multiply(a, b, out=block[:, 0])
        elif len(term) == 1:
            block[:] = _factor_blocks(values, encoding, term[0])
        else:
            first = _factor_blocks(values, encoding, term[0])
            second = _factor_blocks(values, encoding, term[1])
            if is_square(term):
                block[:, 0] = first[:, 0] ** 2
            else:
                # MATLAB's column order: the first factor's levels vary fastest
                block[:] = (second[:, :, None] * first[:, None, :]).reshape(len(values), -1)
        position += width
    return out


@functools.lru_cache(maxsize=256)
def _numeric_plan(terms: tuple[Term, ...]):
    """Column positions of a numeric design: intercepts, main effects (position,
    predictor), products (position, first factor) and the second factors."""
    intercept = [k for k, t in enumerate(terms) if not t]
    single = [(k, t[0]) for k, t in enumerate(terms) if len(t) == 1]
    pairs = [(k, t[0], t[1]) for k, t in enumerate(terms) if len(t) == 2]
    single_index = (
        np.array([k for k, _ in single], dtype=int),
        np.array([i for _, i in single], dtype=int),
    )
    pair_a = (
        np.array([k for k, _, _ in pairs], dtype=int),
        np.array([a for _, a, _ in pairs], dtype=int),
    )
    pair_b = np.array([b for _, _, b in pairs], dtype=int)
    # (number of predictors,) when the terms are the intercept, the main effects of
    # predictors 0..p-1 in order, then products only; else None
    p = len(single)
    canonical = (
        (p,)
        if terms[:1] == ((),)
        and [k for k, _ in single] == list(range(1, p + 1))
        and [i for _, i in single] == list(range(p))
        and [k for k, _, _ in pairs] == list(range(p + 1, len(terms)))
        else None
    )
    return np.array(intercept, dtype=int), single_index, pair_a, pair_b, canonical


def _factor_labels(encoding: Encoding, predictor: int) -> list[str]:
    labels = encoding.levels[predictor]
    name = encoding.names[predictor]
    if labels is None:
        return [name]
    return [f"{name}_{label}" for label in labels[1:]]


def column_names(terms: Sequence[Term], encoding: Encoding) -> list[str]:
    """Coefficient names of the design columns: ``(Intercept)``, ``Weight``,
    ``Year_76`` (dummy of level 76), ``Weight:Year_76``, ``Weight^2``."""
    out: list[str] = []
    for term in terms:
        if not term:
            out.append("(Intercept)")
        elif is_square(term):
            out.append(f"{encoding.names[term[0]]}^2")
        elif len(term) == 1:
            out += _factor_labels(encoding, term[0])
        else:
            first = _factor_labels(encoding, term[0])
            second = _factor_labels(encoding, term[1])
            out += [f"{a}:{b}" for b in second for a in first]
    return out


def _column_parts(terms: Sequence[Term], encoding: Encoding) -> list[tuple]:
    """Identity of each design column: a sorted tuple of (predictor, level) factors,
    level -1 for a numeric factor (a square has its factor twice)."""
    parts: list[tuple] = []
    for term in terms:
        if not term:
            parts.append(())
            continue
        choices = []
        for predictor in term:
            width = encoding.width(predictor)
            if encoding.levels[predictor] is None:
                choices.append([(predictor, -1)])
            else:
                choices.append([(predictor, k) for k in range(1, width + 1)])
        if is_square(term):
            parts.append(((term[0], -1), (term[0], -1)))
        elif len(term) == 1:
            parts += [(c,) for c in choices[0]]
        else:
            parts += [tuple(sorted((a, b))) for b in choices[1] for a in choices[0]]
    return parts


def raw_transform(terms: Sequence[Term], encoding: Encoding) -> np.ndarray | None:
    """Matrix A with ``b_raw = A b_centred`` for the design columns of *terms*.

    A centred column is a product of factors, numeric ones ``x - c``; expanding the
    product gives raw columns of the same term and of lower terms, which the hierarchy
    keeps in the model. Returns None when a needed lower column is not in *terms*.
    """
    if not any(encoding.categorical):
        return _numeric_transform(terms, encoding.centres)
    parts = _column_parts(terms, encoding)
    position = {p: k for k, p in enumerate(parts)}
    size = len(parts)
    A = np.zeros((size, size))
    for j, factors in enumerate(parts):
        numeric = [k for k, (_, level) in enumerate(factors) if level < 0]
        for keep in itertools.product((True, False), repeat=len(numeric)):
            coefficient = 1.0
            dropped = set()
            for k, kept in zip(numeric, keep, strict=True):
                if not kept:
                    coefficient *= -encoding.centres[factors[k][0]]
                    dropped.add(k)
            if coefficient == 0.0:
                continue
            target = tuple(sorted(f for k, f in enumerate(factors) if k not in dropped))
            row = position.get(target)
            if row is None:
                return None
            A[row, j] += coefficient
    return A


def _numeric_transform(terms: Sequence[Term], centres: np.ndarray) -> np.ndarray | None:
    """:func:`raw_transform` when every term has one column (numeric predictors only):
    x - c, (x - c)(z - d) = xz - d x - c z + c d and (x - c)² = x² - 2 c x + c²."""
    plan = _numeric_transform_plan(tuple(terms))
    if plan is None:
        return None
    intercept, single, single_predictor, pair, row_a, row_b, a, b = plan
    A = np.eye(len(terms))
    A[intercept, single] = -centres[single_predictor]
    A[row_a, pair] -= centres[b]
    A[row_b, pair] -= centres[a]
    A[intercept, pair] += centres[a] * centres[b]
    return A


@functools.lru_cache(maxsize=256)
def _numeric_transform_plan(terms: tuple[Term, ...]):
    """Positions used by :func:`_numeric_transform`: the intercept's row, the main effects'
    columns and predictors, the products' columns, their factors' rows and predictors
    (None when a factor's main effect is not among *terms*)."""
    position = {term: k for k, term in enumerate(terms)}
    single = [j for j, term in enumerate(terms) if len(term) == 1]
    pair = [j for j, term in enumerate(terms) if len(term) == 2]
    if any((terms[j][0],) not in position or (terms[j][1],) not in position for j in pair):
        return None
    if (single or pair) and () not in position:
        return None
    return (
        position.get((), 0),
        np.array(single, dtype=int),
        np.array([terms[j][0] for j in single], dtype=int),
        np.array(pair, dtype=int),
        np.array([position[(terms[j][0],)] for j in pair], dtype=int),
        np.array([position[(terms[j][1],)] for j in pair], dtype=int),
        np.array([terms[j][0] for j in pair], dtype=int),
        np.array([terms[j][1] for j in pair], dtype=int),
    )
