"""The monitor: identify blocks as their data lands, track and forecast incrementally.

See :mod:`workbench.monitor` for the state folder, the rules for complete files, late
files and resuming.
"""

from __future__ import annotations

import collections
import functools
import json
import logging
import math
import os
import re
import socket
import threading
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from data_contracts import MODAL, ContractError, atomic_path, set_grid, write_table
from data_contracts.parts import read_since

from ..blocks import BlockGrid
from ..errors import OptionError, WorkbenchError
from ..identification import IdentifyOptions, identify_block, input_fingerprints, resolved_run
from ..identification.adaptive import AdaptiveBlockOptions
from ..identification.engine import BlockTask
from ..processes import interrupts_deferred, worker_initializer
from ..sid.harmonics import HarmonicOptions
from ..sid.tracking import TrackingOptions
from ..signals.file_conditioning import block_cuts
from ..store import (
    CUT_COLUMNS,
    BlockStore,
    StoreDamaged,
    StoreLock,
    block_ranges,
    move_aside,
    unreadable_store_file,
)
from .adaptive import LEFT_OUT, AdaptiveLengths
from .conditioning import block_conditioner, forget_conditioned
from .data_health import DATA_HEALTH_COLUMNS, data_health_frame, data_health_row
from .log_clock import LiveClockCheck
from .log_record import ShipLogRecord
from .notes import NOTES_FILE, NoteList
from .outlook import (
    ForecastSettings,
    OutlookReport,
    empty_table,
    forget_writers,
    part_writer,
    update_outlook,
)
from .readiness import settled
from .shore import AlarmHook
from .state_format import check_state_format
from .taken import TakenFiles
from .tracking import IncrementalTracking, LabelsUnreadable
from .watcher import FolderWatcher, LandedFile

log = logging.getLogger("workbench")

__all__ = ["DATA_HEALTH_COLUMNS", "Monitor", "MonitorOptions"]

_NS = 1_000_000_000


def _newest_time(log: pd.DataFrame) -> pd.Timestamp:
    """The ship log's newest time, UTC (NaT for an empty log): the maximum of its times,
    not of the whole column converted first."""
    newest = pd.Timestamp(log["time"].max())
    return newest.tz_localize("UTC") if newest is not pd.NaT and newest.tzinfo is None else newest


@dataclass(frozen=True)
class MonitorOptions:
    """Settings of :class:`Monitor`.

    Attributes
    ----------
    identify : IdentifyOptions
        Block grid, conditioning, SSI and selection (as ``workbench identify``).
    tracking : TrackingOptions
        As ``workbench track``.
    harmonics : HarmonicOptions
        Shaft orders and blades: with a ship log, the selected modes are marked as
        ``identify --dship`` marks them, from the logged shaft speed
        (:func:`~workbench.sid.harmonics.mark_shaft_orders`; a block's marks are final once
        the log covers it) or, without it, from the speed
        (:class:`~workbench.sid.harmonics.SpeedFollowing`), which keeps the harmonics out
        of the tracked table.
    forecast : ForecastSettings
        As ``workbench forecast`` and ``workbench health``.
    poll_s : float
        Time between two looks at the folder, and between two heartbeats (written by a
        thread of their own, whatever the blocks are doing; see :mod:`workbench.monitor`). [s]
    settle_s : float
        A file is taken once unmodified this long (see :mod:`workbench.monitor.watcher`). [s]
    late_s : float
        Missing data is waited for until data this much newer (in data time) has landed;
        then the blocks over the hole are decided as a batch run over the files present
        would decide them. [s]
    flush_after_s : float
        When no file has landed for this long (wall time), the blocks still waiting (the
        last ones, or those over a hole) are decided with the files present. [s]
    background : bool
        Recompute forecast and health in a background process, so that they never delay
        the next block (live mode); ``False``: in this process after the blocks.
    on_alarm : tuple of str
        Command (argument vector, run without a shell) run once per new alarm episode
        with the alarm as JSON on its stdin (:class:`~workbench.monitor.shore.AlarmHook`);
        empty: none.
    on_alarm_timeout_s : float
        A run of *on_alarm* longer than this is stopped and reported. [s]
    key_indicators : bool
        Write the daily key indicators for the shore (``<state>/shore/``,
        :func:`~workbench.monitor.shore.write_daily_indicators`).
    adaptive : AdaptiveBlockOptions, optional
        Block length by conditions (``--block-minutes auto``): each block's length decided
        as ``identify --block-minutes auto`` decides it, as the data lands
        (:mod:`workbench.monitor.adaptive`); *identify*'s ``length_s`` and ``step_s`` are
        replaced by the adaptive step. None: blocks of *identify*'s one length.
    cases : str, optional
        With *adaptive*: the voyage's states (CSV with ``case``, ``start``, ``end``); a
        block does not straddle a change of state. Read again when it changes.
    """

    identify: IdentifyOptions = field(default_factory=IdentifyOptions)
    tracking: TrackingOptions = field(default_factory=TrackingOptions)
    harmonics: HarmonicOptions = field(default_factory=HarmonicOptions)
    forecast: ForecastSettings = field(default_factory=ForecastSettings)
    poll_s: float = 1.0
    settle_s: float = 1.0
    late_s: float = 900.0
    flush_after_s: float = 900.0
    background: bool = True
    on_alarm: tuple[str, ...] = ()
    on_alarm_timeout_s: float = 30.0
    key_indicators: bool = True
    adaptive: AdaptiveBlockOptions | None = None
    cases: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "on_alarm", tuple(str(a) for a in self.on_alarm))
        timeout = self.on_alarm_timeout_s
        if not (isinstance(timeout, int | float) and math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"on_alarm_timeout_s={timeout!r} must be a positive number of seconds")
        for name in ("poll_s", "settle_s", "late_s", "flush_after_s"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}={value!r} must be a non-negative number of seconds")
        if self.poll_s <= 0:
            raise ValueError(f"poll_s={self.poll_s!r} must be positive")
        if self.identify.short_record != "error":
            raise ValueError("short_record='one-block' is for a finished record, not a monitor")
        if self.cases is not None and self.adaptive is None:
            raise ValueError("cases are used by the adaptive block length only (adaptive=)")
        if self.adaptive is not None:  # the reference grid: blocks of one step
            step = float(self.adaptive.step_s)
            if (self.identify.length_s, self.identify.step_s) != (step, step):
                object.__setattr__(
                    self, "identify", replace(self.identify, length_s=step, step_s=step)
                )


@dataclass
class _Voyage:
    """What the first files fixed: grid, channels, rate, resolved options."""

    grid: BlockGrid
    channels: tuple[str, ...]
    rate_hz: float
    options: IdentifyOptions
    per_file: bool
    parameters: dict
    #: With blocks of varying length: the lengths' decider, and per length the grid,
    #: the resolved options and whether files are conditioned once each.
    lengths: AdaptiveLengths | None = None
    by_length: dict = field(default_factory=dict)

    def length_run(self, length_s: float):
        """(grid, options, per_file) of the blocks *length_s* long (as ``identify
        --block-minutes auto`` runs each length)."""
        found = self.by_length.get(length_s)
        if found is None:
            grid = self.lengths.grid(length_s)
            options = replace(self.unresolved, length_s=float(length_s))
            options = options.resolved(self.rate_hz)
            options, per_file, _ = resolved_run(options, self.rate_hz, grid, self.channels)
            found = self.by_length[length_s] = (grid, options, per_file)
        return found

    unresolved: IdentifyOptions | None = None


class Monitor:
    """Follow *watch* and keep the state folder *state* up to date.

    Parameters
    ----------
    watch : path-like
        Folder where acceleration files arrive (subfolders included).
    state : path-like
        The state folder (see :mod:`workbench.monitor`); its ``store`` subfolder is the
        per-block store, which makes the monitor resumable.
    dship : path-like, optional
        The ship log (growing); without it no forecast and no health chart.
    options : MonitorOptions, optional
    """

    def __init__(self, watch, state, *, dship=None, options: MonitorOptions | None = None):
        self.watch = Path(watch)
        self.state = Path(state)
        self.dship = Path(dship) if dship is not None else None
        self.options = options or MonitorOptions()
        if self.state.exists() and not self.state.is_dir():
            raise WorkbenchError(f"{self.state}: state folder is a file")
        self.state.mkdir(parents=True, exist_ok=True)
        #: Why the store refused a file because it is itself unreadable ("" while whole).
        self.store_damaged = ""
        self.store_path = self.state / "store"
        self.store_path.mkdir(exist_ok=True)
        # one monitor per state folder: the store's lock, held for the monitor's life
        self._lock = StoreLock(self.store_path).acquire()
        self._log_warnings_said: set[str] = set()  # the ship log's warnings said so far
        forecast = self.options.forecast
        # the ship log the state folder's results came from: another one refused, before
        # anything in the folder is touched; and a column the mapping names that the log
        # lacks (read now when it is there; later, the outlook says so)
        self.log_record = ShipLogRecord(
            self.state, self.dship, dict(forecast.dship_mapping), forecast.dship_utc_offset
        )
        content = None  # the part of the log read now
        try:
            log_notes = self.log_record.check(
                has_results=(self.store_path / "store.json").is_file()
            )
            if self.dship is not None and self.dship.is_file():
                self._read_log(refuse_mapping=True)
                content = self._log_content()
            # an older folder is migrated, a newer one refused
            migrated = check_state_format(self.state)
        except (WorkbenchError, OptionError, ContractError):
            self._lock.release()
            raise
        self.log_record.update(content)
        if migrated is not None:
            log.warning("%s", migrated)
        forget_writers(self.state)  # parts written by an earlier run are read again
        repaired = _remove_unreadable_parts(self.state)
        self.watcher = FolderWatcher(
            self.watch,
            settle_s=self.options.settle_s,
            read_options=self.options.identify.read_options,
            exclude=[self.dship] if self.dship is not None else [],
        )
        self.stop_event = threading.Event()
        self.voyage: _Voyage | None = None
        self.store: BlockStore | None = None
        #: the files taken, in time order, and as placed (:meth:`_placed`): a newly taken
        #: file is placed on from the placement of those before it
        self.files = TakenFiles()
        self._drift_noted: set[Path] = set()  # first files of the runs said to drift
        # the files taken before the grid was fixed that are still to be taken again
        self._retaking: collections.deque[LandedFile] = collections.deque()
        self._retimed_noted: set[Path] = set()  # files said to be re-timed for jitter
        self.done: set[int] = set()
        #: Where the decided blocks of a drifting record were cut (the store's
        #: CUT_COLUMNS): block -> (a file taken, by content; the index of the block's
        #: first sample in it); the others were cut at their labels. Those said to lie off
        #: the line of the files landed since; the files taken by content and back.
        self._cuts: dict[int, tuple[str, int]] = {}
        self._cuts_said: set[int] = set()
        #: With varying lengths: the stored blocks' lengths (the store's ``lengths``). [s]
        self._stored_lengths: dict[int, float] = {}
        #: Blocks said to be missed by a drifting record's samples (:meth:`_note_missed_blocks`).
        self._missed_said: set[int] = set()
        self._taken_paths: dict[str, Path] = {}
        self._taken_digests: dict[Path, str] = {}
        self._done_below = 0  # every block before it is in done (see _first_undecided)
        #: Of the blocks this process decided (not those a restart found stored): how
        #: many were identified, and each skipped one as ``block``, ``files`` (names),
        #: ``reason`` and ``faults`` (the dropped channels' reasons), what
        #: :meth:`nothing_identified` reads.
        self.identified_here = 0
        self.skipped_here: list[dict] = []
        #: The notes of this run (the recent ones after a long run); every one is also
        #: appended to ``<state>/notes.txt`` (:mod:`workbench.monitor.notes`).
        self.messages: NoteList = NoteList(self.state / NOTES_FILE)
        if migrated is not None:
            self.messages.append(migrated)
        for note in log_notes:
            log.warning("%s", note)
            self.messages.append(note)
        for notice in repaired:
            log.warning("%s", notice)
            self.messages.append(notice)
        self.conditioned_files = [0]  # files conditioned (per-file path)
        self._shared: dict = {}
        self._health_rows: list[dict] = []
        # _missing_blocks: (blocks and reasons, the rows list read, rows read)
        self._missing_scan: tuple[dict[int, str], list | None, int] = ({}, None, 0)
        # data_health.parquet: every part is written next (at the start), else the parts
        # from the oldest block added since the last write
        self._health_rows_all = True
        self._health_rows_from: int | None = None
        self.baseline = None  # the ship's health baseline (--baseline), checked here
        reference_modes = None
        if self.options.forecast.health_baseline is not None:
            self.baseline = self._load_baseline()
            reference_modes = self.baseline.modes
        self.tracking = IncrementalTracking(self.options.tracking, reference_modes)
        self._last_landing = time.monotonic()
        self._outlook_due = False
        self._outlook_future = None
        self._executor = None
        self.outlook_reports: list[OutlookReport] = []
        self._dship_key = None
        self._defer_outlook = False
        self._log_complete = False
        self._dirty = True
        self._saved_grid = self._stored_grid()
        self._given_up: tuple[tuple[int, int], list[dict]] = ((-1, -1), [])
        # the blocks the last step planned and had not decided (the status's waiting ones)
        self._planned: Sequence = ()
        # each tracked row's harmonic marks (_mark_harmonics) and whether they are kept
        # (the log covers the row's block)
        self._marks = np.empty((0, 3))
        self._marks_kept = np.zeros(0, dtype=bool)
        # block -> shaft speed the marks used (identify's shaft.csv: logged, or from the speed
        # where the log fails), once the log covers it; and with the blocks it does not yet
        self._block_shaft_rpm: dict[int, float] = {}
        self._shaft_rpm_of_block: dict[int, float] = {}
        self._shaft_logged = False  # a block tracked so far has a usable shaft speed
        # the logged shaft speed judged against the speed over the blocks tracked so far
        # (_judge_shaft_log): why it is not used (a frozen log), or None; and each block's
        # logged shaft speed and speed, once the log's verdicts on its readings are final
        self._shaft_log_note: str | None = None
        self._shaft_rows: dict[int, tuple[float, float, float]] = {}
        # each tracked row's mark at the logged shaft speed's orders, and whether kept
        self._orders_at = np.zeros(0, dtype=bool)
        self._orders_kept = np.zeros(0, dtype=bool)
        self._judge_pending = False  # a block's shaft speed above is not final yet
        self._health_schedule = ""  # from which block the health chart monitors
        self._marks_pending = False
        self._marked: np.ndarray | None = None  # the tracked rows' marks, last given
        # the ship log's shaft-speed tests kept as it grows (_marking_log): the
        # LiveShaftLog and the log's read generation it follows
        self._live_shaft: tuple[int, object] | None = None
        # the speed-following test of a log without the shaft speed (_mark_from_speed):
        # the test, each tracked row's index in it, each covered block's speed
        self._speed_test = None
        self._speed_index = np.empty(0, dtype=np.int64)
        self._block_speed: dict[int, float] = {}
        # the shaft rate per knot it found [Hz/kn] and every tracked block's speed [kn]
        # (those the log does not cover yet included), for the order lines
        self._shaft_hz_per_kn = np.nan
        self._speed_of_block: dict[int, float] = {}
        # liveness (heartbeat.json): the last file taken and the background worker's state
        self._last_taken: tuple[str, pd.Timestamp] | None = None
        # what the main loop is doing and since when: a heartbeat from a live thread beside
        # a main loop stuck in one activity longer than stall_s is "not responding" too
        self._activity: tuple[str, pd.Timestamp] = ("starting", pd.Timestamp.now(tz="UTC"))
        self._worker = {"state": "none", "pid": None, "message": ""}
        self._worker_lock = threading.Lock()
        self._heartbeat_stop = threading.Event()
        self._heartbeat_thread: threading.Thread | None = None
        self.host = socket.gethostname()
        # handed on: the alarm hook and the shore's daily key indicators
        self.alarm_hook = None
        if self.options.on_alarm:
            self.alarm_hook = AlarmHook(
                self.options.on_alarm,
                self.state,
                timeout_s=self.options.on_alarm_timeout_s,
                report=self._report,
                host=self.host,
            )
        self._indicators_through = -1  # newest block in the daily key-indicator files
        self._alarms_seen: tuple = (None, None)  # (size, mtime) of alarms.parquet, table
        self._tracked: pd.DataFrame | None = None  # the tracked table last written
        #: After a restart without readable labels: why, and the tracked table the
        #: earlier run wrote, which the replay must give again (:meth:`_labels_again`).
        self._labels_lost: tuple[str, pd.DataFrame | None] | None = None
        # with blocks of varying length: each decided block's length and stationarity
        # (plan row), None for a block no length fits
        self._lengths: dict[int, dict | None] = {}
        self._length_log_key = None  # the ship log's (size, mtime) when lengths last waited
        #: identify's check of the ship log's clock, on the blocks identified so far
        #: (:mod:`workbench.monitor.log_clock`)
        self.clock_check = LiveClockCheck()

    def _load_baseline(self):
        """The health baseline, refused (one line, exit 1) when unreadable or when the ship
        log present lacks a column its model needs."""
        from ..shm import BaselineError
        from .structural_health import load_baseline

        path = self.options.forecast.health_baseline
        try:
            baseline = load_baseline(path)
        except OSError as error:
            self._lock.release()
            raise WorkbenchError(f"{path}: cannot read ({error.strerror or error})") from None
        except BaselineError as error:
            self._lock.release()
            raise WorkbenchError(str(error)) from None
        log = self._read_log()
        if log is not None:
            try:
                baseline.check_predictors(log, str(self.dship))
            except BaselineError as error:
                self._lock.release()
                raise WorkbenchError(str(error)) from None
        return baseline

    def _read_log(self, *, refuse_mapping: bool = False) -> pd.DataFrame | None:
        """The ship log as read now (None when absent or unreadable: the outlook says so),
        recorded as read (:mod:`workbench.monitor.log_record`). *refuse_mapping* (the
        start's read, before the state folder is checked: nothing recorded): a column the
        mapping names that the log lacks raises its ``ContractError``."""
        if self.dship is None or not self.dship.is_file():
            return None
        from data_contracts import ColumnMappingError

        from .outlook import _ship_log, _ship_log_content

        forecast = self.options.forecast
        read = (self.dship, dict(forecast.dship_mapping), forecast.dship_utc_offset)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                log = _ship_log(*read)
            except ColumnMappingError:
                if refuse_mapping:
                    raise
                log = None
            except (ValueError, OSError):
                log = None
        if log is not None and not refuse_mapping:
            self.log_record.update(_ship_log_content(*read))
        # each of the log's warnings said once a run, not again at every read of the growing
        # log (a duplicate or backward time is said with each line appended after it)
        for warning in caught:
            if str(warning.message) not in self._log_warnings_said:
                self._log_warnings_said.add(str(warning.message))
                warnings.warn(warning.message, stacklevel=2)
        return log

    def _log_content(self) -> tuple[int, str] | None:
        """The bytes of the ship log :meth:`_read_log` last read and their SHA-256."""
        from .outlook import _ship_log_content

        forecast = self.options.forecast
        return _ship_log_content(
            self.dship, dict(forecast.dship_mapping), forecast.dship_utc_offset
        )

    def _log_generation(self) -> int | None:
        """The read generation of the ship log :meth:`_read_log` gives: the same while the
        log only grew by appended rows (:class:`~workbench.monitor.ship_log.LiveShipLog`),
        None when not known."""
        from .outlook import _ship_log_generation

        forecast = self.options.forecast
        return _ship_log_generation(
            self.dship, dict(forecast.dship_mapping), forecast.dship_utc_offset
        )

    def _marking_log(self, log: pd.DataFrame, part: pd.DataFrame):
        """The ship log the marks of *part*'s blocks are computed from: the rows over them
        as the whole log's spike and frozen-sensor tests leave them, with the whole log's
        interval (:class:`~workbench.sid.harmonics.LiveShaftLog`, which takes only the rows
        appended since the last marks), or *log* itself when it was read again whole; and
        the :class:`~workbench.sid.harmonics.LiveShaftLog` holding the tests (which tells
        the blocks whose readings' verdicts are final)."""
        from ..sid.harmonics import LiveShaftLog

        generation = self._log_generation()
        if generation is None:  # the tests over the log given, for its verdicts
            live = LiveShaftLog()
            live.update(log)
            return log, live
        if (
            self._live_shaft is None
            or self._live_shaft[0] != generation
            or self._live_shaft[1].rows > len(log)
        ):
            self._live_shaft = (generation, LiveShaftLog())
        live = self._live_shaft[1]
        live.update(log)
        return live.window(log, part["block_start"], part["block_end"]), live

    @property
    def tracked_through(self) -> int:
        """Every block up to this one is decided and in the tracked table (-1: none)."""
        return self.tracking.tracked_through

    # ------------------------------------------------------------------ lifecycle
    def close(self, state: str = "stopped") -> None:
        """Finish the background work, write the final status and release the store."""
        self._stop_heartbeat()
        if self._outlook_future is not None:
            try:
                self._collect(self._outlook_future.result())
            except Exception as error:  # noqa: BLE001 - report, do not lose the status
                self.messages.append(f"forecast: {error}")
            self._outlook_future = None
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None
        if self.voyage is not None and self.tracking.tracked_through >= 0:
            if self._marks_pending:  # the log may cover the last blocks by now
                self._advance_tracking()
            if (
                self.dship is not None
                and not self._log_complete
                and _file_key(self.dship) != self._dship_key
            ):
                self._outlook_due = True
            if self._outlook_due:  # a clean stop leaves the outlook of every block
                self.update_outlook(background=False)
        if self.alarm_hook is not None:
            self.alarm_hook.wait()
        self._write_status(state)
        self.write_heartbeat("stopped")
        if self.store is not None:
            self.store.close()
            self.store = None
        self._lock.release()

    def __enter__(self) -> Monitor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def run(self, *, once: bool = False) -> None:
        """Poll until :attr:`stop_event` is set (by SIGINT/SIGTERM in the CLI), or, with
        *once*, process the files present and return.

        *once* treats the files present as all there will be: it waits for files still
        being written to settle, then decides every block (also those over holes and the
        last ones) as ``workbench identify`` over the same files would.
        """
        self.start_heartbeat()
        self._write_status("running", "starting")
        self._defer_outlook = once
        if once:
            waited = 0.0
            while True:
                self.step(flush=False)
                if self.stop_event.is_set() or not self.watcher.pending:
                    break
                if waited > max(self.options.flush_after_s, 10 * self.options.settle_s):
                    break
                time.sleep(self.options.poll_s)
                waited += self.options.poll_s
            if not self.stop_event.is_set():
                self.step(flush=True)
                if self._outlook_due or not self.outlook_reports:
                    self.update_outlook(background=False)
            return
        while not self.stop_event.is_set():
            idle = time.monotonic() - self._last_landing
            self.step(flush=idle >= self.options.flush_after_s)
            self.stop_event.wait(self.options.poll_s)

    # ------------------------------------------------------------------ one cycle
    def step(self, *, flush: bool = False) -> int:
        """Take the new complete files, identify every block that is ready, update the
        state folder; return the number of blocks decided."""
        self._doing("looking for new files")
        landed, messages = self.watcher.poll()
        self.messages += messages
        for item in landed:
            self._doing(f"reading {item.path.name}")
            self._take(item)
        if self.voyage is None and not self._anchor(flush):
            self._write_status("running", "waiting for the first complete files")
            return 0
        decided = 0
        lengths = self.voyage.lengths
        if lengths is not None and lengths.waiting_for_log:
            key = _file_key(self.dship)
            if key != self._length_log_key:  # a length waits for the log, which grew
                self._length_log_key = key
                self._dirty = True
        # blocks become ready only when data lands (or at a flush): plan only then
        ready = self._ready_blocks(flush) if (self._dirty or flush) else []
        self._dirty = False
        for planned in ready:
            if self.stop_event.is_set():
                self._dirty = True  # the rest is still ready next time
                break
            self._doing(f"identifying block {int(planned.block)}")
            self._process(planned)
            decided += 1
        if decided:
            self._outlook_due = True
            self._check_clock()
        elif (
            self.dship is not None and self.tracking.tracked_through >= 0 and not self._log_complete
        ):
            key = _file_key(self.dship)
            if key != self._dship_key:  # the ship log grew: the newest predictors change
                self._outlook_due = True
        self._poll_outlook()
        self._write_status("running")
        self._doing("waiting for files")
        return decided

    def _check_clock(self) -> None:
        """identify's check of the ship log's clock over the blocks identified so far,
        when due (:mod:`workbench.monitor.log_clock`): its warning said once, as a note."""
        if self.dship is None or not self.clock_check.due():
            return
        ship_log = self._read_log()
        if ship_log is None:  # not there yet, or unreadable (the outlook says so)
            return
        from data_contracts.dship_names import parse_utc_offset

        offset = self.options.forecast.dship_utc_offset
        offset = None if offset is None else parse_utc_offset(offset)
        warning = self.clock_check.check(ship_log, str(self.dship), offset)
        if warning is not None:
            log.warning("%s", warning)
            self.messages.append(warning)

    def _doing(self, what: str) -> None:
        """Record the main loop's current activity for the heartbeat."""
        self._activity = (what, pd.Timestamp.now(tz="UTC"))

    # ------------------------------------------------------------------ files
    def _stored_grid(self):
        config = self.store_path / "store.json"
        if not config.is_file():
            return None
        try:
            found = json.loads(config.read_text(encoding="utf-8"))
            return pd.Timestamp(found["grid_t0"]), tuple(found["channels"])
        except (OSError, ValueError, KeyError, TypeError) as error:
            damaged = unreadable_store_file(self.store_path, "store.json", error)
            raise WorkbenchError(_state_folder(str(damaged))) from None

    def _take(self, item: LandedFile) -> None:
        """Add a complete file to the voyage, or refuse it with a message."""
        from ..signals.block_plan import reference_channels

        self._last_landing = time.monotonic()
        info = item.info
        reason = lacking = extra = ""
        if self.voyage is not None:
            voyage = self.voyage
            half = pd.Timedelta(seconds=0.5 / voyage.rate_hz)
            try:  # a file lacking a few channels is read with them NaN, as identify does
                reference_channels([info], voyage.channels)
            except ValueError as error:
                channels = str(error).removeprefix(f"{info.path}: ")
                channels = channels.replace("from those of the other files", "from the voyage's")
            else:
                channels = ""
                lacking = ", ".join(c for c in voyage.channels if c not in info.channels)
                extra = ", ".join(c for c in info.channels if c not in voyage.channels)
            if info.sampling_rate_hz != voyage.rate_hz:
                reason = (
                    f"sampling rate {info.sampling_rate_hz:g} Hz, not {voyage.rate_hz:g} Hz "
                    "(the voyage's: that of most files); its span is a gap"
                )
            elif channels:
                reason = channels
            elif info.start_time < voyage.grid.t0 - half:
                reason = (
                    f"starts before the monitor's first block ({voyage.grid.t0.isoformat()}); "
                    "blocks are anchored at the first file"
                )
        placed = info
        digest = None
        if not reason:
            reason, placed = self._placed_among(info)
        if not reason and self.store is not None:
            try:
                fingerprint = input_fingerprints([placed])
                self.store.check_inputs(  # a file a late one moves is no changed input
                    fingerprint, placed_now=functools.partial(self._placed_now, info)
                )
                digest = str(fingerprint[0]["sha256"])
            except StoreDamaged as error:  # no file can be used: said by --once, exit 1
                reason = self.store_damaged = _state_folder(str(error))
            except WorkbenchError as error:
                reason = str(error)
        if reason:
            self.messages.append(f"{item.path.name}: not used: {reason}")
            log.warning("%s: not used: %s", item.path, reason)
            self.watcher.refuse(item.path)
            return
        if lacking:
            self.messages.append(
                f"{item.path.name}: channel(s) {lacking} missing; NaN there, dropped as faulty "
                "in the blocks holding it"
            )
        if extra:
            self.messages.append(
                f"{item.path.name}: channel(s) {extra} not among the voyage's (those most "
                "files carried when the monitor started); left out"
            )
        late = bool(self.files) and (info.start_time, str(info.path)) < (
            self.files[-1].info.start_time,
            str(self.files[-1].path),
        )
        before = list(self.files.placed_infos()) if late and self.voyage is not None else None
        self.files.add(item)
        if digest is not None:
            self._taken_digests[item.path], self._taken_paths[digest] = digest, item.path
        self._last_taken = (item.path.name, pd.Timestamp.now(tz="UTC"))
        if before is not None:
            self._note_moved(item, before)
        if placed.clock_shift_s:
            self._note_clock(item, placed)
        self._dirty = True
        if self.voyage is not None:
            self._note_too_late(item, placed)

    def _note_clock(self, item: LandedFile, placed) -> None:
        """Say how the newly taken *item* was re-timed (*placed*): for clock jitter, or -
        once per run - that the run's sample clock drifts from its stamps (as identify's
        summary says them, :func:`~workbench.signals.block_plan.place_files`)."""
        from ..signals.block_plan import CLOCK_JITTER_S, clock_drift_note, clock_runs

        files = self._placed()
        placement = self.files.placement()
        if files and files[-1].path == item.path:  # the newest file: its run is the last
            first = placement.files[placement.run_start]
            drifting = placement.last_run_drifting
            run_files = None  # the run's files, only when its drift is said
        else:
            infos = [f.info for f in files]
            run = next(r for r in clock_runs(infos) if any(i.path == item.path for i in r.files))
            first, drifting, run_files = run.files[0], run.drifting, run.files
        # a run after a gap may start off its stamp (on the record's sample count): its
        # files are re-timed to the previous file's end by their shift beyond the first's
        shift_s = placed.clock_shift_s - first.clock_shift_s
        if not drifting:
            if abs(shift_s) <= 0.5 / placed.sampling_rate_hz:
                return  # less than half a sample: on the previous file's lattice, unsaid
            if item.path in self._retimed_noted:  # taken again once the grid was fixed
                return
            self._retimed_noted.add(item.path)
            jitter = f"{CLOCK_JITTER_S * 1e3:g} ms"
            why = (
                f"a stamp within {jitter} of that end is taken as contiguous"
                if abs(shift_s) <= CLOCK_JITTER_S
                else f"its stamp more than {jitter} from that end but within {jitter} of the "
                "line of the run's stamps on its sample count, a sample clock off its rate: "
                "taken as contiguous"
            )
            self.messages.append(
                f"{item.path.name}: start re-timed by {shift_s * 1e3:+.1f} ms to the "
                f"previous file's end ({why})"
            )
        elif first.path not in self._drift_noted:
            self._drift_noted.add(first.path)
            if first.path == item.path and placement.run_start:  # a gap carried over
                before = placement.files[placement.run_start - 1]
                gap_s = (first.start_time - before.end_time).total_seconds()
                self.messages.append(
                    f"{item.path.name}: after a gap of {gap_s:.1f} s from {before.name}, on the "
                    "record's sample count (the line of its stamps carries the time over the "
                    f"gap): {first.clock_shift_s * 1e3:+.1f} ms from its stamp"
                )
                return
            if run_files is None:
                run_files = placement.files[placement.run_start :]
            self.messages.append(f"{item.path.name}: {clock_drift_note(run_files)}")

    def _placed_now(self, info, recorded: dict) -> dict | None:
        """The fingerprint of the file the store *recorded* (its ``path``) as the files
        taken (and those still to take again) place it with the new file *info* among
        them, or None when that file is not among them: a late file re-places the files
        from the first (:class:`~workbench.monitor.taken.TakenFiles`), so the span the
        store recorded for one of them may lie elsewhere now."""
        from ..signals.block_plan import place_files

        target = str(recorded["path"])
        infos = [f.info for f in self.files] + [f.info for f in self._retaking]
        if not any(str(i.path.resolve()) == target for i in infos):
            return None
        same_rate = [i for i in infos if i.sampling_rate_hz == info.sampling_rate_hz]
        try:
            placed = place_files(
                sorted([*same_rate, info], key=lambda i: (i.start_time, str(i.path)))
            )
        except ValueError:  # overlapping files: the placement cannot be told
            return None
        found = next(i for i in placed if str(i.path.resolve()) == target)
        try:
            return input_fingerprints([found])[0]
        except WorkbenchError:  # gone or unreadable now: not the recorded data
            return None

    def _note_moved(self, item: LandedFile, before: list) -> None:
        """Say which decided blocks used files that the late *item* moved (the files placed
        again from the first, as identify places them; *before*: their placed headers
        before it): they are kept as decided, from the files as placed then."""
        from ..signals.block_plan import CLOCK_JITTER_S

        half_ns = int(0.5e9 / self.voyage.rate_hz)
        after = {i.path: i for i in self.files.placed_infos()}
        placed_before = {i.path: i for i in before}
        moved = []
        for old in before:
            now = after.get(old.path)
            if now is not None and abs(now.start_time.value - old.start_time.value) > half_ns:
                moved.append((old, (now.start_time - old.start_time).total_seconds() * 1e3))
        if not moved:
            return
        edge = pd.Timedelta(seconds=max(CLOCK_JITTER_S, 0.5 / self.voyage.rate_hz))
        missing = self._missing_blocks()
        low, high = moved[0][0].start_time - edge, moved[-1][0].end_time + edge
        used = []
        for block in sorted(self.done):
            if block in missing:  # decided without data there: "landed after" says so
                continue
            start, end = self._decided_span(block, placed_before)
            if end <= low or start >= high:
                continue
            if any(min(end, o.end_time) - max(start, o.start_time) > edge for o, _ in moved):
                used.append(block)
        if used:
            largest = max((shift for _, shift in moved), key=abs)
            names = (
                moved[0][0].name
                if len(moved) == 1
                else (f"{moved[0][0].name} .. {moved[-1][0].name}")
            )
            self.messages.append(
                f"{item.path.name}: landed late: the record's files placed again from the "
                f"first, as identify places them, move {len(moved)} file(s) ({names}) by up to "
                f"{largest:+.1f} ms; block(s) {block_ranges(used)}, decided from them as placed "
                "before, are kept as decided"
            )

    def _decided_span(
        self, block: int, placed: dict | None = None
    ) -> tuple[pd.Timestamp, pd.Timestamp]:
        """Placed start and end of the samples the decided *block* was cut from (its own
        length's with varying lengths), as the files are placed now (or as *placed*,
        path -> placed header, places them): its label's span, or on a drifting record
        the span from where the clock line of the files landed then put its label
        (stored: :data:`~workbench.store.CUT_COLUMNS`), not where the line of the files
        landed since puts it."""
        grid = self.voyage.grid
        length = self._decided_length(block) if self.voyage.lengths is not None else None
        if length is not None:
            grid = self.voyage.length_run(length)[0]
        start, end = grid.start(block), grid.end(block)
        cut = self._cut_ns(block, placed)
        if cut is None:
            return start, end
        return pd.Timestamp(cut, tz="UTC"), pd.Timestamp(cut, tz="UTC") + (end - start)

    def _cut_of(self, planned) -> tuple[str, int] | None:
        """Where the drifting *planned* block is cut among the files taken (the file's
        SHA-256, sample index: :func:`~workbench.signals.block_plan.cut_in_file`), else
        None."""
        from ..signals.block_plan import cut_in_file

        if not planned.drifting:
            return None
        infos = self.files.placed_infos()
        starts, _ = self._coverage()
        position, index = cut_in_file(infos, starts, planned.sample_start.value)
        digest = self._taken_digests.get(infos[position].path)
        return None if digest is None else (digest, index)

    def _cut_ns(self, block: int, placed: dict | None = None) -> int | None:
        """Placed time of the first sample of the decided *block* of a drifting record
        (its stored cut) as the files are placed now, or as *placed* (path -> placed
        header) places them; None when it was cut at its label (or its file is not
        taken). [ns]"""
        from ..signals.block_plan import cut_placed_ns

        cut = self._cuts.get(block)
        path = None if cut is None else self._taken_paths.get(cut[0])
        if path is None:
            return None
        if placed is not None:
            info = placed.get(path)
        else:
            taken = self.files.placed_file(path)
            info = None if taken is None else taken.info
        return None if info is None else cut_placed_ns(info, cut[1])

    def _placed(self) -> list[LandedFile]:
        """The files taken, each with its header as a plan places it (re-timed for clock
        jitter, :func:`~workbench.signals.block_plan.place_files`), as identify places the
        same files: the blocks are cut, conditioned and checked from these times."""
        return self.files.placed()  # placed on from the files placed before (TakenFiles)

    def _placed_among(self, info) -> tuple[str, object]:
        """:func:`_placed_among` of *info* among the files taken; a file landing after all
        of them (the usual case) placed on from their placement (:meth:`_placed`)."""
        from ..signals.block_plan import FileOverlapError, duplicate_reason

        if self.voyage is not None and self.files:  # the files taken share the voyage's rate
            placement = self.files.placement()
            last = self.files[-1].info
            if info.sampling_rate_hz == self.voyage.rate_hz and (
                info.start_time,
                str(info.path),
            ) > (last.start_time, str(last.path)):
                try:
                    return "", placement.place(info)
                except FileOverlapError as error:
                    if _same_data(info, error.previous):
                        return duplicate_reason(error.previous), info
                    return f"overlaps {error.previous.name}", info
        return _placed_among(info, [f.info for f in self.files])

    def _note_too_late(self, item: LandedFile, placed) -> None:
        """Say so when *item* lands after blocks over its span were decided without it:
        its span as placed (*placed*: a stamp may lie the clock's walk before it), more
        than the clock jitter of it (within which a plan takes a block's edge as covered)."""
        from ..signals.block_plan import CLOCK_JITTER_S

        grid = self.voyage.grid
        start, end = placed.start_time.value, placed.end_time.value
        edge = int(max(CLOCK_JITTER_S, 0.5 / placed.sampling_rate_hz) * 1e9)
        missing = self._missing_blocks()
        blocks = np.fromiter(missing, dtype=np.int64, count=len(missing))
        # the spans they were cut from (a drifting record's: off their labels)
        low, high = grid.start(blocks).asi8.copy(), grid.end(blocks).asi8.copy()
        for k, block in enumerate(blocks.tolist()):
            cut = self._cut_ns(block)
            if cut is not None:
                low[k], high[k] = cut, cut + (high[k] - low[k])
        inside = np.minimum(high, end) - np.maximum(low, start)
        skipped = np.sort(blocks[inside > edge])
        if len(skipped) == 1:
            self.messages.append(
                f"{item.path.name}: landed after block {skipped[0]} was decided without it "
                "(skipped: gap); it is not redone"
            )
        elif len(skipped):
            self.messages.append(
                f"{item.path.name}: landed after blocks {block_ranges(skipped)} were "
                "decided without it (skipped: gap); they are not redone"
            )

    def _missing_blocks(self) -> dict[int, str]:
        """The decided blocks skipped for missing data (:func:`_missing_data`) and their
        reasons, in the order decided: kept as data-health rows are appended (all rows read
        again when the rows were replaced, at a restart)."""
        rows = self._health_rows
        found, seen, scanned = self._missing_scan
        if seen is not rows or scanned > len(rows):
            found, scanned = {}, 0
        for row in rows[scanned:]:
            if row["status"] == "skipped" and _missing_data(str(row["reason"])):
                found[int(row["block"])] = str(row["reason"])
        self._missing_scan = (found, rows, len(rows))
        return found

    def _anchor(self, flush: bool = False) -> bool:
        """Fix the grid, channels and options from the files (or the store); open the
        store. Waits while files are still being written (the first one may be among them)
        and, on a new state folder, until the data landed reach the end of the first block
        or ``late_s`` past the earliest file (unless *flush*): a first file landing late
        (after the second) still anchors the grid as in ``workbench identify``, and the
        channels are taken from more than one file."""
        if not self.files or (self.watcher.pending and self._saved_grid is None):
            return False
        from ..signals.block_plan import majority_channels, majority_rate, sort_out_files

        infos = [f.info for f in self.files]
        rate, count = majority_rate(infos)
        if 2 * count <= len(infos):  # no rate most files share (yet): which is the voyage's?
            if not flush:
                return False
            try:
                sort_out_files(infos)
            except ValueError as error:  # as identify says it, exit 1
                raise WorkbenchError(str(error)) from None
        # the voyage's: the rate most files have (a file at another rate is not used)
        first = next(info for info in infos if info.sampling_rate_hz == rate)
        if self._saved_grid is None and not flush:
            newest = max(f.info.end_time for f in self.files)
            wait_s = min(self.options.late_s, self.options.identify.length_s)
            if (newest - first.start_time).total_seconds() < wait_s:
                return False  # no block could be decided yet: an earlier file may land
        if self._saved_grid is not None:
            t0, channels = self._saved_grid
        else:  # as identify over these files: the set most of them carry
            t0 = first.start_time
            channels = majority_channels(
                [f.info for f in self.files if f.info.sampling_rate_hz == first.sampling_rate_hz]
            )
        options = self.options.identify
        try:
            options = options.resolved(first.sampling_rate_hz)
            options.check_data(
                SimpleNamespace(sampling_rate_hz=first.sampling_rate_hz, channels=channels)
            )
        except ValueError as error:
            from ..identification import IdentifyOptionsError

            raise IdentifyOptionsError(str(error)) from None
        grid = BlockGrid(t0, options.length_s, options.step_s)
        options, per_file, parameters = resolved_run(
            options, first.sampling_rate_hz, grid, channels
        )
        adaptive = self.options.adaptive
        if adaptive is not None:  # a store of fixed blocks is not resumed with auto
            parameters["adaptive"] = asdict(adaptive)
        if self.baseline is not None:  # a baseline of another ship or sensor layout
            from ..shm import BaselineError

            try:
                self.baseline.check_channels(channels, str(self.watch))
            except BaselineError as error:
                raise WorkbenchError(str(error)) from None
        self.voyage = _Voyage(
            grid, tuple(channels), float(first.sampling_rate_hz), options, per_file, parameters
        )
        if adaptive is not None:
            if self.dship is not None and _OWN_SPANS not in self.messages:
                self.messages.append(_OWN_SPANS)
            self.voyage.unresolved = self.options.identify
            self.voyage.lengths = AdaptiveLengths(
                adaptive,
                grid.t0,
                tuple(channels),
                options,
                path=self.state / "excitation.csv",
                cases=self.options.cases,
            )
        try:
            self.store = BlockStore.open(self.store_path, parameters)
        except WorkbenchError as error:  # the monitor's store is its state folder's
            message = _state_folder(str(error))
            if message == str(error):
                raise
            raise WorkbenchError(message) from None
        for notice in self.store.notices:  # damaged store files: their blocks are redone
            self.messages.append(notice)
            log.warning("%s", notice)
        self.done = self.store.completed_blocks()
        self._cuts = self.store.block_cuts()  # the spans the stored blocks were cut from
        if adaptive is not None:  # the stored blocks' lengths: the grids they were cut on
            stored = self.store.read("lengths")
            if len(stored):
                blocks = stored["block"].astype(int).tolist()
                lengths_s = stored["block_length_s"].astype(float).tolist()
                self._stored_lengths = dict(zip(blocks, lengths_s, strict=True))
        self._done_below = 0
        # files taken before the voyage was fixed are checked now (those still to take
        # among them placed with them: _placed_now)
        self._retaking = collections.deque(self.files.clear())
        while self._retaking:
            self._take(self._retaking.popleft())
        self._resume()
        return True

    # ------------------------------------------------------------------ readiness
    def _coverage(self) -> tuple[np.ndarray, np.ndarray]:
        return self.files.coverage()

    def _first_undecided(self) -> int:
        """The first block not decided (every block before it is)."""
        while self._done_below in self.done:
            self._done_below += 1
        return self._done_below

    def _ready_blocks(self, flush: bool):
        """Blocks not yet decided whose data (and, when decimating, whose neighbouring
        files) can no longer change, ascending."""
        from ..signals.block_plan import placed_block_numbers, placed_blocks

        if not self.files:
            return []
        voyage = self.voyage
        if voyage.lengths is not None:
            return self._ready_adaptive(flush)
        # the blocks a plan of the files placed lists, those not decided only: each
        # block's plan depends on the files alone (the files were checked as taken)
        infos = self.files.placed_infos()
        starts, ends = self._coverage()
        numbers = placed_block_numbers(infos, voyage.grid)
        numbers = numbers[numbers >= self._first_undecided()]
        plan = placed_blocks(
            infos,
            starts,
            ends,
            voyage.grid,
            [k for k in numbers.tolist() if k not in self.done],
            max_gap_s=voyage.options.max_gap_s,
            lattice=voyage.options.decimation_factor(voyage.rate_hz),
        )
        newest = int(ends.max())
        ready = [
            planned
            for planned in plan
            if flush or self._settled(planned, voyage.per_file, starts, ends, newest)
        ]
        self._planned = plan
        self._note_moved_cuts(infos, starts, ends)
        if flush:
            self._note_missed_blocks(infos, starts)
        return ready

    def _note_moved_cuts(self, infos, starts, ends) -> None:
        """Say once which decided blocks of a drifting record the clock line of the files
        landed now (*infos*, placed) cuts more than :func:`~workbench.signals.block_plan.
        cut_tolerance_s` from where they were cut (the line of the files landed then):
        they are kept as decided. A refit moving an undecided block's cut is how the line
        learns the clock; a decided block's cut within the tolerance is the same cut. With
        blocks of varying length each is judged on its own length's grid."""
        from ..signals.block_plan import record_clocks

        clocks = record_clocks(infos, starts)
        if any(clock.drifting for clock in clocks):
            # those decided before the record was found to drift were cut at their labels
            blocks = sorted(b for b in self.done if b not in self._cuts_said)
        else:
            blocks = sorted(b for b in self._cuts if b not in self._cuts_said)
        if not blocks:
            return
        moved: dict[float, dict[int, float]] = {}  # tolerance [ns] -> block -> off [ms]
        for grid, options, group in self._decided_runs(blocks):
            tolerance_ns, found = self._moved_cuts(
                clocks, infos, starts, ends, grid, options, group
            )
            if found:
                moved.setdefault(tolerance_ns, {}).update(found)
        for tolerance_ns, found in sorted(moved.items()):
            self._cuts_said.update(found)
            largest = max(found.values(), key=abs)
            self.messages.append(
                f"block(s) {block_ranges(sorted(found))} of a drifting record, decided from "
                "the clock line of the files landed then, are cut up to "
                f"{largest:+.1f} ms elsewhere by the line of the files landed now (beyond "
                f"{tolerance_ns / 1e6:g} ms: the clock jitter, or one analysis sample); they "
                "are kept as decided"
            )

    def _note_missed_blocks(self, infos, starts) -> None:
        """At a flush (the data present taken as all there is for now): say once the
        blocks whose span a drifting record's samples hold on their count but whose UTC
        span runs past its first or last sample (:func:`~workbench.signals.block_plan.
        missed_blocks`), as identify's summary says them; with varying lengths, those
        whose shortest span does (no length of theirs is planned)."""
        from ..signals.block_plan import missed_blocks, missed_blocks_line, placed_block_numbers

        voyage = self.voyage
        grid = voyage.grid
        if voyage.lengths is not None:
            grid = voyage.length_run(voyage.lengths.adaptive.lengths()[-1])[0]
        listed = placed_block_numbers(infos, grid).tolist()
        missed = missed_blocks(infos, grid, voyage.rate_hz, listed, starts)
        missed = {b: how for b, how in missed.items() if b not in self._missed_said}
        if not missed:
            return
        self._missed_said.update(missed)
        line = missed_blocks_line(missed)
        log.info("%s", line)
        self.messages.append(line)

    def _decided_runs(self, blocks: Sequence[int]):
        """(grid, options, blocks) of the decided *blocks* by the grid they were cut on:
        the voyage's, or with varying lengths each length's (a block left out, or whose
        length is unknown, is not among them)."""
        voyage = self.voyage
        if voyage.lengths is None:
            yield voyage.grid, voyage.options, list(blocks)
            return
        by_length: dict[float, list[int]] = {}
        for block in blocks:
            length = self._decided_length(block)
            if length is not None:
                by_length.setdefault(length, []).append(block)
        for length, group in sorted(by_length.items()):
            grid, options, _ = voyage.length_run(length)
            yield grid, options, group

    def _decided_length(self, block: int) -> float | None:
        """The length of the decided (or length-decided) *block* with varying lengths,
        from this run's decisions or the store's ``lengths`` table; None for a block no
        length fits or of unknown length. [s]"""
        row = self._lengths.get(block)
        if row is not None:
            return float(row["block_length_s"])
        return self._stored_lengths.get(block)

    def _moved_cuts(
        self, clocks, infos, starts, ends, grid, options, blocks
    ) -> tuple[float, dict[int, float]]:
        """The tolerance [ns] and the decided *blocks* (of *grid*) the clock line of the
        files landed now cuts beyond it from where they were cut: block -> off [ms]."""
        from ..signals.block_plan import cut_tolerance_s, line_placed_ns, placed_blocks

        rate = self.voyage.rate_hz
        lattice = options.decimation_factor(rate)
        tolerance_ns = cut_tolerance_s(rate, lattice) * _NS
        # a cut within the tolerance less half a lattice sample of where the line puts
        # its label now is where the line cuts it (rounded to the lattice) within the
        # tolerance: only the others are planned again (a long voyage's decided blocks
        # are many)
        labels = grid.start(np.asarray(blocks, dtype=np.int64)).asi8
        cuts = np.array(
            [
                c if (c := self._cut_ns(b)) is not None else t
                for b, t in zip(blocks, labels, strict=True)
            ],
            dtype=float,
        )
        lines = line_placed_ns(clocks, starts, labels, rate)
        near_ns = tolerance_ns - 0.5 * lattice / rate * _NS
        blocks = [b for b, far in zip(blocks, np.abs(lines - cuts) > near_ns, strict=True) if far]
        if not blocks:
            return tolerance_ns, {}
        now = placed_blocks(
            infos, starts, ends, grid, blocks, max_gap_s=options.max_gap_s, lattice=lattice
        )
        moved = {}
        for planned in now:
            block = int(planned.block)
            cut = self._cut_ns(block)
            if cut is None and block in self._cuts:  # its file is not taken (now)
                continue
            off_ns = planned.sample_start.value - (
                planned.block_start.value if cut is None else cut
            )
            if abs(off_ns) > tolerance_ns + 1e3:  # 1 us: the placed times' rounding
                moved[block] = off_ns / 1e6
        return tolerance_ns, moved

    def _settled(self, planned, per_file: bool, starts, ends, newest: int) -> bool:
        """Whether the data of *planned* (and, when files are decimated one by one, of
        their neighbours' edges) can no longer change (:func:`settled`)."""
        from ..signals.block_plan import EDGE_SHIFT_S

        voyage = self.voyage
        margin = int(2.0 / voyage.rate_hz * _NS) if per_file else 0
        if planned.drifting:
            # a drifting record's block is cut at the data's last sample when the data
            # ends within EDGE_SHIFT_S of its span's end: known once data beyond landed
            margin += int(EDGE_SHIFT_S * _NS)
        return settled(  # the span of the block's samples (off its label on a drifting clock)
            planned.sample_start.value - margin,
            planned.sample_end.value + margin,
            starts,
            ends,
            newest=newest,
            first_ns=voyage.grid.t0.value,
            sampling_rate_hz=voyage.rate_hz,
            late_s=self.options.late_s,
        )

    def _ready_adaptive(self, flush: bool):
        """:meth:`_ready_blocks` for blocks of varying length: the half-steps whose data
        can no longer change are measured, the blocks whose length they decide get it
        (:class:`~workbench.monitor.adaptive.AdaptiveLengths`), and those of them whose
        data (and, when decimating, whose neighbouring files) can no longer change are
        ready, ascending. A block no length fits is ready as left out."""
        from ..signals.block_plan import PlannedBlock, placed_block_numbers, placed_blocks

        voyage, lengths = self.voyage, self.voyage.lengths
        self._doing("measuring the excitation")
        lengths.measure(self._placed(), flush=flush, late_s=self.options.late_s)
        starts, ends = self._coverage()
        newest = int(ends.max())
        waiting = [b for b in self._undecided() if b not in self._lengths]
        decided, left_out = lengths.decide(
            waiting,
            self._speed_log(),
            newest=pd.Timestamp(newest, tz="UTC"),
            flush=flush,
            late_s=self.options.late_s,
        )
        for row in decided.to_dict("records"):
            self._lengths[int(row["block"])] = row
        for block in left_out:
            self._lengths[block] = None
        for message in lengths.messages:
            if message not in self.messages[-50:]:
                self.messages.append(message)
        lengths.messages.clear()
        numbers: dict[float, np.ndarray] = {}  # the blocks a plan of each length lists
        ready = []
        infos = self.files.placed_infos()
        for block in sorted(b for b in self._lengths if b not in self.done):
            row = self._lengths[block]
            if row is None:
                span = voyage.grid
                ready.append(PlannedBlock(block, span.start(block), span.end(block), (), LEFT_OUT))
                continue
            length = float(row["block_length_s"])
            grid, options, per_file = voyage.length_run(length)
            listed = numbers.get(length)
            if listed is None:
                listed = numbers[length] = placed_block_numbers(infos, grid)
            if not (len(listed) and listed[0] <= block <= listed[-1]):  # cannot happen: the
                # length fits the data
                continue
            (planned,) = placed_blocks(
                infos,
                starts,
                ends,
                grid,
                [block],
                max_gap_s=options.max_gap_s,
                lattice=options.decimation_factor(voyage.rate_hz),
            )
            if flush or self._settled(planned, per_file, starts, ends, newest):
                ready.append(planned)
        self._planned = [b for b in ready if b.block not in self.done]
        self._note_moved_cuts(infos, starts, ends)
        if flush:
            self._note_missed_blocks(infos, starts)
        return ready

    def _undecided(self) -> list[int]:
        """Blocks not yet decided, up to the last block the data present holds."""
        lengths = self.voyage.lengths
        last = lengths.last_block()
        first = self.tracking.tracked_through + 1  # every block before it is decided
        return [b for b in range(first, last + 1) if b not in self.done]

    def _speed_log(self) -> pd.DataFrame | None:
        """The ship log when it logs the speed (the adaptive length reads it), else None."""
        if self.dship is None:
            return None
        log = self._read_log()
        if log is None:  # not there yet, or unreadable: waited for, then decided without
            return pd.DataFrame({"time": pd.Series([], dtype="datetime64[ns, UTC]")})
        return log if "speed_kn" in log.columns else None

    # ------------------------------------------------------------------ one block
    def _process(self, planned) -> None:
        from ..parallel import BlockOutcome, _guarded

        voyage = self.voyage
        grid, options, per_file = voyage.grid, voyage.options, voyage.per_file
        measures = None
        if voyage.lengths is not None and planned.skipped_reason != LEFT_OUT:
            measures = self._lengths[int(planned.block)]
            grid, options, per_file = voyage.length_run(float(measures["block_length_s"]))
        # the block's files, their headers as placed: the block is cut at the re-timed
        # starts, as identify's
        used = [self.files.placed_file(Path(f)) for f in planned.files]
        used = [f for f in used if f is not None]
        task = BlockTask(
            int(planned.block),
            planned.block_start,
            tuple(str(f) for f in planned.files),
            tuple(f.info for f in used),
            skipped=planned.skipped_reason,
            sample_start=planned.sample_start if planned.drifting else None,
        )
        conditioner = None
        if per_file:
            conditioner = block_conditioner(
                self.files.placed_infos(),
                self.files.placed_index,
                planned,
                grid,
                voyage.channels,
                options,
                # a conditioned file is cut on its grid (steps and samples counted from
                # the grid's t0): the blocks of one length share it, not those of another
                shared=self._shared.setdefault(grid.t0, {}) if measures else self._shared,
                counter=self.conditioned_files,
                # the edges of the drifting blocks planned (this one's among them): the
                # step sums are split there
                cuts=block_cuts([planned, *(self._planned or ())]),
            )
        func = functools.partial(
            identify_block,
            grid=grid,
            channels=voyage.channels,
            options=options,
            conditioner=conditioner,
        )
        cpu = time.process_time()
        if planned.skipped_reason == LEFT_OUT:
            outcome = BlockOutcome(int(planned.block), planned.block_start, skipped=LEFT_OUT)
        else:
            outcome = _guarded(func, task)
        if measures is not None:  # the block's length and stationarity, as identify's tables
            outcome = _with_measures(outcome, measures)
        identified_at = pd.Timestamp.now(tz="UTC")
        cpu = time.process_time() - cpu
        row = data_health_row(planned, outcome, identified_at, used)
        tables = {k: v for k, v in outcome.tables.items() if len(v)}
        tables["monitor"] = pd.DataFrame([row])
        blocks = pd.DataFrame(
            {
                "block": [int(outcome.block)],
                "block_start": pd.to_datetime([outcome.block_start], utc=True),
                "status": ["skipped" if outcome.skipped else "ok"],
                "reason": [outcome.skipped],
            }
        )
        cut = self._cut_of(planned)
        if cut is not None:  # where the clock line cut it: kept with it (_decided_span)
            blocks[CUT_COLUMNS[0]], blocks[CUT_COLUMNS[1]] = [cut[0]], np.int64(cut[1])
        self.store.write_batch(blocks, tables)  # the block is done once this returns
        self.done.add(int(outcome.block))
        if cut is not None:
            self._cuts[int(outcome.block)] = cut
        self._health_rows.append(row)
        if outcome.skipped:
            faults = outcome.tables.get("faults")
            self.skipped_here.append(
                {
                    "block": int(outcome.block),
                    "files": [Path(f).name for f in planned.files],
                    "reason": outcome.skipped,
                    "faults": sorted(set(faults["reason"].astype(str)))
                    if faults is not None and "reason" in faults and len(faults)
                    else [],
                }
            )
        else:
            self.identified_here += 1
        since = self._health_rows_from
        self._health_rows_from = int(row["block"]) if since is None else min(since, row["block"])
        if self.dship is not None and not outcome.skipped:  # for the ship log's clock check
            length_s = grid.length_s if measures is None else measures["block_length_s"]
            self.clock_check.add(outcome.tables.get("channels"), float(length_s))
        selected = outcome.tables.get("selected")
        if not outcome.skipped and selected is not None and len(selected):
            self.tracking.add(int(outcome.block), selected)
        self._advance_tracking()
        self._write_data_health()
        waiting = [b.block_start for b in self._planned if b.block not in self.done]
        if voyage.lengths is not None:  # and the longest span of the next block to decide
            undecided = [b for b in self._undecided() if b not in self._lengths]
            if undecided:
                span = voyage.lengths.grid(max(voyage.lengths.adaptive.lengths()))
                waiting.append(span.start(undecided[0]))
        caches = [self._shared] if voyage.lengths is None else list(self._shared.values())
        cached = {key[0] for cache in caches for key in cache}  # the files conditioned
        ends = {p: f.info.end_time for p in cached if (f := self.files.get(p)) is not None}
        if voyage.lengths is None:
            forget_conditioned(self._shared, waiting, ends)
        else:  # a cache per length's grid
            for shared in self._shared.values():
                forget_conditioned(shared, waiting, ends)
        self._write_status("running")
        log.info(
            "block %d: %s, identification CPU %.3f s, state written %.3f s after its last "
            "file landed",
            outcome.block,
            f"skipped ({outcome.skipped})" if outcome.skipped else row["status"],
            cpu,
            (pd.Timestamp.now(tz="UTC") - row["last_file_landed"]).total_seconds(),
        )

    # ------------------------------------------------------------------ tracking
    def _mark_harmonics(self, frame: pd.DataFrame) -> np.ndarray | None:
        """The harmonic marks of the selected modes tracked so far (*frame*), a row each:
        ``harmonic``, ``harmonic_frequency_hz`` and checked (1.0 or 0.0) as
        ``identify --dship`` marks them: from the logged shaft speed
        (:meth:`~workbench.sid.harmonics.HarmonicMarker.mark_selected`: spikes and a frozen
        sensor left out, a block without a usable shaft speed tested from the speed where
        the ship's shaft speed per knot is fixed, else unchecked), or from the speed when
        the log has no shaft speed (:meth:`_mark_from_speed`); None without a ship log.

        A block's marks from the shaft speed are kept once the log covers the block;
        before that they are recomputed, so the tracked table ends equal to
        ``identify --dship`` + ``track`` however late the log. Only the rows not kept are
        marked (the new block's and those of the blocks the log does not cover yet)."""
        log = self._read_log()  # an unreadable log: the outlook reports it
        if log is None:
            return None
        if "shaft_rpm" not in log.columns or log["shaft_rpm"].isna().all():
            return self._mark_from_speed(frame, log) if "speed_kn" in log.columns else None
        if self._judge_shaft_log(frame, log):  # a frozen log: as one without a shaft speed
            marks = self._mark_from_speed(frame, log)
            # marked again while a block's shaft speed may still change the verdict
            self._marks_pending = self._marks_pending or self._judge_pending
            return marks
        from ..sid.harmonics import HarmonicMarker

        n = len(frame)
        kept = np.zeros(n, dtype=bool)
        harmonic = np.full((n, 3), np.nan)
        if len(self._marks_kept) <= n:  # else a new tracker: every row marked again
            kept[: len(self._marks_kept)] = self._marks_kept
            harmonic[: len(self._marks)] = self._marks
        pending = np.flatnonzero(~kept)
        self._marks_pending = bool(len(pending))
        pending_rpm: dict[int, float] = {}
        if len(pending):
            part = frame.iloc[pending]
            window, live = self._marking_log(log, part)
            marker = HarmonicMarker(window, self.options.harmonics)
            marked = marker.mark_selected(
                part, shaft_logged=self._shaft_logged or None, judge_log=False
            )
            shaft = marker.shaft
            missing = (shaft["shaft_rpm_from"] != "log") & shaft["speed_kn"].notna()
            if window is not log and marker.method == "shaft speed" and missing.any():
                # a block without a usable shaft speed: the shaft speed per knot of speed
                # is the whole log's
                marker = HarmonicMarker(log, self.options.harmonics)
                marked = marker.mark_selected(
                    part, shaft_logged=self._shaft_logged or None, judge_log=False
                )
            if marker.method == "shaft speed" and not self._shaft_logged:
                # the voyage's blocks have a shaft speed: those marked before without one
                # (by the speed-following test over their part) are marked again with it
                self._shaft_logged = True
                if kept.any():
                    self._marks_kept = np.zeros(0, dtype=bool)
                    self._block_shaft_rpm = {}
                    return self._mark_harmonics(frame)
            checked = (
                marked["harmonic_checked"].to_numpy(float)
                if "harmonic_checked" in marked.columns
                else np.ones(len(marked))
            )
            harmonic[pending] = np.column_stack(
                [
                    marked["harmonic"].to_numpy(float),
                    marked["harmonic_frequency_hz"].to_numpy(float),
                    checked,
                ]
            )
            # the marks of the blocks the log covers are kept once the verdicts of their
            # shaft-speed readings are final (later readings judge the last ones)
            blocks = part[["block", "block_start", "block_end"]].drop_duplicates("block")
            ends = pd.to_datetime(blocks["block_end"], utc=True)
            final_blocks = (ends <= _newest_time(log)).to_numpy() & live.settled(
                blocks["block_start"], blocks["block_end"]
            )
            final_of = dict(zip(blocks["block"].astype(int), final_blocks, strict=True))
            rpm = (
                marker.shaft.set_index("block")["shaft_rpm"].astype(float)
                if marker.method == "shaft speed"
                else pd.Series(dtype=float)
            )
            for block, inside in part.reset_index(drop=True).groupby("block").indices.items():
                final = bool(final_of[int(block)])
                if final:
                    kept[pending[inside]] = True
                if block in rpm.index:
                    (self._block_shaft_rpm if final else pending_rpm)[int(block)] = rpm[block]
        self._shaft_rpm_of_block = {**self._block_shaft_rpm, **pending_rpm}
        self._marks, self._marks_kept = harmonic, kept
        return harmonic

    def _judge_shaft_log(self, frame: pd.DataFrame, log: pd.DataFrame) -> str | None:
        """Whether the logged shaft speed is not used (a frozen log): a line naming the
        column (:func:`~workbench.sid.harmonics.shaft_log_against_speed`), else None, judged
        as ``identify --dship`` judges the voyage: over every block tracked so far
        (*frame*, the selected modes) and the log read so far, not over the newest blocks
        (whose speed rarely spans the knot the test asks for).

        Judged again at every call, so the verdict at the end is the batch run's on the
        same files: a verdict taken once, early, would hold one drawn from fewer blocks
        (the log steady, the speed not yet spanning a knot, the modes not yet counted).
        When it changes, every tracked row is marked again (:meth:`_mark_harmonics` keeps
        no mark of the other verdict) and a note says so, naming the blocks marked before.

        Each block's logged shaft speed and speed (:func:`~workbench.sid.harmonics.
        block_shaft_table`) are kept once the log's verdicts on its readings are final; the
        modes are compared only while those stay steady over a knot of speed
        (:func:`~workbench.sid.harmonics.steady_shaft_log`), which a log following the
        shaft fails at the cost of a percentile over the blocks. The comparison takes each
        row's order mark once its block is final (:meth:`_at_orders`) and the modes
        following the speed from the speed-following test kept as blocks come
        (:meth:`_mark_from_speed`), so a steady shaft (a controllable-pitch propeller) costs
        the new blocks' rows, not the voyage's, at each call."""
        from ..sid.harmonics import block_shaft_table, frozen_shaft_log, steady_shaft_log

        blocks = frame[["block", "block_start", "block_end"]].drop_duplicates("block")
        numbers = blocks["block"].astype(int).to_numpy()
        unknown = blocks[~np.isin(numbers, list(self._shaft_rows))]
        pending: dict[int, tuple[float, float, float]] = {}
        if len(unknown):
            window, live = self._marking_log(log, unknown)
            table = block_shaft_table(window, unknown)
            ends = pd.to_datetime(unknown["block_end"], utc=True)
            final = (ends <= _newest_time(log)).to_numpy() & live.settled(
                unknown["block_start"], unknown["block_end"]
            )
            values = table[["shaft_rpm", "speed_kn", "speed_energy_kn"]].to_numpy(float)
            for block, row, kept in zip(table["block"].astype(int), values, final, strict=True):
                (self._shaft_rows if kept else pending)[int(block)] = tuple(row)
        self._judge_pending = bool(pending)
        rows = {**self._shaft_rows, **pending}
        shaft = pd.DataFrame(
            np.array([rows[int(b)] for b in numbers], dtype=float).reshape(-1, 3),
            columns=["shaft_rpm", "speed_kn", "speed_energy_kn"],
        )
        steady = steady_shaft_log(shaft)
        note = None
        if steady is not None:
            following = np.isfinite(self._mark_from_speed(frame, log)[:, 0])
            at_orders = self._at_orders(frame, log)
            note = frozen_shaft_log(steady, at_orders, following, self.options.harmonics)
        if (note is None) != (self._shaft_log_note is None):
            self._said_shaft_log(note, numbers)
        self._shaft_log_note = note  # with the newest counts
        return note

    def _at_orders(self, frame: pd.DataFrame, log: pd.DataFrame) -> np.ndarray:
        """Per row of *frame* (the tracked selected modes): whether it sits at an order of
        the logged shaft speed (:func:`~workbench.sid.harmonics.mark_shaft_orders`), a
        block's rows kept once the log's verdicts on its readings are final."""
        from ..sid.harmonics import mark_shaft_orders

        n = len(frame)
        at = np.zeros(n, dtype=bool)
        kept = np.zeros(n, dtype=bool)
        if len(self._orders_kept) <= n:  # else a new tracker: every row again
            at[: len(self._orders_at)] = self._orders_at
            kept[: len(self._orders_kept)] = self._orders_kept
        pending = np.flatnonzero(~kept)
        if len(pending):
            part = frame.iloc[pending]
            window, live = self._marking_log(log, part)
            marks = mark_shaft_orders(part, window, self.options.harmonics)
            at[pending] = marks.notna().to_numpy()
            blocks = part[["block", "block_start", "block_end"]].drop_duplicates("block")
            ends = pd.to_datetime(blocks["block_end"], utc=True)
            final = (ends <= _newest_time(log)).to_numpy() & live.settled(
                blocks["block_start"], blocks["block_end"]
            )
            kept[pending] = np.isin(part["block"].to_numpy(), blocks["block"].to_numpy()[final])
        self._orders_at, self._orders_kept = at, kept
        return at

    def _said_shaft_log(self, note: str | None, blocks: np.ndarray) -> None:
        """The verdict on the logged shaft speed changed to *note* (None: used): a note
        saying so, naming the tracked *blocks* whose marks are given again; the marks and
        the state of the other verdict are dropped, so every row is marked again."""
        earlier = self._shaft_log_note is not None or len(self._marks_kept) > 0
        self._shaft_log_note = note
        self._marks, self._marks_kept = np.empty((0, 3)), np.zeros(0, dtype=bool)
        self._block_shaft_rpm, self._shaft_rpm_of_block = {}, {}
        self._shaft_logged = False
        if note is None and not earlier:
            return
        span = f"blocks {int(blocks.min())}-{int(blocks.max())}"
        if note is None:
            message = (
                "ship log: shaft_rpm: the logged shaft speed is used again (with the blocks "
                f"tracked so far it is no longer contradicted by the speed); the harmonics of "
                f"{span} are marked again from it"
            )
        else:
            message = f"ship log: {note}"
            if earlier:
                message += (
                    f"; the harmonics of {span}, marked from the logged shaft speed before, "
                    "are marked again from the speed"
                )
        self._report(message)

    def _mark_from_speed(self, frame: pd.DataFrame, log: pd.DataFrame) -> np.ndarray:
        """:meth:`_mark_harmonics` from a ship log with the speed but no shaft speed: the
        speed-following test over every block tracked so far, as ``identify --dship``
        tests the whole voyage (:class:`~workbench.sid.harmonics.SpeedFollowing`).

        A block's modes join the test once the log covers the block (its speed is then
        final); a mode added only enlarges the groups of those before it, so the test
        holding the voyage so far is the voyage's test, at the cost of the new modes'
        ratio windows (not the voyage's modes). The modes of blocks the log does not cover
        yet are tested on a copy, with the speed logged so far. Marks of earlier blocks
        change when a new harmonic lowers the shaft rate per knot found (the other orders'
        ratios): every row's marks are given again each time."""
        from ..sid.harmonics import (
            SpeedFollowing,
            _shapes,
            block_shaft_table,
            nearest_order_frequency,
            order_list,
        )

        options = self.options.harmonics
        n = len(frame)
        if self._speed_test is None or n < len(self._speed_index):  # a new tracker
            self._speed_test = SpeedFollowing(options)
            self._speed_index = np.empty(0, dtype=np.int64)
            self._block_speed = {}
        # each block's energy-weighted speed, kept once the log covers the block
        covered = _newest_time(log)
        blocks = frame[["block", "block_start", "block_end"]].drop_duplicates("block")
        unknown = blocks[~blocks["block"].astype(int).isin(self._block_speed)]
        pending_speed: dict[int, float] = {}
        if len(unknown):
            window, _ = self._marking_log(log, unknown)  # the speed: no readings judged
            table = block_shaft_table(window, unknown).set_index("block")["speed_energy_kn"]
            ends = pd.to_datetime(unknown["block_end"], utc=True)
            for block, end in zip(unknown["block"].astype(int), ends, strict=True):
                final = pd.notna(covered) and end <= covered
                (self._block_speed if final else pending_speed)[block] = float(table[block])
        block = frame["block"].to_numpy(dtype=np.int64)
        speed = pd.Series(block).map({**self._block_speed, **pending_speed}).to_numpy(float)
        final = pd.Series(block).isin(self._block_speed).to_numpy()
        usable = np.isfinite(speed) & (speed > options.min_speed_kn)
        # index of each row in the test (-1: not usable; -2: not added yet)
        index = np.concatenate(
            [self._speed_index, np.full(n - len(self._speed_index), -2, dtype=np.int64)]
        )
        test = self._speed_test
        join = np.flatnonzero((index == -2) & final)
        index[join[~usable[join]]] = -1
        join = join[usable[join]]
        frequency = frame["frequency_hz"].to_numpy(float)
        if len(join):
            index[join] = len(test) + np.arange(len(join))
            test.add(frequency[join], speed[join], _shapes(frame.iloc[join]))
        self._speed_index = np.where(final, index, -2)
        waiting = np.flatnonzero((index == -2) & usable)
        self._marks_pending = bool((~final).any())
        if len(waiting):
            test = test.copy()
            index[waiting] = len(test) + np.arange(len(waiting))
            test.add(frequency[waiting], speed[waiting], _shapes(frame.iloc[waiting]))
        marked_in_test, per_kn = test.marked()
        self._shaft_hz_per_kn = float(per_kn)
        self._speed_of_block = {**self._block_speed, **pending_speed}
        marked = np.zeros(n, dtype=bool)
        tested = index >= 0
        marked[tested] = marked_in_test[index[tested]]
        harmonic = np.where(marked, 0.0, np.nan)
        order_hz = nearest_order_frequency(frequency, per_kn * speed, order_list(options))
        return np.column_stack(
            [harmonic, np.where(marked, order_hz, np.nan), np.isfinite(speed).astype(float)]
        )

    def _harmonic_modes(self) -> pd.DataFrame | None:
        """The tracked selected modes marked as harmonics (their block, frequency, shape
        and ``harmonic``), in the order ``identify --dship`` exports them: what its pole
        table's marks are taken from (:func:`~workbench.sid.harmonics.mark_poles`); None
        without marks (no ship log)."""
        frame, marks = self.tracking.frame, self._marked
        if frame is None or marks is None or len(marks) != len(frame):
            return None
        marked = np.isfinite(marks[:, 0])
        modes = frame[marked].assign(harmonic=marks[marked, 0])
        return modes.sort_values(["block", "frequency_hz"], kind="stable").reset_index(drop=True)

    def _write_harmonic_lines(self, tracked: pd.DataFrame) -> None:
        """``harmonics.parquet``: each order's frequency at the tracked blocks, at the
        shaft speed the marks used, as ``identify --dship`` gives it (``shaft.csv``): the
        block's mean logged shaft speed (spikes and a frozen sensor left out; where the log
        fails, the speed x the ship's shaft speed per knot); from a log with the speed but
        no shaft speed, the block's speed x the shaft rate per knot the speed-following
        test found (``harmonics.json``'s ``shaft_hz_per_kn``). Nothing before the test
        has found one, or without a ship log."""
        log = self._read_log()
        if log is None or tracked.empty:
            return
        from ..dashboard.state import HARMONIC_LINES
        from ..sid.harmonics import order_list

        shaft = tracked[["block", "block_start"]].drop_duplicates("block")
        blocks = shaft["block"].astype(int)
        if (
            "shaft_rpm" in log.columns
            and log["shaft_rpm"].notna().any()
            and self._shaft_log_note is None
        ):
            rate_hz = blocks.map(self._shaft_rpm_of_block).to_numpy(float) / 60.0
        elif "speed_kn" in log.columns and np.isfinite(self._shaft_hz_per_kn):
            rate_hz = self._shaft_hz_per_kn * blocks.map(self._speed_of_block).to_numpy(float)
        else:
            return
        known = np.isfinite(rate_hz)
        shaft, rate_hz = shaft[known], rate_hz[known]
        orders = order_list(self.options.harmonics)
        lines = pd.DataFrame(
            {
                "block": np.repeat(shaft["block"].to_numpy(dtype="int64"), len(orders)),
                "block_start": np.repeat(shaft["block_start"].to_numpy(), len(orders)),
                "order": np.tile(np.asarray(orders, dtype=float), len(shaft)),
                "frequency_hz": np.outer(rate_hz, orders).ravel(),
            }
        )
        lines["block_start"] = pd.to_datetime(lines["block_start"], utc=True)
        write_table(lines, self.state / "harmonics.parquet", HARMONIC_LINES)

    def _write_harmonic_tracks(self, labels: list[dict]) -> None:
        """``harmonic_tracks.parquet``: the rows of the tracked lines recognised as shaft
        or blade-pass harmonics (left out of ``tracked.parquet``), so that a reader sees
        them as harmonics, never as modes (``order`` 0: found from the speed, order
        unknown; nothing without a ship log)."""
        from ..dashboard.state import HARMONIC_TRACKS

        path = self.state / "harmonic_tracks.parquet"
        frame, marks = self.tracking.frame, self._marked
        if marks is None or not labels:
            if path.exists():  # the lines once recognised are modes after all
                write_table(empty_table(HARMONIC_TRACKS), path, HARMONIC_TRACKS)
            return
        labels = sorted(labels, key=lambda h: h["frequency_hz"])
        rows = self.tracking.rows_of(h["label"] for h in labels)
        parts = []
        for track, found in enumerate(labels, start=1):
            part = frame.loc[rows[found["label"]], ["block", "block_start", "frequency_hz"]]
            parts.append(part.assign(track=track, order=marks[rows[found["label"]], 0]))
        table = pd.concat(parts, ignore_index=True).drop_duplicates(["block", "track"])
        table["block_start"] = pd.to_datetime(table["block_start"], utc=True)
        table = table.sort_values(["block", "track"], kind="stable").reset_index(drop=True)
        write_table(
            table[["block", "block_start", "track", "frequency_hz", "order"]], path, HARMONIC_TRACKS
        )

    def _advance_tracking(self) -> None:
        """Feed the decided blocks to the tracker in block order and write the tracked
        table and the labels shown when it grew (see :class:`IncrementalTracking`)."""
        grew = self.tracking.advance(self.done)
        # the labels an earlier run gave come back with the same modes (after a restart)
        self.tracking.check_labels()
        # marks of blocks the log did not cover yet may change: written again with the log
        if grew or self._marks_pending or not (self.state / "tracked.parquet").exists():
            self._marked = None

            def marks(frame: pd.DataFrame) -> np.ndarray | None:
                self._marked = self._mark_harmonics(frame)  # kept for the harmonic lines
                return self._marked

            tracked = self.tracking.table(marks=marks)
            if self._labels_lost is not None:  # before the table is written again
                self._labels_again(tracked)
            if self.voyage is not None and self.voyage.lengths is not None:
                # blocks of varying length: readers take each block's own span (forecast,
                # predictors), as they do from track's table of identify --block-minutes auto
                grid = self.voyage.grid
                set_grid(
                    tracked,
                    {"t0": grid.t0, "length_s": grid.step_s, "step_s": grid.step_s,
                     "varying_length": True},
                )  # fmt: skip
            # a day per part; only the parts whose rows changed are written
            part_writer(self.state / "tracked.parquet", MODAL, self._step_s()).write(
                tracked, since_block=self.tracking.changed_from
            )
            self._tracked = tracked  # what the state folder holds, for the key indicators
            self._write_harmonic_lines(tracked)
            self._write_harmonic_tracks(tracked.attrs.get("harmonic_labels", []))
            # after the table: a label in labels.json is in the store's blocks
            self.tracking.write_labels(self.state / "labels.json")

    def _resume(self) -> None:
        """After a restart: replay the stored blocks into the tracker and the data-health
        table (the store is the truth; nothing is identified twice)."""
        if not self.done:
            self._planned = ()
            self._advance_tracking()
            return
        health = self.store.read("monitor")
        if len(health):
            self._health_rows = health.drop(columns=["day"], errors="ignore").to_dict("records")
        selected = self.store.read("selected")
        if len(selected):
            selected = selected.drop(columns=["day"], errors="ignore")
            for block, part in selected.groupby("block", sort=True):
                self.tracking.add(int(block), part)
        if self.dship is not None:  # the stored blocks count for the ship log's clock check
            channels = self.store.read("channels")
            length_s = self.voyage.grid.length_s
            if self.voyage.lengths is not None and len(channels):
                lengths = self.store.read("lengths")
                length_s = lengths.set_index("block")["block_length_s"].astype(float)
            self.clock_check.add(channels, length_s)
            self._check_clock()  # said again in this run when the stored blocks say it
        self._planned = ()
        # the labels given before the restart must come back with the same modes
        labels = self.state / "labels.json"
        try:
            self.tracking.expect_labels(labels)
        except LabelsUnreadable as error:
            self._labels_lost = (str(error), _written_table(self.state / "tracked.parquet"))
        self._advance_tracking()
        self._write_data_health()
        self._outlook_due = True

    def _labels_again(self, tracked: pd.DataFrame) -> None:
        """``labels.json`` was unreadable at the restart: its labels are given again by
        the replay of the stored blocks when that gives the tracked table the earlier run
        wrote (the same modes at the same blocks and frequencies), with a note; else one
        line naming the recovery. *tracked*: the replayed table."""
        why, earlier = self._labels_lost
        self._labels_lost = None
        path = self.state / "labels.json"
        if earlier is None or not len(earlier):
            raise WorkbenchError(
                f"{why}, and no tracked table to check the stored blocks' labels against; "
                "if this run has the first run's tracking options (--mac-min, --gate, "
                f"--frequency-tol, --baseline), move it aside ({move_aside(path)}) and "
                "run again: the labels are given again from the stored blocks; else use "
                "another --state"
            )
        keys = ["block", "mode"]
        last = int(earlier["block"].max())
        now = tracked.loc[tracked["block"].astype(int) <= last, [*keys, "frequency_hz"]]
        modes = set(earlier["mode"].astype(int)) & set(now["mode"].astype(int))
        pairs = [
            table[table["mode"].astype(int).isin(modes)]
            .astype({"block": int, "mode": int})
            .sort_values(keys)
            .reset_index(drop=True)
            for table in (earlier[[*keys, "frequency_hz"]], now)
        ]
        same = (
            bool(modes)
            and pairs[0][keys].equals(pairs[1][keys])
            and np.allclose(pairs[0]["frequency_hz"], pairs[1]["frequency_hz"], rtol=1e-9)
        )
        if not same:
            raise WorkbenchError(
                f"{why}, and tracking the stored blocks again gives other modes than "
                f"{self.state / 'tracked.parquet'} (blocks 0-{last}): the tracking options "
                "(--mac-min, --gate, --frequency-tol, --baseline) differ from the first run's; "
                "use them, or another --state"
            )
        self.messages.append(
            f"{why}; written again: tracking the stored blocks again gives the modes of the "
            f"tracked table the earlier run wrote ({len(earlier)} rows, blocks "
            f"{int(earlier['block'].min())}-{last})"
        )

    # ------------------------------------------------------------------ outlook
    def _poll_outlook(self) -> None:
        if self._defer_outlook:  # --once: one outlook at the end
            return
        future = self._outlook_future
        if future is not None:
            if not future.done():
                return
            self._outlook_future = None
            try:
                self._collect(future.result())
            except Exception as error:  # noqa: BLE001 - a crashed worker: say so, go on
                self.messages.append(f"forecast: background update failed ({error})")
                if self.check_worker() == "stopped":  # its work is redone by a new worker
                    self._outlook_due = True
        if self._outlook_due:
            self._log_complete = False
            self.update_outlook(background=self.options.background)

    def update_outlook(self, *, background: bool = False) -> None:
        """Recompute forecast, health and alarms from the tracked table so far."""
        if self.voyage is None:
            return
        if self._outlook_future is not None:  # wait for the one under way, then recompute
            self._collect(self._outlook_future.result())
            self._outlook_future = None
        self._outlook_due = False
        self._dship_key = _file_key(self.dship) if self.dship is not None else None
        self._read_log()  # recorded as the outlook reads it (log_record)
        arguments = (self.state, self.dship, self.options.forecast, self.voyage.grid)
        keywords = {"store": self.store_path}
        if "B" in self.options.forecast.forecast.options:  # the poles are read
            keywords["harmonic_modes"] = self._harmonic_modes()
            keywords["harmonics"] = self.options.harmonics
        if not background:
            self._doing("updating forecast and health")
            self._collect(update_outlook(*arguments, **keywords))
            return
        if self._executor is not None and self.check_worker() == "stopped":
            # the worker died (killed, out of memory): a new one takes over, said so
            self._executor.shutdown(wait=False, cancel_futures=True)
            self._executor = None
        if self._executor is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            # a lower priority: on a busy machine the next block's identification (the
            # latency users see) goes first, the forecast takes the time left; the worker
            # ends with this process, even after a kill -9 (workbench.processes)
            self._executor = ProcessPoolExecutor(
                max_workers=1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=worker_initializer,
                initargs=(
                    os.getpid(),
                    threading.current_thread() is threading.main_thread(),
                    10,  # niceness
                ),
            )
        # the worker is started by the first submit: with Ctrl-C held back, so that it
        # reaches this process only (which stops the worker in order)
        with interrupts_deferred():
            self._outlook_future = self._executor.submit(
                update_outlook, *arguments, **keywords, parent_pid=os.getpid()
            )
        self.check_worker()

    # ------------------------------------------------------------------ liveness
    def check_worker(self) -> str:
        """Look at the background worker; returns its state (``"none"``: no worker,
        ``"alive"``, ``"stopped"``: it died, see the heartbeat's ``worker.message``).

        Called by the heartbeat thread every poll interval and by the monitor before it
        hands the worker new work; a stopped worker is replaced at the next update, and
        the message stays in the heartbeat (and in ``status.json``'s messages)."""
        executor = self._executor
        with self._worker_lock:
            worker = self._worker
            if executor is None:
                return worker["state"] if worker["state"] == "stopped" else "none"
            # the pool's processes (a CPython attribute; none before the first submit)
            processes = dict(getattr(executor, "_processes", None) or {})
            broken = bool(getattr(executor, "_broken", False))
            dead = {pid: p.exitcode for pid, p in processes.items() if p.exitcode is not None}
            if not broken and not dead:
                alive = next(iter(processes), None)
                if alive is not None:
                    if worker["state"] == "stopped" or worker["pid"] != alive:
                        note = worker["message"]
                        if worker["state"] == "stopped":
                            note = f"{note}; replaced by pid {alive}"
                        self._worker = {"state": "alive", "pid": int(alive), "message": note}
                    return "alive"
                return worker["state"] if worker["state"] == "stopped" else "none"
            if worker["state"] == "stopped" and worker.get("_pool") == id(executor):
                return "stopped"
            pid = next(iter(dead), worker["pid"])
            code = dead.get(pid)
            how = (
                f"killed by signal {-code}"
                if code is not None and code < 0
                else f"exit code {code}"
                if code is not None
                else "the pool broke"
            )
            when = pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ")
            message = (
                f"background forecast/health worker (pid {pid}) stopped at {when} ({how}); "
                "forecast and health are not updated until a new one is started at the "
                "next update"
            )
            self._worker = {"state": "stopped", "pid": pid, "message": message}
            self._worker["_pool"] = id(executor)  # this pool's death is reported once
        log.warning("%s", message)
        self.messages.append(message)
        return "stopped"

    def write_heartbeat(self, state: str = "running") -> None:
        """Write ``heartbeat.json`` (see :mod:`workbench.monitor`): now, pid, host, poll
        interval, the last file taken, the main loop's activity and since when, and the
        background worker's state."""
        self.check_worker()
        taken = self._last_taken
        doing, since = self._activity
        with self._worker_lock:
            worker = {k: self._worker[k] for k in ("state", "pid", "message")}
        beat = {
            "time": pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
            "pid": os.getpid(),
            "host": self.host,
            "poll_s": float(self.options.poll_s),
            "state": state,
            "last_file": None if taken is None else taken[0],
            "last_file_taken_at": None if taken is None else _iso(taken[1]),
            "doing": doing,
            "doing_since": _iso(since),
            "stall_s": stall_limit_s(self.options.poll_s),
            "worker": worker,
        }
        with atomic_path(self.state / "heartbeat.json") as tmp:
            tmp.write_text(json.dumps(beat, indent=1), encoding="utf-8")

    def start_heartbeat(self) -> None:
        """Write the heartbeat now and then every poll interval from a thread of its own
        (so a long block or outlook never delays it), until :meth:`close`."""
        if self._heartbeat_thread is not None:
            return
        self.write_heartbeat()

        def beat() -> None:
            while not self._heartbeat_stop.wait(self.options.poll_s):
                try:
                    self.write_heartbeat()
                except OSError as error:  # a full or vanished disk: said by the silence
                    log.warning("heartbeat not written: %s", error)

        self._heartbeat_thread = threading.Thread(
            target=beat, name="workbench-heartbeat", daemon=True
        )
        self._heartbeat_thread.start()

    def _stop_heartbeat(self) -> None:
        self._heartbeat_stop.set()
        if self._heartbeat_thread is not None:
            self._heartbeat_thread.join(timeout=10)
            self._heartbeat_thread = None

    def _collect(self, report: OutlookReport) -> None:
        self.outlook_reports.append(report)
        # a log that already covered the newest block changes no predictor when it grows
        self._log_complete = report.log_complete
        if report.health_schedule:
            self._health_schedule = report.health_schedule
        log.info(
            "outlook: %d blocks, %d forecast rows, %.3f s (CPU %.3f s)",
            report.n_blocks,
            report.forecast_rows,
            report.seconds,
            report.cpu_seconds,
        )
        for message in report.messages:
            if message not in self.messages[-20:]:
                self.messages.append(message)
        if report.written:
            self.hand_on()

    def _report(self, message: str) -> None:
        log.warning("%s", message)
        self.messages.append(message)

    def hand_on(self) -> None:
        """After an outlook: run the alarm hook for the new alarm episodes and write the
        daily key indicators of the days with new blocks (:mod:`workbench.monitor.shore`).
        A failure is reported in the messages; the monitor goes on."""
        from data_contracts import ALARMS, read_table

        from .shore import days_of_blocks, write_daily_indicators

        alarms = None
        path = self.state / "alarms.parquet"
        try:
            key = _file_key(path)
            if key is not None and key == self._alarms_seen[0]:
                alarms = self._alarms_seen[1]  # unchanged: nothing new to hand on
            elif key is not None:
                alarms = read_table(path, ALARMS)
                if self.alarm_hook is not None:
                    self.alarm_hook.notify(alarms)
                self._alarms_seen = (key, alarms)
        except (OSError, ValueError) as error:  # ContractError is a ValueError
            self._report(f"on-alarm: alarms.parquet not read ({str(error).splitlines()[0]})")
        if not self.options.key_indicators or self.voyage is None:
            return
        newest = self.tracking.tracked_through
        if newest < 0:
            return
        try:
            # the days with new blocks, and the newest day again (its forecast may have
            # caught up with its blocks): a day's worth of rows at most, after a restart all
            grid = self.voyage.grid
            first_new = min(self._indicators_through + 1, newest)
            days = days_of_blocks([grid.start(first_new), grid.start(newest)])
            # whole days: from the first block of the earliest day touched
            day_start = pd.Timestamp(days[0], tz="UTC")
            first = max(
                0, int(math.ceil((day_start - grid.t0) / pd.Timedelta(seconds=grid.step_s)))
            )
            # only the columns and days needed (written by this monitor under their
            # contracts), so the cost stays a day's worth however long the voyage
            columns = ["block", "block_start", "mode", "frequency_hz", "damping_ratio"]
            if self._tracked is not None:
                tracked = self._tracked
                tracked = tracked.loc[tracked["block"].to_numpy() >= first, columns]
            else:
                tracked = read_since(self.state / "tracked.parquet", columns, first)
            forecast = None
            if (self.state / "forecast.parquet").exists():
                forecast = read_since(
                    self.state / "forecast.parquet",
                    [
                        "block",
                        "mode",
                        "option",
                        "ssi_frequency_hz",
                        "model_frequency_hz",
                        "model_lower_hz",
                        "model_upper_hz",
                    ],
                    first,
                )
            if len(tracked):
                days = days_of_blocks(tracked.loc[tracked["block"] >= first_new, "block_start"])
                days = days or days_of_blocks(tracked["block_start"].iloc[-1:])
                write_daily_indicators(
                    self.state,
                    tracked,
                    forecast,
                    alarms,
                    days=days,
                    option=self.options.forecast.forecast.options[0],
                )
            self._indicators_through = newest
        except (OSError, ValueError) as error:
            self._report(f"key indicators: not written ({str(error).splitlines()[0]})")

    # ------------------------------------------------------------------ gaps
    def given_up(self) -> list[dict]:
        """Blocks given up: decided as skipped for missing data (a gap, no data) that
        the files present now cover, because the file filling the hole landed after the
        late window. The monitor does not redo a decided block; ``workbench identify``
        over the folder identifies them. Consecutive blocks form one span.

        Returns
        -------
        list of dict
            ``first_block``, ``last_block``, ``start`` and ``end`` (UTC ISO-8601, the
            span of the blocks) and ``reason``: the files that filled the hole late (their
            span, the files either side) and the blocks given up (the first block's skip
            reason when it does not name the files either side of a hole).
        """
        key = (len(self.files), len(self._health_rows))
        if key == self._given_up[0]:
            return self._given_up[1]
        spans: list[dict] = []
        missing = self._missing_blocks()
        if missing and self.files and self.voyage is not None:
            from ..signals.block_plan import placed_block_numbers, placed_blocks

            grid = self.voyage.grid
            infos = self.files.placed_infos()
            starts, ends = self._coverage()
            listed = placed_block_numbers(infos, grid)  # those a plan of the files lists
            blocks = [b for b in sorted(missing) if len(listed) and listed[0] <= b <= listed[-1]]
            plan = placed_blocks(
                infos,
                starts,
                ends,
                grid,
                blocks,
                max_gap_s=self.voyage.options.max_gap_s,
                lattice=self.voyage.options.decimation_factor(self.voyage.rate_hz),
            )
            now_built = [b.block for b in plan if not b.skipped_reason]
            for block in now_built:
                if spans and spans[-1]["last_block"] == block - 1:
                    spans[-1]["last_block"] = block
                    spans[-1]["end"] = _iso_data(grid.end(block))
                    spans[-1]["reasons"].append(missing[block])
                else:
                    spans.append(
                        {
                            "first_block": block,
                            "last_block": block,
                            "start": _iso_data(grid.start(block)),
                            "end": _iso_data(grid.end(block)),
                            "reasons": [missing[block]],
                        }
                    )
            for span in spans:
                reasons = span.pop("reasons")
                span["reason"] = _given_up_reason(span, reasons, infos) or reasons[0]
        self._given_up = (key, spans)
        return spans

    def given_up_note(self) -> str:
        """One line for the user naming the given-up blocks and what includes them ('' when
        none)."""
        spans = self.given_up()
        if not spans:
            return ""
        named = ", ".join(
            f"{s['first_block']}-{s['last_block']} ({s['start']} to {s['end']})"
            if s["last_block"] > s["first_block"]
            else f"{s['first_block']} ({s['start']} to {s['end']})"
            for s in spans
        )
        count = sum(s["last_block"] - s["first_block"] + 1 for s in spans)
        return (
            f"{count} block(s) given up, their files landed after the late window: {named}; "
            f"`workbench identify {self.watch} --out DIR` over the folder includes them"
        )

    def nothing_identified(self) -> str:
        """One line saying why no block was identified ('' when there is nothing to say).

        Said when the blocks this process decided were all skipped and at least one for
        what its data holds (faulty channels, a failed fit, an unreadable file) rather
        than for data missing (a gap, which a file landing later may fill for the blocks
        after it), or when the state holds no identified block at all (whatever the
        reasons, also on a rerun that decides no new block: ``workbench identify`` over
        the same files ends so too).

        ``workbench monitor --once`` ends with exit 1 on it, as ``workbench identify``
        does when no block is identified; the blocks stay stored and in
        ``data_health.parquet`` as they were decided.
        """
        here = [] if self.identified_here else self.skipped_here
        stored = [
            {"block": int(r["block"]), "files": [], "reason": str(r["reason"]), "faults": []}
            for r in self._health_rows
        ]
        faults_here = bool(here) and not all(_missing_data(d["reason"]) for d in here)
        none_stored = bool(stored) and all(d["reason"] for d in stored)
        if not (faults_here or none_stored):
            return ""
        decided, earlier = (here, "") if here else (stored, " by an earlier run")
        counts: dict[str, int] = {}
        for d in decided:
            why = d["reason"]
            if d["faults"]:
                why += f": {', '.join(d['faults'])}"
            counts[why] = counts.get(why, 0) + 1
        reasons = sorted(counts.items(), key=lambda item: -item[1])
        why = "; ".join(f"{reason} ({n} block(s))" for reason, n in reasons[:3])
        if len(reasons) > 3:
            why += f"; {len(reasons) - 3} more reasons"
        names = sorted({name for d in decided for name in d["files"]})
        files = ", ".join(names) if len(names) <= 3 else f"{names[0]} ... {names[-1]}"
        files = f"; files {files}, {len(names)} in all" if names else ""
        return (
            f"no block identified: {len(decided)} block(s) decided{earlier} "
            f"({block_ranges(d['block'] for d in decided)}{files}) were all skipped: {why}; "
            f"each block's reason is in {self.state / 'data_health.parquet'}"
        )

    # ------------------------------------------------------------------ state files
    def _step_s(self) -> float:
        """Block step of the voyage (a day's blocks per part of the growing tables). [s]"""
        return self.voyage.grid.step_s if self.voyage is not None else 300.0

    def _write_data_health(self) -> None:
        """``data_health.parquet``, a day per part: the parts of the rows added since the
        last write (all after a restart)."""
        writer = part_writer(self.state / "data_health.parquet", None, self._step_s())
        since, rows = self._health_rows_from, self._health_rows
        if self._health_rows_all:
            since = None
        elif since is None:
            return  # no row added
        else:
            first = since // writer.part_blocks * writer.part_blocks
            rows = [r for r in rows if r["block"] >= first]
        writer.write(data_health_frame(rows), since_block=since)
        self._health_rows_all, self._health_rows_from = False, None

    def _write_status(self, state: str, message: str | None = None) -> None:
        del self.messages[:-200]  # a long run keeps its recent messages only
        # every block up to tracked_through is decided (IncrementalTracking.advance)
        last = self.tracking.tracked_through if self.tracking.tracked_through >= 0 else None
        if message is None:
            message = self.messages[-1] if self.messages else ""
        status = {
            "updated_at": pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
            "last_block": None if last is None else int(last),
            "blocks_done": len(self.done),
            "state": state,
            "pid": os.getpid(),
            "watch": str(self.watch.resolve()),
            "message": message,
            # blocks a batch identify over the folder would identify and the monitor
            # gave up (see given_up), and what to run to have them
            "given_up": self.given_up(),
            "given_up_note": self.given_up_note(),
            # from which block (and when) the health chart monitors, once known
            "health_note": self._health_schedule,
        }
        with atomic_path(self.state / "status.json") as tmp:
            tmp.write_text(json.dumps(status, indent=1), encoding="utf-8")


#: The state folder's parted tables: those the monitor writes again whole after a
#: restart (from the store) and those its outlook writes (from the outlook's state).
_STORE_TABLES = ("tracked.parquet", "data_health.parquet")
_OUTLOOK_TABLES = ("forecast.parquet", "health.parquet")


def _written_table(path: Path) -> pd.DataFrame | None:
    """``block``, ``mode`` and ``frequency_hz`` of the tracked table at *path* as the
    earlier run wrote it, or None when there is none to read."""
    from data_contracts.parts import is_parted, read_parts

    if not is_parted(path):
        return None
    try:
        return read_parts(path, None, columns=["block", "mode", "frequency_hz"])
    except (OSError, ValueError):  # ContractError is a ValueError
        return None


def _placed_among(info, taken: list) -> tuple[str, object]:
    """Why the new file *info* (a FileInfo) cannot join the files taken (*taken*, their
    headers as stamped), or "", and *info* as identify places it among them
    (:func:`~workbench.signals.block_plan.place_files`: re-timed for clock jitter or
    drift). A file with the bytes of the one it overlaps is said to be its duplicate."""
    from ..signals.block_plan import FileOverlapError, duplicate_reason, place_files

    same_rate = [other for other in taken if other.sampling_rate_hz == info.sampling_rate_hz]
    infos = sorted([*same_rate, info], key=lambda i: (i.start_time, str(i.path)))
    try:
        placed = place_files(infos)
    except FileOverlapError as error:  # more than the jitter before a predecessor's end
        new, other = (
            (error.info, error.previous) if error.info.path == info.path else (info, error.info)
        )
        if _same_data(new, other):
            return duplicate_reason(other), info
        return f"overlaps {other.name}", info
    return "", next(i for i in placed if i.path == info.path)


def _same_data(a, b) -> bool:
    """Whether the files of headers *a* and *b* hold the same bytes (either may be placed:
    re-timed for clock jitter or drift, so their stamps are compared, to the microsecond:
    a stamp given back from the placed start and its shift in seconds may be 1 ns off)."""
    from ..fingerprints import sha256

    def stamp(info):
        return info.start_time - pd.Timedelta(seconds=info.clock_shift_s)

    if (a.n_samples, a.channels) != (b.n_samples, b.channels):
        return False
    if abs((stamp(a) - stamp(b)).total_seconds()) > 1e-6:
        return False
    try:
        return sha256(a.path) == sha256(b.path)
    except OSError:
        return False


def _state_folder(message: str) -> str:
    """A store's *message* as the monitor's: its store is its state folder's."""
    told = "use another --store directory or delete this one"
    message = message.replace(told, "use another --state folder (or delete its store)")
    return message.replace("use another --store", "use another --state folder")


def _remove_unreadable_parts(state: Path) -> list[str]:
    """Remove the part files of the state folder's tables that cannot be read (cut short
    by a crash or a full disk) and say so, one note per table; the monitor writes them
    again: the tracked and data-health tables whole from the store at the start, the
    forecast and health tables from the first block (the outlook's saved state, which
    only adds the newest blocks, is removed too)."""
    from data_contracts.parts import unreadable_parts

    notes = []
    for name in (*_STORE_TABLES, *_OUTLOOK_TABLES):
        damaged = unreadable_parts(state / name)
        if not damaged:
            continue
        for file in damaged:
            file.unlink(missing_ok=True)
        first, reason = next(iter(damaged.items()))
        more = f" (and {len(damaged) - 1} more part(s))" if len(damaged) > 1 else ""
        if name in _OUTLOOK_TABLES:
            (state / "outlook" / "outlook.json").unlink(missing_ok=True)
            again = "computed again from the first block"
        else:
            again = "written again from the store"
        notes.append(
            f"{name}: {first.name}{more} unreadable ({reason}; cut short by a crash?): "
            f"removed, the table {again}"
        )
    return notes


#: The longest one activity of the main loop (reading one file, identifying one block, a
#: forecast update in the foreground) may take before the monitor counts as not responding
#: although its heartbeat thread still beats. [s]
STALL_S = 300.0


#: What the outlook does with blocks of varying length (said once per run).
_OWN_SPANS = (
    "forecast and health: blocks of varying length, the ship log averaged over each block's "
    "own span as `workbench forecast` does (not weighted by the excitation: forecast "
    "--excitation with the state folder's excitation.csv weights it as SSI reads a block)"
)

#: Columns ``identify --block-minutes auto`` adds to its ``selected`` and ``blocks`` tables.
ADAPTIVE_COLUMNS = ("block_length_s", "excitation_range_db", "speed_range_kn")


def _with_measures(outcome, measures: dict):
    """*outcome* with the block's length and stationarity in its ``selected`` rows (as
    ``identify --block-minutes auto`` merges them) and a ``lengths`` table of its own (the
    block's decision, kept in the store with the block)."""
    from dataclasses import replace as replaced

    tables = dict(outcome.tables)
    selected = tables.get("selected")
    if selected is not None:
        selected = selected.copy()
        for column in ADAPTIVE_COLUMNS:
            selected[column] = float(measures[column])
        tables["selected"] = selected
    tables["lengths"] = pd.DataFrame(
        {
            "block": [int(outcome.block)],
            "block_start": pd.to_datetime([measures["block_start"]], utc=True),
            "block_end": pd.to_datetime([measures["block_end"]], utc=True),
            **{column: [float(measures[column])] for column in ADAPTIVE_COLUMNS},
        }
    )
    return replaced(outcome, tables=tables)


#: The files either side of a hole in a skip reason ("gap of 60.0 s between acc_002.npz
#: and acc_004.npz", "no data (gap between acc_002.npz and acc_004.npz)").
_HOLE = re.compile(r"between (?P<before>.+?) and (?P<after>.+?)\)?$")


def _given_up_reason(span: dict, reasons: Sequence[str], files: Sequence) -> str:
    """What a bridge engineer needs of a given-up *span* (``given_up``'s dict): the files
    that filled its hole(s) late with their span and the files either side, and the
    blocks given up; '' when the skip *reasons* do not name the files either side of a
    hole. *files*: the placed headers of every file taken, in time order."""
    names = [info.name for info in files]
    sides = [_HOLE.search(reason) for reason in reasons]
    if not all(sides):
        return ""
    holes, n_late = [], 0
    for before, after in dict.fromkeys((side["before"], side["after"]) for side in sides):
        first = names.index(before) + 1 if before in names else 0
        last = names.index(after) if after in names else len(names)
        inside = list(files[first:last])
        if not inside:
            return ""
        n_late += len(inside)
        what = (
            inside[0].name
            if len(inside) == 1
            else f"{inside[0].name} .. {inside[-1].name} ({len(inside)} files)"
        )
        seconds = (inside[-1].end_time - inside[0].start_time).total_seconds()
        holes.append(
            f"{what} ({_iso_data(inside[0].start_time)} to {_iso_data(inside[-1].end_time)}, "
            f"{seconds:.1f} s between {before} and {after})"
        )
    blocks = (
        f"block {span['first_block']} ({span['start']} to {span['end']}) was"
        if span["last_block"] == span["first_block"]
        else f"blocks {span['first_block']}-{span['last_block']} ({span['start']} to "
        f"{span['end']}) were"
    )
    return (
        f"{'; '.join(holes)} landed after the late window: {blocks} decided without "
        f"{'it' if n_late == 1 else 'them'} and given up"
    )


def _missing_data(reason: str) -> bool:
    """Whether a block was skipped for data missing (a gap, no data, no length fitting
    a gap): the file filling the hole may still come, unlike faulty data."""
    return "gap" in reason or "no data" in reason


def stall_limit_s(poll_s: float) -> float:
    """Seconds the main loop may stay in one activity: :data:`STALL_S` or 20 polls."""
    return max(STALL_S, 20.0 * float(poll_s))


def _iso(time: pd.Timestamp) -> str:
    return pd.Timestamp(time).tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%SZ")


def _iso_data(time: pd.Timestamp) -> str:
    """A data time (a block's or file's edge) to the nearest second, UTC: a grid anchored
    at a stamp a few ms before a second is said at that second, not a second early."""
    return _iso(pd.Timestamp(time).round("s"))


def _file_key(path: Path | None):
    try:
        stat = Path(path).stat()
    except (OSError, TypeError):
        return None
    return (stat.st_size, stat.st_mtime_ns)
