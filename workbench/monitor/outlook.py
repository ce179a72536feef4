"""Forecast and structural-health chart of the tracked table so far (the monitor's outlook).

:func:`update_outlook` reads ``<state>/tracked.parquet`` and the ship log, and writes
``forecast.parquet``, ``health.parquet`` and ``alarms.parquet`` into the state folder,
exactly as ``workbench forecast --modal tracked.parquet --dship LOG ...`` followed by
``workbench health`` would over the same data: the ship log is averaged onto the tracked
blocks (:func:`~workbench.predictors.block_predictors`), modes measured in fewer than
``min_presence`` of the blocks are left out, and :func:`~workbench.forecasting.sliding_forecast`
runs over the whole table for each measurement option.

With the default settings (memory model, rolling scheme, option A, the operational
model's health chart) the forecast and the chart are resumed from update to update
(:class:`~workbench.monitor.incremental.IncrementalOutlook`, its state saved in
``<state>/outlook/``), at a cost that does not grow with the voyage and with the batch
tables; other settings are recomputed over the whole table at every update, exact by
construction at a cost growing with the table. Either runs in a background process, so it
never delays the identification of the next block.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from data_contracts import ALARMS, FORECAST, HEALTH, MODAL, POLES, PREDICTORS, read_table

from ..forecasting.options import ForecastOptions

__all__ = ["ForecastSettings", "OutlookReport", "empty_table", "update_outlook"]


@dataclass(frozen=True)
class ForecastSettings:
    """Forecast and health-chart settings of the monitor (as ``workbench forecast`` and
    ``workbench health`` take them).

    Attributes
    ----------
    forecast : ForecastOptions
        The forecast's settings, the one options object of ``workbench forecast``
        (:class:`~workbench.forecasting.options.ForecastOptions`; option B needs the
        stabilisation diagrams, read from the store).
    all_predictors : bool
        Use every numeric column of the ship log, not only the canonical predictors.
    dship_mapping : tuple of (str, str)
        Column mapping of the ship log (``speed_kn`` -> source name).
    dship_utc_offset : str, optional
        UTC offset of the log's times written without one (``"+02:00"``; default UTC).
    reference_hours : float
        Reference period of the health chart. [h]
    ewma_lambda, false_alarms_per_day : float
        Health-chart settings (:class:`~workbench.shm.HealthOptions`).
    health_model : {"operational", "forecast"}
        What the health chart charts: the residuals of the operational model
        (:func:`~workbench.shm.fit_operational_model`, fitted on the first
        ``health_train_hours``; the reference period follows), or those of the forecast
        above (as ``workbench health --forecast``; its rolling model absorbs changes).
    health_train_hours : float
        Hours the operational model is fitted on. [h]
    baseline_hours : float or None
        Without ``fuel_on_board_t`` in the ship log, the chart's baseline follows slow
        drifts with this time constant (None: fixed). [h]
    health_baseline : str, optional
        A saved health baseline (:class:`~workbench.shm.HealthBaseline`, ``workbench
        health --save-model``): the operational model and chart limits of an earlier
        voyage, so the chart starts at the first block (``health_train_hours``,
        ``reference_hours``, ``baseline_hours``, ``ewma_lambda`` and
        ``false_alarms_per_day`` are then the baseline's).
    """

    forecast: ForecastOptions = field(default_factory=ForecastOptions)
    all_predictors: bool = False
    dship_mapping: tuple[tuple[str, str], ...] = ()
    dship_utc_offset: str | None = None
    reference_hours: float = 6.0
    ewma_lambda: float = 0.1
    false_alarms_per_day: float = 0.1
    health_model: Literal["operational", "forecast"] = "operational"
    health_train_hours: float = 12.0
    baseline_hours: float | None = 24.0
    health_baseline: str | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.reference_hours) and self.reference_hours > 0):
            raise ValueError(f"reference_hours={self.reference_hours!r} must be positive")
        if self.health_model not in ("operational", "forecast"):
            raise ValueError(
                f"health_model={self.health_model!r} must be 'operational' or 'forecast'"
            )
        if not (math.isfinite(self.health_train_hours) and self.health_train_hours > 0):
            raise ValueError(f"health_train_hours={self.health_train_hours!r} must be positive")
        if self.baseline_hours is not None and not (
            math.isfinite(self.baseline_hours) and self.baseline_hours > 0
        ):
            raise ValueError(f"baseline_hours={self.baseline_hours!r} must be positive or None")
        if self.dship_utc_offset is not None:
            from data_contracts.dship_names import parse_utc_offset

            parse_utc_offset(self.dship_utc_offset)  # ValueError naming the value
        from ..shm import HealthOptions

        # the chart's own checks, now rather than when the chart starts hours later
        HealthOptions(ewma_lambda=self.ewma_lambda, false_alarms_per_day=self.false_alarms_per_day)
        object.__setattr__(
            self,
            "dship_mapping",
            tuple((str(k), str(v)) for k, v in dict(self.dship_mapping).items()),
        )


@dataclass
class OutlookReport:
    """What one :func:`update_outlook` did."""

    seconds: float = 0.0
    cpu_seconds: float = 0.0
    n_blocks: int = 0
    forecast_rows: int = 0
    health_rows: int = 0
    alarms: int = 0
    messages: list[str] = field(default_factory=list)
    written: bool = True
    #: The ship log reached the end of the newest tracked block (its predictors are final).
    log_complete: bool = False
    #: From which block (and when) the health chart monitors, or that it is learning until
    #: then ('' when not known: no ship log, or the forecast's chart).
    health_schedule: str = ""


def empty_table(contract) -> pd.DataFrame:
    """A table of *contract* without rows (what the state files hold before any result)."""
    return contract.validate(pd.DataFrame(columns=list(contract.column_names)))


def _write(frame: pd.DataFrame, path: Path, contract, parent_pid: int | None) -> bool:
    """Write atomically, unless the monitor that asked for it has died meanwhile (a stale
    background result must not overwrite what its restarted successor wrote)."""
    from data_contracts import write_table

    if parent_pid is not None and os.getppid() != parent_pid:
        return False
    write_table(frame, path, contract)
    return True


#: The writers of the state folder's parted tables in this process, by path.
_WRITERS: dict[str, object] = {}


def part_writer(path: Path, contract, step_s: float):
    """The :class:`~data_contracts.parts.PartWriter` of the parted table *path* (a day's
    blocks per part, :func:`part_blocks`), kept between updates: it rewrites only the
    parts that changed since its last write."""
    from data_contracts.parts import PartWriter

    blocks = part_blocks(step_s)
    writer = _WRITERS.get(str(path))
    if writer is None or writer.part_blocks != blocks or writer.contract is not contract:
        writer = PartWriter(path, contract, part_blocks=blocks)
        _WRITERS[str(path)] = writer
    return writer


def forget_writers(state: Path) -> None:
    """Drop this process's part writers of the state folder *state* (a monitor starting
    on it: another process may have written its parts since)."""
    for key in [k for k in _WRITERS if Path(k).parent == Path(state)]:
        del _WRITERS[key]


def part_blocks(step_s: float) -> int:
    """Blocks per part of the state folder's growing tables: a day's. [blocks]"""
    return max(1, int(round(86400.0 / float(step_s))))


def _write_outlook(
    report,
    state: Path,
    forecast,
    health,
    alarms,
    parent_pid,
    step_s: float,
    *,
    forecast_from: int | None = None,
    health_from: int | None = None,
    rows: tuple[int, int] | None = None,
) -> bool:
    """Count the rows into *report* and write the three tables (False, and
    ``report.written`` False, when the monitor that asked has died meanwhile): forecast
    and health as parted tables (a day per part; only the parts from *forecast_from* and
    *health_from* on are compared and rewritten; *forecast* and *health* may hold only
    those rows, *rows* then counts the whole tables), alarms (a row per episode) whole."""
    report.forecast_rows, report.health_rows = rows or (len(forecast), len(health))
    report.alarms = len(alarms)
    for frame, name, contract, since in (
        (forecast, "forecast.parquet", FORECAST, forecast_from),
        (health, "health.parquet", HEALTH, health_from),
    ):
        if parent_pid is not None and os.getppid() != parent_pid:
            report.written = False
            return False
        part_writer(state / name, contract, step_s).write(frame, since_block=since)
    if not _write(alarms, state / "alarms.parquet", ALARMS, parent_pid):
        report.written = False
        return False
    return True


#: The ship log read as it grows (:class:`~workbench.monitor.ship_log.LiveShipLog`), by
#: path, mapping and UTC offset: one at a time.
_LIVE_LOGS: dict[tuple, object] = {}


def _ship_log(
    path: Path, mapping: Mapping[str, str] | None, utc_offset: str | None = None
) -> pd.DataFrame:
    """The ship log (times without an offset at *utc_offset*) as read whole, the line the
    data system is writing left out until it is whole; only the lines appended since the
    last read are parsed (:class:`~workbench.monitor.ship_log.LiveShipLog`), nothing when
    the file's size and modification time are unchanged."""
    from .ship_log import LiveShipLog

    key = (str(path), repr(sorted((mapping or {}).items())), utc_offset)
    live = _LIVE_LOGS.get(key)
    if live is None:
        live = LiveShipLog(path, mapping, utc_offset)
        _LIVE_LOGS.clear()
        _LIVE_LOGS[key] = live
    return live.read()


def _ship_log_generation(
    path: Path | None, mapping: Mapping[str, str] | None, utc_offset: str | None = None
) -> int | None:
    """The read generation of the ship log :func:`_ship_log` last gave for these
    arguments (:attr:`~workbench.monitor.ship_log.LiveShipLog.generation`: the same while
    it only grew by appended rows), None when it has not read it."""
    key = (str(path), repr(sorted((mapping or {}).items())), utc_offset)
    live = _LIVE_LOGS.get(key)
    return None if live is None else live.generation


def _ship_log_content(
    path: Path | None, mapping: Mapping[str, str] | None, utc_offset: str | None = None
) -> tuple[int, str] | None:
    """The bytes of the ship log :func:`_ship_log` last parsed for these arguments and
    their SHA-256 (:attr:`~workbench.monitor.ship_log.LiveShipLog.content`), None when it
    has not read it."""
    key = (str(path), repr(sorted((mapping or {}).items())), utc_offset)
    live = _LIVE_LOGS.get(key)
    return None if live is None else live.content


def block_predictors_of(
    tracked: pd.DataFrame,
    dship: Path,
    grid,
    settings: ForecastSettings,
    from_block: int | None = None,
    *,
    first_block: int | None = None,
) -> pd.DataFrame:
    """The ship log averaged onto the blocks first..last of *tracked* (as ``workbench
    forecast --dship`` does), with the optional predictors (fuel on board) the log has;
    with *from_block*, only the blocks from it on (each block's values are those of the
    whole table). *first_block*: the whole table's first block, when *tracked* holds only
    its newest rows."""
    from data_contracts import (
        CANONICAL_PREDICTORS,
        OPTIONAL_PREDICTORS,
        PREDICTOR_KEYS,
        recorded_grid,
        set_grid,
    )

    from ..predictors import block_predictors
    from ..predictors.tables import ship_log_without_predictors

    log = _ship_log(Path(dship), dict(settings.dship_mapping), settings.dship_utc_offset)
    no_reading = ship_log_without_predictors(log, all_predictors=settings.all_predictors)
    if no_reading:  # no block can have a predictor value
        raise ValueError(f"{dship}: {no_reading}")
    first, last = int(tracked["block"].min()), int(tracked["block"].max())
    if first_block is not None:
        first = int(first_block)
    if from_block is not None:
        first = max(first, int(from_block))
    recorded = recorded_grid(tracked)
    if recorded is not None and recorded.get("varying_length"):
        # blocks of varying length: each block's own span, as load_predictors averages
        # them for `workbench forecast` (a block missing from the table: the grid's span)
        spans = grid.frame(np.arange(first, last + 1))
        own = tracked[["block", "block_start", "block_end"]].drop_duplicates("block")
        own = own.set_index("block")
        present = spans["block"].isin(own.index).to_numpy()
        for column in ("block_start", "block_end"):
            values = pd.to_datetime(own[column], utc=True).reindex(spans["block"][present])
            spans.loc[present, column] = values.to_numpy()
        table = block_predictors(log, blocks=spans, min_coverage=0.5)
        table = set_grid(PREDICTORS.validate(table), recorded)
    else:
        table = block_predictors(
            log, grid=grid, blocks=np.arange(first, last + 1), min_coverage=0.5
        )
        table = PREDICTORS.validate(table)
    if settings.all_predictors:
        return table
    columns = [
        *PREDICTOR_KEYS,
        *(c.name for c in CANONICAL_PREDICTORS),
        *(c.name for c in OPTIONAL_PREDICTORS),
    ]
    return table[[c for c in columns if c in table.columns]]


def forecast_table(
    tracked: pd.DataFrame,
    predictors: pd.DataFrame,
    settings: ForecastSettings,
    poles: pd.DataFrame | None = None,
) -> tuple[pd.DataFrame, list[str]]:
    """Forecast table (FORECAST contract) of every option, and the forecast's warnings:
    the forecast stage (:func:`workbench.stages.forecast`) that ``workbench forecast`` runs.

    Raises
    ------
    ValueError
        When no mode is measured often enough or the table is too short to forecast.
    """
    from ..errors import WorkbenchError
    from ..stages.forecasting import forecast

    if "B" in settings.forecast.options and poles is None:
        raise ValueError("option B needs the stabilisation diagrams (poles)")
    try:
        result = forecast(tracked, predictors, poles=poles, options=settings.forecast)
    except WorkbenchError as error:
        raise ValueError(str(error)) from None
    return result.table, list(result.warnings)


def update_outlook(
    state: str | os.PathLike,
    dship: str | os.PathLike | None,
    settings: ForecastSettings,
    grid,
    *,
    store: str | os.PathLike | None = None,
    harmonic_modes: pd.DataFrame | None = None,
    harmonics=None,
    parent_pid: int | None = None,
) -> OutlookReport:
    """Recompute ``forecast``, ``health`` and ``alarms`` of the state folder from its
    ``tracked.parquet`` and the ship log *dship* (see the module notes).

    Tables that cannot be computed yet (too few blocks, no reference period) are written
    empty, with the reason in the report's messages. *store* (the monitor's block store)
    is read for the stabilisation diagrams when option B is asked for; their poles are
    marked as harmonics from *harmonic_modes* (the tracked selected modes the monitor
    marked, with their shapes and ``harmonic``) with the *harmonics* options
    (:class:`~workbench.sid.harmonics.HarmonicOptions`), as ``identify --dship`` marks
    its pole table.
    """
    from ..predictors.tables import canonical_predictors
    from ..shm import HealthOptions, health_chart
    from .structural_health import operational_health

    started, cpu = time.perf_counter(), time.process_time()
    state = Path(state)
    report = OutlookReport()
    from .incremental import supported

    if dship is not None and supported(settings):
        _incremental_outlook(state, Path(dship), settings, grid, report, parent_pid)
        report.seconds = time.perf_counter() - started
        report.cpu_seconds = time.process_time() - cpu
        return report
    tracked_path = state / "tracked.parquet"
    forecast = empty_table(FORECAST)
    failed = False  # the update failed: the tables computed before are kept
    tracked, predictors = empty_table(MODAL), None
    if tracked_path.exists() and dship is not None:
        tracked = read_table(tracked_path, MODAL)
        report.n_blocks = int(tracked["block"].nunique()) if len(tracked) else 0
        if len(tracked):
            log_notes: list[str] = []
            try:
                # the ship log's notes go to the report (and status.json), not to stderr
                # at every recompute
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    predictors = block_predictors_of(tracked, Path(dship), grid, settings)
                report.messages += list(dict.fromkeys(str(w.message) for w in caught))
                log = _ship_log(
                    Path(dship), dict(settings.dship_mapping), settings.dship_utc_offset
                )
                log_notes = log_start_notes(log, grid, int(tracked["block"].min()))
                newest_end = _newest_end(tracked, grid, int(tracked["block"].max()))
                report.log_complete = bool(len(log) and log["time"].max() >= newest_end)
                poles = None
                if "B" in settings.forecast.options and store is not None:
                    poles = _store_poles(Path(store), tracked, harmonic_modes, harmonics)
                shown = predictors if settings.all_predictors else canonical_predictors(predictors)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # other than the forecast's own notes
                    forecast, notes = forecast_table(tracked, shown, settings, poles)
                report.messages += notes
            except (ValueError, ArithmeticError, np.linalg.LinAlgError, OSError) as error:
                report.messages.append(f"forecast: {str(error).splitlines()[0]}")
                forecast, failed = empty_table(FORECAST), True
            except Exception as error:  # noqa: BLE001 - a contract or data error of the log
                report.messages.append(f"forecast: {type(error).__name__}: {error}")
                forecast, failed = empty_table(FORECAST), True
            report.messages += log_notes
    elif dship is None:
        report.messages.append("forecast: no ship log given")
    health, alarms = empty_table(HEALTH), empty_table(ALARMS)
    if settings.health_model == "operational":
        if predictors is not None and len(tracked):
            try:
                found = operational_health(tracked, predictors, settings, grid.step_s)
                if found[0] is not None:
                    health, alarms = found[0], found[1]
                report.messages += found[2]
                report.health_schedule = found[2][0] if found[2] else ""
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
                report.messages.append(f"health: {str(error).splitlines()[0]}")
            except Exception as error:  # noqa: BLE001 - say so; the next block retries
                report.messages.append(f"health: {type(error).__name__}: {error}")
    elif len(forecast):
        blocks = int(round(settings.reference_hours * 3600.0 / grid.step_s))
        try:
            chart = health_chart(
                forecast,
                HealthOptions(
                    reference_blocks=blocks,
                    ewma_lambda=settings.ewma_lambda,
                    false_alarms_per_day=settings.false_alarms_per_day,
                ),
            )
            health, alarms = chart.table, chart.alarms
        except ValueError as error:
            report.messages.append(f"health: {str(error).splitlines()[0]}")
    if not (failed and _kept(state, report)):
        _write_outlook(report, state, forecast, health, alarms, parent_pid, grid.step_s)
    report.seconds = time.perf_counter() - started
    report.cpu_seconds = time.process_time() - cpu
    return report


def _kept(state: Path, report) -> bool:
    """After an update that failed (the ship log unreadable for a moment, e.g. caught while
    a line was being written): whether the forecast, health and alarm tables of an
    earlier update are there, and are kept as they are (``report.written`` False)
    rather than replaced by empty ones; the next update tries again."""
    names = ("forecast.parquet", "health.parquet", "alarms.parquet")
    if not all((state / name).exists() for name in names):
        return False
    report.written = False
    return True


#: The monitors' resumed outlooks in this process, by state folder.
_OUTLOOKS: dict[str, object] = {}
#: A block's predictors are taken as final (its forecast window committed) once the ship
#: log reaches this long past its end: the log's spike filter looks at samples on both
#: sides of each one (a later change of a committed block is followed all the same, by
#: going back to an earlier committed window). [s]
FINAL_AFTER_S = 3600.0


def _incremental_outlook(
    state: Path, dship: Path, settings: ForecastSettings, grid, report: OutlookReport, parent_pid
) -> None:
    """:func:`update_outlook` with the state of :class:`~workbench.monitor.incremental.
    IncrementalOutlook` carried between updates (and saved in ``<state>/outlook/``)."""
    from .incremental import IncrementalOutlook, NeedsFullHistory

    forecast, health, alarms = empty_table(FORECAST), empty_table(HEALTH), empty_table(ALARMS)
    forecast_from = health_from = rows = None
    failed = False  # the update failed: the tables computed before are kept
    tracked_path = state / "tracked.parquet"
    folder = state / "outlook"
    outlook = _OUTLOOKS.get(str(state))
    if outlook is None or outlook.settings != settings:
        try:
            outlook = IncrementalOutlook.load(
                folder,
                settings,
                grid.step_s,
                forecast=_read_or_empty(state / "forecast.parquet", FORECAST),
                health=_read_or_empty(state / "health.parquet", HEALTH),
            )
        except (ValueError, OSError) as error:
            if (folder / "outlook.json").is_file():
                report.messages.append(f"forecast: {error}; computed again from the first block")
            outlook = IncrementalOutlook(settings, grid.step_s)
        _OUTLOOKS.clear()
        _OUTLOOKS[str(state)] = outlook
    # the tracked rows the update reads (from inputs_from on) and the whole table's counts
    try:
        summary = tracked_summary(tracked_path)
        tracked = read_tracked(tracked_path, since_block=outlook.inputs_from)
    except (ValueError, OSError) as error:  # ContractError is a ValueError
        report.messages.append(f"forecast: {str(error).splitlines()[0]}")
        summary, tracked = None, empty_table(MODAL)
    report.n_blocks = summary["blocks"] if summary is not None else 0
    if len(tracked):
        log_notes: list[str] = []
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                log = _ship_log(dship, dict(settings.dship_mapping), settings.dship_utc_offset)
                first, newest = summary["first_block"], summary["last_block"]
                log_notes = log_start_notes(log, grid, first)
                newest_end = _newest_end(tracked, grid, newest)
                report.log_complete = bool(len(log) and log["time"].max() >= newest_end)
                final_through = None
                if len(log):
                    covered = pd.Timestamp(log["time"].max()) - pd.Timedelta(seconds=FINAL_AFTER_S)
                    final_through = int(
                        np.floor(
                            ((covered - grid.t0) / pd.Timedelta(seconds=grid.step_s))
                            - grid.length_s / grid.step_s
                        )
                    )
                for attempt in range(2):  # resumed, else once from the first block
                    start = None if attempt else outlook.inputs_from
                    if attempt and int(tracked["block"].min()) != first:
                        tracked = read_tracked(tracked_path)  # the whole table, once
                    predictors = block_predictors_of(
                        tracked, dship, grid, settings, start, first_block=first
                    )
                    try:
                        found = outlook.update(
                            tracked,
                            predictors,
                            first_block=first,
                            final_through=final_through,
                            mode_blocks=summary["mode_blocks"],
                            tracked_blocks=summary["blocks"],
                            tails=True,
                        )
                        break
                    except NeedsFullHistory:
                        if attempt:
                            raise
            report.messages += list(dict.fromkeys(str(w.message) for w in caught))
            report.messages += found.messages
            report.health_schedule = found.health_schedule
            forecast, forecast_from = found.forecast, found.forecast_from
            rows = (found.forecast_rows, 0)
            if found.health is not None:
                health, alarms, health_from = found.health, found.alarms, found.health_from
                rows = (found.forecast_rows, found.health_rows)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError, OSError) as error:
            report.messages.append(f"forecast: {str(error).splitlines()[0]}")
            failed = True
        except Exception as error:  # noqa: BLE001 - a contract or data error of the log
            report.messages.append(f"forecast: {type(error).__name__}: {error}")
            failed = True
        report.messages += log_notes
    if failed and _kept(state, report):
        return
    if not _write_outlook(
        report,
        state,
        forecast,
        health,
        alarms,
        parent_pid,
        grid.step_s,
        forecast_from=forecast_from,
        health_from=health_from,
        rows=rows,
    ):
        return
    try:
        outlook.save(folder)
    except (OSError, TypeError, ValueError) as error:
        report.messages.append(f"forecast: state not saved ({error}); a restart computes it again")


def log_start_notes(log: pd.DataFrame, grid, first: int) -> list[str]:
    """One note when the ship log starts after the end of block *first* (the first tracked
    block): a log cut at its start, or replaced by a newer file, leaves the blocks before
    its start without predictors, and the forecast of every block is computed again
    without them."""
    if not len(log):
        return []
    start = pd.Timestamp(log["time"].min())
    if start <= grid.end(first):
        return []
    # the last block that ends at or before the log's first time
    before = (start - grid.t0).total_seconds() - grid.length_s
    last = max(first, int(np.floor(before / grid.step_s + 1e-9)))
    return [
        f"ship log: starts at {start:%Y-%m-%dT%H:%M:%SZ}, after block(s) {first}-{last} "
        f"(from {grid.start(first):%Y-%m-%dT%H:%M:%SZ}): they have no predictors (a log cut "
        "at its start, or another file?)"
    ]


def _newest_end(tracked: pd.DataFrame, grid, newest: int) -> pd.Timestamp:
    """End of block *newest*: the grid's, or its own when it is longer (blocks of
    varying length)."""
    end = grid.end(newest)
    if "block_end" in tracked.columns:
        own = tracked.loc[tracked["block"].to_numpy() == newest, "block_end"]
        if len(own):
            end = max(end, pd.Timestamp(own.max()))
    return end


#: The tracked table's columns the forecast and the health chart read.
TRACKED_COLUMNS = (
    "block",
    "block_start",
    "block_end",
    "mode",
    "frequency_hz",
    "damping_ratio",
    "combined_frequency_std_hz",
    "half_difference_hz",
)


def read_tracked(path: Path, since_block: int | None = None) -> pd.DataFrame:
    """``tracked.parquet`` with the columns the forecast and the chart read
    (:data:`TRACKED_COLUMNS`; not the mode shapes, two per channel), validated (MODAL)
    and with its block grid; with *since_block*, only the rows from that block on (of a
    parted table, only the parts holding them are read)."""
    import pyarrow.parquet as pq

    from data_contracts import grid as _grid
    from data_contracts.parts import is_parted, read_parts

    if is_parted(path):
        return read_parts(path, MODAL, columns=list(TRACKED_COLUMNS), since_block=since_block)
    if not Path(path).is_file():
        return empty_table(MODAL)
    try:
        names = set(pq.read_schema(path).names)
        frame = pd.read_parquet(path, columns=[c for c in TRACKED_COLUMNS if c in names])
    except Exception as error:  # noqa: BLE001 - pyarrow raises many types for a bad file
        raise ValueError(f"{path}: cannot read ({str(error).splitlines()[0]})") from None
    if since_block is not None:
        frame = frame[frame["block"].to_numpy() >= int(since_block)].reset_index(drop=True)
    frame.attrs.pop(_grid.GRID_ATTR, None)
    table = MODAL.validate(frame, source=path)
    return _grid.attach_grid(table, _grid.read_grid(path, "parquet"), path)


def tracked_summary(path: Path) -> dict | None:
    """The whole tracked table in a few numbers: ``first_block``, ``last_block``,
    ``blocks`` (tracked blocks) and ``mode_blocks`` (blocks per mode); None when it has no
    rows. From the index of a parted table (:func:`data_contracts.parts.summarize`),
    else from the file."""
    from data_contracts.parts import is_parted, summarize

    if is_parted(path):
        found = summarize(path)
        if found["first_block"] is None:
            return None
        return found
    if not Path(path).is_file():
        return None
    try:
        frame = pd.read_parquet(path, columns=["block", "mode"])
    except Exception as error:  # noqa: BLE001 - pyarrow raises many types for a bad file
        raise ValueError(f"{path}: cannot read ({str(error).splitlines()[0]})") from None
    if not len(frame):
        return None
    return {
        "first_block": int(frame["block"].min()),
        "last_block": int(frame["block"].max()),
        "rows": len(frame),
        "blocks": int(frame["block"].nunique()),
        "mode_blocks": {
            int(m): int(n) for m, n in frame.groupby("mode")["block"].nunique().items()
        },
    }


def _read_or_empty(path: Path, contract) -> pd.DataFrame:
    return read_table(path, contract) if path.exists() else empty_table(contract)


def _store_poles(
    store: Path, tracked: pd.DataFrame, harmonic_modes: pd.DataFrame | None = None, harmonics=None
) -> pd.DataFrame | None:
    """The pole table of the tracked blocks from the store's committed batches, in the
    order ``poles.parquet`` of ``workbench identify`` has them, with its ``harmonic``
    column as ``identify --dship`` gives it (:func:`~workbench.sid.harmonics.mark_poles`
    against the marked modes of *harmonic_modes*; without them, none: no ship log)."""
    committed = {p.stem for p in (store / "blocks").glob("day=*/*.parquet")}
    files = [p for p in sorted((store / "poles").glob("day=*/*.parquet")) if p.stem in committed]
    if not files:
        return None
    poles = pd.concat([pd.read_parquet(p) for p in files], ignore_index=True)
    poles = poles.sort_values(["block", "model_order"], kind="stable")
    poles = poles.sort_values(["block", "model_order", "frequency_hz"], kind="stable")
    poles = poles.reset_index(drop=True)
    if harmonic_modes is not None:
        from ..sid.harmonics import mark_poles

        poles["harmonic"] = mark_poles(poles, harmonic_modes, harmonics)
    return POLES.validate(poles)
