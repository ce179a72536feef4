"""Modal tables as other tools write them, turned into the tracked modal table (MODAL).

Layouts recognised (column names are matched ignoring case, spaces and underscores, with
the unit in brackets or parentheses):

``contract``
    The MODAL contract itself (``block, block_start, block_end, mode, frequency_hz,
    damping_ratio``).
``long``
    One row per time (or block) and mode: ``time, mode, frequency, damping`` (also
    ``Frequency [Hz]``, ``Damping [%]``, ``zeta``, ``f``, ...), as ARTeMIS, pyOMA2 or MATLAB
    scripts export them.
``wide``
    One row per time (or block): ``f1, f2, ...`` and ``d1, d2, ...`` (also
    ``Mode 1 Frequency [Hz]``, ``zeta_1``).

Times become blocks of the voyage's block grid: the time marks the start, centre or end of
the analysis window (``time_reference``, taken from the column name when it says so:
``window_start``, ``centre_time``, ``t_end``), the window start is snapped to the grid
(``t0 + k * step``) and ``block_end`` is the start plus the block length. A table indexed
by ``block`` alone needs the grid's ``t0``.

A table without damping (frequencies only) keeps ``damping_ratio`` empty, with a warning.
Nothing is guessed silently: a damping column without a unit needs ``damping_unit``;
naive times are taken as UTC with a warning unless ``time_zone`` is given; a time reference
not stated anywhere is taken as the window start with a warning; rows without a frequency
are dropped with a warning that counts them.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from ._core import ContractError, Violation
from .csv_layout import read_delimited, split_unit
from .dship_names import (
    bad_time_values,
    cut_iso_time,
    name_key,
    parse_times,
    strptime_format,
    time_format_hint,
)
from .formats import describe
from .grid import GRID_ATTR, attach_grid, read_grid, set_grid
from .parts import is_parted, read_parts
from .tables import MODAL

__all__ = ["ModalLayout", "read_modal_table", "standardise_modal"]

_TIME_NAMES = {
    "start": ("blockstart", "windowstart", "starttime", "tstart", "start", "timestart"),
    "centre": (
        "windowcentre",
        "windowcenter",
        "centretime",
        "centertime",
        "timecentre",
        "timecenter",
        "tcentre",
        "tcenter",
        "tmid",
        "midtime",
        "centre",
        "center",
    ),
    "end": ("blockend", "windowend", "endtime", "tend", "end", "timeend"),
    None: ("time", "timestamp", "datetime", "date/time", "datetimeutc", "timeutc", "date"),
}
#: Longest block length and step of a grid: an analysis window of a week. [s]
MAX_BLOCK_S = 7 * 86400.0

_BLOCK_NAMES = ("block", "blockindex", "blockno", "blocknumber", "blocknr")
_MODE_NAMES = ("mode", "modeid", "modeno", "modenumber", "modenr", "modelabel")
_FREQUENCY_NAMES = (
    "frequencyhz",
    "frequency",
    "freq",
    "f",
    "fn",
    "naturalfrequency",
    "eigenfrequency",
)
_DAMPING_NAMES = ("dampingratio", "damping", "zeta", "xi", "dampingratiopct", "dampingpct")
_WIDE_FREQUENCY = re.compile(
    r"^(?:frequencyhz|frequency|freq|fn|f)(\d+)$|^mode(\d+)(?:frequency|freq|f)$"
)
_WIDE_DAMPING = re.compile(
    r"^(?:dampingratio|damping|zeta|xi|d)(\d+)$|^mode(\d+)(?:dampingratio|damping|zeta|xi|d)$"
)
_PERCENT_UNITS = {"%", "pct", "percent"}
_FRACTION_UNITS = {"-", "1", "", "fraction", "ratio"}
_FREQUENCY_UNITS = {"hz": 1.0, "1/s": 1.0, "rad/s": 1.0 / (2 * math.pi), "cpm": 1.0 / 60}


@dataclass(frozen=True)
class ModalLayout:
    """How a modal table from another tool is to be read.

    Attributes
    ----------
    layout : {"auto", "contract", "long", "wide"}
        Table layout; ``auto`` recognises it from the columns.
    damping_unit : {"fraction", "percent"}, optional
        Unit of the damping values when no column header states it (``Damping [%]``,
        ``damping_pct`` and ``damping_ratio`` state it).
    time_reference : {"start", "centre", "end"}, optional
        What the time of a row marks in its analysis window; default: from the column
        name, else ``start`` (with a warning).
    time_zone : str, optional
        Zone of times written without one (``"UTC"``, ``"Europe/Berlin"``); default UTC
        with a warning.
    time_format : str, optional
        Format of the times: ``strptime`` (``%d/%m/%Y %H:%M:%S``) or MATLAB ``datestr``
        symbols (``dd/mm/yyyy HH:MM:SS``); default: ISO-8601, ``yyyy/mm/dd``,
        ``dd.mm.yyyy``, ``dd-mmm-yyyy`` and slash dates whose values tell day and month
        apart.
    block_length_s, block_step_s : float
        The block grid, each at most :data:`MAX_BLOCK_S` (a week). [s]
    grid_t0 : str, optional
        Start of block 0 (ISO-8601); default: the first window start floored to a multiple
        of the step since the Unix epoch (as ``workbench identify`` does).
    """

    layout: Literal["auto", "contract", "long", "wide"] = "auto"
    damping_unit: Literal["fraction", "percent"] | None = None
    time_reference: Literal["start", "centre", "end"] | None = None
    time_zone: str | None = None
    time_format: str | None = None
    block_length_s: float = 1200.0
    block_step_s: float = 300.0
    grid_t0: str | None = None

    def __post_init__(self) -> None:
        choices = {
            "layout": ("auto", "contract", "long", "wide"),
            "damping_unit": (None, "fraction", "percent"),
            "time_reference": (None, "start", "centre", "end"),
        }
        for name, allowed in choices.items():
            value = getattr(self, name)
            if value not in allowed:
                raise ValueError(f"{name}={value!r} must be one of {allowed}")
        for name in ("block_length_s", "block_step_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name}={value!r} must be a positive number of seconds")
            if value > MAX_BLOCK_S:
                raise ValueError(
                    f"{name}={value:g} must be at most {MAX_BLOCK_S:g} s (a week): an "
                    "analysis window, not a voyage"
                )
        if self.time_format is not None:
            strptime_format(self.time_format)  # ValueError naming time_format
        if self.block_step_s > self.block_length_s:
            raise ValueError(
                f"block_step_s={self.block_step_s:g} must not exceed "
                f"block_length_s={self.block_length_s:g}"
            )


def _find(columns: dict[str, str], names) -> str | None:
    return next((columns[n] for n in names if n in columns), None)


def read_modal_table(
    path: str | os.PathLike, layout: ModalLayout | None = None, **options
) -> pd.DataFrame:
    """Read a modal table in any recognised layout as a MODAL table.

    Parameters
    ----------
    path : path-like
        CSV/TSV/text (separator and decimal mark sniffed) or Parquet.
    layout : ModalLayout, optional
        Or its fields as keyword arguments.

    Raises
    ------
    ContractError
        Unreadable file, unrecognised layout (the message lists the columns found), a
        damping unit not stated, times off the block grid; every line names the file.
    """
    layout = layout or ModalLayout(**options)
    path = Path(path)
    parted = is_parted(path)  # a table written a part at a time (the monitor's)
    if not (parted or path.is_file()):
        raise ContractError([Violation(None, "file not found")], source=path, contract="modal")
    try:
        if parted:
            frame = read_parts(path, None)  # ContractError naming an unreadable part
        elif path.suffix.lower() in (".parquet", ".pq"):
            frame = pd.read_parquet(path)
        else:
            frame, _, _ = read_delimited(path)
    except ContractError:
        raise
    except Exception as error:  # pandas/pyarrow raise many types for unreadable files
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ContractError(
            [Violation(None, f"cannot read file: {message}")], source=path, contract="modal"
        ) from None
    grid = frame.attrs.pop(GRID_ATTR, None)  # a parted table's, from its newest part
    table = standardise_modal(frame, layout, source=str(path))
    if not parted:
        grid = read_grid(path, "parquet" if path.suffix.lower() in (".parquet", ".pq") else "csv")
    return attach_grid(table, grid, path)


def standardise_modal(
    frame: pd.DataFrame, layout: ModalLayout | None = None, *, source: str | None = None
) -> pd.DataFrame:
    """:func:`read_modal_table` on a DataFrame already in memory."""
    layout = layout or ModalLayout()
    head = source or "<modal>"

    def fail(reason: str, column: str | None = None, rows=(), n_rows=0) -> ContractError:
        return ContractError(
            [Violation(column, reason, tuple(rows), n_rows)], source=source, contract="modal"
        )

    def fail_at(reason: str, column: str, mask: np.ndarray) -> ContractError:
        """:func:`fail` naming the first five of the file's rows *mask* marks in ``long``."""
        rows = _file_rows(long, mask)
        return fail(reason, column, [f"row {r}" for r in rows[:5]], len(rows))

    found = describe([str(c) for c in frame.columns], "columns", limit=len(frame.columns))
    keys: dict[str, str] = {}
    units: dict[str, str | None] = {}
    for column in frame.columns:
        name, unit = split_unit(str(column))
        keys.setdefault(name_key(name), column)
        units[column] = unit
    # the contract's own block columns: the contract names whatever else is wrong
    is_contract = {"block", "blockstart", "blockend"} <= set(keys) and all(
        units[keys[k]] is None for k in ("frequencyhz", "dampingratio") if k in keys
    )
    kind = layout.layout
    found_f = {c: _wide_index(_WIDE_FREQUENCY, c) for c in frame.columns}
    wide_f: dict[str, int] = {c: n for c, n in found_f.items() if n is not None}
    if kind == "auto":
        if is_contract:
            kind = "contract"
        elif _find(keys, _FREQUENCY_NAMES) and _find(keys, _MODE_NAMES):
            kind = "long"
        elif wide_f:
            kind = "wide"
        else:
            raise fail(
                "not a modal table in a known layout: looked for mode and frequency columns "
                "(long: time, mode, frequency, damping), f1, f2, ... (wide) or the MODAL "
                f"columns; {found}"
            )
    if kind == "contract":
        table = frame.copy()
        return _finish(table, head, source)

    time_column = None
    reference: str | None = layout.time_reference
    named_reference = None
    for ref, names in _TIME_NAMES.items():
        column = _find(keys, names)
        if column is not None:
            time_column, named_reference = column, ref
            break
    if reference is None:
        reference = named_reference
    block_column = _find(keys, _BLOCK_NAMES)
    if time_column is None and block_column is None:
        raise fail(f"no time or block column (looked for time, window_start, block, ...; {found})")

    if kind == "long":
        mode_column = _find(keys, _MODE_NAMES)
        frequency_column = _find(keys, _FREQUENCY_NAMES)
        if mode_column is None or frequency_column is None:
            raise fail(f"long layout needs mode and frequency columns; {found}")
        damping_column = _find(keys, _DAMPING_NAMES)
        if damping_column is None:
            _no_damping(head, "damping, damping_ratio, zeta, xi")
        long = pd.DataFrame(
            {
                "_row": np.arange(len(frame)),
                "mode": frame[mode_column],
                "frequency_hz": _frequency(frame[frequency_column], units[frequency_column], fail),
                "damping_ratio": np.nan
                if damping_column is None
                else _damping(frame[damping_column], damping_column, units, layout, fail),
            }
        )
        index_columns = [c for c in (time_column, block_column) if c is not None]
        for column in index_columns:
            long[column] = frame[column].to_numpy()
        for extra in ("mac", "model_order"):
            if extra in frame.columns:
                long[extra] = frame[extra].to_numpy()
        for column in frame.columns:
            if str(column).startswith(("shape_re_", "shape_im_")):
                long[column] = frame[column].to_numpy()
        long["mode"] = _mode_labels(long["mode"], mode_column, fail)
    else:  # wide
        numbers = {c: _wide_index(_WIDE_DAMPING, c) for c in frame.columns}
        wide_d = {n: c for c, n in numbers.items() if n is not None}
        if not wide_d:
            _no_damping(head, "d1, d2, ... or zeta1, ...")
        parts = []
        for column, number in sorted(wide_f.items(), key=lambda item: item[1]):
            damping_column = wide_d.get(number)
            if damping_column is None and wide_d:
                raise fail(f"no damping column for mode {number} (frequency column {column})")
            part = pd.DataFrame(
                {
                    "_row": np.arange(len(frame)),
                    "mode": number,
                    "frequency_hz": _frequency(frame[column], units[column], fail),
                    "damping_ratio": np.nan
                    if damping_column is None
                    else _damping(frame[damping_column], damping_column, units, layout, fail),
                }
            )
            for index_column in (time_column, block_column):
                if index_column is not None:
                    part[index_column] = frame[index_column].to_numpy()
            parts.append(part)
        long = pd.concat(parts, ignore_index=True)

    missing = long["frequency_hz"].isna().to_numpy()
    if frame.empty:
        raise fail("the table has a header but no rows")
    if missing.all():  # nothing to place on the block grid
        raise fail(f"no row has a frequency ({len(frame)} rows)")
    if missing.any():
        rows = _file_rows(long, missing)
        warnings.warn(
            f"{head}: dropped {int(missing.sum())} mode estimate(s) without a frequency "
            f"(in {len(rows)} row(s), first: row {rows[0]})",
            stacklevel=3,
        )
        long = long.loc[~missing].reset_index(drop=True)

    length = pd.Timedelta(seconds=layout.block_length_s)
    step_ns = int(round(layout.block_step_s * 1e9))
    if time_column is not None:
        if reference is None:
            warnings.warn(
                f"{head}: column '{time_column}' is taken as the start of each analysis window; "
                "state the time reference (start, centre or end) if it is not",
                stacklevel=3,
            )
            reference = "start"
        times = _times(
            long[time_column], time_column, layout.time_zone, head, fail, layout.time_format
        )
        offset = {"start": pd.Timedelta(0), "centre": length / 2, "end": length}[reference]
        starts = times - offset
        if layout.grid_t0 is not None:
            t0 = _utc(layout.grid_t0, "grid_t0")
        else:
            first = int(starts.min().value)
            t0 = pd.Timestamp(first - first % step_ns, tz="UTC")
        position = (starts - t0).dt.total_seconds().to_numpy() / layout.block_step_s
        block = np.rint(position).astype(np.int64)
        off_s = np.abs(position - block) * layout.block_step_s
        tolerance_s = min(1.0, layout.block_step_s / 100.0)
        off = off_s > tolerance_s
        if off.any() or (block < 0).any():
            raise fail_at(
                f"{time_column} ({reference} of a {layout.block_length_s / 60:g}-min window) "
                f"is not on the block grid (t0 {t0.isoformat()}, a block every "
                f"{layout.block_step_s / 60:g} min; up to {off_s.max():.3g} s off): give the "
                "block length, step and t0 of the tool's analysis windows",
                time_column,
                off | (block < 0),
            )
        if block_column is not None:
            given = pd.to_numeric(long[block_column], errors="coerce").to_numpy()
            if not np.array_equal(given - given.min(), block - block.min()):
                raise fail(
                    f"block numbers disagree with the times on the block grid (a block every "
                    f"{layout.block_step_s / 60:g} min)",
                    block_column,
                )
    else:
        if layout.grid_t0 is None:
            raise fail(
                f"the table has block numbers ('{block_column}') but no times: give the "
                "grid's t0 (the start of block 0)"
            )
        t0 = _utc(layout.grid_t0, "grid_t0")
        block = pd.to_numeric(long[block_column], errors="coerce").to_numpy()
        if np.isnan(block).any() or (block < 0).any() or (block != np.round(block)).any():
            raise fail("block numbers must be whole numbers >= 0", block_column)
        # block k starts at t0 + k * step: past the last representable time the product
        # of nanoseconds would wrap round silently to a time centuries earlier
        last_s = (pd.Timestamp.max.tz_localize("UTC") - t0).total_seconds() - layout.block_length_s
        beyond = block * layout.block_step_s > last_s
        if beyond.any():
            raise fail_at(
                f"block {int(block[beyond].max())} would start after "
                f"{pd.Timestamp.max.year} on a grid of a block every "
                f"{layout.block_step_s / 60:g} min from {t0.isoformat()}: block numbers "
                "beyond any time",
                block_column,
                beyond,
            )
        block = block.astype(np.int64)
    block_start = t0 + pd.to_timedelta(block * step_ns, unit="ns")
    table = long.drop(columns=[c for c in (time_column, block_column) if c is not None])
    table.insert(0, "block", block)
    table.insert(1, "block_start", pd.DatetimeIndex(block_start))
    table.insert(2, "block_end", pd.DatetimeIndex(block_start) + length)
    table = table.drop(columns="_row")
    table = table.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)
    grid = {"t0": t0, "length_s": layout.block_length_s, "step_s": layout.block_step_s}
    return set_grid(_finish(table, head, source), grid)


def _finish(table: pd.DataFrame, head: str, source: str | None) -> pd.DataFrame:
    if "frequency_hz" in table.columns:
        missing = table["frequency_hz"].isna().to_numpy()
        if len(table) and missing.all():
            raise ContractError(
                [Violation("frequency_hz", f"no row has a frequency ({len(table)} rows)")],
                source=source,
                contract="modal",
            )
        if missing.any():
            rows = table.index[missing][:5].tolist()
            warnings.warn(
                f"{head}: dropped {int(missing.sum())} row(s) without a frequency "
                f"(first: row {rows[0]})",
                stacklevel=3,
            )
            table = table.loc[~missing].reset_index(drop=True)
    return MODAL.validate(table, source=source)


def _no_damping(head: str, looked_for: str) -> None:
    warnings.warn(
        f"{head}: no damping column (looked for {looked_for}); a frequency-only table: "
        "damping_ratio is left empty (NaN)",
        stacklevel=4,
    )


def _wide_index(pattern: re.Pattern, column) -> int | None:
    match = pattern.match(name_key(split_unit(str(column))[0]))
    if not match:
        return None
    return int(next(g for g in match.groups() if g is not None))


def _frequency(values: pd.Series, unit: str | None, fail) -> np.ndarray:
    """The column's frequencies in Hz; a value at or below 0 is refused naming this
    column and its rows (the MODAL contract's rule, said before the table is reshaped:
    a wide table's ``f2`` row 4, not the long table's row 13)."""
    numbers = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
    rule = next(c for c in MODAL.columns if c.name == "frequency_hz")
    with np.errstate(invalid="ignore"):
        low = np.isfinite(numbers) & (numbers <= rule.minimum)
    if low.any():
        rows = values.index[low]
        raise fail(
            f"values at or below {rule.minimum:g} ({rule.hint})",
            str(values.name),
            rows[:5].tolist(),
            len(rows),
        )
    if unit is None:
        return numbers
    key = unit.strip().lower().replace(" ", "")
    if key not in _FREQUENCY_UNITS:
        raise fail(f"frequency unit '{unit}' is not one of Hz, rad/s, cpm", str(values.name))
    return numbers * _FREQUENCY_UNITS[key]


def _damping(values: pd.Series, column, units, layout: ModalLayout, fail) -> np.ndarray:
    numbers = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
    unit = units.get(column)
    name = name_key(split_unit(str(column))[0])
    stated = None
    if unit is not None:
        key = unit.strip().lower()
        if key in _PERCENT_UNITS:
            stated = "percent"
        elif key in _FRACTION_UNITS:
            stated = "fraction"
        else:
            raise fail(f"damping unit '{unit}' is neither % nor a fraction", str(column))
    elif name.endswith(("pct", "percent")):
        stated = "percent"
    elif name == "dampingratio" and str(column) == "damping_ratio":
        stated = "fraction"  # the contract's own column: fractions by definition
    if stated is not None and layout.damping_unit is not None and stated != layout.damping_unit:
        raise fail(
            f"the header says the damping is in {stated} but {layout.damping_unit} was stated",
            str(column),
        )
    unit_used = stated or layout.damping_unit
    if unit_used is None:
        finite = numbers[np.isfinite(numbers)]
        seen = f"values {finite.min():.3g} to {finite.max():.3g}" if finite.size else "no values"
        raise fail(
            f"damping unit not stated ({seen}): give it as percent or fraction, or write it "
            "in the header (Damping [%])",
            str(column),
        )
    return numbers / 100.0 if unit_used == "percent" else numbers


def _mode_labels(values: pd.Series, column, fail) -> np.ndarray:
    numbers = pd.to_numeric(values, errors="coerce")
    if numbers.notna().all() and (numbers == numbers.round()).all():
        return numbers.to_numpy(dtype=np.int64)
    digits = values.astype(str).str.extract(r"(\d+)")[0]
    if digits.notna().all():
        return digits.astype(np.int64).to_numpy()
    raise fail(
        "mode labels must be numbers or contain one (1, 'Mode 2', 'M3'); got "
        f"{', '.join(map(repr, values[digits.isna()].unique()[:3]))}",
        str(column),
    )


def _file_rows(long: pd.DataFrame, mask: np.ndarray) -> list[int]:
    """The rows of the file (``_row``: one file row can hold several modes) *mask* marks."""
    return sorted(set(long.loc[mask, "_row"].tolist()))


def _utc(value, name: str) -> pd.Timestamp:
    if cut_iso_time(value):
        raise ValueError(f"{name}={value!r} is not a complete ISO-8601 time")
    try:
        stamp = pd.Timestamp(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is not a time") from None
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def _times(
    values: pd.Series, column, time_zone, head: str, fail, time_format: str | None = None
) -> pd.Series:
    text = values.astype(str).str.strip()
    zoned = text.str.contains(r"(?:Z|[+-]\d\d:?\d\d)$", regex=True)
    if zoned.any() and not zoned.all():
        unzoned, _ = parse_times(text[~zoned], time_format, utc=False)
        if unzoned.notna().any():
            raise fail("some times carry a time zone and some do not", str(column))
        # the cells without a zone are no times at all: named as such below
        zoned = pd.Series(True, index=text.index)
    used = time_format
    if zoned.all():
        times, used = parse_times(text, time_format, utc=True)
    else:
        times, used = parse_times(text, time_format, utc=False)
        if times.notna().any():
            if times.dt.tz is not None:  # a format with %z
                times = times.dt.tz_convert("UTC")
            elif time_zone is None:
                warnings.warn(
                    f"{head}: times in '{column}' have no time zone; taken as UTC "
                    "(state the zone if they are local times)",
                    stacklevel=4,
                )
                times = times.dt.tz_localize("UTC")
            else:
                try:
                    times = times.dt.tz_localize(time_zone).dt.tz_convert("UTC")
                except Exception as error:  # unknown zone, non-existent local times
                    raise fail(
                        f"cannot place times in zone {time_zone!r}: {error}", str(column)
                    ) from None
    bad = times.isna().to_numpy()
    if bad.any():
        # a wide table repeats each time once per mode: every distinct value is shown once
        if time_format is not None:
            what = f"not a time in the format {time_format}"
        else:
            what = "not a time (ISO-8601, yyyy/mm/dd HH:MM:SS, dd.mm.yyyy HH:MM:SS, dd-mmm-yyyy)"
        raise fail(f"{what}: {bad_time_values(text, bad)}; {time_format_hint(used)}", str(column))
    return times
