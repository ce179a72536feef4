"""The monitor's outlook (forecast and health chart) carried from block to block.

:func:`~workbench.monitor.outlook.update_outlook` used to recompute the forecast and the
health chart over the whole voyage at every update, at a cost growing with the voyage
(``benchmarks/results/monitor_replay.txt``: 14 ms CPU per block of history, minutes per
update late in a 51-day expedition). :class:`IncrementalOutlook` keeps their state between
updates, so an update costs the same at day 51 as at day 1
(``benchmarks/results/monitor_constant_cost.txt``), and gives the same tables as the batch
commands (``workbench forecast`` + ``workbench health`` over the same tracked table and ship
log; ``tests/monitor/test_incremental_outlook.py``):

* forecast: :class:`~workbench.forecasting.incremental.IncrementalMemoryForecast` (its
  notes say what is carried and why that is exact); the modes forecast are the batch's
  (measured in at least ``min_presence`` of the blocks): when that set changes, the
  forecast starts over from the first block (once; the report says so);
* health chart (operational model, :mod:`workbench.monitor.structural_health`): the model
  is fitted once, on the first ``health_train_hours``, when the reference period after
  them is complete, and every block is charted once by a
  :class:`~workbench.shm.monitor.HealthMonitor` (CUSUM or MEWMA state carried); the
  newest ``HEALTH_LAG_BLOCKS`` blocks, and those whose ship log is not complete, are
  charted again at every update from a copy (their inputs may still change: the ship log
  grows, the tracker confirms a new mode up to 3 blocks back). The batch decides whether
  the log has fuel soundings (the model's fuel term, else a following baseline) over the
  whole log: when soundings first appear, the chart starts over from the first block.

Settings run in batch instead (the state is not carried): option B, the window model,
the single-window scheme, the forecast's own chart (``health_model="forecast"``) and a saved
health baseline (``--baseline``: its chart is one model evaluation and one chart pass per
update, :func:`~workbench.monitor.structural_health.operational_health`).

The state is saved with the monitor's state folder (:meth:`IncrementalOutlook.save`,
``<state>/outlook/``: JSON and ``.npy`` arrays, never pickle) and taken up again after a
restart when the settings are the same.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import ALARMS, FORECAST, HEALTH, recorded_grid, set_grid

from ..forecasting.incremental import (
    IncrementalMemoryForecast,
    NeedsFullHistory,
    consolidate,
    pieces_from,
)

__all__ = ["HEALTH_LAG_BLOCKS", "IncrementalOutlook", "NeedsFullHistory", "OutlookTables"]

#: The newest blocks charted again at every update (their tracked rows may still change:
#: the tracker confirms a new mode up to ``confirm_within`` = 3 blocks back). [blocks]
HEALTH_LAG_BLOCKS = 4
#: The state is saved when the committed blocks moved this far since the last save. [blocks]
SAVE_EVERY_BLOCKS = 12


@dataclass
class OutlookTables:
    """What one :meth:`IncrementalOutlook.update` gives: the state folder's tables."""

    forecast: pd.DataFrame
    health: pd.DataFrame | None
    alarms: pd.DataFrame | None
    messages: list[str] = field(default_factory=list)
    health_schedule: str = ""
    #: The forecast's (health table's) rows of the blocks before this one are those of the
    #: previous update's table (None: any row may have changed), so a writer rewrites only
    #: the parts from it on (:class:`data_contracts.parts.PartWriter`).
    forecast_from: int | None = None
    health_from: int | None = None
    #: Rows of the whole forecast and health tables (*forecast* and *health* hold only
    #: the rows from forecast_from and health_from on when the update was asked for tails).
    forecast_rows: int = 0
    health_rows: int = 0


def supported(settings) -> bool:
    """Whether :class:`IncrementalOutlook` carries these settings' state (module notes)."""
    return (
        settings.forecast.model == "memory"
        and settings.forecast.scheme == 2
        and settings.forecast.options == ("A",)
        and settings.health_model == "operational"
        and settings.health_baseline is None
    )


class IncrementalOutlook:
    """Forecast and health chart of the tracked table so far, resumed update by update.

    Parameters
    ----------
    settings : ForecastSettings
        The monitor's forecast and health settings (:func:`supported` ones).
    step_s : float
        Block step. [s]
    """

    def __init__(self, settings, step_s: float) -> None:
        if not supported(settings):
            raise ValueError("these forecast/health settings are run in batch")

        self.settings = settings
        self.step_s = float(step_s)
        self.forecast = IncrementalMemoryForecast(settings.forecast)
        self._modes: tuple[int, ...] | None = None
        self.restarts = 0  # forecast or chart started over from the first block
        self._reset_health()

    def _reset_health(self) -> None:
        self._model = None  # the operational model, once fitted
        self._model_notes: list[str] = []
        self._has_fuel: bool | None = None
        self._reference_design = None
        self._options = None
        self._monitor = None  # HealthMonitor fed through _charted_through
        self._charted_through: int | None = None
        self._health_rows: list[pd.DataFrame] = []
        self._alarms: dict[int, dict] = {}
        self._first_block: int | None = None
        self._health_resets = getattr(self, "_health_resets", -1) + 1
        self._health_total = 0  # rows of the whole health table

    @property
    def inputs_from(self) -> int | None:
        """First block whose tracked rows and predictors :meth:`update` needs (None: all)."""
        if self._model is None:
            return None
        starts = [self.forecast.inputs_from]
        if self._charted_through is not None:
            starts.append(self._charted_through + 1)
        if any(s is None for s in starts):
            return None
        return int(min(starts))

    # ------------------------------------------------------------------ the update
    def update(
        self,
        tracked: pd.DataFrame,
        predictors: pd.DataFrame,
        *,
        first_block: int,
        final_through: int | None,
        mode_blocks: dict[int, int] | None = None,
        tracked_blocks: int | None = None,
        tails: bool = False,
    ) -> OutlookTables:
        """Forecast and health chart of the voyage so far.

        Parameters
        ----------
        tracked : DataFrame
            The tracked table so far (MODAL contract): the whole table, or with
            *mode_blocks* its rows from :attr:`inputs_from` on.
        predictors : DataFrame
            The block predictors (PREDICTORS contract, the optional fuel column included)
            of the consecutive blocks from :attr:`inputs_from` (or *first_block*) to the
            newest tracked block.
        first_block : int
            The voyage's first tracked block.
        final_through : int, optional
            Newest block whose predictors no longer change (the ship log covers it).
        mode_blocks : dict, optional
            Blocks per mode over the whole tracked table (default: counted in *tracked*,
            which must then be whole).
        tracked_blocks : int, optional
            Blocks of the whole tracked table, those a mode's presence is a share of
            (given with *mode_blocks*; default: counted in *tracked*).
        tails : bool
            The tables returned hold only the rows from ``forecast_from`` and
            ``health_from`` on (the whole tables when those are None): what a writer of
            the changed parts needs, without assembling the whole tables.

        Raises
        ------
        NeedsFullHistory
            Pass the whole tables (from *first_block*) once.
        """
        from ..predictors.tables import canonical_predictors

        settings = self.settings
        messages: list[str] = []
        forecast_from = None
        forecast_rows = 0
        health_from = None if self._charted_through is None else self._charted_through + 1
        health_resets = self._health_resets
        # the forecast stage's modes: measured in at least min_presence of the tracked
        # blocks (a block without data - files missing, given up, skipped - is no block
        # a mode was absent from)
        if mode_blocks is None:
            counts = tracked.groupby("mode")["block"].nunique()
            n_blocks = tracked["block"].nunique()
        else:
            if tracked_blocks is None:
                raise ValueError("mode_blocks needs tracked_blocks (the tracked table's blocks)")
            counts = pd.Series(mode_blocks, dtype=float)
            n_blocks = int(tracked_blocks)
        presence = counts / max(n_blocks, 1)
        modes = tuple(
            sorted(int(m) for m in presence.index[presence >= settings.forecast.min_presence])
        )
        forecast = _empty(FORECAST)
        if self._modes is not None and modes != self._modes:
            self.restarts += 1
            self.forecast.reset()
            self._modes = None
            if int(predictors["block"].min()) != int(first_block):
                raise NeedsFullHistory("the modes forecast changed: start over")
        shown = predictors if settings.all_predictors else canonical_predictors(predictors)
        if modes:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    table, notes = self.forecast.update(
                        tracked, shown, modes=modes, final_through=final_through, tail=tails
                    )
                self._modes = modes
                forecast = table if len(table) else forecast
                forecast_rows = self.forecast.table_rows
                forecast_from = self.forecast.changed_from if forecast_rows else None
                set_grid(forecast, recorded_grid(tracked) or recorded_grid(predictors))
                messages += [f"option A: {m}" for m in notes]
            except ValueError as error:
                messages.append(f"forecast: {str(error).splitlines()[0]}")
                forecast_from = None
        else:
            messages.append(
                "forecast: no mode is measured in at least "
                f"{100 * settings.forecast.min_presence:.0f} % of the blocks"
            )
            forecast_from = None
        try:
            health, alarms, notes = self._health(
                tracked,
                predictors,
                first_block,
                final_through,
                tail_from=health_from if tails else None,
            )
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
            # as update_outlook says it; the model is fitted again at the next update
            self._reset_health()
            return OutlookTables(
                forecast,
                None,
                None,
                [*messages, f"health: {str(error).splitlines()[0]}"],
                forecast_from=forecast_from,
                forecast_rows=forecast_rows,
            )
        messages += notes
        health_rows = self._health_total
        if health is None or health_resets != self._health_resets:
            health_from = None
        return OutlookTables(
            forecast,
            health,
            alarms,
            messages,
            notes[0] if notes else "",
            forecast_from=forecast_from,
            health_from=health_from,
            forecast_rows=forecast_rows,
            health_rows=health_rows,
        )

    # ------------------------------------------------------------------ checkpoint
    def _key(self) -> tuple:
        checkpoint = self.forecast.checkpoint()
        return (None if checkpoint is None else checkpoint["block"], self._charted_through)

    def save(self, folder) -> bool:
        """Write the state to resume from into *folder* (``outlook.json`` and its arrays),
        when the committed blocks moved :data:`SAVE_EVERY_BLOCKS` since the last save (the
        first time: always); True when written."""
        from ..forecasting.incremental import save_state

        key = self._key()
        saved = getattr(self, "_saved_key", None)
        if saved is not None and key != saved and None not in key and None not in saved:
            # at most every SAVE_EVERY_BLOCKS committed blocks: the state holds an open alarm
            # episode's residuals, which grow with it; a restart redoes the blocks since
            if max(k - s for k, s in zip(key, saved, strict=True)) < SAVE_EVERY_BLOCKS:
                return False
        if key == saved:
            return False
        health = None
        if self._model is not None:
            health = {
                "model": {f.name: getattr(self._model, f.name) for f in fields(self._model)},
                "model_notes": list(self._model_notes),
                "has_fuel": bool(self._has_fuel),
                "reference_design": np.asarray(self._reference_design, dtype=float),
                "options": {f.name: getattr(self._options, f.name) for f in fields(self._options)},
                "monitor": self._monitor.state(),
                "charted_through": self._charted_through,
                "alarms": dict(self._alarms),
                "first_block": self._first_block,
            }
        payload = {
            "settings": repr(self.settings),
            "step_s": self.step_s,
            "modes": None if self._modes is None else list(self._modes),
            "restarts": self.restarts,
            "forecast": self.forecast.checkpoint(),
            "health": health,
        }
        Path(folder).mkdir(parents=True, exist_ok=True)
        save_state(Path(folder) / "outlook.json", payload)
        self._saved_key = key
        return True

    @classmethod
    def load(cls, folder, settings, step_s: float, *, forecast: pd.DataFrame, health: pd.DataFrame):
        """The outlook saved in *folder* (:meth:`save`), with the state folder's current
        *forecast* and *health* tables (their committed rows are taken up).

        Raises
        ------
        ValueError
            When there is none, it is unreadable, or it was saved with other settings.
        """
        from ..forecasting.incremental import load_state
        from ..shm import HealthOptions
        from ..shm.model import OperationalModel
        from ..shm.monitor import HealthMonitor

        path = Path(folder) / "outlook.json"
        if not path.is_file():
            raise ValueError(f"{path}: no saved outlook")
        payload = load_state(path)
        if payload.get("settings") != repr(settings) or payload.get("step_s") != float(step_s):
            raise ValueError(f"{path}: saved with other forecast/health settings")
        outlook = cls(settings, step_s)
        if payload["forecast"] is not None:
            outlook.forecast.resume(payload["forecast"], forecast)
            outlook._modes = tuple(int(m) for m in payload["modes"])
        outlook.restarts = int(payload["restarts"])
        saved = payload["health"]
        if saved is not None:
            outlook._model = OperationalModel(**saved["model"])
            outlook._model_notes = list(saved["model_notes"])
            outlook._has_fuel = bool(saved["has_fuel"])
            outlook._reference_design = saved["reference_design"]
            outlook._options = HealthOptions(**saved["options"])
            outlook._monitor = HealthMonitor.from_state(saved["monitor"])
            outlook._charted_through = saved["charted_through"]
            outlook._alarms = {int(k): v for k, v in saved["alarms"].items()}
            outlook._first_block = saved["first_block"]
            if outlook._monitor.reference is not None:  # rows charted for good: in the table
                done = health[health["block"] <= outlook._charted_through]
                if not len(done):
                    raise ValueError(f"{path}: the health table lacks the charted blocks")
                outlook._health_rows = [done.reset_index(drop=True)]
        outlook._saved_key = outlook._key()
        return outlook

    # ------------------------------------------------------------------ health
    def _health(self, tracked, predictors, first_block, final_through, tail_from=None):
        """HEALTH and ALARMS tables (None while learning) and the notes, as
        :func:`~workbench.monitor.structural_health.operational_health` gives them; with
        *tail_from*, the HEALTH rows from that block on (all if the chart started over)."""
        resets = self._health_resets
        from ..shm import HealthOptions, fit_operational_model
        from ..shm.monitor import HealthMonitor
        from .structural_health import FUEL_COLUMN, _at, learning_notes

        settings, step_s = self.settings, self.step_s
        train = int(round(settings.health_train_hours * 3600.0 / step_s))
        reference = int(round(settings.reference_hours * 3600.0 / step_s))
        first = int(first_block)
        last = int(predictors["block"].max())
        have = last - first + 1
        start = first + train + reference
        if have <= train + reference:
            return None, None, learning_notes(tracked, settings, step_s, first, have)
        has_fuel = bool(
            FUEL_COLUMN in predictors.columns and predictors[FUEL_COLUMN].notna().any()
        ) or bool(self._has_fuel)
        if self._model is not None and has_fuel != self._has_fuel:
            self.restarts += 1
            self._reset_health()
            if int(predictors["block"].min()) != first:
                raise NeedsFullHistory("the ship log has fuel soundings now: start over")
        if self._model is None:
            if int(predictors["block"].min()) != first:
                raise NeedsFullHistory("the health model is fitted on the first blocks")
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                model = fit_operational_model(
                    tracked, predictors, train_start_block=first, train_blocks=train
                )
            notes = [
                f"health: charting from block {start} ({_at(tracked, start, step_s)}), after "
                f"this voyage's {settings.health_train_hours:g}-h model and "
                f"{settings.reference_hours:g}-h reference"
            ]
            notes += list(dict.fromkeys(f"health: {w.message}" for w in caught))
            baseline = None if has_fuel else settings.baseline_hours
            if baseline is not None and not math.isfinite(baseline):
                baseline = None
            if not has_fuel:
                notes.append(
                    f"health: no {FUEL_COLUMN} in the ship log; the fuel burn is followed by "
                    f"a {baseline:g}-h baseline"
                    if baseline is not None
                    else f"health: no {FUEL_COLUMN} in the ship log and no baseline"
                )
            grid = predictors.sort_values("block").reset_index(drop=True)
            self._reference_design = model.reference_design(grid, first + train, reference)
            self._options = HealthOptions(
                reference_blocks=reference,
                reference_start_block=first + train,
                ewma_lambda=settings.ewma_lambda,
                false_alarms_per_day=settings.false_alarms_per_day,
                baseline_hours=baseline,
            )
            self._model, self._model_notes, self._has_fuel = model, notes, has_fuel
            self._monitor = HealthMonitor(self._options)
            self._first_block = first
        # the blocks not charted for good yet: charted again from a copy of the chart
        since = first if self._charted_through is None else self._charted_through + 1
        rows_from = since
        part = predictors[predictors["block"] >= rows_from]
        rows = self._model.forecast(
            tracked[tracked["block"] >= rows_from],
            part,
            reference_design=self._reference_design,
        )
        set_grid(rows, recorded_grid(tracked) or recorded_grid(predictors))
        final = last - HEALTH_LAG_BLOCKS
        if final_through is not None:
            final = min(final, int(final_through))
        charted = [*self._health_rows]
        done = rows[rows["block"] <= final]
        if len(done):
            update = self._monitor.update(done)
            if len(update.health):
                self._health_rows.append(update.health)
                if len(self._health_rows) > 8:  # a few frames, not one per update
                    self._health_rows = consolidate(self._health_rows)
            for row in update.alarms.to_dict("records"):
                self._alarms[int(row["alarm"])] = row
            self._charted_through = int(done["block"].max())
            charted = [*self._health_rows]
        alarms = dict(self._alarms)
        rest = rows[
            rows["block"] > (self._charted_through if self._charted_through is not None else -1)
        ]
        if len(rest):
            monitor = self._monitor.provisional_copy()
            update = monitor.update(rest)
            if len(update.health):
                charted.append(update.health)
            for row in update.alarms.to_dict("records"):
                alarms[int(row["alarm"])] = row
            reference_known = monitor.reference is not None
        else:
            reference_known = self._monitor.reference is not None
        if not reference_known:
            raise ValueError(self._monitor.waiting_reason())
        self._health_total = sum(len(c) for c in charted)
        if tail_from is not None and resets == self._health_resets:
            charted = pieces_from(charted, tail_from)
        health = pd.concat(charted, ignore_index=True) if charted else _empty(HEALTH)
        health = set_grid(health, recorded_grid(rows))
        alarms_table = (
            ALARMS.validate(pd.DataFrame(list(alarms.values()), columns=list(ALARMS.column_names)))
            if alarms
            else _empty(ALARMS)
        )
        return health, alarms_table, list(self._model_notes)


_EMPTY: dict[str, pd.DataFrame] = {}


def _empty(contract) -> pd.DataFrame:
    """A table of *contract* without rows (validated once per contract)."""
    if contract.name not in _EMPTY:
        _EMPTY[contract.name] = contract.validate(pd.DataFrame(columns=list(contract.column_names)))
    return _EMPTY[contract.name].copy()
