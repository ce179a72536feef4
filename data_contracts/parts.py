"""Tables stored as parts of consecutive blocks: a folder written a part at a time.

The live monitor's tables grow with the voyage (one or more rows per block), and a table
written whole at every block costs more each block. A *parted table* is a folder named
like the table (``tracked.parquet/``) holding one Parquet file per ``part_blocks``
consecutive blocks (``part-000000.parquet`` holds the blocks 0 .. part_blocks - 1) and an
index, ``_parts.json``::

    {"schema": "workbench.parts/1", "contract": "modal", "part_blocks": 288,
     "parts": [{"key": 0, "file": "part-000000.parquet", "rows": 1152,
                "first_block": 0, "last_block": 287, "size": 81234, "mtime_ns": ...,
                "mode_blocks": {"1": 280, ...}}, ...]}

Rules that make it safe to read at any moment:

* the parts, concatenated in key order, are the table (sorted by block; the rows of a
  block are all in one part), so ``read_table(folder, contract)`` (and
  ``pandas.read_parquet(folder)``) give the table the batch commands write as one file;
* every part is replaced atomically (temporary name starting with ``.``, which readers
  skip, then rename): a part file is always whole, old or new;
* the files present are the table, not the index: a part written and the index not yet
  (a crash between the two) leaves a readable table; the index's summaries of a part
  (``rows``, ``mode_blocks``) are taken only when its ``size`` and ``mtime_ns`` still
  match the file, else computed from the file;
* a writer rewrites only the parts whose rows changed (:class:`PartWriter`), so the cost
  of an update is that of the newest part(s), whatever the voyage's length.

``schema`` is the format's version: a reader refuses an index of another version with a
one-line message (:func:`read_index`).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ._core import ContractError, TableContract, Violation, atomic_path

__all__ = [
    "INDEX_NAME",
    "PARTS_SCHEMA",
    "PartWriter",
    "is_parted",
    "part_files",
    "read_index",
    "read_parts",
    "read_since",
    "summarize",
    "unreadable_parts",
]

#: ``schema`` of ``_parts.json``: the version of the parted-table format.
PARTS_SCHEMA = "workbench.parts/1"
#: The index's name in the folder (``_`` first: Parquet dataset readers skip it).
INDEX_NAME = "_parts.json"
_PART = re.compile(r"^part-(\d{6,})\.parquet$")


def _part_name(key: int) -> str:
    return f"part-{int(key):06d}.parquet"


def is_parted(path: str | os.PathLike) -> bool:
    """Whether *path* is a parted table (a folder with its index)."""
    path = Path(path)
    return path.is_dir() and (path / INDEX_NAME).is_file()


def read_index(path: str | os.PathLike) -> dict:
    """The index of the parted table *path*.

    Raises
    ------
    ValueError
        One line naming the index: unreadable, or of another format version.
    """
    index = Path(path) / INDEX_NAME
    try:
        found = json.loads(index.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ValueError(f"{index}: unreadable ({str(error).splitlines()[0]})") from None
    if not isinstance(found, dict) or found.get("schema") != PARTS_SCHEMA:
        schema = found.get("schema") if isinstance(found, dict) else None
        raise ValueError(
            f"{index}: format {schema!r}, this workbench reads {PARTS_SCHEMA!r} (written by "
            "another version of workbench)"
        )
    part_blocks = found.get("part_blocks")
    if not isinstance(part_blocks, int) or part_blocks < 1:
        raise ValueError(f"{index}: part_blocks={part_blocks!r} must be a positive integer")
    if not isinstance(found.get("parts"), list):
        raise ValueError(f"{index}: no list of parts")
    return found


def part_files(path: str | os.PathLike) -> dict[int, Path]:
    """The part files of the parted table *path* by key, in key order (the files present,
    whatever the index says)."""
    found = {}
    for entry in os.scandir(path):
        match = _PART.match(entry.name)
        if match and entry.is_file():
            found[int(match.group(1))] = Path(entry.path)
    return dict(sorted(found.items()))


def read_parts(
    path: str | os.PathLike,
    contract: TableContract | None,
    *,
    columns: list[str] | None = None,
    since_block: int | None = None,
) -> pd.DataFrame:
    """The parted table *path* (its parts concatenated), validated against *contract*,
    with the block grid recorded in its newest part.

    Parameters
    ----------
    columns : list of str, optional
        Only these columns (those the parts have).
    since_block : int, optional
        Only the rows of blocks from this one on (only the parts holding them are read).

    Raises
    ------
    ContractError
        When the index or a part is unreadable or a part violates the contract (the
        message names the file).
    """
    from . import grid as _grid

    path = Path(path)
    name = contract.name if contract is not None else path.name
    try:
        index = read_index(path)
    except ValueError as error:
        raise ContractError([Violation(None, str(error))], source=path, contract=name) from None
    files = part_files(path)
    if since_block is not None:
        first_key = int(since_block) // index["part_blocks"]
        files = {k: f for k, f in files.items() if k >= first_key}
    frames = []
    for file in files.values():
        try:
            if columns is not None:
                import pyarrow.parquet as pq

                have = set(pq.read_schema(file).names)
                frame = pd.read_parquet(file, columns=[c for c in columns if c in have])
            else:
                frame = pd.read_parquet(file)
        except Exception as error:  # noqa: BLE001 - pyarrow raises many types for a bad file
            reason = f"cannot read PARQUET file: {str(error).splitlines()[0] if str(error) else type(error).__name__}"
            raise ContractError([Violation(None, reason)], source=file, contract=name) from None
        frames.append(frame)
    if frames:
        table = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    elif contract is not None:
        table = pd.DataFrame(
            columns=list(contract.column_names)
            if columns is None
            else [c for c in columns if c in contract.column_names]
        )
    else:
        table = pd.DataFrame(columns=columns or [])
    if since_block is not None and len(table):
        table = table[table["block"].to_numpy() >= int(since_block)].reset_index(drop=True)
    table.attrs.pop(_grid.GRID_ATTR, None)
    if contract is not None:
        table = contract.validate(table, source=path)
    if files:
        newest = list(files.values())[-1]
        table = _grid.attach_grid(table, _grid.read_grid(newest, "parquet"), path)
    return table


def read_since(path: str | os.PathLike, columns: list[str], since_block: int) -> pd.DataFrame:
    """*columns* of the rows from *since_block* on of the table *path*, a parted table
    (only the parts holding them are read) or one Parquet file; not validated (for a
    reader of tables a writer validated)."""
    path = Path(path)
    if is_parted(path):
        return read_parts(path, None, columns=columns, since_block=since_block)
    return pd.read_parquet(path, columns=columns, filters=[("block", ">=", int(since_block))])


def summarize(path: str | os.PathLike) -> dict:
    """The whole parted table *path* in a few numbers, from the index's summaries of its
    parts (computed from a part's file where its summary does not match the file: the
    part was written and the index not): ``first_block``, ``last_block`` (None without
    rows), ``rows``, ``blocks`` (blocks with rows) and ``mode_blocks`` (blocks per mode,
    of a ``mode`` column).

    Raises
    ------
    ValueError
        When the index or a part is unreadable (one line naming it).
    """
    path = Path(path)
    index = read_index(path)
    summaries = {int(p["key"]): p for p in index["parts"] if isinstance(p, dict) and "key" in p}
    total: dict[int, int] = {}
    first = last = None
    rows = blocks = 0
    for key, file in part_files(path).items():
        summary = summaries.get(key)
        stat = file.stat()
        if summary is None or (summary.get("size"), summary.get("mtime_ns")) != (
            stat.st_size,
            stat.st_mtime_ns,
        ):
            try:
                columns = [c for c in ("block", "mode") if c in _names(file)]
                summary = _summarize(pd.read_parquet(file, columns=columns))
            except Exception as error:  # noqa: BLE001 - pyarrow raises many types
                raise ValueError(f"{file}: unreadable ({str(error).splitlines()[0]})") from None
        for mode, n in summary.get("mode_blocks", {}).items():
            total[int(mode)] = total.get(int(mode), 0) + int(n)
        rows += int(summary["rows"])
        blocks += int(summary["blocks"])
        if summary["first_block"] is not None:
            first = summary["first_block"] if first is None else min(first, summary["first_block"])
            last = summary["last_block"] if last is None else max(last, summary["last_block"])
    return {
        "first_block": first,
        "last_block": last,
        "rows": rows,
        "blocks": blocks,
        "mode_blocks": dict(sorted(total.items())),
    }


def unreadable_parts(path: str | os.PathLike) -> dict[Path, str]:
    """The part files of the parted table *path* whose Parquet footer cannot be read (a
    file cut short by a crash or a full disk, or overwritten), each with the reason; ``{}``
    for a table that is not parted."""
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_dir():
        return {}
    found = {}
    for file in part_files(path).values():
        try:
            pq.read_metadata(file)
        except Exception as error:  # noqa: BLE001 - pyarrow raises many types for a bad file
            found[file] = str(error).splitlines()[0] if str(error) else type(error).__name__
    return found


def _names(file: Path) -> set[str]:
    import pyarrow.parquet as pq

    return set(pq.read_schema(file).names)


def _summarize(part: pd.DataFrame) -> dict:
    blocks = part["block"].to_numpy() if len(part) else np.array([], dtype=np.int64)
    return {
        "rows": int(len(part)),
        "blocks": int(np.unique(blocks).size),
        "first_block": int(blocks.min()) if blocks.size else None,
        "last_block": int(blocks.max()) if blocks.size else None,
        "mode_blocks": {str(m): n for m, n in _mode_blocks(part).items()},
    }


def _mode_blocks(frame: pd.DataFrame) -> dict[int, int]:
    if "mode" not in frame.columns or not len(frame):
        return {}
    counts = frame.groupby("mode")["block"].nunique()
    return {int(m): int(n) for m, n in counts.items()}


class PartWriter:
    """Writes a table into the parted table *path*, rewriting only the parts whose rows
    changed. The parts hold the rows in block order (a table not sorted by block, such as
    a forecast of several options, one after the other, is sorted by block, stable).

    Parameters
    ----------
    path : path
        The folder (created; a file of that name, an older state's whole table, is
        replaced).
    contract : TableContract, optional
        Each part is validated and written with it (``write_table``: the block grid in
        its metadata); None writes the frame as it is.
    part_blocks : int
        Consecutive blocks per part (a day's blocks for the monitor).
    """

    def __init__(
        self, path: str | os.PathLike, contract: TableContract | None, *, part_blocks: int
    ) -> None:
        if int(part_blocks) < 1:
            raise ValueError(f"part_blocks={part_blocks!r} must be at least 1")
        self.path = Path(path)
        self.contract = contract
        self.part_blocks = int(part_blocks)
        self._written: dict[int, pd.DataFrame] = {}  # the parts this writer wrote
        self._summaries: dict[int, dict] | None = None
        self._index_stale = False  # the index found does not match the parts
        self.rewritten: list[int] = []  # keys of the parts the last write replaced

    def _start(self) -> None:
        """Take up the folder as it is (another writer's parts are kept until rewritten)."""
        if self.path.is_file():  # a whole table of the former layout
            self.path.unlink()
        self.path.mkdir(parents=True, exist_ok=True)
        self._summaries = {}
        if (self.path / INDEX_NAME).is_file():
            try:
                index = read_index(self.path)
            except ValueError:
                index = None
            if index is not None and index["part_blocks"] == self.part_blocks:
                self._summaries = {int(p["key"]): p for p in index["parts"]}
            elif index is not None:  # parts of another size: rewrite them all
                for file in part_files(self.path).values():
                    file.unlink()
        files = part_files(self.path)
        kept = {}
        for key, file in files.items():  # a summary older than its part is made again
            summary = self._summaries.get(key)
            stat = file.stat()
            if summary is None or (summary.get("size"), summary.get("mtime_ns")) != (
                stat.st_size,
                stat.st_mtime_ns,
            ):
                summary = self._summary(key, file, None)
                self._index_stale = True
            kept[key] = summary
        if set(kept) != set(self._summaries):
            self._index_stale = True
        self._summaries = kept

    def _summary(self, key: int, file: Path, part: pd.DataFrame | None) -> dict:
        if part is None:
            part = pd.read_parquet(
                file, columns=[c for c in ("block", "mode") if c in _names(file)]
            )
        stat = file.stat()
        return {
            "key": int(key),
            "file": file.name,
            "size": int(stat.st_size),
            "mtime_ns": int(stat.st_mtime_ns),
            **_summarize(part),
        }

    def write(self, frame: pd.DataFrame, *, since_block: int | None = None) -> list[int]:
        """Write *frame*: the parts from the one holding *since_block*
        on are compared with what this writer wrote and replaced where they differ (all
        parts when *since_block* is None); the rows of the blocks before it are kept as
        they are (the caller says they did not change; *frame* may then start at
        *since_block*). Parts left without rows are removed. Returns the keys replaced.

        Raises
        ------
        ContractError
            When a part violates the contract (nothing after it is written).
        """
        from .tables import write_table

        if self._summaries is None:
            self._start()
        grid_attrs = dict(frame.attrs)  # the block grid, written with each part
        blocks = frame["block"].to_numpy(dtype=np.int64) if len(frame) else np.array([], int)
        if blocks.size and (np.diff(blocks) < 0).any():  # e.g. a forecast's options in turn
            order = np.argsort(blocks, kind="stable")
            frame, blocks = frame.iloc[order], blocks[order]
        first_key = 0 if since_block is None else max(int(since_block), 0) // self.part_blocks
        if since_block is not None:
            # the part holding since_block keeps its rows before it: the frame may start
            # at since_block
            since_block = max(int(since_block), 0)
            frame = frame.iloc[int(np.searchsorted(blocks, since_block)) :]
            blocks = blocks[blocks >= since_block]
            head = self._rows_before(first_key, since_block)
            if head is not None and len(head):
                frame = pd.concat([head, frame], ignore_index=True) if len(frame) else head
                blocks = frame["block"].to_numpy(dtype=np.int64)
        keys = blocks // self.part_blocks
        new_keys = np.unique(keys[keys >= first_key]).tolist()
        if not blocks.size and since_block is None:
            new_keys = [0]  # an empty part keeps the columns and their types
        bounds = (
            np.searchsorted(keys, new_keys, side="left"),
            np.searchsorted(keys, new_keys, side="right"),
        )
        rewritten = []
        for key, lo, hi in zip(new_keys, *bounds, strict=True):
            part = frame.iloc[lo:hi].reset_index(drop=True)
            part.attrs.update(grid_attrs)
            old = self._written.get(key)
            file = self.path / _part_name(key)
            if old is not None and file.is_file() and old.equals(part):
                continue
            if self.contract is not None:
                write_table(part, file, self.contract)
            else:
                with atomic_path(file) as tmp:
                    part.to_parquet(tmp, index=False)
            self._written[key] = part
            self._summaries[key] = self._summary(key, file, part)
            rewritten.append(int(key))
        gone = [k for k in self._summaries if k >= first_key and k not in set(new_keys)]
        for key in gone:
            (self.path / _part_name(key)).unlink(missing_ok=True)
            self._summaries.pop(key, None)
            self._written.pop(key, None)
            rewritten.append(int(key))
        if rewritten or self._index_stale or not (self.path / INDEX_NAME).is_file():
            self._write_index()
            self._index_stale = False
        self.rewritten = sorted(rewritten)
        return self.rewritten

    def _rows_before(self, key: int, block: int) -> pd.DataFrame | None:
        """The rows of part *key* before *block*, as this writer wrote them (else as its
        file holds them; None without such a part)."""
        old = self._written.get(key)
        file = self.path / _part_name(key)
        if old is None:
            if not file.is_file():
                return None
            old = pd.read_parquet(file)
            self._written[key] = old
        stop = int(np.searchsorted(old["block"].to_numpy(dtype=np.int64), block))
        return old.iloc[:stop]

    def _write_index(self) -> None:
        index = {
            "schema": PARTS_SCHEMA,
            "contract": self.contract.name if self.contract is not None else None,
            "part_blocks": self.part_blocks,
            "parts": [self._summaries[k] for k in sorted(self._summaries)],
        }
        with atomic_path(self.path / INDEX_NAME) as tmp:
            tmp.write_text(json.dumps(index, indent=0), encoding="utf-8")
