"""CSV/TSV acceleration files: a time column (absolute or relative) and one column per
channel, units in the headers (``acc01 [m/s^2]``) or stated by the user."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .._core import ContractError, Violation
from ..csv_layout import read_delimited, sniff_separator, split_unit
from ..dship_names import (
    TIME_FORMATS,
    bad_time_values,
    name_key,
    parse_log_times,
    time_format_hint,
)
from ..limits import check_channel_count
from . import AccelerationLayout, convert_units, describe, layout_start, warn_if_gravity_in_g

__all__ = ["TEXT_SUFFIXES", "read_text_accelerations"]

TEXT_SUFFIXES = (".csv", ".tsv", ".txt")

_TIME_NAMES = ("time", "timestamp", "datetime", "date/time", "datetimeutc", "timeutc", "t", "zeit")


def _is_time_name(key: str) -> bool:
    """Whether a header's name key (:func:`name_key`) names a time column: one of the usual
    names, or starting with ``time`` (catman's ``Time  1 - default sample rate``)."""
    return key in _TIME_NAMES or key.startswith("time")


#: Seconds per unit of a relative time column.
_TIME_UNITS = {
    "s": 1.0,
    "sec": 1.0,
    "seconds": 1.0,
    "ms": 1e-3,
    "us": 1e-6,
    "µs": 1e-6,
    "min": 60.0,
}


def read_text_accelerations(path: str | os.PathLike, layout: AccelerationLayout):
    """Read a delimited text acceleration file (see :class:`AccelerationLayout`).

    Returns
    -------
    AccelerationRecord
        Not yet validated; accelerations converted to m/s².
    """
    from ..accelerations import AccelerationRecord

    path = Path(path)

    def fail(reason: str, column: str | None = None, rows=(), n_rows=0) -> ContractError:
        return ContractError(
            [Violation(column, reason, tuple(rows), n_rows)], source=path, contract="accelerations"
        )

    preamble = _preamble(path, layout.separator, layout.time_format)
    _check_width(path, preamble.header_row, layout.separator)
    banner = preamble.stated
    if banner:
        changes = {}
        if layout.start_time is None and "start_time" in banner:
            changes["start_time"] = banner["start_time"]
        if layout.sampling_rate_hz is None and "sampling_rate_hz" in banner:
            changes["sampling_rate_hz"] = banner["sampling_rate_hz"]
        layout = replace(layout, **changes)
    note = ""  # why a start stated above the header was not taken
    if layout.start_time is None and "unread_start" in banner:
        value = banner["unread_start"]
        used = parse_log_times(pd.Series([value]))[1]
        note = (
            f"; the start time {value!r} above the header is not a recognised time "
            f"({time_format_hint(used)})"
        )
    frame, _, _ = read_delimited(
        path,
        separator=layout.separator or preamble.separator,
        decimal=layout.decimal,
        skip_rows=preamble.header_row,
        skip_after_header=preamble.rows_below_header,
    )
    if preamble.unit_row is not None:
        frame.columns = _with_units(list(frame.columns), preamble.unit_row)
    headers = [str(c) for c in frame.columns]
    found = describe(headers, "columns")
    names = [split_unit(h)[0] for h in headers]
    units = [split_unit(h)[1] for h in headers]

    def index_of(name: str) -> int | None:
        key = name_key(name)
        return next(
            (
                j
                for j, (h, n) in enumerate(zip(headers, names, strict=True))
                if key in (name_key(h), name_key(n))
            ),
            None,
        )

    if layout.time_column is not None:
        time_index = index_of(layout.time_column)
        if time_index is None:
            raise fail(f"time column '{layout.time_column}' is missing ({found})")
    else:
        time_index = next((j for t in _TIME_NAMES if (j := index_of(t)) is not None), None)
        if time_index is None:
            time_index = next(
                (j for j, n in enumerate(names) if name_key(n).startswith("time")), None
            )
        if time_index is None and (layout.start_time is None or layout.sampling_rate_hz is None):
            raise fail(
                f"time column is missing (looked for Time, Timestamp, Datetime, t; {found}); "
                "name it (time column) or give the start time and the sampling rate"
            )
    if layout.channels is not None:
        channel_indices = []
        for channel in layout.channels:
            j = index_of(channel)
            if j is None:
                raise fail(f"channel '{channel}' is missing ({found})")
            channel_indices.append(j)
    else:
        channel_indices = [j for j in range(len(headers)) if j != time_index]
    if not channel_indices:
        raise fail(f"no channel columns besides the time ({found})")
    data = frame.iloc[:, channel_indices]
    numeric = data.apply(pd.to_numeric, errors="coerce")
    bad = [
        headers[j]
        for j, c in zip(channel_indices, data.columns, strict=True)
        if (numeric[c].isna() & data[c].notna()).any()
    ]
    if bad:
        raise fail(
            f"non-numeric values in column(s) {', '.join(bad)}; choose the channel columns "
            f"({found})"
        )
    acceleration = numeric.to_numpy(dtype=float)
    channels = [names[j] for j in channel_indices]

    rate = layout.sampling_rate_hz
    if time_index is None:
        given = layout_start(layout, path)
        if given is None or rate is None:
            raise fail(f"no time column: give the start time and the sampling rate ({found}){note}")
        start = given
    else:
        start, step, seconds = _times(
            path,
            frame.iloc[:, time_index],
            headers[time_index],
            units[time_index],
            layout,
            fail,
            note,
        )
        if seconds is not None:
            _check_steps(seconds, rate, headers[time_index], fail)
        if rate is None:
            if not step > 0:
                raise fail("times do not increase", headers[time_index])
            rate = round(1.0 / step, 9)
    if rate is None:
        raise fail("no sampling rate: give it")
    start = start.tz_localize("UTC") if start.tzinfo is None else start.tz_convert("UTC")
    header_units = [units[j] for j in channel_indices]
    acceleration = convert_units(acceleration, channels, header_units, layout, path)
    stated = layout.units is not None or any(u is not None for u in header_units)
    warn_if_gravity_in_g(acceleration, channels, stated, path)
    return AccelerationRecord(acceleration, rate, start, tuple(channels))


def _check_width(path: Path, n_banner: int, separator: str | None) -> None:
    """Refuse a header line of more than :data:`~data_contracts.limits.MAX_CHANNELS`
    columns before parsing (each column costs the parser a fixed overhead: 10^6 columns
    ran minutes, then out of memory)."""
    from ..csv_layout import sniff_separator

    with open(path, "rb") as handle:
        for _ in range(n_banner):
            handle.readline(65536)
        line = handle.readline().decode("utf-8", "replace")
    sep = separator or sniff_separator(line[:65536])
    # columns besides one time column
    check_channel_count(line.count(sep), source=path, what="the header line")


_BANNER_RATE = {"samplerate", "samplingrate", "samplingfrequency", "fs", "rate", "scanrate"}
#: Keys stating the sampling interval (the rate is its inverse).
_BANNER_INTERVAL = {
    "dt",
    "deltat",
    "deltax",
    "delta_x",
    "sampleinterval",
    "samplinginterval",
    "sampleperiod",
    "samplingperiod",
    "increment",
    "timestep",
}
_BANNER_START = {
    "starttime",
    "start",
    "recordingstart",
    "measurementstart",
    "acquisitionstart",
    "triggertime",
    "t0",
    "starttimeutc",
    "datetime",
    "trigger",
}
#: Seconds per unit of a stated sampling interval.
_INTERVAL_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_NUMBER = re.compile(r"[+-]?\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?")
_FIELD_NUMBER = re.compile(r"^[+-]?(?:\d+(?:[.,]\d*)?|[.,]\d+)(?:[eE][+-]?\d+)?$|^(?:nan|NaN|inf)$")
#: Lines of a file's start searched for the header (metadata blocks run to a few dozen).
_HEAD_LINES = 200


@dataclass(frozen=True)
class _Preamble:
    """Where the table of a delimited file starts and what the lines above it state.

    Attributes
    ----------
    header_row : int
        Line (0-based) of the header row.
    separator : str, optional
        Field separator of the table (None: sniff it from the header row).
    rows_below_header : int
        Lines between the header and the first data row (units, descriptions).
    unit_row : tuple of str, optional
        A row of units directly below the header (catman, Dewesoft), one per column.
    stated : dict
        ``start_time`` (ISO-8601) and ``sampling_rate_hz`` from the metadata lines.
    """

    header_row: int
    separator: str | None
    rows_below_header: int
    unit_row: tuple[str, ...] | None
    stated: dict


def _fields(line: str, sep: str) -> list[str]:
    return [f.strip().strip('"').strip() for f in line.split(sep)]


def _is_data_row(fields: list[str]) -> bool:
    """At least half of the non-empty fields are numbers (a time column may be text)."""
    filled = [f for f in fields if f]
    numeric = sum(bool(_FIELD_NUMBER.match(f)) for f in filled)
    return bool(filled) and numeric > 0 and 2 * numeric >= len(filled)


def _table_start(lines: list[str], sep: str) -> tuple[int, int, int] | None:
    """(header line, first data line, field count) of the table at the end of *lines*
    separated by *sep*, or None when *sep* does not make one.

    The data rows are the numeric lines at the end sharing the field count of the last
    line; the header is the row above them, among the rows of that count, with every
    field filled (a spreadsheet pads ``key,value`` lines to the table's width), then
    naming a time column, then with the most filled fields, the first on a tie.
    """
    filled = [(i, line) for i, line in enumerate(lines) if line.strip()]
    if len(filled) < 2:
        return None
    n = filled[-1][1].count(sep)
    if n == 0:
        return None
    run: list[int] = []
    for i, line in reversed(filled):
        if line.count(sep) != n:
            break
        run.append(i)
    run.reverse()
    first_data = None  # the data rows: the longest stretch of numeric rows at the end
    for i in reversed(run):
        if not _is_data_row(_fields(lines[i], sep)):
            break
        first_data = i
    if first_data is None:
        return None
    above = [i for i in run if i < first_data]
    if not above:
        return None

    def score(i: int) -> tuple[bool, bool, int, int]:
        fields = _fields(lines[i], sep)
        keys = {name_key(split_unit(f)[0]) for f in fields}
        timed = any(_is_time_name(k) for k in keys)
        return (all(fields), timed, sum(bool(f) for f in fields), -i)

    return max(above, key=score), first_data, n + 1


def _preamble(path, separator: str | None, time_format: str | None = None) -> _Preamble:
    """Find the header row of a delimited file below an acquisition system's metadata.

    The header is the first row whose field count the data rows below it share and which
    names the columns (a time column preferred: NI, Dewesoft and catman exports put the
    device, task, start time and rate on ``key,value`` lines above it, and some a row of
    units below it). ``key: value`` (or ``key = value``, ``key<separator>value``) lines
    above it give the start time (``Start time``, ``Recording start``, ``t0``, or ``Date``
    and ``Time`` lines) and the sampling rate (``Sample rate``, ``Sampling Rate (Hz)``,
    ``fs``, or the interval ``dt``, ``Delta t``, ``Sample interval``).
    """
    from ..csv_layout import decode_text

    with open(path, "rb") as handle:
        raw = handle.read(65536)
    lines = decode_text(raw, None).splitlines()
    if len(raw) == 65536 and len(lines) > 1:
        lines = lines[:-1]  # cut at the read's end
    lines = lines[:_HEAD_LINES]
    candidates = [separator] if separator else [",", ";", "\t", "|"]
    best = None
    for sep in candidates:
        found = _table_start(lines, sep)
        if found is not None and (best is None or found[2] > best[1][2]):
            best = (sep, found)
    unit_row, below = None, 0
    if best is None:  # no numeric rows to tell the header by: the first line the next share
        header, sep = 0, separator
        for i, line in enumerate(lines):
            sep_i = separator or sniff_separator(line)
            n = line.count(sep_i)
            following = [x for x in lines[i + 1 : i + 4] if x.strip()][:2]
            if n and following and all(x.count(sep_i) == n for x in following):
                header = i
                break
    else:
        sep, (header, first_data, _) = best
        below = first_data - header - 1
        between = [_fields(lines[i], sep) for i in range(header + 1, first_data)]
        between = [f for f in between if any(f)]
        if len(between) == 1 and all(len(f) <= 12 and " " not in f for f in between[0]):
            unit_row = tuple(between[0])
    return _Preamble(header, sep, below, unit_row, _metadata(lines[:header], sep, time_format))


def _with_units(headers: list[str], units: tuple[str, ...]) -> list[str]:
    """Header names with the unit row's units (``AI0`` and ``g`` -> ``AI0 [g]``) where the
    header does not state one."""
    named = []
    for j, header in enumerate(headers):
        unit = units[j] if j < len(units) else ""
        has_unit = split_unit(header)[1] is not None
        named.append(f"{header} [{unit}]" if unit and not has_unit else header)
    return named


def _metadata(lines: list[str], sep: str | None, time_format: str | None) -> dict:
    """Start time and sampling rate stated by ``key: value`` lines."""
    pairs: dict[str, tuple[str, str]] = {}  # key -> (value, unit stated in the key)
    for line in lines:
        text = line.strip().lstrip("#%").strip()
        splits = []
        if sep and sep in text:  # key<separator>value (trailing separators of a padded row)
            key, value = text.split(sep, 1)
            splits.append((key, value.strip().strip(sep)))
        parts = re.split(r"\s*[:=;\t]\s*", text, maxsplit=1)
        if len(parts) == 2:
            splits.append((parts[0], parts[1]))
        for key, value in splits:
            value = value.strip().strip('"').strip()
            name, unit = split_unit(key.strip().strip('"'))
            if value and name:
                pairs.setdefault(name_key(name), (value, (unit or "").lower()))
    found: dict = {}
    for key, (value, key_unit) in pairs.items():
        number = _NUMBER.search(value)
        unit = (value[number.end() :].strip().lower() if number else "") or key_unit
        if key in _BANNER_RATE and number and "sampling_rate_hz" not in found:
            rate = float(number.group(0).replace(",", "."))
            found["sampling_rate_hz"] = rate * 1000 if unit.startswith("khz") else rate
        elif key in _BANNER_INTERVAL and number and "sampling_rate_hz" not in found:
            interval = float(number.group(0).replace(",", "."))
            scale = _INTERVAL_UNITS.get(unit.split()[0] if unit else "")
            if scale is not None and interval > 0:
                found["sampling_rate_hz"] = round(1.0 / (interval * scale), 9)
        elif key in _BANNER_START and "start_time" not in found:
            start = _text_time(value, time_format)
            if start is not None:
                found["start_time"] = start.isoformat()
            else:
                found.setdefault("unread_start", value)
    if "start_time" not in found and "date" in pairs and "time" in pairs:
        start = _text_time(f"{pairs['date'][0]} {pairs['time'][0]}", time_format)
        if start is not None:
            found["start_time"] = start.isoformat()
    return found


def _text_time(value: str, time_format: str | None) -> pd.Timestamp | None:
    """*value* as a UTC time (the given format, else the recognised ones), or None."""
    fmt = time_format if time_format not in (None, "seconds", "unix") else None
    times, _ = parse_log_times(pd.Series([value]), fmt)
    return times.iat[0] if times.notna().all() else None


def _times(path, values: pd.Series, header: str, unit: str | None, layout, fail, note=""):
    """Start time, median step [s] and the times [s] of a time column (*note*: added to
    the message asking for a start time)."""
    fmt = layout.time_format
    numbers = pd.to_numeric(values, errors="coerce")
    is_numeric = numbers.notna().all() and len(numbers) > 0
    if fmt not in (None, "seconds", "unix") and is_numeric:
        # a date format given for every input: a numeric column is still relative seconds
        # unless the format reads it (``%Y%m%d%H%M%S``)
        parsed, _ = parse_log_times(values.astype(str).str.strip(), fmt)
        if parsed.isna().all():
            fmt = None
    if fmt in ("seconds", "unix") or (fmt is None and is_numeric):
        if not is_numeric:
            rows = [f"row {r}" for r in np.nonzero(numbers.isna().to_numpy())[0][:5]]
            raise fail("not a number", header, rows, int(numbers.isna().sum()))
        scale = 1.0
        if unit is not None:
            if unit.strip().lower() not in _TIME_UNITS:
                raise fail(f"time unit '{unit}' is not one of {', '.join(_TIME_UNITS)}", header)
            scale = _TIME_UNITS[unit.strip().lower()]
        seconds = numbers.to_numpy(dtype=float) * scale
        step = float(np.median(np.diff(seconds))) if len(seconds) > 1 else float("nan")
        if fmt == "unix":
            return pd.Timestamp(round(seconds[0] * 1e9), tz="UTC"), step, seconds
        if layout.start_time is None:
            raise fail(
                f"holds relative times ({seconds[0]:g} to {seconds[-1]:g} s): give the start "
                f"time of the file{note}",
                header,
            )
        start = layout_start(layout, path) + pd.Timedelta(seconds=float(seconds[0]))
        return start, step, seconds
    text = values.astype(str).str.strip()
    times, used = parse_log_times(text, fmt)
    bad = times.isna().to_numpy()
    if bad.all() and fmt is None:
        raise fail(
            f"no known time format fits ({bad_time_values(text, bad)}; tried ISO-8601, "
            f"{', '.join(TIME_FORMATS)}, numbers); {time_format_hint(used)}",
            header,
        )
    if bad.any():
        rows = [f"row {r}" for r in np.nonzero(bad)[0][:5]]
        raise fail(
            f"not a time in the format {used}: {bad_time_values(text, bad)}",
            header,
            rows,
            int(bad.sum()),
        )
    if len(times) < 2:
        return times.iat[0], float("nan"), None
    seconds = (times - times.iat[0]).dt.total_seconds().to_numpy()
    return times.iat[0], float(np.median(np.diff(seconds))), seconds


def _check_steps(seconds: np.ndarray, rate: float | None, header: str, fail) -> None:
    """Refuse sample times that are not evenly spaced at the rate.

    The times must increase strictly (no shuffled or duplicated rows), every step must lie
    within half a sample interval of the nominal one (a gap inside a file would shift the
    later samples) and a given *rate* must agree with the median step.
    """
    steps = np.diff(seconds)
    if len(steps) == 0:
        return
    for mask, reason in (
        (steps == 0, "duplicate sample times"),
        (steps < 0, "times go backwards (rows out of order)"),
    ):
        rows = np.flatnonzero(mask) + 1
        if len(rows):
            raise fail(reason, header, [f"row {r}" for r in rows[:5]], len(rows))
    median = float(np.median(steps))
    if rate is not None and abs(median * rate - 1.0) > 1e-3:
        raise fail(
            f"time step {median:g} s contradicts the sampling rate {rate:g} Hz "
            f"(step {1 / rate:g} s)",
            header,
        )
    nominal = 1.0 / rate if rate is not None else median
    rows = np.flatnonzero(np.abs(steps / nominal - 1.0) > 0.5) + 1
    if len(rows):
        raise fail(
            f"uneven sampling: a step of {steps[rows[0] - 1]:g} s (interval {nominal:g} s) - a "
            "gap inside a file shifts the later samples; split the file at the gap",
            header,
            [f"row {r}" for r in rows[:5]],
            len(rows),
        )


def looks_like_acceleration_table(path: str | os.PathLike) -> bool:
    """Whether a text file found by a folder search is an acceleration record.

    Yes when its header has a time column (``time``, ``Timestamp``, ``Time [s]``, ...) or
    lines above the header state the start and the sampling rate, and it is neither a
    workbench table (``block``, ``case`` columns), a ship log (a ``/* ... */`` description
    block or predictor names such as ``Speed``, ``TTT``, ``SYS.STR.SOG``) nor unreadable.
    """
    from ..csv_layout import decode_text
    from ..dship_names import DSHIP_NAMES

    try:
        with open(path, "rb") as handle:
            raw = handle.read(65536)
        preamble = _preamble(path, None)
    except (OSError, ValueError):
        return False
    text = decode_text(raw, None)
    lines = text.splitlines()
    if text.lstrip().startswith("/*"):
        return False
    banner = preamble.stated
    header = lines[preamble.header_row] if preamble.header_row < len(lines) else ""
    sep = preamble.separator or sniff_separator(header)
    keys = {name_key(split_unit(f.strip().strip('"'))[0]) for f in header.split(sep)}
    if keys & {"block", "blockstart", "case", "mode"}:
        return False
    keys |= {k.rsplit(".", 1)[-1] for k in keys}  # DSHIP's DEVICE.SENSOR.PARAMETER
    if keys & {name_key(n) for names in DSHIP_NAMES.values() for n in names}:
        return False
    if {"start_time", "sampling_rate_hz"} <= set(banner):
        return True
    return any(_is_time_name(k) for k in keys)
