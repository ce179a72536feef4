"""Checks that tables joined on block numbers mean the same blocks.

Stages join their inputs on ``block`` (the modal table with the block predictors, the
poles, the true modal table). A block number is only meaningful with its grid: predictors
of another day, a table shifted by one block or the poles of another voyage carry the same
numbers for other times. These checks compare the block times (or, for pole tables
without times, the tracked poles themselves) and raise a one-line
:class:`~workbench.errors.WorkbenchError` naming the file and the first disagreeing block.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from data_contracts import PREDICTOR_KEYS

from .errors import WorkbenchError
from .signals.block_plan import CLOCK_JITTER_S

__all__ = [
    "check_block_grid",
    "check_block_times",
    "check_poles_cover",
    "check_poles_match",
    "check_predictors_overlap",
]

#: Block starts closer than this are the same time (CSV round trips keep microseconds). [s]
_TIME_TOLERANCE_S = 1e-3
#: Two tables' starts of a block closer than this are the same block: a grid anchored at a
#: recorder's first stamp (``identify``'s) lies up to the clock jitter from one anchored at
#: the true time (a simulator's truth, a table on whole minutes), as the placement takes
#: stamps that close as contiguous (:data:`~workbench.signals.block_plan.CLOCK_JITTER_S`).
#: A table of another voyage, day or block lies a step (minutes) or more away. [s]
_BLOCK_TOLERANCE_S = CLOCK_JITTER_S


def _varying(table: pd.DataFrame) -> bool:
    """Blocks of varying length (``identify --block-minutes auto``): their centres, not
    their starts, lie on the grid."""
    if "block_end" not in table.columns or table.empty:
        return False
    spans = table[["block", "block_start", "block_end"]].drop_duplicates("block")
    length = pd.to_datetime(spans["block_end"], utc=True) - pd.to_datetime(
        spans["block_start"], utc=True
    )
    seconds = length.dt.total_seconds().to_numpy()
    return bool(np.ptp(seconds) > _TIME_TOLERANCE_S) if seconds.size else False


def _starts(table: pd.DataFrame, centres: bool = False) -> pd.Series:
    """Block start per block (or, with *centres*, the middle of each block's span)."""
    columns = ["block", "block_start", "block_end"] if centres else ["block", "block_start"]
    spans = table[columns].drop_duplicates("block").set_index("block")
    start = pd.to_datetime(spans["block_start"], utc=True)
    if not centres:
        return start
    return start + (pd.to_datetime(spans["block_end"], utc=True) - start) / 2


def check_block_times(
    reference: pd.DataFrame, reference_name, other: pd.DataFrame, other_name
) -> None:
    """Raise if *other* gives any block number another start time than *reference* (more
    than the clock jitter apart, :data:`_BLOCK_TOLERANCE_S`), or if the two tables have no
    block in common.

    Tables without a ``block_start`` column cannot be checked this way and pass.

    Raises
    ------
    WorkbenchError
        ``"<other>: block 7 starts 2026-03-02T00:35:00Z, but 2026-03-01T00:35:00Z in
        <reference> ..."``.
    """
    if reference.empty or other.empty:
        return
    if not {"block", "block_start"} <= set(reference.columns) & set(other.columns):
        return
    centres = _varying(reference) or _varying(other)
    if centres and not {"block_end"} <= set(reference.columns) & set(other.columns):
        return  # blocks of varying length are told apart by their centres
    ref, oth = _starts(reference, centres), _starts(other, centres)
    common = ref.index.intersection(oth.index)
    if not len(common):
        raise WorkbenchError(
            f"{other_name}: no block in common with {reference_name} (blocks "
            f"{int(oth.index.min())}..{int(oth.index.max())} against "
            f"{int(ref.index.min())}..{int(ref.index.max())})"
        )
    delta = (oth[common] - ref[common]).dt.total_seconds().to_numpy()
    off = np.abs(delta) > _BLOCK_TOLERANCE_S
    if not off.any():
        return
    first = common[np.flatnonzero(off)[0]]
    shift = float(delta[np.flatnonzero(off)[0]])
    starts = "is centred at" if centres else "starts"  # blocks of varying length: centres
    raise WorkbenchError(
        f"{other_name}: block {int(first)} {starts} {_iso(oth[first])}, but {_iso(ref[first])} "
        f"in {reference_name} ({int(off.sum())} of {len(common)} common blocks differ, first "
        f"by {shift:+g} s; starts within {_BLOCK_TOLERANCE_S:g} s, a recorder's clock "
        "jitter, are the same): block numbers must mean the same times in every input"
    )


def check_block_grid(table: pd.DataFrame, name) -> None:
    """Raise if a table's block numbers and block starts do not lie on one grid
    (``block_start = t0 + block * step``), e.g. a block number of 1e18 among blocks 0..44.
    """
    if table.empty or not {"block", "block_start"} <= set(table.columns):
        return
    centres = _varying(table)
    starts = _starts(table, centres).sort_index()
    if len(starts) < 2:
        return
    blocks = starts.index.to_numpy(dtype=float)
    seconds = (starts - starts.iloc[0]).dt.total_seconds().to_numpy()
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        step = float(np.median(np.diff(seconds) / np.diff(blocks)))
        off = np.abs(seconds - (blocks - blocks[0]) * step) > _TIME_TOLERANCE_S
    if not off.any():
        return
    k = int(np.flatnonzero(off)[0])
    at = "is centred at" if centres else "starts"  # blocks of varying length: centres
    raise WorkbenchError(
        f"{name}: block {int(starts.index[k])} {at} {_iso(starts.iloc[k])}, off the grid of "
        f"the other blocks (a block every {step:g} s from block {int(starts.index[0])} "
        f"{'centred ' if centres else ''}at {_iso(starts.iloc[0])}): block numbers and times "
        "disagree"
    )


def check_predictors_overlap(
    modal: pd.DataFrame, predictors: pd.DataFrame, name, *, table: bool = False
) -> None:
    """Raise if *predictors* have no value at all on the blocks of *modal* (e.g. a ship log
    of another voyage averaged onto the modal table's blocks); warn when some blocks have
    none (a log that ends early, starts late or stops for a while), naming how many and
    the first and last of them. *table*: *predictors* are a predictor table as read (not
    a log averaged onto the modal table's blocks), so one with no row, or no value in any
    row, is named as such rather than as not overlapping the blocks."""
    columns = [
        c
        for c in predictors.columns
        if c not in PREDICTOR_KEYS and pd.api.types.is_numeric_dtype(predictors[c])
    ]
    if not columns or modal.empty:
        return
    blocks = np.unique(modal["block"].to_numpy())
    rows = predictors[predictors["block"].isin(blocks)]
    logged = rows.loc[rows[columns].notna().to_numpy().any(axis=1), "block"].unique()
    if len(logged):
        starts = modal.drop_duplicates("block").set_index("block")["block_start"]
        # a row of NaN (the log stopped) is filled by the forecast; a block with no row
        # at all lies outside the forecast's grid, which is the predictor table's blocks
        absent = np.setdiff1d(blocks, rows["block"].unique())
        empty = np.setdiff1d(np.setdiff1d(blocks, logged), absent)
        for unlogged, what, forecast in (
            (empty, "no predictor value on", "forecasts fill them from the logged blocks"),
            (absent, "no predictor row for", "forecasts do not reach them"),
        ):
            if len(unlogged):
                warnings.warn(
                    f"{name}: {what} {len(unlogged)} of {len(blocks)} blocks of the modal "
                    f"table (blocks {int(unlogged[0])} to {int(unlogged[-1])}, "
                    f"{_iso(starts[unlogged[0]])} to {_iso(starts[unlogged[-1]])}): "
                    f"correlations and fits leave them out, {forecast}",
                    stacklevel=2,
                )
        return
    if table and predictors.empty:
        raise WorkbenchError(f"{name}: the table has a header but no rows: no predictor value")
    if table and not predictors[columns].notna().to_numpy().any():
        raise WorkbenchError(
            f"{name}: no predictor value in any of its {len(predictors)} rows "
            f"({', '.join(columns)} empty throughout)"
        )
    first, last = modal["block_start"].min(), modal["block_start"].max()
    raise WorkbenchError(
        f"{name}: no predictor value on any block of the modal table ({_iso(first)} to "
        f"{_iso(last)}): the ship log or predictor table does not overlap the blocks"
    )


def check_poles_match(
    modal: pd.DataFrame, modal_name, poles: pd.DataFrame, poles_name, *, min_share: float = 0.5
) -> None:
    """Raise if *poles* do not hold the tracked poles of *modal* (another voyage's poles).

    With ``block_start`` in both tables the block times are compared. Otherwise, when the
    modal table records each mode's ``model_order``, at least *min_share* of the rows of
    the blocks they share must find their pole: the tracked frequency is one of the poles
    of its block and order (relative difference 1e-6), or - a mode selected as a pole
    cluster reports the cluster's median frequency, with ``pole_index`` the position in
    the block's poles of its member nearest the median - the pole at ``pole_index`` has
    the row's model order and lies within the cluster's ``frequency_std_hz`` of the
    median. A pole table without rows holds none of them.
    """
    if poles.empty and not modal.empty:
        raise WorkbenchError(
            f"{poles_name}: the pole table has a header but no rows: no stabilisation "
            "diagram to measure the modes in"
        )
    if "block_start" in poles.columns:
        check_block_times(modal, modal_name, poles, poles_name)
        return
    if modal.empty or poles.empty or "model_order" not in modal.columns:
        return
    tracked = modal.dropna(subset=["model_order", "frequency_hz"])
    tracked = tracked[tracked["block"].isin(poles["block"].unique())]
    if not len(common_blocks := tracked["block"].unique()):
        raise WorkbenchError(
            f"{poles_name}: no block in common with {modal_name} (poles of another voyage?)"
        )
    keys = tracked[["block", "model_order", "frequency_hz"]].astype({"model_order": "int64"})
    keys = keys.reset_index(drop=True).reset_index(names="row")
    candidates = poles[poles["block"].isin(common_blocks)][["block", "model_order", "frequency_hz"]]
    merged = keys.merge(
        candidates.astype({"model_order": "int64"}),
        on=["block", "model_order"],
        suffixes=("", "_pole"),
    )
    close = np.abs(merged["frequency_hz_pole"] - merged["frequency_hz"]) <= 1e-6 * np.maximum(
        merged["frequency_hz"].abs(), 1.0
    )
    found_rows = set(merged.loc[close, "row"])
    if {"pole_index", "frequency_std_hz"} <= set(tracked.columns):
        found_rows |= _cluster_rows(tracked, poles[poles["block"].isin(common_blocks)])
    found = len(found_rows)
    if found < min_share * len(keys):
        raise WorkbenchError(
            f"{poles_name}: only {found} of {len(keys)} tracked poles of {modal_name} are "
            "among these poles at their block and model order: poles of another voyage or "
            "shifted blocks"
        )


def check_poles_cover(modal: pd.DataFrame, poles: pd.DataFrame, poles_name) -> None:
    """Warn when blocks of *modal* have no pole in *poles* (a pole table of part of the
    voyage): option B has no measurement there, naming how many and the first and last."""
    if modal.empty or poles.empty:
        return
    blocks = np.unique(modal["block"].to_numpy())
    absent = np.setdiff1d(blocks, poles["block"].unique())
    if not len(absent):
        return
    where = ""
    if "block_start" in modal.columns:
        starts = modal.drop_duplicates("block").set_index("block")["block_start"]
        where = f", {_iso(starts[absent[0]])} to {_iso(starts[absent[-1]])}"
    warnings.warn(
        f"{poles_name}: no pole in {len(absent)} of {len(blocks)} blocks of the modal table "
        f"(blocks {int(absent[0])} to {int(absent[-1])}{where}): option B has no "
        "measurement there",
        stacklevel=2,
    )


def _cluster_rows(tracked: pd.DataFrame, poles: pd.DataFrame) -> set[int]:
    """Rows (positions in *tracked*) whose pole at ``pole_index`` in its block's poles
    (in the pole table's order) has the row's model order and lies within the row's
    ``frequency_std_hz`` of its frequency."""
    rows = (
        tracked.reset_index(drop=True)
        .reset_index(names="row")
        .dropna(subset=["pole_index", "frequency_std_hz"])
    )
    if rows.empty:
        return set()
    positioned = poles[["block", "model_order", "frequency_hz"]].copy()
    positioned["pole_index"] = positioned.groupby("block").cumcount()
    merged = rows[["row", "block", "pole_index", "model_order", "frequency_hz", "frequency_std_hz"]]
    merged = merged.astype({"pole_index": "int64", "model_order": "int64"}).merge(
        positioned.astype({"model_order": "int64"}),
        on=["block", "pole_index"],
        suffixes=("", "_pole"),
    )
    tolerance = np.maximum(merged["frequency_std_hz"], 1e-6 * merged["frequency_hz"].abs())
    same = (merged["model_order"] == merged["model_order_pole"]) & (
        np.abs(merged["frequency_hz_pole"] - merged["frequency_hz"]) <= tolerance
    )
    return set(merged.loc[same, "row"])


def _iso(time) -> str:
    """*time* in UTC to the second, or to the millisecond when it falls between seconds
    (a grid anchored at a recorder's stamp; else two times a few ms apart read alike)."""
    time = pd.Timestamp(time)
    if time.microsecond or time.nanosecond:
        return time.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"
    return time.strftime("%Y-%m-%dT%H:%M:%SZ")
