"""A ship log being written, read as it grows: only the lines appended since the last read.

The monitor reads its ``--dship`` log at every step that finds it changed. A 1-s log grows
by 86 400 lines a day, and reading it whole each time costs in proportion to the voyage
(``benchmarks/results/monitor_costs_52.txt``).
:class:`LiveShipLog` parses only the complete lines appended since its last read and gives
the table :func:`data_contracts.read_dship` (``complete_lines=True``) gives over the whole
file, with the same warnings. It reads the file whole again when the append may not give
that table:

* the file was replaced (another inode: rotated, or written anew under the same name) or
  is shorter than the part read (truncated);
* its first lines (the header and the first :data:`PREFIX_ROWS` readings, which fix the
  columns, units, decimal mark and time format) or the :data:`TAIL_CHECK` bytes before the
  end of the part read changed (rewritten in place; a change further back is not seen:
  a data system appends to its log);
* the new lines go back in time or repeat a time, give a value to a column empty so far,
  mix UTC offsets, make a column of numbers hold text, are not UTF-8 in a UTF-8 log, or
  fail the log's contract (the whole read then says where).

A last line without its line end (the data system writing it) is left for the next read.
A log shorter than the first :data:`PREFIX_ROWS` readings is read whole.

The rows appended are written into column buffers with room to grow (:class:`_GrowingTable`),
so a read costs what the new lines cost, not a copy of the whole table; each read hands
out a view of the rows so far, which later appends never change (pandas' copy-on-write
copies a column a reader writes to, never the buffers).
"""

from __future__ import annotations

import hashlib
import itertools
import os
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import ContractError, Violation
from data_contracts.dship import parse_dship

__all__ = ["PREFIX_ROWS", "TAIL_CHECK", "LiveShipLog"]

#: Readings of the log's start parsed with each append (the decimal mark is judged on the
#: first 50 rows, the header rows on the first 4). [rows]
PREFIX_ROWS = 60
#: Bytes before the end of the part read compared at each read (a log rewritten in place
#: is read whole again). [bytes]
TAIL_CHECK = 512
#: The log's start is looked for in its first bytes only (a longer description block: the
#: log is read whole each time). [bytes]
PREFIX_MAX_BYTES = 1 << 20
_LINE_END = re.compile(rb"\r\n|\r|\n")
#: Warnings of a parse whose text depends on rows beyond the log's start.
_ORDER_WARNINGS = ("time goes back", "duplicate time stamp", "mixes UTC offsets")
#: Read generations: a new one for every read of a whole log, in this process.
_GENERATIONS = itertools.count(1)


def _prefix_length(raw: bytes) -> int | None:
    """Bytes of *raw* through the line holding its :data:`PREFIX_ROWS`-th reading (after
    the ``/* ... */`` description block, the header line and up to three header rows);
    None when *raw* has fewer lines."""
    wanted = 4 + PREFIX_ROWS
    found = 0
    describing = None  # None: the first line not seen yet
    start = 0
    for match in _LINE_END.finditer(raw, 0, min(len(raw), PREFIX_MAX_BYTES)):
        line = raw[start : match.start()].strip()
        start = match.end()
        if describing is None:
            describing = line.removeprefix(b"\xef\xbb\xbf").startswith(b"/*")
            if describing:
                describing = not line.endswith(b"*/")
                continue
        elif describing:
            describing = not line.endswith(b"*/")
            continue
        if line:
            found += 1
            if found >= wanted:
                return start
    return None


#: Room a column buffer grows by when full: this fraction of the rows needed, at least
#: :data:`GROWTH_MIN_ROWS` (the copies of the table stay a fixed share of the rows appended).
GROWTH = 0.25
GROWTH_MIN_ROWS = 4096


class _GrowingTable:
    """A table grown by rows appended at its end, kept in column buffers with room to grow
    (each :attr:`GROWTH` of the rows needed when full): :meth:`append` writes the new rows
    in place, :attr:`frame` is a view of the rows so far (``iloc`` of a frame over the
    whole buffers, so pandas' copy-on-write protects the buffers from a reader writing to
    it; :meth:`view` gives each reader its own). For tables of NumPy and tz-aware datetime
    columns (:meth:`supports`)."""

    def __init__(self, frame: pd.DataFrame):
        self._attrs = dict(frame.attrs)
        self._columns = list(frame.columns)
        self.n = 0
        self._buffers: dict[str, object] = {}
        self._grow(frame, len(frame))
        self.frame = self.view()

    @staticmethod
    def supports(frame: pd.DataFrame) -> bool:
        return frame.columns.is_unique and all(
            isinstance(d, (np.dtype, pd.DatetimeTZDtype)) for d in frame.dtypes
        )

    def _grow(self, rows: pd.DataFrame, need: int) -> None:
        """New buffers for *need* rows and room to grow: the rows so far, then *rows*."""
        capacity = need + max(GROWTH_MIN_ROWS, int(GROWTH * need))
        buffers = {}
        for name in self._columns:
            dtype = rows[name].dtype
            if isinstance(dtype, pd.DatetimeTZDtype):  # NaT in the column's unit and zone
                buffer = pd.array(np.full(capacity, np.datetime64("NaT", dtype.unit)), dtype=dtype)
            else:
                buffer = np.empty(capacity, dtype=dtype)
            if self.n:
                buffer[: self.n] = self._buffers[name][: self.n]
            buffer[self.n : need] = _values(rows[name])
            buffers[name] = buffer
        self._buffers = buffers
        self._whole = pd.DataFrame(buffers, columns=self._columns, copy=False)
        self.n = need

    def view(self) -> pd.DataFrame:
        """A view of the rows so far, a new frame each call."""
        frame = self._whole.iloc[: self.n]
        frame.attrs = dict(self._attrs)
        return frame

    def append(self, rows: pd.DataFrame) -> pd.DataFrame:
        """The table with *rows* (the same columns and dtypes) added: :attr:`frame`."""
        need = self.n + len(rows)
        if need > len(self._whole):
            self._grow(rows, need)
        else:
            for name in self._columns:
                self._buffers[name][self.n : need] = _values(rows[name])
            self.n = need
        if rows.attrs != self._attrs:  # as pd.concat: the attributes all the parts share
            self._attrs = {}
        self.frame = self.view()
        return self.frame


def _values(column: pd.Series):
    """A column's values as its buffer takes them."""
    return column.array if isinstance(column.dtype, pd.DatetimeTZDtype) else column.to_numpy()


@dataclass
class _Read:
    """What the last read of the log found and needs for the next."""

    identity: tuple[int, int]  # (st_dev, st_ino)
    stamp: tuple[int, int]  # (st_size, st_mtime_ns) when read
    end: int  # bytes parsed: through the last line end
    prefix: bytes | None  # the log's start (None: too short, read whole)
    prefix_rows: int
    tail: bytes  # the TAIL_CHECK bytes before end
    utf8: bool
    frame: pd.DataFrame
    caught: list  # the warnings the whole file's read gives, in order
    empty: list[str]  # the columns without a value so far
    table: _GrowingTable | None = None  # the frame's buffers (None: grown by pd.concat)
    digest: object = None  # hashlib SHA-256 of the end bytes parsed


class LiveShipLog:
    """The ship log at *path* as :func:`~data_contracts.read_dship` reads it whole
    (``complete_lines=True``, *mapping*, *utc_offset*), each :meth:`read` parsing only the
    lines appended since the one before (see the module notes).

    Attributes
    ----------
    whole_reads, appended_reads : int
        Reads of the whole file and reads of its appended lines, so far.
    generation : int or None
        A number new at every read of the whole file (unique in the process): two tables
        read with the same generation are one the other's first rows. None before the
        first read and after a failed one.
    """

    def __init__(
        self, path: str | os.PathLike, mapping: Mapping | None = None, utc_offset: str | None = None
    ):
        self.path = Path(path)
        self.mapping = dict(mapping) if mapping else None
        self.utc_offset = utc_offset
        self._last: _Read | None = None
        self.whole_reads = 0
        self.appended_reads = 0
        self.generation: int | None = None

    @property
    def content(self) -> tuple[int, str] | None:
        """What the last read parsed: the bytes through its last line end and their SHA-256
        (hex); None before the first read and after a failed one. A log that only grew by
        appended lines starts with those bytes still (what
        :mod:`workbench.monitor.log_record` checks at a restart)."""
        if self._last is None:
            return None
        return self._last.end, self._last.digest.hexdigest()

    def _parse(self, raw: bytes, encoding: str | None = None) -> pd.DataFrame:
        return parse_dship(
            raw,
            source=str(self.path),
            mapping=self.mapping,
            complete_lines=True,
            utc_offset=self.utc_offset,
            encoding=encoding,
        )

    def read(self) -> pd.DataFrame:
        """The log's table now: the one read before when the file is unchanged (no
        warnings, as before), else with the whole read's warnings.

        Raises
        ------
        ContractError
            As :func:`~data_contracts.read_dship` (an unreadable file included).
        OSError
            The file is not there.
        """
        try:
            stat = os.stat(self.path)
        except OSError:
            self._last, self.generation = None, None
            raise
        last = self._last
        identity, stamp = (stat.st_dev, stat.st_ino), (stat.st_size, stat.st_mtime_ns)
        if last is not None and last.identity == identity and last.stamp == stamp:
            return last.frame if last.table is None else last.table.view()
        frame = None
        if last is not None and last.identity == identity and last.prefix is not None:
            frame = self._appended(last, stamp)
        if frame is None:
            frame = self._whole(identity, stamp)
        for caught in self._last.caught:
            warnings.warn(caught.message, stacklevel=2)
        # a view of its own for each reader: one writing to it changes no other's table
        return frame if self._last.table is None else self._last.table.view()

    def _whole(self, identity, stamp) -> pd.DataFrame:
        self._last, self.generation = None, None
        try:
            raw = self.path.read_bytes()
        except OSError as error:
            violation = Violation(None, f"cannot read file: {error.strerror or error}")
            raise ContractError([violation], source=str(self.path), contract="dship") from None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            frame = self._parse(raw)
        self.whole_reads += 1
        self.generation = next(_GENERATIONS)
        end = max(raw.rfind(b"\n"), raw.rfind(b"\r")) + 1
        try:
            raw[:end].decode("utf-8-sig")
            utf8 = True
        except UnicodeDecodeError:
            utf8 = False
        prefix_end = _prefix_length(raw[:end])
        prefix, prefix_rows = None, 0
        if prefix_end is not None:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    prefix_rows = len(self._parse(raw[:prefix_end], None if utf8 else "latin-1"))
                prefix = raw[:prefix_end]
            except ContractError:
                prefix = None
        table = None
        if prefix is not None and _GrowingTable.supports(frame):  # appended to from now on
            table = _GrowingTable(frame)
            frame = table.frame
        self._last = _Read(
            identity=identity,
            stamp=stamp,
            end=end,
            prefix=prefix,
            prefix_rows=prefix_rows,
            tail=raw[max(0, end - TAIL_CHECK) : end],
            utf8=utf8,
            frame=frame,
            caught=list(caught),
            empty=list(frame.columns[frame.isna().all().to_numpy()]) if len(frame) else [],
            table=table,
            digest=hashlib.sha256(raw[:end]),
        )
        return frame

    def _appended(self, last: _Read, stamp) -> pd.DataFrame | None:
        """The table with the lines appended since *last* (None: read whole instead)."""
        if stamp[0] < last.end:
            return None  # truncated
        try:
            with open(self.path, "rb") as file:
                if file.read(len(last.prefix)) != last.prefix:
                    return None
                file.seek(last.end - len(last.tail))
                new = file.read()
        except OSError:
            return None
        if not new.startswith(last.tail):
            return None  # rewritten in place
        new = new[len(last.tail) :]
        cut = max(new.rfind(b"\n"), new.rfind(b"\r")) + 1
        complete = new[:cut]
        frame = last.frame
        if complete.strip():
            frame = self._parse_appended(last, complete)
            if frame is None:
                return None
        self.appended_reads += 1
        end = last.end + cut
        tail = (last.tail + complete)[-TAIL_CHECK:]
        digest = last.digest.copy()
        digest.update(complete)
        self._last = _Read(
            identity=last.identity,
            stamp=stamp,
            end=end,
            prefix=last.prefix,
            prefix_rows=last.prefix_rows,
            tail=tail,
            utf8=last.utf8,
            frame=frame,
            caught=last.caught,
            empty=last.empty,
            table=last.table,
            digest=digest,
        )
        return frame

    def _parse_appended(self, last: _Read, complete: bytes) -> pd.DataFrame | None:
        """The table with the rows of *complete* (whole lines) added, parsed after the log's
        start; None when the whole file's read could differ."""
        if last.utf8:
            try:
                complete.decode("utf-8")
            except UnicodeDecodeError:
                return None  # the whole log is then read as Latin-1
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                parsed = self._parse(last.prefix + complete, None if last.utf8 else "latin-1")
        except (ContractError, ValueError):
            return None
        if any(any(w in str(c.message) for w in _ORDER_WARNINGS) for c in caught):
            return None
        before, n = last.frame, last.prefix_rows
        if list(parsed.columns) != list(before.columns) or not parsed.dtypes.equals(before.dtypes):
            return None  # a column found, or lost to text, by the new lines
        if len(parsed) <= n or len(before) < n:
            return None
        if not parsed.iloc[:n].equals(before.iloc[:n]):
            return None  # the log's start read otherwise with the new lines
        rows = parsed.iloc[n:]
        if len(before) and not rows["time"].iloc[0] > before["time"].iloc[-1]:
            return None
        if last.empty and rows[last.empty].notna().any().any():
            return None  # a column empty so far gets a value: the warnings change
        if last.table is not None:
            return last.table.append(rows)
        return pd.concat([before, rows], ignore_index=True)
