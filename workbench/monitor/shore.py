"""What the monitor hands on: an alarm hook and the daily key indicators for the shore.

The reference work's monitoring concept (ch. 8.2) streams *key indicators* to stations on
land rather than the raw data: per mode its median frequency, damping and model residual,
and the alarms, a few kilobytes a day over a ship's satellite link.

:class:`AlarmHook` runs a command of the user's (``workbench monitor --on-alarm COMMAND``)
once per new alarm episode, with the alarm as JSON on its standard input; the episodes
already handed on are kept in ``<state>/alarm_hook.json``, so a restarted monitor does not
repeat them. The command runs in a thread of its own with a timeout, so it never delays a
block; its failure (exit status, timeout, not found) becomes one of the monitor's messages
and the monitor goes on.

:func:`write_daily_indicators` writes ``<state>/shore/key_indicators_YYYY-MM-DD.json``
and ``.csv`` for each UTC day of the voyage (:func:`daily_indicators`), each atomically.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shlex
import subprocess
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_contracts import atomic_path

__all__ = [
    "INDICATOR_COLUMNS",
    "AlarmHook",
    "alarm_message",
    "daily_indicators",
    "parse_command",
    "write_daily_indicators",
]

log = logging.getLogger("workbench")

#: File in the state folder listing the alarm episodes already handed to the hook.
HOOK_FILE = "alarm_hook.json"
#: Folder of the daily key-indicator files in the state folder.
SHORE_FOLDER = "shore"
#: Columns of the daily CSV, one row per mode.
INDICATOR_COLUMNS = (
    "day",
    "mode",
    "blocks",
    "median_frequency_hz",
    "median_damping_ratio",
    "median_model_residual_hz",
    "median_model_residual_percent",
    "blocks_outside_band",
    "alarms",
)


def parse_command(text: str) -> tuple[str, ...]:
    """The argument vector of *text*, split as a POSIX shell would split it (quotes,
    escapes) but never run by a shell.

    Raises
    ------
    ValueError
        Empty, or unbalanced quotes (the message names the command).
    """
    try:
        argv = tuple(shlex.split(text))
    except ValueError as error:
        raise ValueError(f"--on-alarm {text!r}: {error}") from None
    if not argv:
        raise ValueError("--on-alarm needs a command, got an empty one")
    return argv


def _text_time(value) -> str | None:
    if value is None or pd.isna(value):
        return None
    return pd.Timestamp(value).tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%SZ")


def _number(value) -> float | None:
    if value is None or pd.isna(value):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def alarm_message(row: pd.Series | Any, *, state: Path, host: str) -> dict[str, Any]:
    """The JSON object handed to the alarm hook for one episode (ALARMS contract row)."""
    return {
        "event": "alarm",
        "alarm": int(row.alarm),
        "start_block": int(row.start_block),
        "end_block": int(row.end_block),
        "start_time": _text_time(row.start_time),
        "end_time": _text_time(row.end_time),
        "peak_block": int(row.peak_block),
        "peak_statistic": _number(row.peak_statistic),
        "limit": _number(row.limit),
        "modes": str(row.modes),
        "top_mode": int(row.top_mode),
        "top_mode_shift_percent": _number(row.top_mode_shift_percent),
        "state": str(state),
        "host": host,
        "sent_at": pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ"),
    }


class AlarmHook:
    """Run *command* once per new alarm episode, the episode as JSON on its stdin.

    Parameters
    ----------
    command : sequence of str
        Argument vector (:func:`parse_command`); run without a shell.
    state : path-like
        The monitor's state folder (where :data:`HOOK_FILE` is kept).
    timeout_s : float
        A run longer than this is killed and reported. [s]
    report : callable
        Called with one line per failure (the monitor's messages).
    host : str
        Name of the machine, part of the message.

    Notes
    -----
    An episode is new when its first block (``start_block``) was not handed on before:
    the episode growing block by block is the same alarm. It is handed on once, whether
    the command succeeds or not (a failing command is reported, not retried at every
    block).
    """

    def __init__(
        self,
        command: Sequence[str],
        state: str | os.PathLike,
        *,
        timeout_s: float = 30.0,
        report: Callable[[str], None] = lambda line: None,
        host: str = "",
    ) -> None:
        if not command:
            raise ValueError("command must name a program, got an empty one")
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s={timeout_s!r} must be a positive number of seconds")
        self.command = tuple(str(a) for a in command)
        self.state = Path(state)
        self.timeout_s = float(timeout_s)
        self.report = report
        self.host = host
        self._sent = self._load()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()

    @property
    def path(self) -> Path:
        return self.state / HOOK_FILE

    def _load(self) -> set[int]:
        try:
            found = json.loads(self.path.read_text(encoding="utf-8"))
            return {int(b) for b in found["start_blocks"]}
        except FileNotFoundError:
            return set()
        except (OSError, ValueError, KeyError, TypeError) as error:
            self.report(f"on-alarm: {self.path.name} unreadable ({error}); starting afresh")
            return set()

    def _save(self) -> None:
        with atomic_path(self.path) as tmp:
            Path(tmp).write_text(
                json.dumps({"start_blocks": sorted(self._sent)}, indent=1), encoding="utf-8"
            )

    def notify(self, alarms: pd.DataFrame) -> list[dict]:
        """Hand on the episodes of *alarms* (ALARMS contract) not handed on before, each
        in a thread of its own; returns their messages."""
        new = [
            row for row in alarms.itertuples(index=False) if int(row.start_block) not in self._sent
        ]
        messages = [alarm_message(row, state=self.state, host=self.host) for row in new]
        if not messages:
            return []
        self._sent.update(int(row.start_block) for row in new)
        self._save()
        for message in messages:
            thread = threading.Thread(
                target=self._run, args=(message,), name="workbench-on-alarm", daemon=True
            )
            thread.start()
            with self._lock:
                self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        return messages

    def _run(self, message: dict) -> None:
        name = shlex.join(self.command)
        what = f"on-alarm: `{name}` for alarm {message['alarm']} (block {message['start_block']})"
        try:
            done = subprocess.run(
                self.command,
                input=json.dumps(message).encode(),
                capture_output=True,
                timeout=self.timeout_s,
                check=False,
            )
        except subprocess.TimeoutExpired:
            self.report(f"{what} timed out after {self.timeout_s:g} s and was stopped")
            return
        except OSError as error:
            self.report(f"{what} could not be started: {error.strerror or error}")
            return
        if done.returncode != 0:
            lines = done.stderr.decode(errors="replace").strip().splitlines()
            said = f": {lines[-1][:200]}" if lines else ""
            self.report(f"{what} failed with exit status {done.returncode}{said}")
        else:
            log.info("%s: handed on", what)

    def wait(self, timeout_s: float | None = None) -> None:
        """Wait for the runs under way (each is bounded by its own timeout)."""
        limit = self.timeout_s + 5.0 if timeout_s is None else timeout_s
        with self._lock:
            threads = list(self._threads)
        for thread in threads:
            thread.join(timeout=limit)


# ---------------------------------------------------------------------------- shore
def _day_of(times: pd.Series) -> pd.Series:
    return pd.to_datetime(times, utc=True).dt.strftime("%Y-%m-%d")


def daily_indicators(
    day: str,
    tracked: pd.DataFrame,
    forecast: pd.DataFrame | None = None,
    alarms: pd.DataFrame | None = None,
    *,
    option: str | None = None,
) -> dict[str, Any]:
    """Key indicators of one UTC *day* (``YYYY-MM-DD``; blocks starting that day).

    Parameters
    ----------
    tracked : DataFrame
        Tracked modal table (MODAL contract).
    forecast : DataFrame, optional
        FORECAST contract: the model residual (SSI minus model prediction) and the blocks
        outside the model's 95 % band, of *option* (default A when present, else B).
    alarms : DataFrame, optional
        ALARMS contract: the episodes that overlap the day.

    Returns
    -------
    dict
        ``day``, ``blocks`` (tracked blocks that day), ``first_block``, ``last_block``,
        ``option``, ``modes`` (one dict per mode with the :data:`INDICATOR_COLUMNS`
        values) and ``alarms`` (the day's episodes).
    """
    start = pd.Timestamp(day, tz="UTC")
    end = start + pd.Timedelta(days=1)
    rows = tracked[(tracked["block_start"] >= start) & (tracked["block_start"] < end)]
    if len(rows):
        first, last = int(rows["block"].min()), int(rows["block"].max())
    else:
        first = last = None
    residual = None
    shown = None
    if forecast is not None and len(forecast) and first is not None:
        shown = option
        present = set(forecast["option"].unique())
        if shown is None:
            shown = "A" if "A" in present else ("B" if "B" in present else None)
        part = forecast[(forecast["option"] == shown) & forecast["block"].between(first, last)]
        part = part[part["ssi_frequency_hz"].notna() & part["model_frequency_hz"].notna()]
        residual = part.assign(
            residual_hz=part["ssi_frequency_hz"] - part["model_frequency_hz"],
            residual_percent=100.0 * (part["ssi_frequency_hz"] / part["model_frequency_hz"] - 1),
            outside=(part["ssi_frequency_hz"] < part["model_lower_hz"])
            | (part["ssi_frequency_hz"] > part["model_upper_hz"]),
        )
    episodes = []
    if alarms is not None and len(alarms):
        on = alarms[(alarms["start_time"] < end) & (alarms["end_time"] >= start)]
        for row in on.sort_values("start_block").itertuples(index=False):
            episodes.append(
                {
                    "alarm": int(row.alarm),
                    "start_time": _text_time(row.start_time),
                    "end_time": _text_time(row.end_time),
                    "peak_statistic": _number(row.peak_statistic),
                    "limit": _number(row.limit),
                    "modes": str(row.modes),
                    "top_mode": int(row.top_mode),
                    "top_mode_shift_percent": _number(row.top_mode_shift_percent),
                }
            )
    modes = []
    for mode, part in rows.groupby("mode", sort=True):
        found = None if residual is None else residual[residual["mode"] == mode]
        has = found is not None and len(found) > 0
        modes.append(
            {
                "day": day,
                "mode": int(mode),
                "blocks": int(part["block"].nunique()),
                "median_frequency_hz": _number(part["frequency_hz"].median()),
                "median_damping_ratio": _number(part["damping_ratio"].median()),
                "median_model_residual_hz": _number(found["residual_hz"].median()) if has else None,
                "median_model_residual_percent": (
                    _number(found["residual_percent"].median()) if has else None
                ),
                "blocks_outside_band": int(found["outside"].sum()) if has else None,
                "alarms": sum(1 for e in episodes if e["top_mode"] == int(mode)),
            }
        )
    return {
        "day": day,
        "blocks": int(rows["block"].nunique()),
        "first_block": first,
        "last_block": last,
        "option": shown,
        "modes": modes,
        "alarms": episodes,
    }


def _csv_value(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def write_daily_indicators(
    state: str | os.PathLike,
    tracked: pd.DataFrame,
    forecast: pd.DataFrame | None = None,
    alarms: pd.DataFrame | None = None,
    *,
    days: Sequence[str] | None = None,
    option: str | None = None,
) -> list[Path]:
    """Write ``<state>/shore/key_indicators_<day>.json`` and ``.csv`` (one row per mode,
    :data:`INDICATOR_COLUMNS`) for each of *days* (default: every day of *tracked*),
    atomically; returns the JSON files written.

    The JSON carries the day's summary, the modes (as the CSV) and the alarm episodes;
    ``updated_at`` says when (UTC). A day is written again while blocks are added to it.
    """
    folder = Path(state) / SHORE_FOLDER
    folder.mkdir(exist_ok=True)
    if days is None:
        days = sorted(_day_of(tracked["block_start"]).unique()) if len(tracked) else []
    written = []
    for day in days:
        summary = daily_indicators(day, tracked, forecast, alarms, option=option)
        summary["updated_at"] = pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ")
        path = folder / f"key_indicators_{day}.json"
        with atomic_path(path) as tmp:
            Path(tmp).write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
        lines = [",".join(INDICATOR_COLUMNS)]
        lines += [",".join(_csv_value(m[c]) for c in INDICATOR_COLUMNS) for m in summary["modes"]]
        with atomic_path(path.with_suffix(".csv")) as tmp:
            Path(tmp).write_text("\n".join(lines) + "\n", encoding="utf-8")
        written.append(path)
    return written


def days_of_blocks(block_starts: Sequence | np.ndarray) -> list[str]:
    """The UTC days (``YYYY-MM-DD``) of the given block starts, sorted, each once."""
    if len(block_starts) == 0:
        return []
    return sorted(_day_of(pd.Series(pd.to_datetime(block_starts, utc=True))).unique())
