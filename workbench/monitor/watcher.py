"""Follow a folder where acquisition files arrive; report each file once it is complete.

A file is *complete* when it is a regular file (a named pipe, socket or device under a
data file's name is left out with one message: opening it would wait for a writer) and

1. its name is not hidden (``.name.tmp`` files of a write-then-rename are not data: the
   atomic writers of :mod:`data_contracts` and most recorders write a hidden temporary file
   and rename it when it is whole);
2. it has not been modified for ``settle_s`` seconds (its modification time is at least
   that old at a poll, or - stamped by a clock ahead of this machine's, e.g. a file
   server's - the polls have seen its size and modification time unchanged that long),
   so a file written in place is left alone while the writer appends to it;
3. its header reads and is consistent (:func:`~workbench.signals.block_plan.read_file_info`:
   for ``.npz`` files the archive's directory, which a writer puts last, and the sample
   array's header against the bytes stored; other formats are read whole).

Why these rules: (1) costs nothing and makes the common atomic-rename writers exact; (2)
catches writers that write in place without the latency of waiting for two identical polls
(a file written long ago is taken at the first poll that sees it, e.g. after a restart);
(3) catches what (2) cannot, a writer pausing longer than ``settle_s`` in the middle of a
binary file. A file failing (3) is reported once and looked at again when it changes (an
empty file too: a recorder that stopped after creating it leaves one, which would
otherwise keep the monitor waiting for it, and from its first block on if it is the
oldest). A
file that changes after it was taken is reported and not taken again: the blocks that used
it are kept (see :mod:`workbench.monitor`).
"""

from __future__ import annotations

import os
import stat as stat_kinds
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..signals.block_plan import FileInfo, read_file_info

__all__ = ["FolderWatcher", "LandedFile"]


@dataclass(frozen=True)
class LandedFile:
    """A complete acquisition file.

    Parameters
    ----------
    info : FileInfo
        Its header (start time, rate, samples, channels).
    landed : pandas.Timestamp
        Its modification time when it was found complete: when its last byte landed. [UTC]
    size : int
        [bytes]
    mtime_ns : int
        Modification time. [ns since the epoch]
    """

    info: FileInfo
    landed: pd.Timestamp
    size: int
    mtime_ns: int

    @property
    def path(self) -> Path:
        return self.info.path


class FolderWatcher:
    """Poll *folder* (and its subfolders) for acceleration files.

    Parameters
    ----------
    folder : path-like
    settle_s : float
        Quiet time after the last modification before a file is looked at. [s]
    read_options : mapping, optional
        File layout (:func:`data_contracts.read_accelerations` keyword arguments).
    exclude : iterable of path-like
        Files never taken (the ship log when it lies in the watched folder).
    """

    def __init__(self, folder, *, settle_s: float = 1.0, read_options=None, exclude=()):
        self.folder = Path(folder)
        self.settle_s = float(settle_s)
        self.read_options = dict(read_options or {})
        self.exclude = {Path(p).resolve() for p in exclude}
        self._taken: dict[Path, tuple[int, int]] = {}
        self._refused: dict[Path, tuple[int, int]] = {}
        self._changed: set[Path] = set()
        #: (size, mtime_ns) of each file not yet taken and when a poll first saw it so.
        self._seen: dict[Path, tuple[tuple[int, int], float]] = {}
        #: Files seen but not yet complete at the last poll.
        self.pending: set[Path] = set()
        #: Why each refused file was not taken (its reader's first line), by path.
        self.refused_reasons: dict[Path, str] = {}

    def _candidates(self) -> list[Path]:
        from data_contracts.formats import ACCELERATION_SUFFIXES

        out = []
        for root, dirs, names in os.walk(self.folder):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for name in sorted(names):
                if name.startswith("."):
                    continue
                path = Path(root) / name
                if path.suffix.lower() in ACCELERATION_SUFFIXES:
                    out.append(path)
        return out

    def forget(self, path: Path) -> None:
        """Look at *path* again at the next poll (e.g. a file refused by the caller)."""
        self._taken.pop(Path(path), None)

    def refuse(self, path: Path) -> None:
        """Do not take *path* again until it changes."""
        key = self._taken.pop(Path(path), None)
        if key is not None:
            self._refused[Path(path)] = key

    def poll(self, now: float | None = None) -> tuple[list[LandedFile], list[str]]:
        """New complete files (in time order of their first sample) and messages."""
        from data_contracts.formats.text import TEXT_SUFFIXES, looks_like_acceleration_table

        now = time.time() if now is None else now
        landed: list[LandedFile] = []
        messages: list[str] = []
        pending = set()
        if not self.folder.is_dir():
            return [], [f"{self.folder}: no such folder"]
        for path in self._candidates():
            try:
                stat = path.stat()
            except OSError:  # renamed or removed meanwhile
                continue
            key = (stat.st_size, stat.st_mtime_ns)
            if not stat_kinds.S_ISREG(stat.st_mode):
                # a named pipe, socket or device under a data file's name: opening it to
                # read its header would wait for a writer, the monitor hung for good
                if path not in self.refused_reasons:
                    self._refused[path] = key
                    self.refused_reasons[path] = "not a regular file (a pipe, socket or device)"
                    messages.append(
                        f"{path.name}: not a regular file (a pipe, socket or device); left out"
                    )
                continue
            taken = self._taken.get(path)
            if taken is not None:
                if taken != key and path not in self._changed:
                    self._changed.add(path)
                    messages.append(
                        f"{path.name}: changed after it was used; the change is ignored "
                        "(run `workbench identify` over the folder for a clean result)"
                    )
                continue
            if self._refused.get(path) == key or path.resolve() in self.exclude:
                continue
            if self._seen.get(path, (None,))[0] != key:
                self._seen[path] = (key, now)
            unchanged_s = now - self._seen[path][1]
            if now - stat.st_mtime < self.settle_s and unchanged_s < self.settle_s:
                pending.add(path)
                continue
            del self._seen[path]
            if path.suffix.lower() in TEXT_SUFFIXES and not looks_like_acceleration_table(path):
                self._refused[path] = key  # a table or log, not an acceleration record
                self.refused_reasons[path] = (
                    "no acceleration header (a time column and numeric channels) found; "
                    "left out as a table or log"
                )
                continue
            try:
                info = read_file_info(path, read_options=self.read_options)
            except Exception as error:  # noqa: BLE001 - any reader failure: not complete
                detail = str(error).splitlines()[0] if str(error) else type(error).__name__
                detail = detail.removeprefix(f"{path}: ")  # the message names the file once
                self._refused[path] = key
                self.refused_reasons[path] = detail
                messages.append(f"{path.name}: unreadable ({detail}); taken when it changes")
                continue
            self._taken[path] = key
            self.refused_reasons.pop(path, None)
            landed.append(
                LandedFile(
                    info,
                    pd.Timestamp(stat.st_mtime_ns, unit="ns", tz="UTC"),
                    int(stat.st_size),
                    int(stat.st_mtime_ns),
                )
            )
        self.pending = pending
        self._seen = {path: seen for path, seen in self._seen.items() if path in pending}
        landed.sort(key=lambda f: (f.info.start_time, str(f.path)))
        return landed, messages
