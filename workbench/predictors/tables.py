"""The block predictor table a stage works on: read, or averaged from a DSHIP log.

:func:`load_predictors` gives the PREDICTORS table from either source;
:func:`canonical_predictors` keeps the block columns and the canonical predictors.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np
import pandas as pd

from data_contracts import (
    CANONICAL_PREDICTORS,
    PREDICTOR_KEYS,
    PREDICTORS,
    ContractError,
    Violation,
    read_dship,
    read_table,
    set_grid,
)
from data_contracts.dship_names import complete_times

from ..blocks import BlockGrid, block_grid_of

__all__ = [
    "canonical_predictors",
    "load_predictors",
    "read_excitation",
    "ship_log_without_predictors",
]


def ship_log_without_predictors(log: pd.DataFrame, *, all_predictors: bool = False) -> str:
    """What is wrong with a canonical ship log (:func:`~data_contracts.read_dship`) whose
    predictor columns hold no reading in any row (``""`` when one does): no block can have
    a predictor value, whatever its span. With *all_predictors* every numeric column
    counts."""
    columns = [c.name for c in CANONICAL_PREDICTORS if c.name in log.columns]
    if all_predictors:
        columns += [
            c
            for c in log.columns
            if c != "time" and c not in columns and pd.api.types.is_numeric_dtype(log[c])
        ]
    if not columns or log[columns].notna().to_numpy().any():
        return ""
    return (
        f"no reading of any predictor in its {len(log)} rows ({', '.join(columns)} empty "
        "throughout)"
    )


def load_predictors(
    *,
    predictors: str | os.PathLike | None = None,
    dship: str | os.PathLike | None = None,
    onto: pd.DataFrame | None = None,
    min_coverage: float = 0.5,
    dship_mapping: Mapping[str, str] | None = None,
    dship_utc_offset: str | None = None,
    time_format: str | None = None,
    all_predictors: bool = False,
    excitation: str | os.PathLike | pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Block predictors from a predictor table, or averaged from a DSHIP log.

    The canonical predictors only (speed, water and air temperature, wind speed, relative
    wind direction: :func:`canonical_predictors`), as ``workbench correlate/fit/forecast``
    use them; every numeric column (position, depth, heading, ...) with *all_predictors*
    (``--all-predictors``).

    Parameters
    ----------
    predictors : path, optional
        A block predictor table (PREDICTORS contract).
    dship : path, optional
        A raw DSHIP log; averaged onto the block grid of *onto*.
    onto : DataFrame, optional
        A table with block, block_start, block_end (e.g. the tracked modal table) whose block
        grid the DSHIP log is averaged onto; its full block range is used.
    min_coverage : float
        Share of a block the log must cover for the block's average (see
        :func:`~workbench.predictors.block_predictors`).
    dship_mapping : mapping, optional
        Column mapping for :func:`~data_contracts.read_dship` (``speed_kn`` -> source name).
    dship_utc_offset : str, optional
        UTC offset of the log's times written without one (``"+02:00"``; the
        ``utc_offset`` of :func:`~data_contracts.read_dship`); default: UTC.
    time_format : str, optional
        Format of the log's times (``strptime`` or MATLAB ``datestr`` symbols); default:
        recognised (:func:`data_contracts.dship_names.parse_times`).
    all_predictors : bool
        Keep every numeric column, not only the canonical predictors.
    excitation : path or DataFrame, optional
        The excitation of the voyage (``start``, ``end``, ``power``; the ``excitation.csv``
        of ``identify --block-minutes auto``): the log is averaged over each block with
        the excitation's weights, as SSI reads the block
        (:func:`~workbench.predictors.averaging.excitation_weighted_predictors`).

    Notes
    -----
    Blocks of varying length (a table whose recorded grid has ``varying_length``) are
    averaged over their own spans; blocks of the range missing from *onto* over the
    grid's nominal span (same centre).
    """
    if (predictors is None) == (dship is None):
        raise ValueError("give exactly one of predictors and dship")
    if predictors is not None:
        table = read_table(predictors, PREDICTORS)
        return table if all_predictors else canonical_predictors(table)
    if onto is None:
        raise ValueError("averaging a DSHIP log needs the blocks of a modal table (onto=)")
    from data_contracts import recorded_grid

    from .averaging import block_predictors, excitation_weighted_predictors

    log = read_dship(
        dship, mapping=dship_mapping, time_format=time_format, utc_offset=dship_utc_offset
    )
    no_reading = ship_log_without_predictors(log, all_predictors=all_predictors)
    if no_reading:  # no block can have a predictor value: said before any averaging
        raise ContractError([Violation(None, no_reading)], source=str(dship), contract="dship")
    t0, length_s, step_s = block_grid_of(onto)
    first, last = int(onto["block"].min()), int(onto["block"].max())
    grid = BlockGrid(t0=t0, length_s=length_s, step_s=step_s)
    recorded = recorded_grid(onto)
    spans = grid.frame(np.arange(first, last + 1))
    if recorded is not None and recorded.get("varying_length"):
        own = onto[["block", "block_start", "block_end"]].drop_duplicates("block")
        own = own.set_index("block")
        present = spans["block"].isin(own.index).to_numpy()
        for column in ("block_start", "block_end"):
            values = pd.to_datetime(own[column], utc=True).reindex(spans["block"][present])
            spans.loc[present, column] = values.to_numpy()
    if excitation is not None:
        weights = read_excitation(excitation)
        table = excitation_weighted_predictors(log, spans, weights, min_coverage=min_coverage)
    else:
        table = block_predictors(log, blocks=spans, min_coverage=min_coverage)
    table = set_grid(
        PREDICTORS.validate(table),
        recorded if recorded is not None and recorded.get("varying_length") else grid,
    )
    return table if all_predictors else canonical_predictors(table)


def read_excitation(excitation: str | os.PathLike | pd.DataFrame) -> pd.DataFrame:
    """The excitation table (``start``, ``end``, ``power``; the ``excitation.csv`` of
    ``identify --block-minutes auto``) with its times as UTC, in the file's order.

    Raises
    ------
    ContractError
        A file that cannot be read, lacks a column, or holds a start or end that is no
        time; the message names the file, the column and the rows.
    """
    from data_contracts.csv_layout import read_delimited

    source = "<excitation>" if isinstance(excitation, pd.DataFrame) else str(excitation)

    def fail(column, reason, rows=(), n_rows=0) -> ContractError:
        return ContractError(
            [Violation(column, reason, tuple(rows), n_rows)], source=source, contract="excitation"
        )

    if isinstance(excitation, pd.DataFrame):
        table = excitation.copy()
    else:
        try:
            table, _, _ = read_delimited(excitation)
        except FileNotFoundError:
            raise fail(None, "file not found") from None
        except Exception as error:  # pandas raises many types for what is no table
            reason = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise fail(None, f"cannot read file: {reason}") from None
    missing = [c for c in ("start", "end", "power") if c not in table.columns]
    if missing:
        raise fail(None, f"excitation table lacks column(s) {', '.join(missing)}")
    for column in ("start", "end"):
        times = pd.to_datetime(table[column], utc=True, errors="coerce", format="ISO8601")
        bad = times.isna().to_numpy() | ~complete_times(table[column], "ISO8601")
        if bad.any():
            values = ", ".join(repr(str(v)) for v in table.loc[bad, column].unique()[:3])
            rows = [f"row {r}" for r in np.flatnonzero(bad)[:5]]
            raise fail(column, f"not an ISO-8601 time: {values}", rows, int(bad.sum()))
        table[column] = times
    table["power"] = pd.to_numeric(table["power"], errors="coerce")
    return table


def canonical_predictors(predictors: pd.DataFrame) -> pd.DataFrame:
    """The block columns (with the log's coverage of each block) and the canonical
    predictors (speed, temperatures, wind) only.

    A ship log carries more numeric columns (position, heading, depth...). They are kept in
    the predictor table, but latitude and longitude, for instance, stand in for elapsed time
    in a regression, so models and correlations use the canonical predictors unless asked.
    """
    columns = [*PREDICTOR_KEYS, *(c.name for c in CANONICAL_PREDICTORS)]
    return predictors[[c for c in columns if c in predictors.columns]]
