"""Pearson correlation of tracked modes with block predictors, per operating case.

:func:`correlation_table` returns a tidy table (one row per pair and case) of Pearson's r,
its two-sided p-value and the number of blocks used, with ``significant`` and ``useful``
flags, for every mode quantity (``mode1_frequency_hz``, ``mode1_damping_ratio``, ...)
against every predictor and among the predictors. Missing values are handled pairwise
(each pair uses the blocks where both are finite). Cases come from a column or from time
ranges (:func:`read_cases`); the case ``"all"`` stitches the cases together.
:func:`modal_wide` turns the long modal table into one row per block.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from scipy import special as _special

from data_contracts import PREDICTOR_KEYS

from ..errors import PredictorError
from ..predictors.directions import model_columns, with_direction_components
from .effective_sample import effective_p_value, effective_sample_size, effective_significance

__all__ = [
    "adjust_p_values",
    "case_masks",
    "correlation_table",
    "correlation_table_effective",
    "effective_p_value",
    "effective_significance",
    "effective_sample_size",
    "joined_blocks",
    "modal_wide",
    "pairwise_pearson",
    "predictor_columns",
    "read_cases",
]

#: Columns of the tidy correlation table, in order.
TABLE_COLUMNS = ["x", "y", "case", "r", "p_value", "p_adjusted", "n", "significant", "useful"]

#: Key and time columns of a block table that are never predictors.
_KEY_COLUMNS = (*PREDICTOR_KEYS, "mode", "case")


# --------------------------------------------------------------------------- tables
def modal_wide(
    modal: pd.DataFrame,
    quantities: Sequence[str] = ("frequency_hz", "damping_ratio"),
) -> pd.DataFrame:
    """One row per block, one column per mode and quantity (``mode1_frequency_hz``...).

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract, long format): ``block``, ``mode`` and the
        *quantities*.
    quantities : sequence of str
        Columns of *modal* to spread, e.g. ``frequency_hz`` [Hz] and ``damping_ratio`` [-].

    Returns
    -------
    DataFrame
        Indexed by ``block`` (sorted); columns ordered by mode, then quantity. Blocks
        where a mode was not tracked are NaN.
    """
    missing = [c for c in ("block", "mode", *quantities) if c not in modal.columns]
    if missing:
        raise ValueError(f"modal table has no column {missing[0]!r}")
    duplicated = modal.duplicated(["block", "mode"])
    if duplicated.any():
        row = modal.loc[duplicated].iloc[0]
        raise ValueError(
            f"modal table has more than one row for block {int(row['block'])}, "
            f"mode {int(row['mode'])}"
        )
    if modal.empty:
        return pd.DataFrame(index=pd.Index([], name="block", dtype="int64"))
    wide = modal.pivot(index="block", columns="mode", values=list(quantities))
    modes = sorted(int(m) for m in modal["mode"].unique())
    columns = {f"mode{m}_{q}": wide[(q, m)] for m in modes for q in quantities}
    out = pd.DataFrame(columns, index=wide.index).sort_index()
    out.index = out.index.astype("int64").rename("block")
    return out.astype(float)


def predictor_columns(predictors: pd.DataFrame) -> list[str]:
    """Numeric columns of a block predictor table other than keys and times."""
    return [
        str(c)
        for c in predictors.columns
        if c not in _KEY_COLUMNS
        and pd.api.types.is_numeric_dtype(predictors[c])
        and not pd.api.types.is_bool_dtype(predictors[c])
    ]


def joined_blocks(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    quantities: Sequence[str] = ("frequency_hz", "damping_ratio"),
    predictors_used: Sequence[str] | None = None,
) -> tuple[pd.DataFrame, list[str], list[str]]:
    """Mode quantities and predictors side by side, one row per block of *predictors*.

    Returns the joined frame (index ``block``; ``block_start``/``block_end`` kept when
    present), the mode-quantity column names and the predictor column names. A direction
    column (``wind_dir_rel_deg``) enters as its cosine (``wind_dir_rel_cos``:
    :mod:`workbench.predictors.directions`), in *predictors_used*
    too.
    """
    if "block" not in predictors.columns:
        raise PredictorError("predictor table has no column 'block'")
    if predictors["block"].duplicated().any():
        block = int(predictors.loc[predictors["block"].duplicated(), "block"].iloc[0])
        raise PredictorError(f"predictor table has more than one row for block {block}")
    inputs = with_direction_components(predictors)
    if predictors_used is not None:
        given = list(predictors_used)
        missing = [c for c in given if c not in predictors.columns and c not in inputs.columns]
        if missing:
            raise PredictorError(f"predictor table has no column {missing[0]!r}")
        names = model_columns(given)
    else:
        names = predictor_columns(inputs)
    if not names:
        raise PredictorError("predictor table has no numeric predictor columns")
    wide = modal_wide(modal, quantities)
    frame = inputs.set_index("block")
    frame.index = frame.index.astype("int64")
    keep = [c for c in ("block_start", "block_end", "case") if c in frame.columns]
    joined = frame[keep + names].join(wide, how="left")
    for column in names:
        joined[column] = pd.to_numeric(joined[column], errors="coerce").astype(float)
    return joined, list(wide.columns), names


# --------------------------------------------------------------------------- cases
def read_cases(path: str | os.PathLike) -> pd.DataFrame:
    """Read operating cases from a small CSV with columns ``case,start,end``.

    Times are ISO-8601 (UTC when no offset is given); a case covers ``[start, end)``.
    Several rows may share a case name (the case is their union).

    Returns
    -------
    DataFrame
        Columns ``case`` (str), ``start``, ``end`` (UTC timestamps), in file order.

    Raises
    ------
    ValueError
        Missing file or columns, an empty file, a time that does not parse, or an end not
        after its start; the message names the file and the row.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such cases file")
    try:
        raw = pd.read_csv(path, dtype=str, skipinitialspace=True, comment="#")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: not a readable CSV file ({error})") from None
    raw.columns = [str(c).strip().lower() for c in raw.columns]
    missing = [c for c in ("case", "start", "end") if c not in raw.columns]
    if missing:
        raise ValueError(f"{path}: missing column {missing[0]!r}; expected columns case,start,end")
    if raw.empty:
        raise ValueError(f"{path}: no cases (the file has a header only)")
    rows = []
    for number, (case, start, end) in enumerate(
        raw[["case", "start", "end"]].itertuples(index=False), start=2
    ):
        if not isinstance(case, str) or not case.strip():
            raise ValueError(f"{path}: line {number}: empty case name")
        times = []
        for label, text in (("start", start), ("end", end)):
            try:
                stamp = pd.Timestamp(str(text).strip())
            except (ValueError, TypeError):
                stamp = pd.NaT
            if pd.isna(stamp):
                raise ValueError(f"{path}: line {number}: {label} {text!r} is not a time")
            times.append(_utc(stamp))
        if times[1] <= times[0]:
            raise ValueError(
                f"{path}: line {number}: end {end.strip()} is not after start {start.strip()}"
            )
        rows.append((case.strip(), times[0], times[1]))
    out = pd.DataFrame(rows, columns=["case", "start", "end"])
    out["case"] = out["case"].astype(object)
    return out


def case_masks(
    frame: pd.DataFrame,
    cases: str | os.PathLike | pd.DataFrame | None,
) -> list[tuple[str, np.ndarray]]:
    """Row masks of *frame* per case: ``[("all", mask), (case, mask), ...]``.

    Parameters
    ----------
    frame : DataFrame
        Block table with ``block_start`` (and ``block_end``) for time-range cases, or the
        case column.
    cases : None, str, path or DataFrame
        ``None``: every row is case "all". A column name of *frame*: its distinct non-empty
        values are the cases. A path (or a str naming an existing file) read with
        :func:`read_cases`, or a DataFrame with ``case, start, end``: a block belongs to a
        case when it lies inside one of the case's ranges (``block_start >= start`` and
        ``block_end <= end``; ``block_start < end`` when there is no ``block_end``).

    Notes
    -----
    With cases, "all" is the union of the cases' blocks (the cases stitched together);
    blocks outside every case are not used.
    """
    n = len(frame)
    if cases is None:
        return [("all", np.ones(n, dtype=bool))]
    if isinstance(cases, str) and cases in frame.columns:
        labels = frame[cases]
        present = labels.notna() & (labels.astype(str).str.strip() != "")
        out = [("all", present.to_numpy())]
        for value in pd.unique(labels[present]):
            out.append((str(value), (labels == value).to_numpy() & present.to_numpy()))
        return out
    if isinstance(cases, (str, os.PathLike)):
        if not Path(cases).is_file():
            raise ValueError(
                f"cases={str(cases)!r} is neither a column of the block table nor a file"
            )
        cases = read_cases(cases)
    if not isinstance(cases, pd.DataFrame):
        raise TypeError(f"cases must be None, a column name, a path or a DataFrame, got {cases!r}")
    missing = [c for c in ("case", "start", "end") if c not in cases.columns]
    if missing:
        raise ValueError(f"cases table has no column {missing[0]!r}")
    if "block_start" not in frame.columns:
        raise ValueError("time-range cases need the column 'block_start' in the block table")
    start = pd.to_datetime(frame["block_start"], utc=True)
    end = pd.to_datetime(frame["block_end"], utc=True) if "block_end" in frame.columns else None
    masks: dict[str, np.ndarray] = {}
    for case, lower, upper in cases[["case", "start", "end"]].itertuples(index=False):
        lower, upper = _utc(lower), _utc(upper)
        inside = (start >= lower) & ((end <= upper) if end is not None else (start < upper))
        inside = inside.to_numpy(dtype=bool)
        key = str(case)
        masks[key] = masks.get(key, np.zeros(n, dtype=bool)) | inside
    union = np.zeros(n, dtype=bool)
    for mask in masks.values():
        union |= mask
    return [("all", union), *masks.items()]


# --------------------------------------------------------------------------- statistics
def pairwise_pearson(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pearson r, two-sided p-value and n for every column pair, pairwise complete.

    Parameters
    ----------
    a : ndarray, shape (n_rows, p)
    b : ndarray, shape (n_rows, q)
        Data with NaN for missing values.

    Returns
    -------
    r, p_value, n : ndarray, shape (p, q)
        Correlation, p-value of H0: ρ = 0 and the number of rows where both are finite.
        r and p are NaN with fewer than 3 rows or a constant column.

    Notes
    -----
    On the rows where both columns are finite,
    r = Σ(a - ā)(b - b̄) / √(Σ(a - ā)² Σ(b - b̄)²) and t = r √((n - 2) / (1 - r²)) follows
    Student's t with n - 2 degrees of freedom under H0 (bivariate normal data), so
    p = 2 P(T > |t|) [1]_. Sums over the pairwise rows are matrix products of the
    zero-filled data and the validity masks; columns are first centred on their own means
    to avoid cancellation.

    References
    ----------
    .. [1] R. A. Fisher, "Frequency distribution of the values of the correlation
       coefficient in samples from an indefinitely large population", Biometrika 10(4),
       507-521, 1915. doi:10.2307/2331838
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    valid_a = np.isfinite(a)
    valid_b = np.isfinite(b)
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns: "empty slice"
        a = a - np.where(valid_a.any(0), np.nanmean(np.where(valid_a, a, np.nan), 0), 0.0)
        b = b - np.where(valid_b.any(0), np.nanmean(np.where(valid_b, b, np.nan), 0), 0.0)
    a0 = np.where(valid_a, a, 0.0)
    b0 = np.where(valid_b, b, 0.0)
    ma = valid_a.astype(float)
    mb = valid_b.astype(float)
    n = ma.T @ mb
    sum_a = a0.T @ mb
    sum_b = ma.T @ b0
    with np.errstate(invalid="ignore", divide="ignore"):
        cross = a0.T @ b0 - sum_a * sum_b / n
        var_a = (a0**2).T @ mb - sum_a**2 / n
        var_b = ma.T @ (b0**2) - sum_b**2 / n
        scale_a = (a0**2).T @ mb
        scale_b = ma.T @ (b0**2)
        degenerate = (n < 3) | (var_a <= 1e-13 * scale_a) | (var_b <= 1e-13 * scale_b)
        degenerate |= (var_a <= 0) | (var_b <= 0)
        r = np.clip(cross / np.sqrt(var_a * var_b), -1.0, 1.0)
        r[degenerate] = np.nan
        dof = n - 2
        t = r * np.sqrt(dof / ((1.0 - r) * (1.0 + r)))
        p = 2.0 * _special.stdtr(dof, -np.abs(t))
    p[np.abs(r) == 1.0] = 0.0
    p[degenerate] = np.nan
    return r, p, n.astype(int)


def adjust_p_values(p_values: np.ndarray, method: Literal["holm", "fdr_bh"] | None) -> np.ndarray:
    """Multiple-comparison adjusted p-values (NaN entries ignored and kept NaN).

    ``"holm"``: Holm's step-down family-wise error control [1]_,
    p̃_(i) = max_{j<=i} min(1, (m - j + 1) p_(j)). ``"fdr_bh"``: Benjamini-Hochberg false
    discovery rate [2]_, p̃_(i) = min_{j>=i} min(1, m p_(j) / j). ``None``: unchanged.

    References
    ----------
    .. [1] S. Holm, "A simple sequentially rejective multiple test procedure", Scand. J.
       Statist. 6(2), 65-70, 1979. https://www.jstor.org/stable/4615733
    .. [2] Y. Benjamini, Y. Hochberg, "Controlling the false discovery rate: a practical
       and powerful approach to multiple testing", J. R. Statist. Soc. B 57(1), 289-300,
       1995. doi:10.1111/j.2517-6161.1995.tb02031.x
    """
    p_values = np.asarray(p_values, dtype=float)
    if method is None:
        return p_values.copy()
    if method not in ("holm", "fdr_bh"):
        raise ValueError(f"correction={method!r}: expected None, 'holm' or 'fdr_bh'")
    out = np.full_like(p_values, np.nan)
    finite = np.flatnonzero(np.isfinite(p_values))
    m = finite.size
    if m == 0:
        return out
    order = finite[np.argsort(p_values[finite], kind="stable")]
    sorted_p = p_values[order]
    rank = np.arange(1, m + 1)
    if method == "holm":
        adjusted = np.maximum.accumulate(np.minimum((m - rank + 1) * sorted_p, 1.0))
    else:
        adjusted = np.minimum.accumulate((m * sorted_p / rank)[::-1])[::-1]
        adjusted = np.minimum(adjusted, 1.0)
    out[order] = adjusted
    return out


def correlation_table(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    cases: str | os.PathLike | pd.DataFrame | None = None,
    alpha: float = 0.05,
    correction: Literal["holm", "fdr_bh"] | None = None,
    quantities: Sequence[str] = ("frequency_hz", "damping_ratio"),
    predictors_used: Sequence[str] | None = None,
    useful_r: float = 0.5,
) -> pd.DataFrame:
    """Pearson correlation of every mode quantity with every predictor, and among predictors.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract): ``block``, ``mode`` and *quantities*.
    predictors : DataFrame
        Block predictors (PREDICTORS contract, extra numeric columns allowed): ``block``,
        ``block_start``, ``block_end`` and the predictor columns. Its blocks are the rows
        correlated.
    cases : None, str, path or DataFrame
        Operating cases, see :func:`case_masks`: a column of *predictors*, a CSV of time
        ranges (``case,start,end``) or such a DataFrame. Each case is a separate family of
        tests; ``"all"`` stitches the cases together.
    alpha : float
        Significance level: ``significant`` is ``p_adjusted < alpha``.
    correction : {None, "holm", "fdr_bh"}
        Multiple-comparison correction within each case (:func:`adjust_p_values`).
    quantities : sequence of str
        Modal columns correlated, named ``mode<k>_<quantity>`` in the table.
    predictors_used : sequence of str, optional
        Predictor columns; default every numeric column except block keys and times.
    useful_r : float
        ``useful`` is ``significant and |r| >= useful_r``.

    Returns
    -------
    DataFrame
        Columns ``x`` (a predictor), ``y`` (a mode quantity, or a later predictor),
        ``case``, ``r``, ``p_value`` (two-sided, uncorrected), ``p_adjusted``, ``n``
        (blocks where both are finite), ``significant``, ``useful``. Rows: case "all"
        first, then the cases in order; within a case mode quantities by mode, then
        predictor pairs.
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha={alpha!r} must lie in (0, 1)")
    if correction not in (None, "holm", "fdr_bh"):
        raise ValueError(f"correction={correction!r}: expected None, 'holm' or 'fdr_bh'")
    joined, mode_columns, names = joined_blocks(
        modal, predictors, quantities=quantities, predictors_used=predictors_used
    )
    masks = case_masks(joined.reset_index(), cases)
    predictor_values = joined[names].to_numpy(dtype=float)
    mode_values = joined[mode_columns].to_numpy(dtype=float)
    upper_i, upper_j = np.triu_indices(len(names), k=1)
    # pair labels: (x predictor, y mode quantity) for every mode quantity, then predictor pairs
    x_labels = [name for _ in mode_columns for name in names] + [names[i] for i in upper_i]
    y_labels = [column for column in mode_columns for _ in names] + [names[j] for j in upper_j]
    frames = []
    for case, mask in masks:
        r_mode, p_mode, n_mode = pairwise_pearson(predictor_values[mask], mode_values[mask])
        r_pred, p_pred, n_pred = pairwise_pearson(predictor_values[mask], predictor_values[mask])
        r = np.concatenate([r_mode.T.ravel(), r_pred[upper_i, upper_j]])
        p = np.concatenate([p_mode.T.ravel(), p_pred[upper_i, upper_j]])
        n = np.concatenate([n_mode.T.ravel(), n_pred[upper_i, upper_j]])
        adjusted = adjust_p_values(p, correction)
        significant = np.nan_to_num(adjusted, nan=1.0) < alpha
        frames.append(
            pd.DataFrame(
                {
                    "x": x_labels,
                    "y": y_labels,
                    "case": case,
                    "r": r,
                    "p_value": p,
                    "p_adjusted": adjusted,
                    "n": n.astype("int64"),
                    "significant": significant,
                    "useful": significant & (np.abs(np.nan_to_num(r)) >= useful_r),
                }
            )
        )
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=TABLE_COLUMNS)
    return table[TABLE_COLUMNS]


def _utc(value) -> pd.Timestamp:
    """A timestamp in UTC (naive values are taken as UTC)."""
    stamp = pd.Timestamp(value)
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def correlation_table_effective(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    cases: str | os.PathLike | pd.DataFrame | None = None,
    alpha: float = 0.05,
    min_blocks: int = 10,
    **kwargs,
) -> pd.DataFrame:
    """:func:`correlation_table` with :func:`effective_significance` (significance that
    respects autocorrelated blocks). Other keyword arguments go to
    :func:`correlation_table`.
    """
    table = correlation_table(modal, predictors, cases=cases, alpha=alpha, **kwargs)
    joined, _, _ = joined_blocks(
        modal,
        predictors,
        quantities=kwargs.get("quantities", ("frequency_hz", "damping_ratio")),
        predictors_used=kwargs.get("predictors_used"),
    )
    masks = dict(case_masks(joined.reset_index(), cases))
    return effective_significance(table, joined, masks, alpha=alpha, min_blocks=min_blocks)
