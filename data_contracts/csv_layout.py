"""Delimited text as other tools write it: separator, decimal mark, units in the header.

Shared by the readers of user files (modal tables, CSV accelerations): the separator is
sniffed from the header line (``,``, ``;``, tab or ``|``), a decimal comma is recognised when
the separator is not a comma, and header names carry their unit in brackets or parentheses
(``acc01 [m/s^2]``, ``Damping (%)``).
"""

from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path

import pandas as pd

from ._core import CSV_READ_OPTIONS

__all__ = ["ends_mid_row", "read_delimited", "sniff_layout", "sniff_separator", "split_unit"]

_NAME_UNIT = re.compile(r"^\s*(?P<name>.*?)\s*[\[(](?P<unit>[^\])]*)[\])]\s*$")
_DECIMAL_COMMA = re.compile(r"(^|;)\s*[+-]?\d+,\d+\s*(?=$|;)", re.MULTILINE)


def split_unit(header: str) -> tuple[str, str | None]:
    """``"acc01 [m/s^2]"`` -> ``("acc01", "m/s^2")``; ``"Damping (%)"`` -> ``("Damping", "%")``."""
    match = _NAME_UNIT.match(str(header))
    if match and match["name"]:
        return match["name"], match["unit"].strip()
    return str(header).strip(), None


def decode_text(raw: bytes, encoding: str | None) -> str:
    """*raw* decoded with *encoding*; without one, UTF-8 (a byte-order mark dropped), else
    Latin-1, which every byte sequence is (exported ship logs are often Windows-1252)."""
    if encoding:
        return raw.decode(encoding)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def sniff_separator(header_line: str) -> str:
    """The most frequent of ``,``, ``;``, tab and ``|`` in *header_line* (``,`` if none)."""
    counts = {sep: header_line.count(sep) for sep in (",", ";", "\t", "|")}
    best = max(counts, key=lambda sep: counts[sep])
    return best if counts[best] else ","


def sniff_layout(
    lines: list[str], *, separator: str | None = None, decimal: str | None = None
) -> tuple[str, str]:
    """Separator and decimal mark of the table in *lines* (header first): the separator
    :func:`sniff_separator` finds in the header line, the decimal mark ``,`` when the
    separator is not a comma and the first lines hold numbers such as ``12,5``, else
    ``.``; a given *separator* or *decimal* is kept."""
    header = next((line for line in lines if line.strip()), "")
    sep = separator or sniff_separator(header)
    if decimal is None:
        sample = "\n".join(lines[1:50])
        decimal = "," if sep != "," and _DECIMAL_COMMA.search(sample.replace(sep, ";")) else "."
    return sep, decimal


def _field_count(line: str, sep: str) -> int:
    if '"' not in line:
        return line.count(sep) + 1
    try:
        return len(next(csv.reader([line], delimiter=sep)))
    except (csv.Error, StopIteration):
        return line.count(sep) + 1


def ends_mid_row(lines: list[str], sep: str, first_line: int = 1) -> str | None:
    """Why the table in *lines* (header first; *first_line* its line number in the file)
    ends mid-row, or None: its last non-empty line has fewer fields than the header, as a
    file cut short (a copy interrupted, a disk full, a file still being written) does.
    pandas would read the missing fields as NaN and the cut number as a valid one."""
    header = next((k for k, line in enumerate(lines) if line.strip()), None)
    last = next((k for k in range(len(lines) - 1, -1, -1) if lines[k].strip()), None)
    if header is None or last is None or last == header:
        return None
    expected = _field_count(lines[header], sep)
    found = _field_count(lines[last], sep)
    if found >= expected:
        return None
    return (
        f"line {first_line + last}: {found} of the header's {expected} fields: the file ends "
        "mid-row (cut short or still being written)"
    )


def read_delimited(
    path: str | os.PathLike,
    *,
    separator: str | None = None,
    decimal: str | None = None,
    encoding: str | None = None,
    skip_rows: int = 0,
    skip_after_header: int = 0,
    dtype=None,
) -> tuple[pd.DataFrame, str, str]:
    """Read a delimited text table; return it with the separator and decimal mark used.

    Parameters
    ----------
    path : path-like
    separator : str, optional
        Default: sniffed from the header line (:func:`sniff_separator`).
    decimal : {".", ","}, optional
        Default: ``,`` when the separator is not a comma and the first lines hold numbers
        such as ``12,5``, else ``.``.
    encoding : str, optional
        Default UTF-8 (with or without BOM), falling back to latin-1.
    skip_rows : int
        Lines before the header line (e.g. a tool's banner).
    skip_after_header : int
        Lines between the header line and the data (e.g. a row of units).
    dtype : optional
        Passed to :func:`pandas.read_csv` (``str`` keeps the text of every cell).

    Raises
    ------
    OSError, UnicodeDecodeError, pandas.errors.ParserError
        For files that cannot be read; the callers turn them into contract errors.
    ValueError
        When the file ends mid-row (:func:`ends_mid_row`), naming the line.
    """
    text = decode_text(Path(path).read_bytes(), encoding)
    lines = text.splitlines()
    body = lines[skip_rows:]
    if skip_after_header and body:
        body = body[:1] + body[1 + skip_after_header :]
    sep, decimal = sniff_layout(body, separator=separator, decimal=decimal)
    cut = ends_mid_row(body, sep, skip_rows + 1)
    if cut is not None:
        raise ValueError(cut)
    frame = pd.read_csv(
        io.StringIO("\n".join(body)),
        sep=sep,
        decimal=decimal,
        skipinitialspace=True,
        dtype=dtype,
        **({} if dtype is str else CSV_READ_OPTIONS),
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    return frame, sep, decimal
