"""Ship data-system (DSHIP) logs: parsing the raw export into the canonical log table.

The raw file is delimited text as exported by the ship's data system or by PANGAEA:

* an optional ``/* ... */`` description block,
* one header line whose names carry units in brackets (``Speed [kn]``, ``TTT [°C]``),
  or three header rows (name, sensor, unit) as in raw DSHIP extractions,
* a time column (``Date/Time``; ISO-8601, UTC unless an offset is given),
* tab (PANGAEA) or ``;`` (DSHIP) separators, empty cells for missing values,
* UTF-8 or latin-1 text.

:func:`read_dship` maps source columns to the canonical columns of :data:`DSHIP_LOG`
through a configurable mapping, converts units, and keeps every other numeric column
under a snake_case name with its unit (``dd [deg]`` becomes ``dd_deg``).
"""

from __future__ import annotations

import io
import os
import re
import unicodedata
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ._core import Column, ContractError, TableContract, Violation
from .tables import CANONICAL_PREDICTORS

__all__ = ["DEFAULT_DSHIP_MAPPING", "DSHIP_LOG", "read_dship"]

#: Source names (case-insensitive, without the bracketed unit) tried for each canonical
#: column, in order. Pass your own mapping to :func:`read_dship` for other ships.
DEFAULT_DSHIP_MAPPING: dict[str, tuple[str, ...]] = {
    "speed_kn": ("Speed", "SOG", "Speed over ground", "Speed through water", "STW", "Ship speed"),
    "water_temp_c": ("Temp", "Water temp", "Water temperature", "SST", "Tw", "Temp water"),
    "air_temp_c": ("TTT", "Air temp", "Air temperature", "Ta"),
    "wind_speed_ms": ("ff", "Wind speed", "Wind speed true", "FF"),
    "wind_dir_rel_deg": (
        "RelWindDir",
        "Rel wind dir",
        "Relative wind direction",
        "dd rel",
        "Wind direction relative",
    ),
}

TIME_COLUMN_NAMES = ("Date/Time", "DATE/TIME", "Date Time", "Datetime", "time", "Time")

_KNOT_PER_MS = 3600.0 / 1852.0


def _unit_key(unit: str) -> str:
    text = unicodedata.normalize("NFKC", unit).strip().lower().replace(" ", "")
    return text.replace("deg.c", "°c").replace("degc", "°c").replace("deg", "°")


#: Unit conversions into each canonical unit: source unit (normalised) -> function.
_CONVERSIONS: dict[str, dict[str, object]] = {
    "speed_kn": {
        "kn": None,
        "kt": None,
        "kts": None,
        "knots": None,
        "knot": None,
        "m/s": lambda v: v * _KNOT_PER_MS,
        "ms-1": lambda v: v * _KNOT_PER_MS,
        "km/h": lambda v: v / 1.852,
    },
    "water_temp_c": {"°c": None, "c": None, "k": lambda v: v - 273.15},
    "air_temp_c": {"°c": None, "c": None, "k": lambda v: v - 273.15},
    "wind_speed_ms": {
        "m/s": None,
        "ms-1": None,
        "kn": lambda v: v / _KNOT_PER_MS,
        "kt": lambda v: v / _KNOT_PER_MS,
        "kts": lambda v: v / _KNOT_PER_MS,
        "km/h": lambda v: v / 3.6,
    },
    "wind_dir_rel_deg": {"°": None, "degrees": None},
}

DSHIP_LOG = TableContract(
    name="dship",
    description="Canonical ship log after parsing: one row per time stamp, UTC, sorted.",
    columns=(
        Column("time", "time", "Time of the record, UTC.", unit="UTC"),
        *CANONICAL_PREDICTORS,
    ),
    unique=("time",),
)

_NAME_UNIT = re.compile(r"^\s*(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]\s*$")


def _split_name(header: str) -> tuple[str, str | None]:
    match = _NAME_UNIT.match(header)
    if match:
        return match["name"], match["unit"]
    return header.strip(), None


def _snake(name: str, unit: str | None) -> str:
    text = unicodedata.normalize("NFKD", name).encode("ascii", "ignore").decode()
    base = re.sub(r"[^0-9a-zA-Z]+", "_", text).strip("_").lower() or "column"
    if unit:
        unit_text = _unit_key(unit).replace("°c", "c").replace("°", "deg").replace("/", "")
        unit_text = re.sub(r"[^0-9a-z]+", "", unit_text)
        if unit_text and not base.endswith(unit_text):
            base = f"{base}_{unit_text}"
    return base


def _decode(raw: bytes, encoding: str | None) -> str:
    if encoding:
        return raw.decode(encoding)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _looks_like_time(text: str) -> bool:
    return not pd.isna(pd.to_datetime(text.strip(), errors="coerce", format="ISO8601", utc=True))


def read_dship(
    path: str | os.PathLike,
    *,
    mapping: Mapping[str, str | Sequence[str]] | None = None,
    time_column: str | None = None,
    encoding: str | None = None,
    separator: str | None = None,
) -> pd.DataFrame:
    """Parse a raw DSHIP / PANGAEA ship log into the canonical log table.

    Parameters
    ----------
    path : path-like
        The exported text file.
    mapping : mapping, optional
        Canonical column -> source name or names (case-insensitive, with or without the
        bracketed unit). Entries replace those of :data:`DEFAULT_DSHIP_MAPPING`.
    time_column : str, optional
        Name of the time column; default: the first of :data:`TIME_COLUMN_NAMES` present.
    encoding : str, optional
        Text encoding; default UTF-8, falling back to latin-1.
    separator : str, optional
        Field separator; default: tab or ``;``, whichever the header line uses.

    Returns
    -------
    DataFrame
        ``time`` (UTC) and the canonical predictor columns in canonical units, then the
        other numeric columns, sorted by time. Canonical columns absent from the file are
        NaN (with a warning). Exact duplicate time stamps keep their first row (warning).

    Raises
    ------
    ContractError
        Unreadable file, no header or time column, unparseable times or numbers, a unit
        that cannot be converted, or values outside physical bounds. Each message names the
        file, the column and the line numbers.
    """
    path = Path(path)
    source = str(path)

    def fail(problems: list[Violation]) -> ContractError:
        return ContractError(problems, source=source, contract="dship")

    try:
        raw = path.read_bytes()
    except OSError as error:
        raise fail([Violation(None, f"cannot read file: {error.strerror or error}")]) from None
    text = _decode(raw, encoding)
    lines = text.splitlines()
    first_data_line = 0
    stripped = [line.strip() for line in lines]
    if stripped and stripped[0].startswith("/*"):
        for number, line in enumerate(stripped):
            if line.endswith("*/"):
                first_data_line = number + 1
                break
        else:
            raise fail([Violation(None, "the '/*' description block is never closed by '*/'")])
    # (file line number, text) of the non-empty lines after the description block
    body = [
        (n + 1, line)
        for n, line in enumerate(lines[first_data_line:], first_data_line)
        if line.strip()
    ]
    if not body:
        raise fail([Violation(None, "no header line and no data")])
    header_text = body[0][1]
    sep = separator or max(("\t", ";", ","), key=header_text.count)
    if header_text.count(sep) == 0:
        raise fail(
            [
                Violation(
                    None,
                    f"line {body[0][0]}: header has a single column; expected "
                    "tab- or ';'-separated names",
                )
            ]
        )
    headers = [h.strip() for h in header_text.split(sep)]
    rows = body[1:]
    units: list[str | None] = [_split_name(h)[1] for h in headers]
    names = [_split_name(h)[0] for h in headers]

    if time_column is None:
        lowered = {n.lower(): i for i, n in enumerate(names)}
        time_index = next(
            (lowered[t.lower()] for t in TIME_COLUMN_NAMES if t.lower() in lowered), None
        )
        if time_index is None:
            raise fail(
                [
                    Violation(
                        "Date/Time",
                        f"time column is missing (looked for {', '.join(TIME_COLUMN_NAMES)})",
                    )
                ]
            )
    else:
        if time_column not in names and time_column not in headers:
            raise fail([Violation(time_column, "time column is missing")])
        time_index = (
            names.index(time_column) if time_column in names else headers.index(time_column)
        )

    # Raw DSHIP extractions: name row, sensor row, unit row before the data.
    def time_field(line: str) -> str:
        fields = line.split(sep)
        return fields[time_index] if time_index < len(fields) else ""

    if len(rows) >= 2 and not any(_looks_like_time(time_field(line)) for _, line in rows[:2]):
        unit_fields = [u.strip() for u in rows[1][1].split(sep)]
        for j in range(min(len(names), len(unit_fields))):
            if unit_fields[j]:
                bracketed = _split_name(unit_fields[j])[1]
                units[j] = bracketed if bracketed is not None else unit_fields[j]
        rows = rows[2:]
    line_numbers = np.array([n for n, _ in rows], dtype=int)
    try:
        table = (
            pd.read_csv(
                io.StringIO("\n".join(line for _, line in rows)),
                sep=sep,
                header=None,
                dtype=str,
                keep_default_na=False,
                names=list(range(len(headers))),
                engine="python",
            )
            if rows
            else pd.DataFrame(columns=list(range(len(headers))), dtype=str)
        )
    except pd.errors.ParserError as error:  # a ragged row: more fields than the header
        found = re.search(r"line (\d+), saw (\d+)", str(error))
        if found is None:
            raise fail([Violation(None, "rows could not be split into fields")]) from None
        k, n_fields = int(found.group(1)), int(found.group(2))
        line = int(line_numbers[k - 1]) if 0 < k <= len(line_numbers) else k
        raise fail(
            [Violation(None, f"line {line}: {n_fields} fields, the header has {len(headers)}")]
        ) from None
    if len(table) != len(rows):
        raise fail([Violation(None, "rows could not be split into fields consistently")])

    problems: list[Violation] = []

    def bad_lines(mask: np.ndarray) -> tuple[tuple, int]:
        labels = [f"line {n}" for n in line_numbers[mask][:5]]
        return tuple(labels), int(mask.sum())

    time_text = table[time_index].str.strip()
    times = pd.to_datetime(time_text, utc=True, errors="coerce", format="ISO8601")
    bad_time = (times.isna() & (time_text != "")).to_numpy() | (time_text == "").to_numpy()
    if bad_time.any():
        shown, n = bad_lines(bad_time)
        problems.append(Violation(headers[time_index], "not an ISO-8601 time", shown, n))

    candidates = {
        k: (v,) if isinstance(v, str) else tuple(v)
        for k, v in {**DEFAULT_DSHIP_MAPPING, **(mapping or {})}.items()
    }
    unknown = sorted(set(candidates) - {c.name for c in CANONICAL_PREDICTORS})
    if unknown:
        raise ValueError(
            f"mapping has unknown canonical column(s) {', '.join(unknown)}; "
            f"known: {', '.join(c.name for c in CANONICAL_PREDICTORS)}"
        )
    out = pd.DataFrame({"time": times})
    used: set[int] = {time_index}
    absent: list[str] = []
    for column in CANONICAL_PREDICTORS:
        wanted = [w.lower() for w in candidates.get(column.name, ())]
        index = next(
            (
                j
                for w in wanted
                for j, (h, n) in enumerate(zip(headers, names, strict=True))
                if j not in used and (h.lower() == w or n.lower() == w)
            ),
            None,
        )
        if index is None:
            absent.append(column.name)
            out[column.name] = np.nan
            continue
        used.add(index)
        values, bad = _numbers(table[index])
        if bad.any():
            shown, n = bad_lines(bad)
            problems.append(Violation(headers[index], "not a number", shown, n))
        unit = units[index]
        if unit is not None:
            conversions = _CONVERSIONS[column.name]
            key = _unit_key(unit)
            if key not in conversions:
                problems.append(
                    Violation(
                        headers[index],
                        f"unit '{unit}' cannot be converted to {column.unit} for {column.name}",
                    )
                )
            elif conversions[key] is not None:
                values = conversions[key](values)
        out[column.name] = values
    for j, header in enumerate(headers):
        if j in used or not header:
            continue
        values, bad = _numbers(table[j])
        if bad.any() or np.isnan(values).all():
            continue  # text columns (events, labels) are not predictors
        name = _snake(names[j], units[j])
        while name in out.columns:
            name += "_"
        out[name] = values
    if problems:
        raise fail(problems)
    if absent:
        if len(absent) == len(CANONICAL_PREDICTORS):
            raise fail(
                [
                    Violation(
                        None,
                        "none of the predictor columns was found (speed, water "
                        "and air temperature, wind); pass a column mapping",
                    )
                ]
            )
        warnings.warn(f"{source}: no column for {', '.join(absent)}; filled with NaN", stacklevel=2)
    order = np.argsort(out["time"].to_numpy(), kind="stable")
    if (np.diff(order) < 0).any():
        warnings.warn(
            f"{source}: time stamps are not sorted; rows were sorted by time", stacklevel=2
        )
        out = out.iloc[order].reset_index(drop=True)
        line_numbers = line_numbers[order]
    duplicated = out["time"].duplicated(keep="first").to_numpy()
    if duplicated.any():
        first = line_numbers[duplicated][0]
        warnings.warn(
            f"{source}: {int(duplicated.sum())} duplicate time stamp(s) (first at line "
            f"{first}); kept the first row of each",
            stacklevel=2,
        )
        out = out.loc[~duplicated].reset_index(drop=True)
    try:
        return DSHIP_LOG.validate(out, source=source)
    except ContractError as error:
        # Re-label row numbers as file lines for the user.
        relabelled = [
            Violation(
                v.column,
                v.reason,
                tuple(f"line {line_numbers[r]}" for r in v.rows if isinstance(r, int | np.integer)),
                v.n_rows,
            )
            for v in error.violations
        ]
        raise fail(relabelled) from None


def _numbers(cells: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """Float values of text cells; empty cells are NaN; also a mask of unparseable cells."""
    text = cells.str.strip()
    values = pd.to_numeric(text.where(text != ""), errors="coerce").to_numpy(dtype=float)
    bad = (
        np.isnan(values)
        & (text != "").to_numpy()
        & ~text.str.lower().isin(["nan", "na", "n/a"]).to_numpy()
    )
    return values, bad
