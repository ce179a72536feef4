"""Which ship log a state folder's results came from, checked when the monitor starts again.

The forecast, the health chart and the block lengths of ``--block-minutes auto`` that a
state folder holds were computed from the ship log as the monitor read it, and a restart
takes them up (:mod:`workbench.monitor.incremental`): the health chart's model fitted
once, the forecast's rows of committed windows. A restart reading another log, or the same
log with other ``--dship-columns`` or ``--dship-utc-offset``, would go on from results of
the first while adding those of the second. So the state folder records the log
(``<state>/ship_log.json``)::

    {"schema": "workbench.monitor.ship_log/1", "path": str | null,
     "columns": {canonical: source name}, "utc_offset": str | null,
     "bytes": int, "sha256": str | null}

``bytes`` and ``sha256`` are the part of the log read so far, through its last whole line
(:attr:`~workbench.monitor.ship_log.LiveShipLog.content`), kept as the log grows. A restart
is refused (nothing in the state folder touched) when

* ``--dship`` is left out, or its ``--dship-columns`` or ``--dship-utc-offset`` differ
  from the recorded ones: a usage error (:class:`~workbench.errors.OptionError`, exit 2)
  naming the option and the state folder;
* ``--dship`` names another file whose first ``bytes`` are not those recorded: a usage
  error too (another file with those bytes is the same log, moved: taken, with a note);
* the recorded file itself no longer starts with them (cut short, rewritten in place or
  replaced: a changed input, as the block store refuses a changed acceleration file):
  bad data (:class:`~workbench.errors.WorkbenchError`, exit 1).

A log that only grew by lines appended starts with the recorded bytes: the follow mode.
Nothing is checked while no byte of the log was read (the state folder holds nothing
computed from it); a folder without the record but with results (written before the
record existed) records the log as it is now, with a note.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path

from data_contracts import atomic_path

from ..errors import OptionError, WorkbenchError

__all__ = ["LOG_RECORD_FILE", "LOG_RECORD_SCHEMA", "ShipLogRecord"]

#: The record's file in the state folder.
LOG_RECORD_FILE = "ship_log.json"
#: ``schema`` of the record.
LOG_RECORD_SCHEMA = "workbench.monitor.ship_log/1"
#: Bytes hashed per read when a restart checks the log. [B]
_CHUNK_BYTES = 1 << 24


def _columns_text(columns: Mapping[str, str]) -> str:
    return ",".join(f"{k}={v}" for k, v in sorted(columns.items())) or "(not given)"


def _offset(text: str | None):
    """A UTC offset as the log's reader takes it (None: UTC), to compare two spellings."""
    from data_contracts.dship_names import parse_utc_offset

    try:
        return parse_utc_offset(text) if text is not None else parse_utc_offset("+00:00")
    except ValueError:  # a record's value the reader would not take: compared as text
        return text


def _prefix_digest(path: Path, size: int) -> tuple[str | None, int | None]:
    """SHA-256 (hex) of the first *size* bytes of *path* and the file's size now; (None,
    None) when it is not there, (None, its size) when it is shorter."""
    try:
        with open(path, "rb") as handle:
            now = os.fstat(handle.fileno()).st_size
            if now < size:
                return None, now
            digest = hashlib.sha256()
            left = size
            while left:
                chunk = handle.read(min(left, _CHUNK_BYTES))
                if not chunk:  # cut meanwhile
                    return None, size - left
                digest.update(chunk)
                left -= len(chunk)
    except FileNotFoundError:
        return None, None
    except OSError as error:
        raise WorkbenchError(f"{path}: cannot read ({error.strerror or error})") from None
    return digest.hexdigest(), now


class ShipLogRecord:
    """The state folder's record of its ship log (see the module notes).

    Parameters
    ----------
    state : path-like
        The state folder.
    dship : path-like or None
        This run's ``--dship``.
    columns : mapping
        This run's ``--dship-columns`` (canonical name -> source name).
    utc_offset : str or None
        This run's ``--dship-utc-offset``.
    """

    def __init__(self, state, dship, columns: Mapping[str, str], utc_offset: str | None):
        self.path = Path(state) / LOG_RECORD_FILE
        self.state = Path(state)
        self.dship = None if dship is None else Path(dship)
        self.columns = {str(k): str(v) for k, v in dict(columns).items()}
        self.utc_offset = utc_offset
        self._content: tuple[int, str | None] = (0, None)
        self._written: dict | None = None

    def _wanted(self) -> dict:
        size, digest = self._content
        return {
            "schema": LOG_RECORD_SCHEMA,
            "path": None if self.dship is None else os.path.abspath(self.dship),
            "columns": dict(sorted(self.columns.items())),
            "utc_offset": self.utc_offset,
            "bytes": int(size),
            "sha256": digest,
        }

    def check(self, *, has_results: bool) -> list[str]:
        """Compare this run's ship log with the recorded one; returns the notes to say.
        Reads only; the record is written by :meth:`update`.

        Raises
        ------
        OptionError
            ``--dship`` left out or naming another log, other ``--dship-columns`` or
            ``--dship-utc-offset`` (exit 2).
        WorkbenchError
            The recorded log changed in place (exit 1).
        """
        try:
            found = json.loads(self.path.read_text(encoding="utf-8"))
            if not isinstance(found, dict) or found.get("schema") != LOG_RECORD_SCHEMA:
                raise ValueError(f"not a {LOG_RECORD_SCHEMA} record")
            size = int(found["bytes"])
            recorded_path = found["path"]
            digest = found["sha256"]
            columns = {str(k): str(v) for k, v in dict(found["columns"]).items()}
            offset = found["utc_offset"]
        except FileNotFoundError:
            if not has_results:
                return []
            return [
                f"{self.path}: absent: the ship log is recorded as this run gives it, "
                "unchecked against the one the state folder's results came from"
            ]
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            why = str(error).splitlines()[0] if str(error) else type(error).__name__
            return [
                f"{self.path}: unreadable ({why}): the ship log is recorded again as this "
                "run gives it, unchecked against the one the state folder's results came from"
            ]
        if size <= 0 or recorded_path is None:
            return []  # no byte of a log read: nothing computed from one
        self._content = (size, digest)
        self._written = found
        state = self.state
        keep = "(or use another --state folder)"
        if self.dship is None:
            raise OptionError(
                f"--dship: the state folder {state} was made with the ship log "
                f"{recorded_path} ({size} bytes read); give it again {keep}"
            )
        if columns != self.columns:
            raise OptionError(
                f"--dship-columns {_columns_text(self.columns)}: the state folder {state} "
                f"was made with --dship-columns {_columns_text(columns)}; give the same {keep}"
            )
        if _offset(offset) != _offset(self.utc_offset):
            raise OptionError(
                f"--dship-utc-offset {self.utc_offset or '(not given)'}: the state folder "
                f"{state} was made with --dship-utc-offset {offset or '(not given)'}; "
                f"give the same {keep}"
            )
        now, now_size = _prefix_digest(self.dship, size)
        if now == digest:
            if os.path.abspath(self.dship) != recorded_path:
                return [
                    f"ship log now {self.dship}: its first {size} bytes are those of "
                    f"{recorded_path} that the state folder's results came from"
                ]
            return []
        if os.path.abspath(self.dship) != recorded_path:
            if now_size is None:
                why = "no such file"
            elif now is None:
                why = f"{now_size} bytes, fewer than the {size} read from it"
            else:
                why = f"the first {size} bytes differ"
            raise OptionError(
                f"--dship {self.dship}: not the ship log the state folder {state} was made "
                f"with ({recorded_path}; {why}); give that log {keep}"
            )
        if now_size is None:
            why = "gone"
        elif now is None:
            why = f"now {now_size} bytes, fewer than the {size} read: cut short or replaced"
        else:
            why = f"its first {size} bytes differ: rewritten or replaced"
        raise WorkbenchError(
            f"{self.dship}: changed since the state folder {state} read it ({why}); its "
            f"forecast and health chart came from the log as it was: give it so {keep}"
        )

    def update(self, content: tuple[int, str] | None = None) -> None:
        """Record the log as read now (*content*: bytes and SHA-256 of the part read, as
        :attr:`~workbench.monitor.ship_log.LiveShipLog.content` gives them; None: as
        recorded), written (atomically) only when the record changes."""
        if content is not None:
            self._content = (int(content[0]), str(content[1]))
        wanted = self._wanted()
        if wanted == self._written:
            return
        with atomic_path(self.path) as tmp:
            tmp.write_text(json.dumps(wanted, indent=1), encoding="utf-8")
        self._written = wanted
