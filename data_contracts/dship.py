"""Ship data-system (DSHIP) logs: parsing the raw export into the canonical log table.

The raw file is delimited text as exported by the ship's data system or by PANGAEA:

* an optional ``/* ... */`` description block,
* one header line whose names carry units in brackets (``Speed [kn]``, ``TTT [°C]``),
  or three header rows (name, sensor, unit) as in raw DSHIP extractions,
* a time column (``Date/Time``; ISO-8601, ``yyyy/mm/dd HH:MM:SS`` or day-first
  ``dd.mm.yyyy HH:MM:SS``; UTC unless an offset is given; every time carries an offset
  or none),
* DSHIP channel names ``DEVICE.SENSOR.PARAMETER`` (``SYS.STR.SOG``), matched through the
  built-in table :data:`~data_contracts.dship_names.DSHIP_NAMES` or the user's mapping,
* up to three header rows before the data (name, description, unit),
* tab (PANGAEA) or ``;`` (DSHIP) separators, decimal points or decimal commas, empty cells
  for missing values,
* UTF-8 or latin-1 text.

When the log has no relative wind direction but the true wind, the heading, the course and
the speed, the relative wind is derived (:func:`~data_contracts.dship_names.relative_wind`).

:func:`read_dship` maps source columns to the canonical columns of :data:`DSHIP_LOG`
through a configurable mapping, converts units, and keeps every other numeric column
under a snake_case name with its unit (``dd [deg]`` becomes ``dd_deg``).
"""

from __future__ import annotations

import csv
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
from .csv_layout import decode_text
from .dship_names import (
    AUXILIARY_COLUMNS,
    DSHIP_NAMES,
    SHAFT_COLUMNS,
    SLASH_FORMATS,
    TIME_FORMATS,
    bad_time_values,
    name_key,
    parse_log_times,
    parse_utc_offset,
    relative_wind,
    resolve_mapping,
    strptime_format,
    time_format_hint,
)
from .tables import CANONICAL_PREDICTORS, OPTIONAL_PREDICTORS

__all__ = ["DEFAULT_DSHIP_MAPPING", "DSHIP_LOG", "ColumnMappingError", "read_dship"]


class ColumnMappingError(ContractError):
    """A column the column mapping names (``speed_kn=SOG``) is not in the log: the user
    asked for it, so the log is refused rather than read without the quantity."""


#: Source names (case-insensitive, without the bracketed unit) tried for each canonical
#: column, in order. Pass your own mapping to :func:`read_dship` for other ships.
DEFAULT_DSHIP_MAPPING: dict[str, tuple[str, ...]] = {
    c.name: DSHIP_NAMES[c.name] for c in CANONICAL_PREDICTORS
}

TIME_COLUMN_NAMES = (
    "Date/Time",
    "DATE/TIME",
    "Date Time",
    "Datetime",
    "time",
    "Time",
    "Timestamp",
    "Time (UTC)",
    "UTC",
    "Zeit",
)

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
_CONVERSIONS["fuel_on_board_t"] = {"t": None, "kg": lambda v: v / 1000.0}
_CONVERSIONS["shaft_rpm"] = {
    "rpm": None,
    "1/min": None,
    "min-1": None,
    "u/min": None,
    "r/min": None,
    "rps": lambda v: v * 60.0,
    "1/s": lambda v: v * 60.0,
    "hz": lambda v: v * 60.0,
}
_CONVERSIONS["wind_speed_true_ms"] = _CONVERSIONS["wind_speed_ms"]
for _angle in ("wind_dir_true_deg", "heading_deg", "course_deg"):
    _CONVERSIONS[_angle] = _CONVERSIONS["wind_dir_rel_deg"]
#: Units recognised in a unit row besides the convertible ones.
_OTHER_UNITS = {
    "%",
    "hpa",
    "mbar",
    "psu",
    "m",
    "°n",
    "°e",
    "w/m2",
    "w/m^2",
    "mm",
    "1",
    "-",
    "m3",
    "m³",
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


def _fields(line: str, sep: str) -> list[str]:
    """The fields of one line, RFC 4180 quotes removed (``"Date/Time"`` -> ``Date/Time``)."""
    if '"' not in line:
        return line.split(sep)
    try:
        return next(csv.reader([line], delimiter=sep, skipinitialspace=True))
    except (csv.Error, StopIteration):
        return line.split(sep)


def _has_column(headers: Sequence[str], names: Sequence[str], wanted: str) -> bool:
    """Whether the log has a column *wanted* names, as :func:`parse_dship` looks it up: its
    name or whole header, or the last part of a dotted name (``SOG`` for ``SYS.STR.SOG``)."""
    key = name_key(wanted)
    return any(key in (name_key(h), name_key(n)) for h, n in zip(headers, names, strict=True)) or (
        any("." in n and name_key(n.rsplit(".", 1)[1]) == key for n in names)
    )


def _looks_like_time(text: str, time_format: str | None) -> bool:
    slash = [f for pair in SLASH_FORMATS for f in pair]
    formats = (strptime_format(time_format),) if time_format else ("ISO8601", *TIME_FORMATS, *slash)
    return any(
        not pd.isna(pd.to_datetime(text.strip(), errors="coerce", format=f, utc=True))
        for f in formats
    )


def _is_unit(text: str) -> bool:
    key = _unit_key(_split_name(text)[1] or text)
    return bool(key) and (key in _OTHER_UNITS or any(key in c for c in _CONVERSIONS.values()))


def _unit_row(rows: list[list[str]]) -> int | None:
    """Which of the header rows after the names holds the units (None: none does)."""
    if not rows:
        return None
    counts = [sum(_is_unit(c) for c in row if c) for row in rows]
    if max(counts) > 0:
        return len(counts) - 1 - counts[::-1].index(max(counts))
    last = [c for c in rows[-1] if c]
    if last and not any(" " in c for c in last):
        return len(rows) - 1
    return None


def read_dship(
    path: str | os.PathLike,
    *,
    mapping: Mapping[str, str | Sequence[str]] | None = None,
    time_column: str | None = None,
    encoding: str | None = None,
    separator: str | None = None,
    decimal: str | None = None,
    time_format: str | None = None,
    complete_lines: bool = False,
    utc_offset: str | pd.Timedelta | None = None,
) -> pd.DataFrame:
    """Parse a raw DSHIP / PANGAEA ship log into the canonical log table.

    Parameters
    ----------
    path : path-like
        The exported text file.
    mapping : mapping, optional
        Canonical column -> source name or names (case-insensitive, with or without the
        bracketed unit; a bare name also matches the last part of a dotted DSHIP name).
        Entries replace those of :data:`~data_contracts.dship_names.DSHIP_NAMES`; besides
        the predictors, ``wind_dir_true_deg``, ``wind_speed_true_ms``, ``heading_deg`` and
        ``course_deg`` may be mapped (used to derive the relative wind), and ``time``
        names the time column. A column an entry names must be in the file (a log
        without it is refused; a quantity left to the built-in names may be absent).
    time_column : str, optional
        Name of the time column; default: the first of :data:`TIME_COLUMN_NAMES` present.
    encoding : str, optional
        Text encoding; default UTF-8, falling back to latin-1.
    separator : str, optional
        Field separator; default: tab or ``;``, whichever the header line uses.
    decimal : {".", ","}, optional
        Decimal mark; default ``,`` when the separator is not ``,`` and numbers such as
        ``12,5`` occur, else ``.``.
    time_format : str, optional
        Format of the times: :func:`~datetime.datetime.strptime` (``%d/%m/%Y %H:%M:%S``)
        or MATLAB ``datestr`` symbols (``dd-mmm-yyyy HH:MM:SS``); default: ISO-8601,
        ``yyyy/mm/dd HH:MM:SS``, day-first ``dd.mm.yyyy HH:MM:SS``, ``dd-mmm-yyyy
        HH:MM:SS`` or slash dates whose days tell day and month apart, whichever fits.
    complete_lines : bool
        Leave out a last line without its line end (a live log read while the data system
        writes its next line, whose cut time could read as another time); default False.
    utc_offset : str or Timedelta, optional
        The offset from UTC of times written without one (``"+02:00"``: a local clock two
        hours ahead of UTC; :func:`~data_contracts.dship_names.parse_utc_offset`): they are
        moved back by it. Default: such times are UTC. Times that carry their own offset
        keep it (the option is then not used).

    Returns
    -------
    DataFrame
        ``time`` (UTC) and the canonical predictor columns in canonical units, then the
        other numeric columns, sorted by time. Canonical columns absent from the file are
        NaN (with a warning), and so are those present with no value in any row (with a
        warning naming them: a sensor dead for the whole export). Exact duplicate time
        stamps keep their first row (warning). Times with an offset are converted to UTC
        each with its own; a log mixing offsets says so in a warning.

    Raises
    ------
    ContractError
        Unreadable file, no readings (an empty file, a header and no data rows, rows
        holding nothing but a time), no header or time column, no column that a *mapping*
        entry names, unparseable times or
        numbers, times
        with a UTC offset mixed with times without one (the first of the other kind is
        named: they cannot be placed), a unit
        that cannot be converted, or values outside physical bounds. Each message names the
        file, the column and the line numbers.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as error:
        violation = Violation(None, f"cannot read file: {error.strerror or error}")
        raise ContractError([violation], source=str(path), contract="dship") from None
    return parse_dship(
        raw,
        source=str(path),
        mapping=mapping,
        time_column=time_column,
        encoding=encoding,
        separator=separator,
        decimal=decimal,
        time_format=time_format,
        complete_lines=complete_lines,
        utc_offset=utc_offset,
    )


def parse_dship(
    raw: bytes,
    *,
    source: str,
    mapping: Mapping[str, str | Sequence[str]] | None = None,
    time_column: str | None = None,
    encoding: str | None = None,
    separator: str | None = None,
    decimal: str | None = None,
    time_format: str | None = None,
    complete_lines: bool = False,
    utc_offset: str | pd.Timedelta | None = None,
) -> pd.DataFrame:
    """:func:`read_dship` of the file's bytes *raw* (*source*: the name its messages give;
    :class:`workbench.monitor.ship_log.LiveShipLog` parses a growing log's new lines so)."""
    mapping = dict(mapping or {})
    if "time" in mapping:
        time_column = str(mapping.pop("time"))

    def fail(problems: list[Violation]) -> ContractError:
        return ContractError(problems, source=source, contract="dship")

    if complete_lines and encoding is None and not raw.endswith((b"\n", b"\r")):
        # UTF-8 or Latin-1: cut before decoding (a character cut in two is left out too)
        raw = raw[: max(raw.rfind(b"\n"), raw.rfind(b"\r")) + 1]
    text = decode_text(raw, encoding)
    if complete_lines and not text.endswith(("\n", "\r")):
        text = text[: max(text.rfind("\n"), text.rfind("\r")) + 1]
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
        raise fail([Violation(None, "no readings: the file is empty (no header line, no data)")])
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
    headers = [h.strip() for h in _fields(header_text, sep)]
    rows = body[1:]
    units: list[str | None] = [_split_name(h)[1] for h in headers]
    names = [_split_name(h)[0] for h in headers]

    found = f"columns in the file: {', '.join(h for h in headers if h)}"
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
                        f"time column is missing (looked for {', '.join(TIME_COLUMN_NAMES)}; "
                        f"{found}); name it in the mapping as time=NAME",
                    )
                ]
            )
    else:
        if time_column not in names and time_column not in headers:
            raise fail([Violation(time_column, f"time column is missing ({found})")])
        time_index = (
            names.index(time_column) if time_column in names else headers.index(time_column)
        )

    # Raw DSHIP extractions: up to three header rows (name, description, unit) before
    # the data; the first row whose time cell holds a time starts the data.
    def time_field(line: str) -> str:
        fields = _fields(line, sep)
        return fields[time_index] if time_index < len(fields) else ""

    n_header = next(
        (
            k
            for k, (_, line) in enumerate(rows[:4])
            if _looks_like_time(time_field(line), time_format)
        ),
        0,
    )
    if 0 < n_header <= 3:
        extra = [[u.strip() for u in _fields(line, sep)] for _, line in rows[:n_header]]
        unit_index = _unit_row(extra)
        if unit_index is not None:
            unit_fields = extra[unit_index]
            for j in range(min(len(names), len(unit_fields))):
                if unit_fields[j] and j != time_index:
                    bracketed = _split_name(unit_fields[j])[1]
                    units[j] = bracketed if bracketed is not None else unit_fields[j]
        rows = rows[n_header:]
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

    if not len(table):
        raise fail([Violation(None, "no readings: the file has a header and no data rows")])
    others = [j for j in table.columns if j != time_index]
    blank = table[others].fillna("").apply(lambda c: c.str.strip()) == ""
    if not others or blank.to_numpy().all():
        first, last = int(line_numbers[0]), int(line_numbers[-1])
        raise fail(
            [
                Violation(
                    None,
                    f"no readings: its {len(table)} data row(s) (lines {first}-{last}) hold "
                    "no value besides the time",
                )
            ]
        )

    problems: list[Violation] = []

    def bad_lines(mask: np.ndarray) -> tuple[tuple, int]:
        labels = [f"line {n}" for n in line_numbers[mask][:5]]
        return tuple(labels), int(mask.sum())

    time_text = table[time_index].fillna("").str.strip()
    times, used_format = parse_log_times(time_text, time_format)
    bad_time = (times.isna() & (time_text != "")).to_numpy() | (time_text == "").to_numpy()
    if bad_time.all() and len(bad_time) and time_format is None:
        problems.append(
            Violation(
                headers[time_index],
                f"no known time format fits ({bad_time_values(time_text, bad_time)}; tried "
                f"ISO-8601, {', '.join(TIME_FORMATS)}); {time_format_hint(used_format)}",
            )
        )
    elif bad_time.any():
        shown, n = bad_lines(bad_time)
        what = "an ISO-8601 time" if used_format == "ISO8601" else f"a time in {used_format}"
        problems.append(
            Violation(
                headers[time_index],
                f"not {what}: {bad_time_values(time_text, bad_time)}",
                shown,
                n,
            )
        )

    mixed_offsets = _time_offsets(time_text, times, line_numbers, headers[time_index], problems)
    if utc_offset is not None and not _carries_offsets(time_text, times):
        # a local clock without an offset in the text: UTC = local time - offset
        shift = utc_offset if isinstance(utc_offset, pd.Timedelta) else parse_utc_offset(utc_offset)
        times = times - shift

    known = (
        [c.name for c in CANONICAL_PREDICTORS]
        + [c.name for c in OPTIONAL_PREDICTORS]
        + list(AUXILIARY_COLUMNS)
        + list(SHAFT_COLUMNS)
    )
    candidates = resolve_mapping(mapping, known)
    # a column the user's mapping names is asked for: a log without it is refused, not
    # read without the quantity (the default names may be absent: the quantity is then)
    for name, wanted in mapping.items():
        given = (wanted,) if isinstance(wanted, str) else tuple(wanted)
        if not any(_has_column(headers, names, w) for w in given):
            raise ColumnMappingError(
                [
                    Violation(
                        " or ".join(map(str, given)),
                        f"not in the file, named by the column mapping "
                        f"{name}={'|'.join(map(str, given))} ({found})",
                    )
                ],
                source=source,
                contract="dship",
            )
    if decimal is None:
        decimal = "," if sep != "," and _has_decimal_commas(table, time_index) else "."
    out = pd.DataFrame({"time": times})
    used: set[int] = {time_index}
    absent: list[str] = []
    empty: list[str] = []  # columns found whose every cell is empty (a sensor dead throughout)

    def find(name: str) -> int | None:
        """Column index of canonical *name*: exact names first, then dotted suffixes."""
        for wanted in candidates.get(name, ()):
            w = name_key(wanted)
            exact = [
                j
                for j, (h, n) in enumerate(zip(headers, names, strict=True))
                if j not in used and w in (name_key(h), name_key(n))
            ]
            if exact:
                return exact[0]
            suffix = [
                j
                for j, n in enumerate(names)
                if j not in used and "." in n and name_key(n.rsplit(".", 1)[1]) == w
            ]
            if len(suffix) > 1:
                choices = ", ".join(headers[j] for j in suffix)
                problems.append(
                    Violation(
                        None,
                        f"several columns could be {name} ({choices}); choose one with a "
                        f"mapping ({name}=NAME)",
                    )
                )
                return suffix[0]
            if suffix:
                return suffix[0]
        return None

    def convert(index: int, name: str, unit_text: str) -> np.ndarray:
        values, bad = _numbers(table[index], decimal)
        if bad.any():
            shown, n = bad_lines(bad)
            problems.append(Violation(headers[index], "not a number", shown, n))
        unit = units[index]
        if unit is not None:
            conversions = _CONVERSIONS[name]
            key = _unit_key(unit)
            if key not in conversions:
                problems.append(
                    Violation(
                        headers[index],
                        f"unit '{unit}' cannot be converted to {unit_text} for {name}",
                    )
                )
            elif conversions[key] is not None:
                values = conversions[key](values)
        return values

    for column in CANONICAL_PREDICTORS:
        index = find(column.name)
        if index is None:
            absent.append(column.name)
            out[column.name] = np.nan
            continue
        used.add(index)
        out[column.name] = convert(index, column.name, column.unit or "")
        if len(table) and out[column.name].isna().all():
            empty.append(f"{headers[index]!r} ({column.name})")
    # kept when the log has them, never NaN-filled
    for name, unit_text in [(c.name, c.unit or "") for c in OPTIONAL_PREDICTORS] + [
        (name, "rpm") for name in SHAFT_COLUMNS
    ]:
        n_problems = len(problems)
        index = find(name)
        if name in SHAFT_COLUMNS and len(problems) > n_problems:
            # two shafts (or engines) logged: not a reason to refuse the log
            warnings.warn(f"{source}: {problems.pop().reason}; {name} not read", stacklevel=3)
            continue
        if index is None:
            continue
        unit = units[index]
        if unit is not None and _unit_key(unit) not in _CONVERSIONS[name]:
            warnings.warn(
                f"{source}: column {headers[index]!r} could be {name} but its unit "
                f"'{unit}' is not {unit_text}; kept under its own name",
                stacklevel=3,
            )
            continue
        used.add(index)
        out[name] = convert(index, name, unit_text)
    if "wind_dir_rel_deg" in absent:
        derived = _derive_relative_wind(out, find, used, convert, headers)
        if derived is not None:
            absent.remove("wind_dir_rel_deg")
            if "wind_speed_ms" in absent:
                absent.remove("wind_speed_ms")
    for j, header in enumerate(headers):
        if j in used or not header:
            continue
        values, bad = _numbers(table[j], decimal)
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
                        f"and air temperature, wind; {found}); pass a column mapping "
                        "(e.g. speed_kn=NAME,air_temp_c=NAME)",
                    )
                ]
            )
        warnings.warn(f"{source}: no column for {', '.join(absent)}; filled with NaN", stacklevel=3)
    if empty:
        warnings.warn(
            f"{source}: column{'s' if len(empty) > 1 else ''} {', '.join(empty)} "
            f"{'hold' if len(empty) > 1 else 'holds'} no value in any row; left empty",
            stacklevel=3,
        )
    if mixed_offsets:
        warnings.warn(
            f"{source}: column {headers[time_index]!r} mixes UTC offsets ({mixed_offsets}); "
            "each time was converted to UTC with its own offset",
            stacklevel=3,
        )
    stamps = pd.DatetimeIndex(out["time"]).as_unit("ns")
    order = np.argsort(stamps.asi8, kind="stable")
    if (np.diff(order) < 0).any():
        back = np.flatnonzero(np.diff(stamps.asi8) < 0)
        k = int(back[0]) + 1
        seconds = (stamps[k - 1] - stamps[k]).total_seconds()
        warnings.warn(
            f"{source}: time goes back {len(back)} time(s), first at line "
            f"{line_numbers[k]} ({seconds:g} s before line {line_numbers[k - 1]}: "
            f"{stamps[k - 1]:%Y-%m-%dT%H:%M:%SZ} then {stamps[k]:%Y-%m-%dT%H:%M:%SZ}); "
            "rows were sorted by time",
            stacklevel=3,
        )
        out = out.iloc[order].reset_index(drop=True)
        line_numbers = line_numbers[order]
    duplicated = out["time"].duplicated(keep="first").to_numpy()
    if duplicated.any():
        first = line_numbers[duplicated][0]
        warnings.warn(
            f"{source}: {int(duplicated.sum())} duplicate time stamp(s) (first at line "
            f"{first}); kept the first row of each",
            stacklevel=3,
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


#: A UTC offset ending a time of day (``12:00:00+02:00``, ``12:00Z``, ``12:00:00.5 -0130``).
_OFFSET = re.compile(r"\d:\d\d(?::\d\d(?:[.,]\d*)?)?\s*(Z|[+-]\d\d(?::?\d\d)?)$", re.IGNORECASE)


def _time_offsets(
    text: pd.Series,
    times: pd.Series,
    line_numbers: np.ndarray,
    column: str,
    problems: list[Violation],
) -> str:
    """Check that the parsed *times* all carry a UTC offset or none.

    A time without an offset among times with one cannot be placed (UTC is a guess, the
    others' offset another): a violation naming the first row of the other kind is added
    to *problems*. Returns, when every time carries an offset and they differ, the
    offsets and the line where the first change happens (``+01:00, +02:00; +02:00 from
    line 9``), else ``""``.
    """
    parsed = times.notna().to_numpy()
    if not parsed.any():
        return ""
    found = text.str.extract(_OFFSET, expand=False).to_numpy()[parsed]
    lines = line_numbers[parsed]
    zoned = np.array([isinstance(v, str) for v in found])
    if zoned.any() and not zoned.all():
        first = int(np.flatnonzero(zoned != zoned[0])[0])
        if zoned[0]:
            reason = (
                f"line {lines[first]} has no UTC offset while line {lines[0]} before it "
                f"carries one ({found[0]})"
            )
        else:
            reason = (
                f"line {lines[first]} carries a UTC offset ({found[first]}) while line "
                f"{lines[0]} before it has none"
            )
        problems.append(
            Violation(
                column,
                f"{reason}: a time without an offset cannot be placed among times with "
                "one; give every time its offset, or none (then all are UTC)",
            )
        )
        return ""
    if not zoned.any():
        return ""

    def normal(offset: str) -> str:
        if offset.upper() == "Z":
            return "+00:00"
        digits = offset[1:].replace(":", "").ljust(4, "0")
        return f"{offset[0]}{digits[:2]}:{digits[2:]}"

    offsets = np.array([normal(v) for v in found])
    change = np.flatnonzero(offsets != offsets[0])
    if not len(change):
        return ""
    distinct = ", ".join(pd.unique(offsets))
    return f"{distinct}; {offsets[change[0]]} from line {lines[change[0]]}"


def _carries_offsets(text: pd.Series, times: pd.Series) -> bool:
    """Whether the first parsed time of *text* carries a UTC offset (all or none do:
    :func:`_time_offsets`)."""
    parsed = np.flatnonzero(times.notna().to_numpy())
    return bool(len(parsed)) and _OFFSET.search(text.iloc[parsed[0]]) is not None


_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+$")


def _has_decimal_commas(table: pd.DataFrame, time_index: int) -> bool:
    """Whether numbers such as ``12,5`` occur in the first rows (separator is not ``,``)."""
    head = table.drop(columns=[time_index]).head(50)
    return any(head[c].str.strip().str.match(_DECIMAL_COMMA).any() for c in head.columns)


def _derive_relative_wind(out, find, used, convert, headers) -> bool | None:
    """Relative wind from true wind, heading, course and speed (columns added to *out*)."""
    direction = find("wind_dir_true_deg")
    if direction is None:
        return None
    speed = find("wind_speed_true_ms")
    needed = {"heading_deg": find("heading_deg"), "course_deg": find("course_deg")}
    missing = [k for k, v in needed.items() if v is None]
    if out["speed_kn"].isna().all():
        missing.append("speed_kn")
    if speed is None and out["wind_speed_ms"].isna().all():
        missing.append("wind speed")
    if missing:
        warnings.warn(
            f"true wind ({headers[direction]}) is logged but no relative wind direction; "
            f"deriving it needs {', '.join(missing)} (not found)",
            stacklevel=4,
        )
        return None
    for index in (direction, speed, *needed.values()):
        if index is not None:
            used.add(index)
    true_dir = convert(direction, "wind_dir_true_deg", "deg")
    true_speed = (
        convert(speed, "wind_speed_true_ms", "m/s")
        if speed is not None
        else out["wind_speed_ms"].to_numpy(dtype=float)
    )
    heading = convert(needed["heading_deg"], "heading_deg", "deg")
    course = convert(needed["course_deg"], "course_deg", "deg")
    rel_dir, rel_speed = relative_wind(
        true_dir, true_speed, heading, course, out["speed_kn"].to_numpy(dtype=float)
    )
    out["wind_speed_ms"] = rel_speed
    out["wind_dir_rel_deg"] = rel_dir
    out["wind_speed_true_ms"] = true_speed
    out["wind_dir_true_deg"] = true_dir
    out["heading_deg"] = heading
    out["course_deg"] = course
    return True


def _numbers(cells: pd.Series, decimal: str = ".") -> tuple[np.ndarray, np.ndarray]:
    """Float values of text cells; empty cells are NaN (so are the cells a row shorter than
    the header lacks); also a mask of unparseable cells."""
    text = cells.fillna("").str.strip()
    if decimal != ".":
        text = text.str.replace(decimal, ".", regex=False)
    values = pd.to_numeric(text.where(text != ""), errors="coerce").to_numpy(dtype=float)
    bad = (
        np.isnan(values)
        & (text != "").to_numpy()
        & ~text.str.lower().isin(["nan", "na", "n/a"]).to_numpy()
    )
    return values, bad
