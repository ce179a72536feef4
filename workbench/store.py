"""A resumable, crash-safe store of per-block results: Parquet datasets partitioned by day.

Layout under the store root::

    <root>/store.json                      parameters the results were computed with
    <root>/inputs.jsonl                    fingerprints of the input files (see below)
    <root>/lock                            who is running on the store now (see below)
    <root>/manifest.jsonl                  size and SHA-256 of every batch file (see below)
    <root>/<kind>/day=YYYY-MM-DD/<batch>.parquet

``kind`` is a result family (``poles``, ``selected``, ``moments``, ``faults``, ...). Results
arrive in *batches*: one batch writes one Parquet file per kind and day, and finally its
``blocks`` file, which lists the blocks it completed (status ``ok`` or ``skipped`` with a
reason). A block counts as done only once its batch's line is in the manifest (below), and
every file is written to a temporary name and renamed, so killing the process at any moment
leaves either a whole batch or files that :meth:`BlockStore.open` removes as orphans. Any
Parquet engine reads a kind as a hive-partitioned dataset (``pd.read_parquet(root /
"poles")``).

The store checks its own files. ``<root>/manifest.jsonl`` holds one line per batch, appended
(and flushed to disk) once all the batch's files are written: for every file its path, size,
SHA-256 and the blocks it holds. The line commits the batch. :meth:`BlockStore.open` checks
every file against it: a file missing, truncated or with other content (overwritten with
another file, renamed away) takes the blocks it held out of the store - the batch is
rewritten without them, so they are computed again - and a file the manifest does not
list (a killed write, a file renamed or copied in) is removed. Each finding is one line in
:attr:`BlockStore.notices` naming the file and the blocks; nothing damaged is ever read.

One run at a time: :meth:`BlockStore.open` takes an exclusive lock (``<root>/lock``, an
``flock`` held for the life of the store object, with the holder's pid, host and start
time written inside). A second run on the same store is refused with a message naming the
holder; the lock of a dead process is released by the kernel, so a killed run never
blocks the next one.

Inputs are fingerprinted (:meth:`BlockStore.check_inputs`): size, modification time and a
SHA-256 of the content of every input file, with the time span it covers, a line of
``<root>/inputs.jsonl`` each (appended and flushed to disk as files are taken; a line cut
short by a killed run is left out and the file written again whole, as are the rare
changes: inputs forgotten, the unreadable files). A store whose index is the
``inputs.json`` of earlier versions (one JSON object written whole for each file) has it
converted when opened. A resumed run
whose file for a stored time span has other content is refused, so results of one voyage
are never exported as those of another. Content that cannot be read whole (a file
damaged on disk after a run read it) is no other voyage's data: the caller records it
flagged (:meth:`BlockStore.record_damaged`), keeping the content read before and the
blocks computed from it. Inputs recorded but no longer given are found by
:meth:`BlockStore.removed_inputs`; the caller drops the blocks that depended on them
(:meth:`BlockStore.drop_blocks`, :meth:`BlockStore.forget_inputs`) or keeps them.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shlex
import socket
import time
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from stat import S_ISREG

import numpy as np
import pandas as pd

from data_contracts import atomic_path

from .errors import WorkbenchError

__all__ = [
    "BLOCKS_KIND",
    "CUT_COLUMNS",
    "UNREADABLE_COLUMN",
    "BlockStore",
    "StoreDamaged",
    "block_ranges",
    "move_aside",
    "unreadable_store_file",
]

#: The kind whose files mark blocks as done.
BLOCKS_KIND = "blocks"
#: Column of the ``blocks`` kind naming the input files (resolved paths, one a line) a
#: skipped block could not read; written only by batches holding such a block.
UNREADABLE_COLUMN = "unreadable_input"
#: Columns of the ``blocks`` kind holding where a drifting record's block was cut
#: (``PlannedBlock.sample_start``, on the record's clock line): the input file its first
#: sample is counted from (by content: its SHA-256, as the input index knows it, wherever
#: it lies now) and that sample's index in the file (from the file's first sample; the
#: placed times of a record's files change when a late file re-places them, its samples do
#: not), so a later run can tell when the line of the files given then cuts the block
#: elsewhere; written only by batches holding such a block (empty for the others: cut at
#: their labels).
CUT_COLUMNS = ("cut_sha256", "cut_sample")
_CONFIG = "store.json"
_INPUTS = "inputs.jsonl"
#: The input index of earlier versions (one object, written whole), converted when opened.
_INPUTS_WHOLE = "inputs.json"
_LOCK = "lock"
_MANIFEST = "manifest.jsonl"

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows: pid-based lock only
    fcntl = None

#: Locks this process holds, by store path: {path: [fd, count]} (re-entrant in-process).
_HELD: dict[str, list] = {}


#: Overlap of two files' spans that is only rounding of their end times or the recorder's
#: clock jitter: a file is re-timed by up to CLOCK_JITTER_S (50 ms,
#: :mod:`workbench.signals.block_plan`) to its predecessor's end, and runs over other
#: neighbours may place two files up to twice that apart. A changed file overlaps its
#: recorded span by nearly its whole length. [ns]
_SPAN_TOLERANCE_NS = 100_000_000


#: A recorded file placed no further than this from its recorded span is where it was: a
#: placed start given back from a stamp and a shift in seconds may be 1 ns off. [ns]
_MOVED_NS = 1_000


def _moved(old: Mapping, now: Mapping, by: str) -> dict:
    """What :meth:`BlockStore.check_inputs` says of a recorded file (*old*) placed elsewhere
    now (*now*), found through the file at *by*."""
    return {
        "path": old["path"],
        "start": old["start"],
        "end": old["end"],
        "now_start": now["start"],
        "now_end": now["end"],
        "by": by,
    }


def _file_version(path: Path) -> tuple[int, int, int] | None:
    """(inode, size, modification time [ns]) of the regular file *path*, None if there is
    none: a file rewritten (atomically: a new inode) has another version."""
    try:
        stat = path.stat()
    except OSError:
        return None
    if not S_ISREG(stat.st_mode):
        return None
    return (stat.st_ino, stat.st_size, stat.st_mtime_ns)


def _ns(times) -> np.ndarray:
    """ISO times as int64 nanoseconds since the epoch (UTC)."""
    if not len(times):
        return np.empty(0, np.int64)
    return (
        pd.DatetimeIndex(pd.to_datetime(list(times), utc=True, format="ISO8601")).as_unit("ns").asi8
    )


class StoreDamaged(WorkbenchError):
    """A file of the store itself (its configuration, input index or manifest) cannot be
    read: no block can be added or trusted until the store is repaired or replaced."""


#: How to go on from an unreadable file of the store, keeping the blocks computed: its
#: parameters and its input index are recorded anew from the run once moved aside (the
#: run must be the one that computed the blocks: the store cannot tell any more); a batch
#: file moved aside is missing, so only its blocks are computed again.
_RECOVERY = {
    _CONFIG: "and run again with the options that computed the blocks (the store "
    "records this run's)",
    _INPUTS: "and run again on the input files the blocks were computed from (they are "
    "fingerprinted anew)",
    _INPUTS_WHOLE: "and run again on the input files the blocks were computed from (they are "
    "fingerprinted anew)",
}


def move_aside(path: Path) -> str:
    """The shell command that moves the damaged file *path* aside (to ``.damaged``)."""
    return f"mv {shlex.quote(str(path))} {shlex.quote(f'{path}.damaged')}"


def unreadable_store_file(root: Path, what: str, error: BaseException) -> StoreDamaged:
    """The error of the unreadable store file *what* (relative to *root*), naming the
    recovery that keeps the computed blocks."""
    detail = str(error).splitlines()[0] if str(error) else type(error).__name__
    path = root / what
    if what == _MANIFEST:  # moved aside, every batch file would be unlisted: removed
        recovery = "make it readable and run again (the blocks it lists are kept)"
    else:
        done = _RECOVERY.get(what, "and run again: only its blocks are computed again")
        recovery = (
            f"to keep the computed blocks, move it aside ({move_aside(path)}) {done}; "
            "else use another --store"
        )
    return StoreDamaged(f"{root}: {what} is unreadable ({detail}); {recovery}")


def block_ranges(blocks: Iterable[int]) -> str:
    """Block numbers as ranges: ``[0, 1, 2, 5, 7, 8]`` -> ``"0-2, 5, 7-8"``."""
    numbers = sorted({int(b) for b in blocks})
    parts: list[str] = []
    k = 0
    while k < len(numbers):
        j = k
        while j + 1 < len(numbers) and numbers[j + 1] == numbers[j] + 1:
            j += 1
        parts.append(str(numbers[k]) if j == k else f"{numbers[k]}-{numbers[j]}")
        k = j + 1
    return ", ".join(parts)


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _file_digest(path: Path) -> str:
    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class StoreLock:
    """An exclusive, re-entrant (within one process) lock on a store folder.

    The lock file records ``pid``, ``host`` and ``started`` (UTC) of the holder. With
    ``fcntl`` the lock is an ``flock`` on that file, so it dies with its process; without
    it the file's existence is the lock and a lock of a dead process on this host is taken
    over.
    """

    def __init__(self, root: Path):
        self.root = Path(root)
        self.path = self.root / _LOCK
        self._key = str(self.path.resolve())
        self._held = False

    def holder(self) -> str:
        """``pid N on HOST since TIME`` from the lock file, or ``an unknown process``."""
        try:
            info = json.loads(self.path.read_text(encoding="utf-8"))
            return f"pid {int(info['pid'])} on {info['host']} since {info['started']}"
        except (OSError, ValueError, KeyError, TypeError):
            return "an unknown process"

    def _refuse(self) -> WorkbenchError:
        return WorkbenchError(
            f"{self.root}: store is in use by another run ({self.holder()}); wait for it to "
            "finish or use another --store"
        )

    def _info(self) -> bytes:
        started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        return json.dumps(
            {"pid": os.getpid(), "host": socket.gethostname(), "started": started}
        ).encode()

    def acquire(self) -> StoreLock:
        held = _HELD.get(self._key)
        if held is not None:
            held[1] += 1
            self._held = True
            return self
        fd = self._acquire_flock() if fcntl is not None else self._acquire_file()
        _HELD[self._key] = [fd, 1]
        self._held = True
        return self

    def _acquire_flock(self) -> int:
        for _ in range(10):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise self._refuse() from None
            try:  # the file may have been unlinked by a releasing holder meanwhile
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, self._info())
                os.fsync(fd)
                return fd
            os.close(fd)
        raise self._refuse()

    def _acquire_file(self) -> int:  # pragma: no cover - platforms without fcntl
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                try:
                    info = json.loads(self.path.read_text(encoding="utf-8"))
                    stale = info["host"] == socket.gethostname() and not _pid_alive(
                        int(info["pid"])
                    )
                except (OSError, ValueError, KeyError, TypeError):
                    stale = False
                if not stale:
                    raise self._refuse() from None
                self.path.unlink(missing_ok=True)
                continue
            os.write(fd, self._info())
            return fd
        raise self._refuse()

    def release(self) -> None:
        if not self._held:
            return
        self._held = False
        held = _HELD.get(self._key)
        if held is None:
            return
        held[1] -= 1
        if held[1] > 0:
            return
        del _HELD[self._key]
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(held[0])  # closing the descriptor releases the flock


@dataclass
class BlockStore:
    """Per-block results of one job, on disk.

    Use :meth:`open`, which locks the store, creates it or checks that an existing one was
    made with the same parameters (so a resumed job never mixes results of different
    settings). :meth:`close` (or leaving a ``with`` block) releases the lock.
    """

    root: Path
    lock: StoreLock | None = None
    #: What :meth:`open` found wrong with the store's files and did about it, one line each.
    notices: list[str] = field(default_factory=list)
    _owners_cache: dict | None = field(default=None, repr=False, compare=False)
    #: The manifest: batch -> relative path -> ``{"size", "sha256", "blocks"}``.
    _manifest: dict[str, dict[str, dict]] = field(default_factory=dict, repr=False, compare=False)
    #: inputs.jsonl as :meth:`check_inputs` last read or wrote it: the file's version
    #: (inode, size, mtime), the recorded fingerprints, the unreadable files, the recorded
    #: contents, their spans [ns] and whether a cut line ends the file; a monitor checks
    #: every landed file, and a long voyage's fingerprints are not parsed again for each
    _inputs_cache: tuple | None = field(default=None, repr=False, compare=False)

    def close(self) -> None:
        """Release the store's lock (results stay on disk)."""
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def __enter__(self) -> BlockStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # pragma: no cover - interpreter shutdown
            pass

    @classmethod
    def open(cls, root: str | os.PathLike, parameters: Mapping[str, object]) -> BlockStore:
        """Open (or create) the store at *root* for a job with *parameters*.

        Raises
        ------
        WorkbenchError
            If another run holds the store, the store exists and was made with other
            parameters, or its files are damaged.
        """
        root = Path(root)
        if root.exists() and not root.is_dir():
            raise WorkbenchError(f"{root}: store path is a file, not a folder")
        root.mkdir(parents=True, exist_ok=True)
        lock = StoreLock(root).acquire()
        try:
            return cls._open_locked(root, parameters, lock)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def _open_locked(cls, root: Path, parameters: Mapping[str, object], lock) -> BlockStore:
        config_path = root / _CONFIG
        wanted = json.loads(json.dumps(dict(parameters), sort_keys=True, default=str))
        had_config = config_path.is_file()
        if had_config:
            try:
                found = json.loads(config_path.read_text(encoding="utf-8"))
                if not isinstance(found, dict):
                    raise ValueError("not a JSON object")
            except (OSError, ValueError) as error:
                raise unreadable_store_file(root, _CONFIG, error) from None
            if found != wanted:
                changed = sorted(
                    k for k in set(found) | set(wanted) if found.get(k) != wanted.get(k)
                )
                raise WorkbenchError(
                    f"{root}: store was made with other parameters ({', '.join(changed)}); "
                    "use another --store directory or delete this one"
                )
        store = cls(root, lock)
        store._open_inputs()
        store._check_files()
        if store._manifest:
            store._note_lost_index(had_config, wanted)
        if not had_config:
            with atomic_path(config_path) as tmp:
                tmp.write_text(json.dumps(wanted, indent=2, sort_keys=True), encoding="utf-8")
        return store

    def _note_lost_index(self, had_config: bool, wanted: Mapping[str, object]) -> None:
        """Say so when blocks are stored but the parameters or the input index that
        vouched for them are absent (the index: moved aside as :func:`unreadable_store_file`
        tells; a store used without inputs has none): what the store takes on trust from
        this run. Blocks off this run's grid are refused."""
        inputs = self.root / _INPUTS
        lost_inputs = not inputs.is_file() and any(
            (self.root / f"{name}.damaged").is_file() for name in (_INPUTS, _INPUTS_WHOLE)
        )
        if had_config and not lost_inputs:
            return
        blocks = self.completed_blocks()
        if not had_config:
            stored = self.read(BLOCKS_KIND)
            if "grid_t0" in wanted and "step_s" in wanted and "adaptive" not in wanted:
                expected = pd.Timestamp(str(wanted["grid_t0"])) + pd.to_timedelta(
                    stored["block"].astype(int) * float(wanted["step_s"]), unit="s"
                )
                off = stored["block"][
                    pd.to_datetime(stored["block_start"], utc=True).to_numpy()
                    != expected.to_numpy()
                ]
                if len(off):
                    raise WorkbenchError(
                        f"{self.root}: stored block(s) {block_ranges(off)} are not on this "
                        f"run's grid (t0 {wanted['grid_t0']}, a block every "
                        f"{float(wanted['step_s']):g} s): they were computed with other "
                        "options; use another --store"
                    )
            self.notices.append(
                f"{self.root}: {_CONFIG} was absent: the {len(blocks)} stored block(s) "
                f"{block_ranges(blocks)} are taken as computed with this run's parameters "
                "(recorded now)"
            )
        if lost_inputs:
            self.notices.append(
                f"{self.root}: {_INPUTS} was absent: the input files of the {len(blocks)} "
                f"stored block(s) {block_ranges(blocks)} are recorded as they are now, "
                "unchecked against those the blocks were computed from"
            )

    # ------------------------------------------------------------------ inputs
    def check_inputs(
        self,
        fingerprints: Iterable[Mapping[str, object]],
        *,
        placed_now: Callable[[Mapping[str, object]], Mapping[str, object] | None] | None = None,
        every_span: bool = False,
    ) -> list[dict]:
        """Check the input files against those the stored results came from, then record them.

        Each fingerprint has ``path``, ``start``, ``end`` (ISO times of the span it covers),
        ``size``, ``mtime_ns`` and ``sha256``. A file whose content is already recorded is
        the same data (wherever it lies now); a file with new content whose span overlaps a
        recorded file's span is a *changed* input: the stored results of that span came
        from other data - unless that recorded content is still given, only placed
        elsewhere now (a late file among a record's files re-places them: a drifting
        clock's line, or a run joined over a filled gap, moves the files after it by up to
        the clock's walk, 150 ms after 25 min at 100 ppm), away from the new file: its
        recorded span is then moved to where it lies now.

        Parameters
        ----------
        fingerprints : iterable of mapping
            This run's files, as placed.
        placed_now : callable, optional
            Given a recorded fingerprint (its ``path``) clashing with a new file, the
            fingerprint of the file at that path as this run places it now, or None when
            the run has no such file. The run's own *fingerprints* are looked up first (by
            content).
        every_span : bool
            Whether every recorded file among *fingerprints* placed elsewhere now is moved
            (and returned), not only those overlapping a new file (*fingerprints* are then
            all of a run's files: a rerun redoes the blocks they moved under).

        Returns
        -------
        list of dict
            The recorded files moved so: ``path``, ``start`` and ``end`` recorded before,
            ``start`` and ``end`` now (``now_start``, ``now_end``), and ``by`` (the new
            file whose span they overlapped, or the file itself with *every_span*).

        Raises
        ------
        WorkbenchError
            Naming the changed file, when the stored results cannot be reused.
        """
        path = self.root / _INPUTS
        version = _file_version(path)
        cache = self._inputs_cache
        if version is not None and cache is not None and cache[0] == version:
            recorded, unreadable, known, lows, highs, cut = cache[1:]
        elif version is not None:
            recorded, unreadable, cut = self._read_inputs()
            known = {r["sha256"] for r in recorded}
            try:
                lows = _ns([r["start"] for r in recorded])
                highs = _ns([r["end"] for r in recorded])
            except (ValueError, TypeError) as error:
                raise unreadable_store_file(self.root, _INPUTS, error) from None
        else:
            recorded, unreadable, cut = [], [], False
            known, lows, highs = set(), np.empty(0, np.int64), np.empty(0, np.int64)
        fingerprints = [dict(item) for item in fingerprints]
        given = {item["sha256"]: item for item in fingerprints}
        new: list = []
        added: set[str] = set()
        moved: list[dict] = []
        if every_span and recorded:
            where = {r["sha256"]: k for k, r in enumerate(recorded) if not r.get("damaged")}
            for item in fingerprints:
                index = where.get(item["sha256"])
                if index is None:
                    continue
                old = recorded[index]
                low, high = (int(v) for v in _ns([item["start"], item["end"]]))
                if abs(low - lows[index]) > _MOVED_NS or abs(high - highs[index]) > _MOVED_NS:
                    moved.append(_moved(old, item, item["path"]))
                    recorded[index] = {**old, "start": item["start"], "end": item["end"]}
                    lows, highs = lows.copy(), highs.copy()  # the cache's: not in place
                    lows[index], highs[index] = low, high
        # a recorded file given again with other content is checked, and named, before the
        # files its recorded span overlaps (a late file beside it is not the changed one)
        names = {Path(str(r["path"])).name for r in recorded}
        checked = sorted(
            enumerate(fingerprints), key=lambda pair: Path(str(pair[1]["path"])).name not in names
        )
        for position, item in checked:
            if item["sha256"] in known or item["sha256"] in added:
                continue
            start, end = (int(v) for v in _ns([item["start"], item["end"]]))
            # spans sharing more than rounding and clock jitter (0.1 s) hold other data
            overlap = np.minimum(highs, end) - np.maximum(lows, start)
            for index in np.flatnonzero(overlap > _SPAN_TOLERANCE_NS):
                old = recorded[int(index)]
                now = given.get(old["sha256"])
                if now is None and placed_now is not None:
                    now = placed_now(old)
                if now is not None and now["sha256"] == old["sha256"]:
                    low, high = (int(v) for v in _ns([now["start"], now["end"]]))
                    if min(high, end) - max(low, start) <= _SPAN_TOLERANCE_NS:
                        # the same data, placed elsewhere now: its span moves there
                        moved.append(_moved(old, now, item["path"]))
                        recorded[int(index)] = {**old, "start": now["start"], "end": now["end"]}
                        lows, highs = lows.copy(), highs.copy()  # the cache's: not in place
                        lows[index], highs[index] = low, high
                        continue
                if moved:  # the spans moved in the cached index are not written
                    self._inputs_cache = None
                what = "size" if old.get("size") != item["size"] else "content"
                raise WorkbenchError(
                    f"{item['path']}: input changed since the store {self.root} was made "
                    f"(other {what} than {old['path']} for {old['start']} to "
                    f"{old['end']}); its results would be of other data: use another "
                    "--store or delete this one"
                )
            new.append((position, item))
            added.add(item["sha256"])
        new = [item for _, item in sorted(new, key=lambda pair: pair[0])]  # as given
        if version is None or cut or moved:  # no index yet, a line cut short or a span
            recorded.extend(new)  # moved: written whole (the list read or cached here)
            self._write_inputs(recorded, unreadable)
        elif new:
            recorded.extend(new)
            if not self._append_inputs(version, new):
                self._inputs_cache = None  # another writer appended too: read again
                return moved
        if new:
            known.update(added)
            lows = np.append(lows, _ns([r["start"] for r in new]))
            highs = np.append(highs, _ns([r["end"] for r in new]))
        self._inputs_cache = (_file_version(path), recorded, unreadable, known, lows, highs, False)
        return moved

    def recorded_inputs(self) -> list[dict]:
        """The input files the stored results came from (their fingerprints)."""
        return list(self._read_inputs()[0])

    def removed_inputs(self, fingerprints: Iterable[Mapping[str, object]]) -> list[dict]:
        """Recorded input files whose content is not among *fingerprints* (the files of
        this run): the data some stored blocks came from is no longer given."""
        given = {str(f["sha256"]) for f in fingerprints}
        return [r for r in self.recorded_inputs() if r["sha256"] not in given]

    def record_damaged(self, entries: Iterable[Mapping[str, object]]) -> None:
        """Record the contents of input files found damaged after an earlier run read them
        whole: fingerprints (``path``, ``start``, ``end``, ``size``, ``mtime_ns``,
        ``sha256``) flagged ``"damaged": True`` with ``"why"`` (the reader's complaint).

        The entry of the content read before stays, and with it the blocks computed from
        it; the damaged content fed no block. Recorded, it is no changed input to
        :meth:`check_inputs`, and the next run knows the file is still damaged (the same
        content) or repaired (another).
        """
        recorded, unreadable, _ = self._read_inputs()
        known = {r["sha256"] for r in recorded}
        new = []
        for entry in entries:
            if entry["sha256"] not in known:
                new.append({**dict(entry), "damaged": True})
                known.add(entry["sha256"])
        if new:
            self._write_inputs(recorded + new, unreadable)

    def forget_inputs(self, entries: Iterable[Mapping[str, object]]) -> None:
        """Remove *entries* (by content) from the recorded inputs."""
        gone = {str(e["sha256"]) for e in entries}
        recorded, unreadable, _ = self._read_inputs()
        kept = [r for r in recorded if r["sha256"] not in gone]
        if len(kept) != len(recorded):
            self._write_inputs(kept, unreadable)

    def unreadable_files(self) -> list[str]:
        """The input files the last run left out as unreadable (resolved paths; see
        :meth:`set_unreadable_files`)."""
        return list(self._read_inputs()[1])

    def set_unreadable_files(self, paths: Iterable[str]) -> None:
        """Record the input files this run leaves out as unreadable (resolved paths), so a
        later run can tell when one has changed and redo the blocks it left unpadded."""
        paths = sorted({str(p) for p in paths})
        recorded, unreadable, _ = self._read_inputs()
        if paths != unreadable:
            self._write_inputs(recorded, paths)

    def _read_inputs(self) -> tuple[list[dict], list[str], bool]:
        """``inputs.jsonl``: the recorded fingerprints, the unreadable files and whether a
        line cut short ends the file (an append a killed run left unfinished: left out).

        Raises
        ------
        StoreDamaged
            A whole line is not a fingerprint or the unreadable files (one line naming
            the file, the line and the recovery).
        """
        path = self.root / _INPUTS
        files: list[dict] = []
        unreadable: list[str] = []
        try:
            text = path.read_bytes().decode("utf-8")
        except FileNotFoundError:
            return files, unreadable, False
        except (OSError, UnicodeDecodeError) as error:
            raise unreadable_store_file(self.root, _INPUTS, error) from None
        lines = text.split("\n")
        cut = lines.pop() != ""  # the text after the last newline: a line cut short
        for number, line in enumerate(lines, start=1):
            try:
                entry = json.loads(line)
                if "file" in entry:
                    item = entry["file"]
                    str(item["sha256"]), str(item["path"]), str(item["start"]), str(item["end"])
                    files.append(item)
                elif "unreadable" in entry:
                    unreadable = [str(p) for p in entry["unreadable"]]
                else:
                    raise ValueError("neither 'file' nor 'unreadable'")
            except (ValueError, KeyError, TypeError, AttributeError) as error:
                detail = str(error).splitlines()[0] if str(error) else type(error).__name__
                error = ValueError(f"line {number}: {detail}")
                raise unreadable_store_file(self.root, _INPUTS, error) from None
        return files, unreadable, cut

    def _write_inputs(self, files: list[dict], unreadable: list[str]) -> None:
        """Write ``inputs.jsonl`` whole (atomically): a line per fingerprint of *files*,
        then the *unreadable* files' line when there are any."""
        lines = [{"file": item} for item in files]
        if unreadable:
            lines.append({"unreadable": list(unreadable)})
        with atomic_path(self.root / _INPUTS) as tmp:
            tmp.write_text("".join(_json_line(line) for line in lines), encoding="utf-8")
        self._inputs_cache = None

    def _append_inputs(self, version: tuple[int, int, int], files: list[dict]) -> bool:
        """Append a line per fingerprint of *files* to ``inputs.jsonl`` (whose *version*
        was read) and flush it to disk; False when the file grew by more than those lines
        (another writer appended too)."""
        data = "".join(_json_line({"file": item}) for item in files).encode()
        size = len(data)
        _append_synced(self.root / _INPUTS, data, create=False)
        now = _file_version(self.root / _INPUTS)
        return now is not None and now[0] == version[0] and now[1] == version[1] + size

    def _open_inputs(self) -> None:
        """Convert the ``inputs.json`` of earlier versions (one object: ``files`` and
        ``unreadable``) to ``inputs.jsonl``, or write ``inputs.jsonl`` again without the
        line a killed run cut short, each with a notice.

        Raises
        ------
        StoreDamaged
            The index is unreadable (one line naming it and the recovery).
        """
        whole = self.root / _INPUTS_WHOLE
        if (self.root / _INPUTS).exists():
            files, unreadable, cut = self._read_inputs()
            if cut:
                self._write_inputs(files, unreadable)
                self.notices.append(
                    f"{self.root}: the last line of {_INPUTS} was cut short (a run killed "
                    "while recording an input file): left out, the file is fingerprinted "
                    "again when taken"
                )
            return
        if not whole.is_file():
            return
        try:
            content = json.loads(whole.read_text(encoding="utf-8"))
            files = list(content["files"])
            for r in files:
                str(r["sha256"]), str(r["path"]), str(r["start"]), str(r["end"])
            unreadable = [str(p) for p in content.get("unreadable", [])]
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            raise unreadable_store_file(self.root, _INPUTS_WHOLE, error) from None
        self._write_inputs(files, unreadable)
        whole.unlink()
        self.notices.append(
            f"{self.root}: {_INPUTS_WHOLE} ({len(files)} input file(s), written whole for "
            f"each file) converted to {_INPUTS} (a line appended for each file)"
        )

    # ------------------------------------------------------------------ reading
    def _files(self, kind: str) -> list[Path]:
        return sorted((self.root / kind).glob("day=*/*.parquet"))

    # ------------------------------------------------------------------ integrity
    def _read_manifest(self) -> tuple[dict[str, dict[str, dict]], bool]:
        """The manifest's batches and whether it needs rewriting (a torn or unreadable
        line: the write of a killed run, or an edit)."""
        path = self.root / _MANIFEST
        entries: dict[str, dict[str, dict]] = {}
        if not path.is_file():
            return entries, False
        try:
            text = path.read_bytes().decode("utf-8", errors="replace")
        except OSError as error:
            raise unreadable_store_file(self.root, _MANIFEST, error) from None
        dirty = bool(text) and not text.endswith("\n")
        for line in text.splitlines():
            try:
                entry = json.loads(line)
                batch, files = str(entry["batch"]), entry["files"]
                for info in files.values():
                    int(info["size"]), str(info["sha256"]), [int(b) for b in info["blocks"]]
            except (ValueError, KeyError, TypeError, AttributeError):
                dirty = True
                continue
            entries[batch] = files
        return entries, dirty

    def _write_manifest(self) -> None:
        """Rewrite the manifest from :attr:`_manifest` (atomically)."""
        lines = [
            json.dumps({"batch": batch, "files": files}, sort_keys=True, separators=(",", ":"))
            for batch, files in sorted(self._manifest.items())
        ]
        with atomic_path(self.root / _MANIFEST) as tmp:
            tmp.write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")

    def _append_manifest(self, batch: str, files: dict[str, dict]) -> None:
        """Commit *batch*: its manifest line, appended and flushed to disk."""
        line = json.dumps({"batch": batch, "files": files}, sort_keys=True, separators=(",", ":"))
        data = f"{line}\n".encode()
        _append_synced(self.root / _MANIFEST, data, create=True)
        self._manifest[batch] = files

    def _check_files(self) -> None:
        """Check every batch file against the manifest; take the blocks of damaged files
        out of the store and remove files the manifest does not list (see the module)."""
        for leftover in self.root.glob("**/.*.tmp*"):  # temporary files of a killed write
            leftover.unlink(missing_ok=True)
        self._manifest, dirty = self._read_manifest()
        present = {
            path.relative_to(self.root).as_posix(): path
            for kind_dir in self.root.iterdir()
            if kind_dir.is_dir()
            for path in kind_dir.glob("day=*/*.parquet")
        }
        damaged: dict[str, set[int]] = {}
        for batch, files in self._manifest.items():
            for name, info in files.items():
                path = self.root / name
                why = ""
                try:
                    size = path.stat().st_size if name in present else None
                    if size is None:
                        why = "missing"
                    elif size != int(info["size"]):
                        why = (
                            f"{'shorter' if size < int(info['size']) else 'longer'} than "
                            f"written ({size} bytes, {int(info['size'])} written: truncated "
                            "or overwritten)"
                        )
                    elif _file_digest(path) != info["sha256"]:
                        why = "of other content than written (overwritten)"
                except OSError as error:
                    why = f"unreadable ({error.strerror or error})"
                if why:
                    blocks = {int(b) for b in info["blocks"]}
                    damaged.setdefault(batch, set()).update(blocks)
                    self.notices.append(
                        f"{self.root}: {name} is {why}: "
                        + (
                            f"block(s) {block_ranges(blocks)} are taken out of the store and "
                            "computed again"
                            if blocks
                            else "it held no rows"
                        )
                    )
        listed = {name for files in self._manifest.values() for name in files}
        unlisted = sorted(set(present) - listed)
        if unlisted:
            blocks: set[int] = set()
            for name in unlisted:
                if name.startswith(f"{BLOCKS_KIND}/"):
                    try:
                        frame = pd.read_parquet(present[name], columns=["block"])
                        blocks.update(int(b) for b in frame["block"])
                    except Exception:  # noqa: BLE001 - an unreadable stray file is removed too
                        pass
                present[name].unlink(missing_ok=True)
            if blocks or any(not n.startswith(f"{BLOCKS_KIND}/") for n in unlisted):
                done = f" (blocks {block_ranges(blocks)} are computed again)" if blocks else ""
                self.notices.append(
                    f"{self.root}: {len(unlisted)} file(s) the store's manifest does not list "
                    f"removed{done}: {', '.join(unlisted[:3])}"
                    + (", ..." if len(unlisted) > 3 else "")
                )
        if damaged:
            self._drop(damaged)
        elif dirty:
            self._write_manifest()

    def _drop(self, drops: Mapping[str, set[int]]) -> None:
        """Rewrite each batch of *drops* without its blocks (a new batch of the remaining
        rows, committed before the old one is removed)."""
        self._owners_cache = None
        old_files = []
        for batch, drop in drops.items():
            files = self._manifest.get(batch)
            if files is None:
                continue
            kept_blocks = {int(b) for info in files.values() for b in info["blocks"]} - drop
            if kept_blocks:
                new = f"b{min(kept_blocks):07d}-{max(kept_blocks):07d}-{uuid.uuid4().hex[:8]}"
                written: dict[str, dict] = {}
                for name, info in sorted(files.items(), key=lambda i: i[0].startswith("blocks/")):
                    if not {int(b) for b in info["blocks"]} - drop:
                        continue
                    frame = self._read_file(self.root / name)
                    frame = frame[~frame["block"].astype(int).isin(drop)]
                    kind_day = name.rsplit("/", 1)[0]
                    written.update(self._write_file(frame, f"{kind_day}/{new}.parquet"))
                self._append_manifest(new, written)
            old_files += [self.root / name for name in files]
            del self._manifest[batch]
        self._write_manifest()
        for path in old_files:
            path.unlink(missing_ok=True)

    def drop_blocks(self, blocks: Iterable[int]) -> set[int]:
        """Take *blocks* out of the store (their batches are rewritten without them);
        return those that were stored."""
        wanted = {int(b) for b in blocks}
        drops = {}
        for batch, files in self._manifest.items():
            held = {int(b) for info in files.values() for b in info["blocks"]} & wanted
            if held:
                drops[batch] = held
        if drops:
            self._drop(drops)
        return set().union(*drops.values()) if drops else set()

    def _read_file(self, path: Path, **kwargs) -> pd.DataFrame:
        try:
            return pd.read_parquet(path, **kwargs)
        except (OSError, ValueError) as error:
            raise unreadable_store_file(
                self.root, str(path.relative_to(self.root)), error
            ) from None

    def _owners(self) -> dict[int, str]:
        """The batch each block's results are read from: the first batch (by name) whose
        ``blocks`` file lists it. A block stored twice (by two runs that shared a store
        before stores were locked) is thus read once."""
        if self._owners_cache is None:
            owners: dict[int, str] = {}
            for path in self._files(BLOCKS_KIND):
                for block in self._read_file(path, columns=["block"])["block"].tolist():
                    owners.setdefault(int(block), path.stem)
            self._owners_cache = owners
        return self._owners_cache

    def _own_rows(self, frame: pd.DataFrame, path: Path) -> pd.DataFrame:
        if frame.empty:
            return frame
        owners = self._owners()
        keep = frame["block"].map(lambda b: owners.get(int(b)) == path.stem).to_numpy(bool)
        return frame if keep.all() else frame[keep]

    def unreadable_inputs(self) -> dict[str, dict]:
        """The input files stored blocks were skipped for because they could not be read
        (:data:`UNREADABLE_COLUMN`): resolved path -> ``{"blocks": set of int, "reason":
        str}`` (the reason of its first block)."""
        table = self.read(BLOCKS_KIND)
        if table.empty or UNREADABLE_COLUMN not in table.columns:
            return {}
        found: dict[str, dict] = {}
        for block, reason, paths in zip(
            table["block"], table["reason"], table[UNREADABLE_COLUMN], strict=True
        ):
            if not isinstance(paths, str) or not paths:
                continue
            for path in paths.split("\n"):
                entry = found.setdefault(path, {"blocks": set(), "reason": str(reason)})
                entry["blocks"].add(int(block))
        return found

    def block_cuts(self) -> dict[int, tuple[str, int]]:
        """Where the stored blocks of a drifting record were cut (:data:`CUT_COLUMNS`):
        block -> (the input file's SHA-256; the index of the block's first sample in it); a
        block without one was cut at its label."""
        table = self.read(BLOCKS_KIND)
        path, sample = CUT_COLUMNS
        if table.empty or path not in table.columns:
            return {}
        known = table[path].notna() & (table[path].astype(str) != "")
        return {
            int(block): (str(file), int(index))
            for block, file, index in zip(
                table.loc[known, "block"],
                table.loc[known, path],
                table.loc[known, sample],
                strict=True,
            )
        }

    def completed_blocks(self) -> set[int]:
        """Blocks already processed (successfully or skipped with a recorded reason)."""
        table = self.read(BLOCKS_KIND)
        return set() if table.empty else set(table["block"].astype(int).tolist())

    def read(self, kind: str) -> pd.DataFrame:
        """All rows of *kind*, sorted by block (and model order when present)."""
        files = self._files(kind)
        if not files:
            return pd.DataFrame()
        frames = [self._own_rows(self._read_file(path), path) for path in files]
        table = pd.concat([f for f in frames if len(f)] or frames[:1], ignore_index=True)
        keys = [k for k in ("block", "model_order") if k in table.columns]
        if keys:
            table = table.sort_values(keys, kind="stable").reset_index(drop=True)
        return table

    def read_chunks(self, kind: str, blocks_per_chunk: int = 512):
        """Yield the rows of *kind* in block order, *blocks_per_chunk* blocks at a time.

        Memory stays bounded by the chunk, whatever the size of the store: each batch file's
        block range is in its name, so a chunk reads only the files overlapping it (and of
        those only its rows).
        """
        ranges = []
        for path in self._files(kind):
            try:
                low, high = (
                    int(part[1:] if part.startswith("b") else part)
                    for part in path.stem.split("-")[:2]
                )
            except ValueError as error:
                raise unreadable_store_file(
                    self.root, str(path.relative_to(self.root)), error
                ) from None
            ranges.append((low, high, path))
        if not ranges:
            return
        keys = None
        first = min(r[0] for r in ranges)
        last = max(r[1] for r in ranges)
        for start in range(first, last + 1, blocks_per_chunk):
            stop = start + blocks_per_chunk
            frames = [
                self._own_rows(
                    self._read_file(path, filters=[("block", ">=", start), ("block", "<", stop)]),
                    path,
                )
                for low, high, path in ranges
                if low < stop and high >= start
            ]
            frames = [f for f in frames if len(f)]
            if not frames:
                continue
            table = pd.concat(frames, ignore_index=True)
            if keys is None:
                keys = [k for k in ("block", "model_order") if k in table.columns]
            yield table.sort_values(keys, kind="stable").reset_index(drop=True)

    # ------------------------------------------------------------------ writing
    def write_batch(self, blocks: pd.DataFrame, results: Mapping[str, pd.DataFrame]) -> str:
        """Write one batch atomically per file, the ``blocks`` file last.

        Parameters
        ----------
        blocks : DataFrame
            One row per block of the batch: ``block``, ``block_start``, ``status``
            (``ok``/``skipped``), ``reason`` (and :data:`UNREADABLE_COLUMN` where a block was
            skipped for an input file that cannot be read, :data:`CUT_COLUMNS` where a
            drifting record's block was cut off its label).
        results : mapping of kind -> DataFrame
            Result rows; each must have ``block`` and ``block_start`` columns.

        Returns
        -------
        str
            The batch name (file stem shared by all its files).
        """
        if blocks.empty:
            return ""
        batch = (
            f"b{int(blocks['block'].min()):07d}-{int(blocks['block'].max()):07d}-"
            f"{uuid.uuid4().hex[:8]}"
        )
        self._owners_cache = None
        if BLOCKS_KIND in results:
            raise ValueError(f"kind {BLOCKS_KIND!r} is reserved")
        written: dict[str, dict] = {}
        for kind, frame in results.items():
            written.update(self._write_partitioned(kind, frame, batch, blocks))
        written.update(self._write_partitioned(BLOCKS_KIND, blocks, batch, blocks))
        self._append_manifest(batch, written)  # the batch is committed once this returns
        return batch

    def _write_partitioned(
        self, kind: str, frame: pd.DataFrame, batch: str, blocks: pd.DataFrame
    ) -> dict[str, dict]:
        starts = dict(
            zip(blocks["block"], pd.to_datetime(blocks["block_start"], utc=True), strict=True)
        )
        if frame.empty:
            return {}
        days = frame["block"].map(starts).dt.strftime("%Y-%m-%d")
        written: dict[str, dict] = {}
        for day, part in frame.groupby(days.to_numpy(), sort=True):
            written.update(self._write_file(part, f"{kind}/day={day}/{batch}.parquet"))
        return written

    def _write_file(self, frame: pd.DataFrame, name: str) -> dict[str, dict]:
        """Write *frame* to ``root/name`` atomically; its manifest record."""
        buffer = io.BytesIO()
        frame.reset_index(drop=True).to_parquet(buffer, index=False)
        data = buffer.getvalue()
        with atomic_path(self.root / name) as tmp:
            tmp.write_bytes(data)
        blocks = sorted({int(b) for b in frame["block"]})
        return {name: {"size": len(data), "sha256": _digest(data), "blocks": blocks}}


def batched(items: Iterable, size: int):
    """Yield lists of up to *size* consecutive items."""
    batch: list = []
    for item in items:
        batch.append(item)
        if len(batch) >= size:
            yield batch
            batch = []
    if batch:
        yield batch


def _json_line(entry: Mapping[str, object]) -> str:
    """*entry* as one line of JSON (keys sorted, no spaces), newline included."""
    return json.dumps(entry, sort_keys=True, separators=(",", ":")) + "\n"


def _append_synced(path: Path, data: bytes, *, create: bool) -> None:
    """Append *data* to *path* (created with *create*) and flush it to disk: a line of an
    append-only record (the manifest, the input index) is whole once this returns."""
    flags = os.O_WRONLY | os.O_APPEND | (os.O_CREAT if create else 0)
    fd = os.open(path, flags, 0o644)
    try:
        while data:
            data = data[os.write(fd, data) :]
        os.fsync(fd)
    finally:
        os.close(fd)
