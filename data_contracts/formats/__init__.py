"""Acceleration files as acquisition systems and other tools write them.

:class:`AccelerationLayout` says what a file's headers do not: which column holds the
time and how it is written, the separator and decimal mark, the start time of a relative
time axis, the units, the MATLAB/HDF5 names. Every field has an automatic default, so a
file that states its layout (``Timestamp``, ``acc01 [m/s^2]``) needs none.

Readers, by suffix:

* ``.csv``, ``.tsv``, ``.txt`` — :func:`~data_contracts.formats.text.read_text_accelerations`
* ``.h5``, ``.hdf5`` — :func:`~data_contracts.formats.hdf5.read_hdf5_accelerations`
* ``.uff``, ``.unv`` (universal file, dataset 58) —
  :func:`~data_contracts.formats.uff.read_uff_accelerations` (needs ``pyuff``)
* ``.mat`` (v5 and v7.3) — :func:`data_contracts.accelerations.read_accelerations` with
  the variable names resolved by :func:`~data_contracts.formats.matlab.matlab_variables`.

Units are converted to m/s² (:data:`ACCELERATION_UNITS`): per file, per channel, or from the
headers (``acc01 [g]``). When a file cannot be read, the error lists what it does contain
(columns, variables, datasets).

Every reader follows two rules. A container file (HDF5, MATLAB v7.3, any future one) must
hold its own data: :mod:`~data_contracts.formats.containers` refuses external links,
external storage and virtual datasets before anything is read. No array is allocated
before its declared size is checked against the file and the memory budget
(:mod:`data_contracts.limits`, ``WORKBENCH_MAX_ARRAY_BYTES``).
"""

from __future__ import annotations

import logging
import math
import os
import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from .._core import ContractError, Violation

log = logging.getLogger("workbench")

__all__ = [
    "ACCELERATION_SUFFIXES",
    "ACCELERATION_UNITS",
    "STANDARD_GRAVITY_MS2",
    "AccelerationLayout",
    "acceleration_factor",
    "acceleration_files",
    "as_layout",
]

#: Standard acceleration of gravity (CGPM 1901; ISO 80000-3). [m/s²]
STANDARD_GRAVITY_MS2 = 9.80665

#: Factor from each unit (lower case, spaces removed) to m/s².
ACCELERATION_UNITS: dict[str, float] = {
    "m/s^2": 1.0,
    "m/s²": 1.0,
    "m/s2": 1.0,
    "m/s/s": 1.0,
    "ms^-2": 1.0,
    "ms-2": 1.0,
    "m*s^-2": 1.0,
    "mm/s^2": 1e-3,
    "mm/s²": 1e-3,
    "mm/s2": 1e-3,
    "cm/s^2": 1e-2,
    "cm/s²": 1e-2,
    "cm/s2": 1e-2,
    "gal": 1e-2,
    "g": STANDARD_GRAVITY_MS2,
    "g0": STANDARD_GRAVITY_MS2,
    "gn": STANDARD_GRAVITY_MS2,
    "mg": 1e-3 * STANDARD_GRAVITY_MS2,
    "µg": 1e-6 * STANDARD_GRAVITY_MS2,
    "ug": 1e-6 * STANDARD_GRAVITY_MS2,
    "ft/s^2": 0.3048,
    "ft/s²": 0.3048,
    "ft/s2": 0.3048,
    "in/s^2": 0.0254,
    "in/s2": 0.0254,
}

#: Suffixes of the acceleration files a folder search picks up.
ACCELERATION_SUFFIXES = (".npz", ".mat", ".csv", ".tsv", ".txt", ".h5", ".hdf5", ".uff", ".unv")


def acceleration_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """Files named by *inputs*: files as given, folders searched (with their subfolders)
    for acceleration files of every supported format (:data:`ACCELERATION_SUFFIXES`).

    Hidden files and text files without an acceleration header are left out.

    Raises
    ------
    FileNotFoundError
        For an input that does not exist, or when no file is found (one-line message).
    """
    from .text import TEXT_SUFFIXES, looks_like_acceleration_table

    found: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            # hidden files (e.g. ``.name.tmp.npz`` of an interrupted write) are not data
            candidates = sorted(
                p
                for p in path.rglob("*")
                if p.suffix.lower() in ACCELERATION_SUFFIXES
                and not any(part.startswith(".") for part in p.relative_to(path).parts)
                and p.is_file()
            )
            other = [
                p
                for p in candidates
                if p.suffix.lower() in TEXT_SUFFIXES and not looks_like_acceleration_table(p)
            ]
            if other:
                log.info(
                    "%s: %d text file(s) without an acceleration header left out (%s)",
                    path,
                    len(other),
                    ", ".join(p.name for p in other[:5]) + (", ..." if len(other) > 5 else ""),
                )
            found += [p for p in candidates if p not in set(other)]
        elif path.is_file():
            found.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such file or folder")
    if not found:
        raise FileNotFoundError("no acceleration files found in " + ", ".join(map(str, inputs)))
    return found


def acceleration_factor(unit: str, *, what: str = "unit") -> float:
    """Factor converting *unit* to m/s².

    Raises
    ------
    ValueError
        For a unit that is not an acceleration (the message lists the known ones).
    """
    key = re.sub(r"\s+", "", str(unit)).lower().replace("**", "^").replace("μ", "µ")
    if key not in ACCELERATION_UNITS:
        raise ValueError(
            f"{what} {unit!r} is not an acceleration unit (known: m/s^2, mm/s^2, cm/s^2, g, "
            "mg, gal, ft/s^2)"
        )
    return ACCELERATION_UNITS[key]


@dataclass(frozen=True)
class AccelerationLayout:
    """How to read acceleration files whose headers do not say everything.

    Attributes
    ----------
    time_column : str, optional
        Column (CSV) or variable/dataset (MATLAB/HDF5) of the sample times. Default: the
        first of ``time``, ``timestamp``, ``datetime``, ``date/time``, ``t`` present
        (case-insensitive, with or without a unit); none: every column is a channel and
        *start_time* and *sampling_rate_hz* are needed.
    time_format : str, optional
        Format of absolute times, in the time column and in a text start time (metadata
        lines, MATLAB ``t0``, HDF5 ``start_time``): ``strptime`` (``%d/%m/%Y %H:%M:%S``) or
        MATLAB ``datestr`` symbols (``dd-mmm-yyyy HH:MM:SS``); or ``"seconds"`` for times
        relative to *start_time* (the unit in the header, ``Time [ms]``, is honoured), or
        ``"unix"`` for seconds since 1970-01-01 UTC. Default: ISO-8601, ``yyyy/mm/dd
        HH:MM:SS``, ``dd.mm.yyyy HH:MM:SS``, ``dd-mmm-yyyy HH:MM:SS`` and slash dates whose
        values tell day and month apart; numbers are relative seconds when *start_time* is
        given (also with a date format: a numeric time column is relative).
    separator : str, optional
        Field separator of text files; default sniffed from the header line.
    decimal : {".", ","}, optional
        Decimal mark; default ``,`` when the separator is not ``,`` and numbers such as
        ``0,12`` occur.
    start_time : str, optional
        UTC time of the first sample (ISO-8601), for relative times or files without times;
        ``"filename"``: the time in each file's name (``acc_20261123T100000Z.csv``,
        ``rec_2026-11-23_10-00-00.csv``; UTC).
    sampling_rate_hz : float, optional
        Sampling rate; default from the file (header, variable or median time step). [Hz]
    units : str or mapping, optional
        Unit of every channel (``"g"``) or per channel (``{"acc03": "mm/s^2"}``); default
        from the headers, else m/s².
    channels : sequence of str, optional
        Only these columns/datasets are channels (others, e.g. a temperature, ignored).
    variables : mapping, optional
        MATLAB variable or HDF5 dataset names for ``acceleration``, ``sampling_rate_hz``,
        ``start_time``, ``channels`` and ``time``; default: the usual names (``data``,
        ``fs``, ``t0``, ``chanNames``, ...), when exactly one is present.
    orientation : {"auto", "samples_first", "channels_first"}
        Layout of a MATLAB/HDF5 matrix; ``auto`` takes the longer dimension as samples.
    file_starts : mapping, optional
        Per file (resolved path): the time that stands for *start_time* in that file. Set
        by :func:`workbench.identification.planning.follow_on_starts` when one start time
        is given for several files with relative times: the first file starts at it, the
        others follow on.
    """

    time_column: str | None = None
    time_format: str | None = None
    separator: str | None = None
    decimal: str | None = None
    start_time: str | None = None
    sampling_rate_hz: float | None = None
    units: str | Mapping[str, str] | None = None
    channels: tuple[str, ...] | None = None
    variables: Mapping[str, str] = field(default_factory=dict)
    orientation: Literal["auto", "samples_first", "channels_first"] = "auto"
    file_starts: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.orientation not in ("auto", "samples_first", "channels_first"):
            raise ValueError(
                f"orientation={self.orientation!r} must be auto, samples_first or channels_first"
            )
        if self.decimal not in (None, ".", ","):
            raise ValueError(f"decimal={self.decimal!r} must be '.' or ','")
        if self.sampling_rate_hz is not None:
            rate = float(self.sampling_rate_hz)
            if not math.isfinite(rate) or rate <= 0:
                raise ValueError(
                    f"sampling_rate_hz={self.sampling_rate_hz!r} must be a positive number"
                )
            object.__setattr__(self, "sampling_rate_hz", rate)
        if self.time_format not in (None, "seconds", "unix"):
            from ..dship_names import strptime_format

            strptime_format(self.time_format)  # ValueError naming time_format
        if self.start_time is not None and self.start_time != "filename":
            from ..dship_names import cut_iso_time

            if cut_iso_time(self.start_time):
                raise ValueError(f"start_time={self.start_time!r} is not a complete ISO-8601 time")
            try:
                stamp = pd.Timestamp(self.start_time)
                if pd.isna(stamp):
                    raise ValueError
            except (TypeError, ValueError):
                raise ValueError(f"start_time={self.start_time!r} is not a time") from None
        if isinstance(self.units, str):
            acceleration_factor(self.units, what="units")
        elif self.units is not None:
            units = dict(self.units)
            for channel, unit in units.items():
                acceleration_factor(unit, what=f"unit of {channel}")
            object.__setattr__(self, "units", units)
        if self.channels is not None:
            object.__setattr__(self, "channels", tuple(str(c) for c in self.channels))
        known = {"acceleration", "sampling_rate_hz", "start_time", "channels", "time", "units"}
        unknown = sorted(set(self.variables) - known)
        if unknown:
            raise ValueError(
                f"variables has unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
            )
        object.__setattr__(self, "variables", dict(self.variables))
        starts = {str(k): str(v) for k, v in dict(self.file_starts).items()}
        for name, value in starts.items():
            from ..dship_names import cut_iso_time

            if cut_iso_time(value) or pd.isna(pd.Timestamp(value)):
                raise ValueError(f"file_starts[{name!r}]={value!r} is not a time")
        object.__setattr__(self, "file_starts", starts)

    def to_dict(self) -> dict:
        """JSON-able form (stored with identification results)."""
        values = asdict(self)
        values["channels"] = list(self.channels) if self.channels else None
        return {k: v for k, v in values.items() if v not in (None, {}, "auto")}


def as_layout(layout: AccelerationLayout | Mapping | None, **overrides) -> AccelerationLayout:
    """*layout* (or a mapping of its fields) with the non-None *overrides* applied."""
    if layout is None:
        base = AccelerationLayout()
    elif isinstance(layout, AccelerationLayout):
        base = layout
    else:
        base = AccelerationLayout(**dict(layout))
    changes = {k: v for k, v in overrides.items() if v is not None}
    return replace(base, **changes) if changes else base


def convert_units(
    acceleration: np.ndarray,
    channels: Sequence[str],
    header_units: Sequence[str | None],
    layout: AccelerationLayout,
    source,
) -> np.ndarray:
    """Accelerations in m/s²: the layout's units first, then the file's own, else m/s²."""
    factors = np.ones(len(channels))
    problems = []
    per_channel = layout.units if isinstance(layout.units, Mapping) else {}
    unknown = sorted(set(per_channel) - set(channels))
    if unknown:
        problems.append(
            Violation(
                None,
                f"units given for channel(s) {', '.join(unknown)} not in the file "
                f"(channels: {', '.join(channels)})",
            )
        )
    for j, channel in enumerate(channels):
        unit = per_channel.get(channel)
        if unit is None and isinstance(layout.units, str):
            unit = layout.units
        if unit is None:
            unit = header_units[j] if j < len(header_units) else None
        if unit is None:
            continue
        try:
            factors[j] = acceleration_factor(unit, what=f"unit of {channel}")
        except ValueError as error:
            problems.append(Violation(channel, str(error)))
    if problems:
        raise ContractError(problems, source=source, contract="accelerations")
    if (factors != 1.0).any():
        acceleration = np.asarray(acceleration, dtype=float) * factors
    return acceleration


def warn_if_gravity_in_g(acceleration: np.ndarray, channels, stated: bool, source) -> None:
    """Warn when a channel without a stated unit looks like a DC-coupled sensor in g.

    A mean of 1 ± 0.03 with a standard deviation below 0.5 is gravity in g; in m/s² it
    would be 9.81. Only a hint: AC-coupled data in g cannot be told from m/s².
    """
    if stated or acceleration.size == 0:
        return
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(acceleration, axis=0)
        std = np.nanstd(acceleration, axis=0)
    suspect = [
        c
        for c, m, s in zip(channels, mean, std, strict=False)
        if abs(abs(m) - 1.0) < 0.03 and s < 0.5
    ]
    if suspect:
        warnings.warn(
            f"{source}: channel(s) {', '.join(suspect)} have a mean of about 1 like gravity "
            "in g, but no unit is stated; taken as m/s² (state the unit, e.g. g)",
            stacklevel=4,
        )


#: What a text file whose first line is one undelimited field is said to hold: that line
#: is not quoted (a file given by mistake, a key or a password, is not shown).
NO_DELIMITED_HEADER = "no delimited column names on its first line"


def describe(names: Sequence[str], what: str, limit: int = 30) -> str:
    """``"variables in the file: a, b, c"`` (at most *limit* names); for ``"columns"``, a
    single one is not quoted (:data:`NO_DELIMITED_HEADER`)."""
    if what == "columns" and len(names) == 1:
        return NO_DELIMITED_HEADER
    shown = list(names)[:limit]
    more = len(names) - len(shown)
    listed = ", ".join(shown) if shown else "none"
    return f"{what} in the file: {listed}" + (f" (+{more} more)" if more > 0 else "")


_NAME_TIME = re.compile(
    r"(\d{4})-?(\d\d)-?(\d\d)[T_ -]?(\d\d)[-:h]?(\d\d)[-:m]?(\d\d)(?:[.,](\d+))?"
)


def layout_start(layout: AccelerationLayout, path) -> pd.Timestamp | None:
    """The layout's start time for the file at *path* (UTC), or None when it gives none."""
    if layout.start_time is None:
        return None
    if layout.file_starts:
        given = layout.file_starts.get(str(Path(path).resolve()))
        if given is not None:
            stamp = pd.Timestamp(given)
            return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    if layout.start_time == "filename":
        match = _NAME_TIME.search(Path(path).stem)
        if match is None:
            raise ContractError(
                [Violation(None, "no time (yyyymmddTHHMMSS) in the file name for the start time")],
                source=path,
                contract="accelerations",
            )
        y, mo, d, h, mi, sec, frac = match.groups()
        stamp = pd.Timestamp(int(y), int(mo), int(d), int(h), int(mi), int(sec), tz="UTC")
        return stamp + pd.Timedelta(seconds=float(f"0.{frac}")) if frac else stamp
    stamp = pd.Timestamp(layout.start_time)
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def resolve_start(value, source, time_format: str | None = None) -> pd.Timestamp:
    """A start time from text, a MATLAB datenum, a MATLAB datevec or POSIX seconds.

    Numbers are told apart by size: a datenum of the years 1 to 2737 lies in
    [366, 1e6), POSIX seconds of the years 1973 to 2286 in [1e8, 1e10); a 6-vector is a
    datevec. Text is read in *time_format* (a ``strptime`` or MATLAB ``datestr`` format),
    else as ISO-8601, ``dd-mmm-yyyy HH:MM:SS`` (MATLAB's ``datestr``) or another
    recognised form (:func:`data_contracts.dship_names.parse_times`). Anything else is
    refused.
    """
    if isinstance(value, str):  # read back as text by the MATLAB reader
        try:
            value = float(value)
        except ValueError:
            return text_start(value, source, time_format)
    array = np.asarray(value)
    if array.dtype.kind in "fiu":
        flat = array.astype(float).ravel()
        if flat.size == 6:  # datevec [Y M D h m s]
            y, mo, d, h, mi, s = flat
            return pd.Timestamp(int(y), int(mo), int(d), int(h), int(mi), tz="UTC") + pd.Timedelta(
                seconds=float(s)
            )
        if flat.size == 1 and 366.0 <= flat[0] < 1.0e6:  # datenum: days from 0000-01-00
            days = flat[0] - 719529.0  # datenum of 1970-01-01
            return pd.Timestamp(round(days * 86400e9), tz="UTC")
        if flat.size == 1 and 1.0e8 <= flat[0] < 1.0e10:  # POSIX seconds (1973 to 2286)
            return pd.Timestamp(round(flat[0] * 1e9), tz="UTC")
        raise ContractError(
            [
                Violation(
                    "start_time",
                    f"the number {flat[:6].tolist()} is neither a MATLAB datenum nor a datevec; "
                    "give the start time",
                )
            ],
            source=source,
            contract="accelerations",
        )
    return value


def text_start(written: str, source, time_format: str | None = None) -> pd.Timestamp:
    """A start time written as text (UTC unless it states an offset).

    Raises
    ------
    ContractError
        Naming the value and how to state its format.
    """
    from ..dship_names import parse_log_times, time_format_hint

    fmt = time_format if time_format not in (None, "seconds", "unix") else None
    value = str(written).strip()
    times, used = parse_log_times(pd.Series([value]), fmt)
    if times.notna().all():
        return times.iat[0]
    what = f"not a time in the format {fmt}" if fmt else "not a recognised time"
    raise ContractError(
        [Violation("start_time", f"{value!r} is {what}; {time_format_hint(used)}")],
        source=source,
        contract="accelerations",
    )


def matlab_record(record, layout: AccelerationLayout, source):
    """A record read from MATLAB with its start time resolved (datenum, datevec or text),
    the layout's start time, rate, channels and units applied."""
    from ..accelerations import AccelerationRecord

    start = layout_start(layout, source)
    if start is None:
        start = resolve_start(record.start_time, source, layout.time_format)
    acceleration = np.asarray(record.acceleration, dtype=float)
    channels = list(record.channels)
    if layout.channels is not None:
        missing = [c for c in layout.channels if c not in channels]
        if missing:
            raise ContractError(
                [
                    Violation(
                        None, f"channel(s) {', '.join(missing)} not among {', '.join(channels)}"
                    )
                ],
                source=source,
                contract="accelerations",
            )
        acceleration = acceleration[:, [channels.index(c) for c in layout.channels]]
        channels = list(layout.channels)
    acceleration = convert_units(acceleration, channels, [None] * len(channels), layout, source)
    warn_if_gravity_in_g(acceleration, channels, layout.units is not None, source)
    return AccelerationRecord(
        acceleration,
        layout.sampling_rate_hz or record.sampling_rate_hz,
        start,
        tuple(channels),
    )


__all__ += [
    "convert_units",
    "describe",
    "layout_start",
    "matlab_record",
    "resolve_start",
    "text_start",
    "warn_if_gravity_in_g",
]

from . import hdf5, matlab, text, uff  # noqa: E402, F401  (they use the helpers above)
