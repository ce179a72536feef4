"""The monitor's notes: every one kept in ``<state>/notes.txt`` as it is made.

The monitor says what it did not do as asked (a file not used, a block decided without a
late file, a forecast update that failed) in short notes. The command prints the last of
them when it stops and ``status.json`` holds the newest; a long run keeps only its recent
ones in memory. So that none is lost, each note is also appended to ``notes.txt`` in the
state folder, one line each, ``YYYY-MM-DDTHH:MM:SSZ note`` (UTC, when it was made), over
every run of the state folder.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import pandas as pd

__all__ = ["NOTES_FILE", "NoteList"]

#: The notes file's name in the state folder.
NOTES_FILE = "notes.txt"

log = logging.getLogger("workbench")


class NoteList(list):
    """A list of notes that appends every note added to *path* too.

    ``append``, ``extend`` and ``+=`` write the new notes (one line each, with the UTC
    time); trimming the list (``del notes[:-200]``) leaves the file alone. :attr:`total`
    counts the notes added in this process. A note that cannot be written (disk full) is
    kept in the list, and the first such failure is logged.
    """

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = Path(path)
        self.total = 0
        self._lock = threading.Lock()
        self._failed = False

    def append(self, note: str) -> None:
        super().append(note)
        self._write([note])

    def extend(self, notes) -> None:
        notes = list(notes)
        super().extend(notes)
        self._write(notes)

    def __iadd__(self, notes):
        self.extend(notes)
        return self

    def _write(self, notes: list[str]) -> None:
        if not notes:
            return
        when = pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ")
        text = "".join(f"{when} {' '.join(str(n).splitlines())}\n" for n in notes)
        with self._lock:
            self.total += len(notes)
            try:
                with open(self.path, "a+b") as handle:
                    handle.seek(0, 2)
                    if handle.tell():  # a line cut by a crash is ended first
                        handle.seek(-1, 2)
                        if handle.read(1) != b"\n":
                            text = "\n" + text
                    handle.write(text.encode("utf-8"))
            except OSError as error:
                if not self._failed:
                    log.warning("%s: notes not written (%s)", self.path, error.strerror or error)
                self._failed = True
