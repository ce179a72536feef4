"""CSV/TSV acceleration files: a time column (absolute or relative) and one column per
channel, units in the headers (``acc01 [m/s^2]``) or stated by the user."""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from .._core import ContractError, Violation
from ..limits import check_channel_count
from ..csv_layout import read_delimited, split_unit
from ..dship_names import TIME_FORMATS, name_key, parse_log_times
from . import AccelerationLayout, convert_units, describe, layout_start, warn_if_gravity_in_g

__all__ = ["TEXT_SUFFIXES", "read_text_accelerations"]

TEXT_SUFFIXES = (".csv", ".tsv", ".txt")

_TIME_NAMES = ("time", "timestamp", "datetime", "date/time", "datetimeutc", "timeutc", "t", "zeit")
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

    n_banner, banner = _banner(path, layout.separator)
    _check_width(path, n_banner, layout.separator)
    if banner:
        changes = {}
        if layout.start_time is None and "start_time" in banner:
            changes["start_time"] = banner["start_time"]
        if layout.sampling_rate_hz is None and "sampling_rate_hz" in banner:
            changes["sampling_rate_hz"] = banner["sampling_rate_hz"]
        layout = replace(layout, **changes)
    frame, _, _ = read_delimited(
        path, separator=layout.separator, decimal=layout.decimal, skip_rows=n_banner
    )
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
            raise fail(f"no time column: give the start time and the sampling rate ({found})")
        start = given
    else:
        start, step, seconds = _times(
            path, frame.iloc[:, time_index], headers[time_index], units[time_index], layout, fail
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
_BANNER_START = {
    "starttime",
    "start",
    "recordingstart",
    "t0",
    "starttimeutc",
    "datetime",
    "trigger",
}
_NUMBER = re.compile(r"[+-]?\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?")


def _banner(path, separator: str | None) -> tuple[int, dict]:
    """Lines above the header (an acquisition system's metadata) and what they state.

    The header is the first line whose field count the next lines share; ``key: value``
    (or ``key = value``, ``key;value``) lines above it give the start time (``Start time``,
    ``Recording start``, ``t0``) and the sampling rate (``Sample rate``, ``Sampling
    frequency``, ``fs``) when the layout does not.
    """
    from ..csv_layout import sniff_separator

    with open(path, "rb") as handle:
        head = handle.read(65536).decode("utf-8", "replace")
    lines = head.splitlines()[:60]
    start = 0
    for i, line in enumerate(lines):
        sep = separator or sniff_separator(line)
        n = line.count(sep)
        following = [x for x in lines[i + 1 : i + 4] if x.strip()][:2]
        if n and following and all(x.count(sep) == n for x in following):
            start = i
            break
    found: dict = {}
    for line in lines[:start]:
        parts = re.split(r"\s*[:=;\t]\s*", line.strip().lstrip("#%").strip(), maxsplit=1)
        if len(parts) != 2 or not parts[1]:
            continue
        key = name_key(split_unit(parts[0])[0])
        value = parts[1].strip().strip('"')
        if key in _BANNER_RATE and (number := _NUMBER.search(value)):
            rate = float(number.group(0).replace(",", "."))
            unit = value[number.end() :].strip().lower()
            found["sampling_rate_hz"] = rate * 1000 if unit.startswith("khz") else rate
        elif key in _BANNER_START:
            times, _ = parse_log_times(pd.Series([value]))
            if times.notna().all():
                found["start_time"] = times.iat[0].isoformat()
    return start, found


def _times(path, values: pd.Series, header: str, unit: str | None, layout, fail):
    """Start time, median step [s] and the times [s] of a time column."""
    fmt = layout.time_format
    numbers = pd.to_numeric(values, errors="coerce")
    is_numeric = numbers.notna().all() and len(numbers) > 0
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
                "time of the file",
                header,
            )
        start = layout_start(layout, path) + pd.Timedelta(seconds=float(seconds[0]))
        return start, step, seconds
    text = values.astype(str).str.strip()
    times, used = parse_log_times(text, fmt)
    bad = times.isna().to_numpy()
    if bad.all():
        raise fail(
            f"no known time format fits (first value {text.iat[0]!r}; tried ISO-8601, "
            f"{', '.join(TIME_FORMATS)}, numbers); give the time format",
            header,
        )
    if bad.any():
        rows = [f"row {r}" for r in np.nonzero(bad)[0][:5]]
        raise fail(f"not a time in the format {used}", header, rows, int(bad.sum()))
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
    from ..csv_layout import sniff_separator
    from ..dship_names import DSHIP_NAMES

    try:
        with open(path, "rb") as handle:
            raw = handle.read(65536)
        n_banner, banner = _banner(path, None)
    except (OSError, ValueError):
        return False
    text = raw.decode("utf-8", "replace")
    lines = text.splitlines()
    if text.lstrip().startswith("/*"):
        return False
    header = lines[n_banner] if n_banner < len(lines) else ""
    keys = {name_key(split_unit(f)[0]) for f in header.split(sniff_separator(header))}
    if keys & {"block", "blockstart", "case", "mode"}:
        return False
    keys |= {k.rsplit(".", 1)[-1] for k in keys}  # DSHIP's DEVICE.SENSOR.PARAMETER
    if keys & {name_key(n) for names in DSHIP_NAMES.values() for n in names}:
        return False
    if {"start_time", "sampling_rate_hz"} <= set(banner):
        return True
    return bool(keys & set(_TIME_NAMES))
