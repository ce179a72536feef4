"""Ship-log vocabulary: the usual DSHIP names of the predictors, time formats, relative wind.

DSHIP (the data system of German research vessels such as Polarstern, Meteor and Sonne)
names its channels ``DEVICE.SENSOR.PARAMETER`` (``SYS.STR.SOG``, ``SYS.STR.HDG``,
``Weatherstation.PEWDS.Air_temperature``). :data:`DSHIP_NAMES` lists, for every canonical
predictor and for the auxiliary channels needed to derive the relative wind, the full names
and the bare parameter names the reader recognises. A bare name matches the last part of a
dotted name, so ``Air_temperature`` finds ``Weatherstation.PEWDS.Air_temperature`` whatever
the device is called on a given ship; when two columns match, the reader refuses to choose
and asks for a mapping.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

__all__ = [
    "AUXILIARY_COLUMNS",
    "DSHIP_NAMES",
    "DATESTR_FORMATS",
    "SLASH_FORMATS",
    "SHAFT_COLUMNS",
    "TIME_FORMATS",
    "bad_time_values",
    "complete_times",
    "cut_iso_time",
    "parse_column_mapping",
    "parse_log_times",
    "parse_times",
    "parse_utc_offset",
    "format_utc_offset",
    "strptime_format",
    "time_format_hint",
    "relative_wind",
]

#: Knots per metre per second (1 kn = 1852 m / 3600 s).
KNOT_PER_MS = 3600.0 / 1852.0

#: Names tried for each column, in order (case, spaces and underscores ignored:
#: ``Air temperature`` matches ``AirTemperature`` and ``Air_temperature``; with or without
#: the bracketed unit; a bare parameter name also matches the last part of a dotted DSHIP
#: name).
DSHIP_NAMES: dict[str, tuple[str, ...]] = {
    "speed_kn": (
        "Speed",
        "SYS.STR.SOG",
        "SOG",
        "Speed over ground",
        "Speed through water",
        "STW",
        "Ship speed",
    ),
    "water_temp_c": ("Temp", "Water temp", "Water temperature", "SST", "Tw", "Temp water"),
    "air_temp_c": ("TTT", "Air temp", "Air temperature", "TT", "Ta"),
    "wind_speed_ms": (
        "ff",
        "Wind speed",
        "Wind speed true",
        "Wind speed rel",
        "Rel wind speed",
    ),
    "wind_dir_rel_deg": (
        "RelWindDir",
        "Rel wind dir",
        "Relative wind direction",
        "dd rel",
        "Wind direction relative",
        "Wind direction rel",
        "Wind dir rel",
    ),
    # Auxiliary channels: used to derive the relative wind when none is logged.
    "wind_dir_true_deg": (
        "dd",
        "Wind direction",
        "Wind direction true",
        "Wind dir true",
        "True wind dir",
        "True wind direction",
    ),
    "wind_speed_true_ms": ("Wind speed true", "True wind speed", "ff true"),
    "heading_deg": ("SYS.STR.HDG", "HDG", "Heading", "HDT", "True heading"),
    "course_deg": ("SYS.STR.COG", "COG", "SYS.STR.Course", "Course", "Course over ground"),
    # Optional predictors (data_contracts.tables.OPTIONAL_PREDICTORS)
    "fuel_on_board_t": (
        "Fuel on board",
        "FOB",
        "Fuel ROB",
        "Fuel remaining on board",
        "Fuel remaining",
        "Fuel total",
        "Bunker ROB",
    ),
    # Shaft speed: read when logged (harmonic orders of identify), not a predictor itself.
    "shaft_rpm": (
        "Shaft speed",
        "Shaft rpm",
        "ShaftRPM",
        "Shaft revolutions",
        "Shaft1 rpm",
        "Propeller rpm",
        "Propeller speed",
        "Prop rpm",
        "PropRPM",
        "SYS.PROP.RPM",
        "SYS.ENG.ShaftRPM",
        "Main engine rpm",
        "ME rpm",
    ),
}

#: Columns read only to derive the relative wind (not predictors themselves).
AUXILIARY_COLUMNS = ("wind_dir_true_deg", "wind_speed_true_ms", "heading_deg", "course_deg")

#: MATLAB's ``datestr`` forms (``14-May-2024 08:00:00``): the month's name makes them
#: unambiguous (English month abbreviations).
DATESTR_FORMATS = (
    "%d-%b-%Y %H:%M:%S.%f",
    "%d-%b-%Y %H:%M:%S",
    "%d-%b-%Y %H:%M",
    "%d-%b-%Y",
)
#: Columns kept in the canonical log when the ship log carries them, but not predictors:
#: the shaft speed gives the frequencies of the shaft and blade-pass orders
#: (:mod:`workbench.sid.harmonics`). [rpm]
SHAFT_COLUMNS = ("shaft_rpm",)

#: Time formats recognised without being told, tried after ISO-8601. Only unambiguous ones:
#: ``dd.mm.yyyy`` is day-first by convention and MATLAB's ``dd-mmm-yyyy`` names the month;
#: ``dd/mm/yyyy`` and ``mm/dd/yyyy`` (:data:`SLASH_FORMATS`) are taken only when the values
#: tell them apart (a day above 12), else the format must be stated (``time_format``).
TIME_FORMATS = (
    "%Y/%m/%d %H:%M:%S.%f",
    "%Y/%m/%d %H:%M:%S",
    "%Y/%m/%d %H:%M",
    "%d.%m.%Y %H:%M:%S.%f",
    "%d.%m.%Y %H:%M:%S",
    "%d.%m.%Y %H:%M",
    *DATESTR_FORMATS,
)

#: Day-first and month-first slash dates, in pairs.
SLASH_FORMATS = tuple(
    (f"%d/%m/%Y{clock}", f"%m/%d/%Y{clock}") for clock in (" %H:%M:%S.%f", " %H:%M:%S", " %H:%M")
)

_RECOGNISED = frozenset([*TIME_FORMATS, *(f for pair in SLASH_FORMATS for f in pair)])

#: MATLAB ``datestr``/``datetime`` format symbols and their ``strptime`` equivalents,
#: longest first (``mm`` is the month, ``MM`` the minutes, as in MATLAB).
_MATLAB_SYMBOLS = (
    ("yyyy", "%Y"),
    ("mmmm", "%B"),
    ("mmm", "%b"),
    ("FFF", "%f"),
    ("yy", "%y"),
    ("mm", "%m"),
    ("dd", "%d"),
    ("HH", "%H"),
    ("MM", "%M"),
    ("SS", "%S"),
    ("PM", "%p"),
    ("AM", "%p"),
)


#: A complete ISO-8601 time: a date (``yyyy-mm-dd`` or ``yyyymmdd``; ``yyyy/mm/dd`` too,
#: which pandas' ISO-8601 parser reads) alone or with a time of at least hours and minutes
#: (``T`` or a space), seconds and their fraction optional, then ``Z`` or an offset
#: (``+hh``, ``+hhmm``, ``+hh:mm``). Every field has all its digits: pandas reads
#: ``T00:1`` as 00:01 and ``2026-03`` as the first of March. The hour alone may be
#: unpadded (``T0:10``): minutes follow it, so it is not a field cut short.
ISO_TIME = re.compile(
    r"[+-]?\d{4}(?:-\d{2}-|/\d{2}/)\d{2}(?:[T ]\d{1,2}:\d{2}(?::\d{2}(?:[.,]\d+)?)?"
    r"(?:\s?(?:Z|[+-]\d{2}(?::?\d{2})?))?)?"
    r"|[+-]?\d{8}(?:T\d{4}(?:\d{2}(?:[.,]\d+)?)?(?:Z|[+-]\d{2}(?:\d{2})?)?)?"
)

#: The text each ``strptime`` directive of the recognised formats must match in full
#: (``strptime`` itself takes ``%M`` from one digit: ``00:5:00`` is read as 00:05). A
#: day, month or hour followed by another field may be unpadded (:data:`_UNPADDED`).
_DIRECTIVE_TEXT = {
    "Y": r"\d{4}",
    "y": r"\d{2}",
    "m": r"\d{2}",
    "d": r"\d{2}",
    "H": r"\d{2}",
    "M": r"\d{2}",
    "S": r"\d{2}",
    "f": r"\d+",
    "b": r"[^\W\d_]{3}",
}


#: Directives a spreadsheet writes without padding (``1/3/2026 0:05``): one or two digits
#: where another field follows, so that a line cut short is still told from an unpadded
#: one (a cut removes the last field's digits: ``1/3/2026 0:0`` is refused).
_UNPADDED = {"d": r"\d{1,2}", "m": r"\d{1,2}", "H": r"\d{1,2}"}


def _format_text(fmt: str) -> re.Pattern:
    """What a whole time text of the ``strptime`` format *fmt* (one of the recognised
    formats, whose directives are those of :data:`_DIRECTIVE_TEXT`) looks like."""
    parts = [part for part in re.split(r"(%.|\s+)", fmt) if part]
    last = max(i for i, part in enumerate(parts) if part.startswith("%"))

    def text(i: int, part: str) -> str:
        if part.startswith("%"):
            if i < last and part[1] in _UNPADDED:
                return _UNPADDED[part[1]]
            return _DIRECTIVE_TEXT[part[1]]
        return r"\s+" if part.isspace() else re.escape(part)

    return re.compile("".join(text(i, part) for i, part in enumerate(parts)))


def complete_times(text: pd.Series, fmt: str) -> np.ndarray:
    """Where *text* (stripped) is a whole time of *fmt*: ``ISO8601`` (:data:`ISO_TIME`)
    or one of the recognised formats (:data:`TIME_FORMATS`, :data:`SLASH_FORMATS`), each
    field with all its digits. Other formats (a user's own) are taken as ``strptime``
    reads them: True everywhere."""
    if fmt == "ISO8601":
        pattern = ISO_TIME.pattern
    elif fmt in _RECOGNISED:
        pattern = _format_text(fmt).pattern
    else:
        return np.ones(len(text), dtype=bool)
    import pyarrow as pa  # Arrow's regex: 5x pandas' .str.fullmatch on a 1-s log
    import pyarrow.compute as pc

    values = pc.utf8_trim_whitespace(pa.array(text.astype(str)))
    found = pc.match_substring_regex(values, f"^(?:{pattern})$")
    return pc.fill_null(found, False).to_numpy(zero_copy_only=False).astype(bool)


def cut_iso_time(value) -> bool:
    """Whether *value* is text that begins as an ISO-8601 date (``yyyy-m``) but is no
    complete ISO-8601 time (:data:`ISO_TIME`): a start time or grid origin that
    :class:`pandas.Timestamp` would read as another time (``2026-03-01T00:1`` as 00:01)."""
    if not isinstance(value, str):
        return False
    text = value.strip()
    return bool(re.match(r"[+-]?\d{4}-\d", text)) and not ISO_TIME.fullmatch(text)


def strptime_format(time_format: str) -> str:
    """*time_format* as a ``strptime`` format pandas understands.

    ``strptime`` formats (``%d/%m/%Y %H:%M:%S``) pass unchanged, ``ISO8601`` too; MATLAB
    ``datestr`` formats (``dd/mm/yyyy HH:MM:SS``, ``dd-mmm-yyyy HH:MM:SS.FFF``) are
    translated.

    Raises
    ------
    ValueError
        For a format with neither ``%`` directives nor MATLAB symbols.
    """
    text = str(time_format).strip()
    if "%" in text:
        return text
    if text.lower() in ("iso8601", "iso-8601", "iso"):
        return "ISO8601"
    out, i = "", 0
    while i < len(text):
        for symbol, directive in _MATLAB_SYMBOLS:
            if text.startswith(symbol, i):
                out += directive
                i += len(symbol)
                break
        else:
            out += text[i]
            i += 1
    if "%" not in out:
        raise ValueError(
            f"time_format={time_format!r} is neither a strptime format (%d/%m/%Y %H:%M:%S) "
            "nor a MATLAB datestr format (dd/mm/yyyy HH:MM:SS)"
        )
    return out


def parse_times(
    text: pd.Series, time_format: str | None = None, *, utc: bool = True
) -> tuple[pd.Series, str]:
    """Times of *text* and the format used (``"ambiguous"``: day- or month-first).

    With *time_format* (``strptime`` or MATLAB ``datestr`` symbols, see
    :func:`strptime_format`) only that format is used. Without one, ISO-8601 and
    :data:`TIME_FORMATS` are tried, then the slash dates of :data:`SLASH_FORMATS` when
    exactly one reading of the pair fits every value; the format that parses most cells
    wins. *utc*: times without an offset are UTC (else they stay naive). Unparseable
    cells are NaT, and so are those of ISO-8601 or a recognised format missing a digit of
    a field (:func:`complete_times`).
    """
    text = text.astype(str).str.strip()

    def parse(fmt: str) -> pd.Series:
        times = pd.to_datetime(text, utc=utc, errors="coerce", format=fmt)
        parsed = times.notna().to_numpy()
        if not parsed.any():
            return times
        whole = complete_times(text if parsed.all() else text[parsed], fmt)
        if whole.all():
            return times
        cut = np.zeros(len(times), dtype=bool)  # T00:1 is not 00:01
        cut[np.flatnonzero(parsed)[~whole]] = True
        return times.mask(cut)

    if time_format is not None:
        fmt = strptime_format(time_format)
        return parse(fmt), fmt
    best = parse("ISO8601")
    best_format = "ISO8601"
    if best.notna().all() or not len(text):
        return best, best_format
    for fmt in TIME_FORMATS:
        times = parse(fmt)
        if times.notna().sum() > best.notna().sum():
            best, best_format = times, fmt
            if best.notna().all():  # none can parse more
                break
    if best.notna().all():
        return best, best_format
    for day_first, month_first in SLASH_FORMATS:
        days, months = parse(day_first), parse(month_first)
        n_days, n_months = int(days.notna().sum()), int(months.notna().sum())
        if max(n_days, n_months) <= best.notna().sum():
            continue
        if n_days == n_months:  # no day above 12: cannot tell
            best, best_format = days.where(days.isna()), "ambiguous"
        elif n_days > n_months:
            best, best_format = days, day_first
        else:
            best, best_format = months, month_first
    return best, best_format


def parse_log_times(text: pd.Series, time_format: str | None = None) -> tuple[pd.Series, str]:
    """UTC times of *text* and the format used (:func:`parse_times`; times without an
    offset are UTC: ship data systems log UTC)."""
    return parse_times(text, time_format, utc=True)


#: A UTC offset as the user gives it: ``+02:00``, ``-0530``, ``UTC-05:30``, ``+2``, ``Z``.
_UTC_OFFSET = re.compile(
    r"^(?:(?P<zulu>Z|UTC)|(?:UTC)?(?P<sign>[+-])(?P<hours>\d{1,2})(?::?(?P<minutes>\d\d))?)$"
)
#: The offsets of the world's clocks (UTC-12:00 to UTC+14:00). [h]
UTC_OFFSET_RANGE_H = (-12.0, 14.0)


def parse_utc_offset(text: str) -> pd.Timedelta:
    """The UTC offset *text* (``+02:00``, ``-05:30``, ``UTC-05:30``, ``+0200``, ``+2``, ``Z``
    or ``UTC``)
    as a signed duration: local time minus UTC.

    Raises
    ------
    ValueError
        Not such an offset, minutes of 60 or more, or beyond UTC-12:00..UTC+14:00.
    """
    found = _UTC_OFFSET.match(str(text).strip().upper())
    if found is None:
        raise ValueError(
            f"not a UTC offset: {text!r}; give a sign and hours[:minutes], e.g. +02:00 or -05:30"
        )
    if found["zulu"]:
        return pd.Timedelta(0)
    hours, minutes = int(found["hours"]), int(found["minutes"] or 0)
    if minutes >= 60:
        raise ValueError(f"not a UTC offset: {text!r}; minutes must be below 60")
    offset = (hours + minutes / 60.0) * (-1.0 if found["sign"] == "-" else 1.0)
    low, high = UTC_OFFSET_RANGE_H
    if not low <= offset <= high:
        raise ValueError(
            f"UTC offset {text!r} is beyond the world's clocks (UTC{low:+03.0f}:00 to "
            f"UTC{high:+03.0f}:00)"
        )
    return pd.Timedelta(hours=hours, minutes=minutes) * (-1 if found["sign"] == "-" else 1)


def format_utc_offset(offset: pd.Timedelta) -> str:
    """*offset* as ``+02:00`` / ``-05:30``."""
    minutes = int(round(offset.total_seconds() / 60.0))
    sign = "-" if minutes < 0 else "+"
    return f"{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def bad_time_values(text: pd.Series, bad, limit: int = 3) -> str:
    """The distinct values of *text* where *bad*, each once: ``'14/05/2024 08:10:00'
    (5 rows)`` or ``'a', 'b' (+2 more values; 9 rows)``."""
    values = pd.unique(text[np.asarray(bad)].astype(str))
    n_rows = int(np.asarray(bad).sum())
    shown = ", ".join(repr(v) for v in values[:limit])
    more = len(values) - limit
    rows = f"{n_rows} row" + ("s" if n_rows != 1 else "")
    return shown + (f" (+{more} more values; {rows})" if more > 0 else f" ({rows})")


def time_format_hint(fmt: str) -> str:
    """What to do when times do not parse (*fmt*: the format used or ``ambiguous``)."""
    if fmt == "ambiguous":
        return (
            "dd/mm/yyyy or mm/dd/yyyy: no day above 12 tells them apart; give the time "
            "format, e.g. --time-format %d/%m/%Y %H:%M:%S"
        )
    return "give the time format, e.g. --time-format %d/%m/%Y %H:%M:%S or dd-mmm-yyyy HH:MM:SS"


def parse_column_mapping(text: str | Sequence[str]) -> dict[str, str]:
    """``"speed_kn=SYS.STR.SOG,air_temp_c=TT"`` (or a list of such) as a dict.

    Raises
    ------
    ValueError
        For an entry without ``=`` or with an empty side.
    """
    items = [text] if isinstance(text, str) else list(text)
    mapping: dict[str, str] = {}
    for item in items:
        for entry in re.split(r",(?![^\[]*\])", item):  # no split inside [unit]
            if not entry.strip():
                continue
            key, sep, value = entry.partition("=")
            if not sep or not key.strip() or not value.strip():
                raise ValueError(f"column mapping entry {entry!r} is not COLUMN=SOURCE_NAME")
            mapping[key.strip()] = value.strip()
    return mapping


def relative_wind(
    true_direction_deg: np.ndarray,
    true_speed_ms: np.ndarray,
    heading_deg: np.ndarray,
    course_deg: np.ndarray,
    ship_speed_kn: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Relative (apparent) wind on board from the true wind and the ship's motion.

    Parameters
    ----------
    true_direction_deg : array
        Direction the true wind blows *from*, clockwise from north. [deg]
    true_speed_ms : array
        True wind speed. [m/s]
    heading_deg : array
        Direction the bow points to, clockwise from north. [deg]
    course_deg : array
        Direction of the ship's motion over ground, clockwise from north. [deg]
    ship_speed_kn : array
        Ship speed along *course_deg*. [kn]

    Returns
    -------
    direction_rel_deg, speed_ms : arrays
        Direction the apparent wind comes from, clockwise from the bow, in [0, 360)
        (0 = head wind, 90 = from starboard) [deg]; apparent wind speed [m/s].

    Notes
    -----
    With east/north components, the true wind moves the air by
    :math:`w = -V_t(\\sin\\theta_t, \\cos\\theta_t)`, the ship moves by
    :math:`s = V_s(\\sin C, \\cos C)`; the air relative to the ship moves by
    :math:`a = w - s`. It comes from :math:`\\theta_a = \\operatorname{atan2}(-a_e, -a_n)`
    and, relative to the bow, from :math:`(\\theta_a - H) \\bmod 360`: the
    meteorological "from" convention for both the true and the relative wind, which is
    what a ship's anemometer reports as relative wind.
    """
    theta = np.deg2rad(np.asarray(true_direction_deg, dtype=float))
    course = np.deg2rad(np.asarray(course_deg, dtype=float))
    speed_ship_ms = np.asarray(ship_speed_kn, dtype=float) / KNOT_PER_MS
    wind_e = -np.asarray(true_speed_ms, dtype=float) * np.sin(theta)
    wind_n = -np.asarray(true_speed_ms, dtype=float) * np.cos(theta)
    air_e = wind_e - speed_ship_ms * np.sin(course)
    air_n = wind_n - speed_ship_ms * np.cos(course)
    speed = np.hypot(air_e, air_n)
    from_deg = np.rad2deg(np.arctan2(-air_e, -air_n))
    relative = np.mod(from_deg - np.asarray(heading_deg, dtype=float), 360.0)
    relative = np.where(relative >= 360.0, 0.0, relative)  # -1e-15 mod 360 rounds to 360
    return relative, speed


def name_key(name: str) -> str:
    """Comparison key of a column name: lower case, without spaces and underscores."""
    return re.sub(r"[\s_]+", "", name).lower()


def resolve_mapping(
    mapping: Mapping[str, str | Sequence[str]] | None, known: Sequence[str]
) -> dict[str, tuple[str, ...]]:
    """The built-in names with the user's entries in place of the defaults.

    A built-in column is also found under its canonical name (``speed_kn``, ``shaft_rpm``):
    a log written with the project's own names needs no mapping. It is tried last, after
    the ship's names; a user's entry replaces it too.

    Raises
    ------
    ValueError
        For a canonical name that does not exist.
    """
    unknown = sorted(set(mapping or {}) - set(known))
    if unknown:
        raise ValueError(
            f"mapping has unknown column(s) {', '.join(unknown)}; known: {', '.join(known)}"
        )
    return {
        k: (v,) if isinstance(v, str) else tuple(v)
        for k, v in {
            **{name: (*names, name) for name, names in DSHIP_NAMES.items()},
            **(mapping or {}),
        }.items()
    }
