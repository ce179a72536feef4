"""Read-only access to a monitor's state folder.

The monitor (``workbench monitor``) publishes its results into a state folder, each file
written atomically (temporary file, then rename). Any file may be absent early on. The
tables that grow with the voyage (tracked, forecast, health, data health) are folders of
a Parquet part per day of blocks (:mod:`data_contracts.parts`), read as one table by
``read_table``:

==========================  ============================================================
``tracked.parquet``         MODAL contract: the tracked modal table so far
``forecast.parquet``        FORECAST contract: model prediction with 95 % bounds, SSI and
                            Kalman estimates per block and mode
``health.parquet``          HEALTH contract: the control chart, one row per block
``alarms.parquet``          ALARMS contract: alarm episodes with their evidence
``data_health.parquet``     :data:`DATA_HEALTH`: channels, gaps and latency per block
``harmonics.parquet``       :data:`HARMONIC_LINES`: frequency of each shaft order per block
                            (from the ship log's shaft speed, or its speed x the shaft
                            rate per knot the harmonics found follow)
``harmonic_tracks.parquet`` :data:`HARMONIC_TRACKS`: the tracked lines recognised as shaft
                            or blade-pass harmonics (kept out of the modes), per block
``status.json``             :data:`STATUS_KEYS`: the monitor's progress (per block)
``heartbeat.json``          :data:`HEARTBEAT_KEYS`: the monitor's heartbeat (every poll
                            interval, from a timer thread), with the last file it took
                            and its background worker's state
==========================  ============================================================

:class:`StateFolder` reads a file again only when its signature (modification time in
ns, size, inode) changed, keeps the last good version when a new one cannot be read, and
never writes, creates or locks anything in the folder.
"""

from __future__ import annotations

import json
import math
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from data_contracts import (
    ALARMS,
    FORECAST,
    HEALTH,
    MODAL,
    Column,
    ContractError,
    TableContract,
    read_table,
)

__all__ = [
    "DATA_HEALTH",
    "HARMONIC_LINES",
    "HARMONIC_TRACKS",
    "HEARTBEAT_KEYS",
    "STATE_FILES",
    "STATUS_KEYS",
    "FileSnapshot",
    "StateFolder",
    "read_heartbeat",
    "read_status",
]

#: Data health of the acquisition, one row per block (written by the monitor).
DATA_HEALTH = TableContract(
    name="data_health",
    description="Health of the acquisition per identified block: channels used and dropped, "
    "gaps in the files, when the last file landed and the latency to identification.",
    columns=(
        Column("block", "int", "Block number on the voyage's block grid.", minimum=0),
        Column("block_start", "time", "Start of the block, UTC.", unit="UTC"),
        Column("n_channels", "int", "Channels used for identification.", minimum=0),
        Column(
            "dropped_channels",
            "str",
            "Channels left out of this block, comma-separated ('' if none).",
            nullable=True,
        ),
        Column("gap_seconds", "float", "Missing data inside the block. [s]", unit="s", minimum=0),
        Column("last_file_landed", "time", "When the block's last file arrived, UTC.", unit="UTC"),
        Column("identified_at", "time", "When the block was identified, UTC.", unit="UTC"),
        Column(
            "latency_s",
            "float",
            "From the last file landing to the block's results being published. [s]",
            unit="s",
        ),
    ),
    unique=("block",),
)

#: Shaft orders at the block's shaft speed, one row per block and order (written by the
#: monitor when the ship log carries the shaft speed, or the speed only once the
#: speed-following test has found the shaft rate per knot: then the speed x that rate).
HARMONIC_LINES = TableContract(
    name="harmonic_lines",
    description="Frequency of each shaft order (and the blade pass) at the block's mean "
    "logged shaft speed (without one: its speed x the shaft rate per knot found): the lines "
    "the harmonics follow, drawn beside the tracked modes.",
    columns=(
        Column("block", "int", "Block number on the voyage's block grid.", minimum=0),
        Column("block_start", "time", "Start of the block, UTC.", unit="UTC"),
        Column("order", "float", "Shaft order (the blade count for the blade pass).", minimum=0),
        Column(
            "frequency_hz",
            "float",
            "order x mean shaft speed / 60 (order x shaft rate per knot x speed).",
            unit="Hz",
            minimum=0,
        ),
    ),
    unique=("block", "order"),
)

#: The tracked lines that are shaft or blade-pass harmonics, not modes (written by the
#: monitor when the ship log carries the shaft speed or the speed): one row per block and
#: line.
HARMONIC_TRACKS = TableContract(
    name="harmonic_tracks",
    description="Lines the tracking followed from block to block and recognised as shaft "
    "or blade-pass harmonics (most of their blocks on a shaft order), so kept out of the "
    "tracked modes, forecasts and health chart: shown as harmonics, never as modes.",
    columns=(
        Column("block", "int", "Block number on the voyage's block grid.", minimum=0),
        Column("block_start", "time", "Start of the block, UTC.", unit="UTC"),
        Column("track", "int", "Number of the harmonic line (by median frequency).", minimum=1),
        Column("frequency_hz", "float", "Identified frequency in the block.", unit="Hz"),
        Column(
            "order",
            "float",
            "Shaft order the block's frequency sits on (empty: none in this block).",
            nullable=True,
        ),
    ),
    unique=("block", "track"),
)

#: File names of the state folder by part, with the contract of each table.
STATE_FILES: dict[str, tuple[str, TableContract | None]] = {
    "tracked": ("tracked.parquet", MODAL),
    "forecast": ("forecast.parquet", FORECAST),
    "health": ("health.parquet", HEALTH),
    "alarms": ("alarms.parquet", ALARMS),
    "data_health": ("data_health.parquet", DATA_HEALTH),
    "harmonics": ("harmonics.parquet", HARMONIC_LINES),
    "harmonic_tracks": ("harmonic_tracks.parquet", HARMONIC_TRACKS),
    "status": ("status.json", None),
    "heartbeat": ("heartbeat.json", None),
}

#: Keys of ``status.json`` and the JSON types each takes.
STATUS_KEYS: dict[str, tuple[type, ...]] = {
    "updated_at": (str,),
    "last_block": (int, type(None)),
    "blocks_done": (int,),
    "state": (str,),
    "pid": (int,),
    "watch": (str,),
    "message": (str,),
}

#: Keys ``status.json`` may hold (a state without given-up blocks may leave them out).
STATUS_OPTIONAL_KEYS: dict[str, tuple[type, ...]] = {
    "given_up": (list,),
    "given_up_note": (str,),
    "health_note": (str,),
}
#: Keys of each span of ``given_up`` and their JSON types.
GIVEN_UP_KEYS: dict[str, tuple[type, ...]] = {
    "first_block": (int,),
    "last_block": (int,),
    "start": (str,),
    "end": (str,),
    "reason": (str,),
}

#: Keys of ``heartbeat.json`` and the JSON types each takes (``null`` where allowed).
HEARTBEAT_KEYS: dict[str, tuple[type, ...]] = {
    "time": (str,),
    "pid": (int,),
    "host": (str,),
    "poll_s": (float, int),
    "state": (str,),
    "last_file": (str, type(None)),
    "last_file_taken_at": (str, type(None)),
    "doing": (str,),
    "doing_since": (str,),
    "stall_s": (float, int),
    "worker": (dict,),
}
#: Keys of the heartbeat's ``worker`` object and their JSON types.
WORKER_KEYS: dict[str, tuple[type, ...]] = {
    "state": (str,),
    "pid": (int, type(None)),
    "message": (str,),
}
#: Values of the heartbeat's ``state`` and of its worker's ``state``.
HEARTBEAT_STATES = ("running", "stopped")
WORKER_STATES = ("none", "alive", "stopped")

Signature = tuple[int, int, int]


@dataclass(frozen=True)
class FileSnapshot:
    """One state file as last read.

    Parameters
    ----------
    name : str
        Part name (``tracked``, ``forecast``, ... see :data:`STATE_FILES`).
    signature : tuple of int or None
        (mtime in ns, size in bytes, inode) of the file; None when it is absent.
    data : DataFrame, dict or None
        The validated table (or the status dictionary); None when nothing good was read
        yet.
    error : str or None
        Why the current file could not be used (absent, unreadable, contract violation).
        When *data* is not None as well, *data* is the last good version.
    """

    name: str
    signature: Signature | None
    data: Any
    error: str | None

    @property
    def available(self) -> bool:
        return self.data is not None


def read_status(path: str | os.PathLike) -> dict:
    """Read and check ``status.json``.

    Raises
    ------
    ValueError
        The file is not a JSON object with the keys and types of :data:`STATUS_KEYS`
        (message names the file and the key).
    """
    path = Path(path)
    try:
        status = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path.name}: not valid JSON ({error})") from None
    if not isinstance(status, dict):
        raise ValueError(f"{path.name}: expected a JSON object, got {type(status).__name__}")
    problems = []
    for key, types in STATUS_KEYS.items():
        if key not in status:
            problems.append(f"missing key '{key}'")
        elif not isinstance(status[key], types) or isinstance(status[key], bool):
            problems.append(f"key '{key}' has type {type(status[key]).__name__}")
    for key, types in STATUS_OPTIONAL_KEYS.items():
        if key in status and not isinstance(status[key], types):
            problems.append(f"key '{key}' has type {type(status[key]).__name__}")
    for k, span in enumerate(status.get("given_up", []) if not problems else []):
        wrong = [
            name
            for name, types in GIVEN_UP_KEYS.items()
            if not isinstance(span, dict)
            or not isinstance(span.get(name), types)
            or isinstance(span.get(name), bool)
        ]
        if wrong:
            problems.append(f"key 'given_up' item {k}: missing or wrong {', '.join(wrong)}")
            break
    if not problems:
        try:
            pd.Timestamp(status["updated_at"])
        except ValueError:
            problems.append(f"key 'updated_at' is not an ISO-8601 time: {status['updated_at']!r}")
    if problems:
        raise ValueError(f"{path.name}: " + "; ".join(problems))
    return status


def _wrong_keys(mapping: dict, keys: dict[str, tuple[type, ...]]) -> list[str]:
    problems = []
    for key, types in keys.items():
        if key not in mapping:
            problems.append(f"missing key '{key}'")
        elif not isinstance(mapping[key], types) or isinstance(mapping[key], bool):
            problems.append(f"key '{key}' has type {type(mapping[key]).__name__}")
    return problems


def read_heartbeat(path: str | os.PathLike) -> dict:
    """Read and check ``heartbeat.json`` (see :data:`HEARTBEAT_KEYS`).

    Raises
    ------
    ValueError
        The file is not a JSON object with the keys, types and values of
        :data:`HEARTBEAT_KEYS` (message names the file and every failing key).
    """
    path = Path(path)
    try:
        beat = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path.name}: not valid JSON ({error})") from None
    if not isinstance(beat, dict):
        raise ValueError(f"{path.name}: expected a JSON object, got {type(beat).__name__}")
    problems = _wrong_keys(beat, HEARTBEAT_KEYS)
    if not problems:
        problems += [f"key 'worker': {p}" for p in _wrong_keys(beat["worker"], WORKER_KEYS)]
    if not problems:
        if beat["state"] not in HEARTBEAT_STATES:
            problems.append(f"key 'state' is {beat['state']!r}, not one of {HEARTBEAT_STATES}")
        if beat["worker"]["state"] not in WORKER_STATES:
            problems.append(
                f"key 'worker': state {beat['worker']['state']!r} is not one of {WORKER_STATES}"
            )
        if not (math.isfinite(beat["poll_s"]) and beat["poll_s"] > 0):
            problems.append(f"key 'poll_s' is {beat['poll_s']!r}, not a positive number")
        for key in ("time", "last_file_taken_at"):
            if beat[key] is not None:
                try:
                    pd.Timestamp(beat[key])
                except ValueError:
                    problems.append(f"key '{key}' is not an ISO-8601 time: {beat[key]!r}")
    if problems:
        raise ValueError(f"{path.name}: " + "; ".join(problems))
    return beat


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


class StateFolder:
    """Cached, read-only view of a monitor's state folder.

    Parameters
    ----------
    folder : path
        The state folder; it may not exist yet.

    Notes
    -----
    Thread-safe: the dashboard's request threads share one instance, so each file is
    parsed once per change, however many screens are watching.
    """

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self._cache: dict[str, FileSnapshot] = {}
        self._lock = threading.Lock()

    def path(self, name: str) -> Path:
        return self.folder / STATE_FILES[name][0]

    def signature(self, name: str) -> Signature | None:
        """(mtime in ns, size, inode) of a state file, None when absent."""
        try:
            st = os.stat(self.path(name))
        except OSError:
            return None
        return (st.st_mtime_ns, st.st_size, st.st_ino)

    def signatures(self) -> dict[str, Signature | None]:
        return {name: self.signature(name) for name in STATE_FILES}

    def read(self, name: str) -> FileSnapshot:
        """The current content of state file *name* (re-read only when it changed)."""
        if name not in STATE_FILES:
            raise KeyError(name)
        with self._lock:
            signature = self.signature(name)
            cached = self._cache.get(name)
            if cached is not None and cached.signature == signature:
                return cached
            last_good = cached.data if cached is not None else None
            filename, contract = STATE_FILES[name]
            if signature is None:
                if not self.folder.is_dir():
                    error = f"state folder {self.folder} does not exist (yet)"
                else:
                    error = f"{filename} not written yet"
                # a file that disappears (monitor reset) takes its data with it
                snapshot = FileSnapshot(name, None, None, error)
            else:
                try:
                    if contract is None:
                        reader = read_heartbeat if name == "heartbeat" else read_status
                        data = reader(self.path(name))
                    else:
                        data = read_table(self.path(name), contract)
                    snapshot = FileSnapshot(name, signature, data, None)
                except ContractError as error:
                    reason = "; ".join(str(v) for v in error.violations[:3])
                    snapshot = FileSnapshot(name, signature, last_good, f"{filename}: {reason}")
                except (OSError, ValueError) as error:
                    reason = _first_line(error)  # the JSON readers name the file already
                    if not reason.startswith(f"{filename}: "):
                        reason = f"{filename}: {reason}"
                    snapshot = FileSnapshot(name, signature, last_good, reason)
            self._cache[name] = snapshot
            return snapshot
