"""Incremental structural-health chart: feed forecast rows block by block.

:class:`HealthMonitor` keeps what :func:`~workbench.shm.health_chart` needs between
blocks (the reference blocks until the reference is learned, then the EWMA vector and the
open alarm episode), so a live monitor feeds it each block's FORECAST rows as they come and
gets the new HEALTH rows and the new or changed ALARMS rows back. Fed a voyage block by
block, or all at once, it gives the batch chart's tables (``health_chart`` is this class fed
once). Its state saves to and loads from JSON (no pickle).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_contracts import ALARMS, FORECAST, HEALTH, atomic_path, recorded_grid

from ..blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S
from .chart import HealthReference, _residual_matrix, learn_reference
from .options import HealthOptions
from .statistics import cusum_step, ewma_step, hotelling

__all__ = ["HealthMonitor", "MonitorUpdate"]

#: Version of the JSON state layout.
STATE_VERSION = 3


@dataclass(frozen=True)
class MonitorUpdate:
    """What one :meth:`HealthMonitor.update` produced.

    Parameters
    ----------
    health : DataFrame
        New HEALTH rows (with ``contribution_<mode>``), one per block charted by this
        update (the reference blocks all at once when the reference is learned).
    alarms : DataFrame
        ALARMS rows of the episodes that started or changed in this update; a row with an
        ``alarm`` number seen before replaces the earlier one.
    """

    health: pd.DataFrame
    alarms: pd.DataFrame


def _num(value: float) -> float | None:
    """JSON-safe float (NaN and infinities as null)."""
    value = float(value)
    return value if math.isfinite(value) else None


def _arr(values) -> list:
    return [_num(v) for v in np.ravel(np.asarray(values, dtype=float))]


def _from_json(values) -> np.ndarray:
    return np.array([np.nan if v is None else float(v) for v in values], dtype=float)


class HealthMonitor:
    """Structural-health chart updated block by block.

    Parameters
    ----------
    options : HealthOptions, optional
        As for :func:`~workbench.shm.health_chart`.
    reference : HealthReference, optional
        An in-control state learned before (an earlier voyage's, from a saved
        :class:`~workbench.shm.baseline.HealthBaseline`): every block is charted from
        the first, in the ``monitor`` phase; ``reference_blocks`` is not used.

    Notes
    -----
    Blocks must arrive in increasing block order, each with all its rows in one update
    (rows of a block already charted are refused, so nothing is counted twice). Until the
    ``reference_blocks`` blocks from the reference start have arrived the monitor only
    buffers them; the update that completes the reference learns it and charts all of
    them at once. The block step (blocks per day) is the median step between the
    reference blocks.

    Examples
    --------
    >>> monitor = HealthMonitor(HealthOptions(reference_blocks=144))  # doctest: +SKIP
    >>> for rows in blocks_as_they_come:  # doctest: +SKIP
    ...     update = monitor.update(rows)
    ...     monitor.save_state("health_state.json")
    """

    def __init__(
        self, options: HealthOptions | None = None, reference: HealthReference | None = None
    ) -> None:
        self.options = options or HealthOptions()
        self.reference: HealthReference | None = None
        self._given_reference = reference is not None
        self._option: str | None = None
        # with a saved reference: the first block in the forecast phase (every block)
        self._reference_start: int | None = (
            None if reference is not None else self.options.reference_start_block
        )
        self._pending: list[dict[str, Any]] = []  # reference blocks before learning
        self._last_block: int | None = None
        self._charted = 0  # blocks charted since the reference start
        self._chart_state: np.ndarray | None = None  # EWMA z or CUSUM S per mode
        # the following baseline (baseline_hours): level, slope per block, level's block
        self._location: np.ndarray | None = None
        self._slope: np.ndarray | None = None
        self._baseline_block: int | None = None
        # CUSUM: sum and count of each mode's x since its S last left 0 (the estimated
        # change point), for the size of the change
        self._run_sum: np.ndarray | None = None
        self._run_count: np.ndarray | None = None
        self._episodes = 0
        self._open: dict[str, Any] | None = None  # the alarm episode in progress
        self._step_s: float | None = None  # block step of the recorded grid, if any
        self._length_s: float | None = None  # block length of the recorded grid, if any
        if reference is not None:
            self._start_chart(reference)
            self._step_s = 86400.0 / reference.blocks_per_day

    # ------------------------------------------------------------------ public
    def provisional_copy(self) -> HealthMonitor:
        """A copy to chart provisional blocks on, the same as ``copy.deepcopy`` at a cost
        that does not grow with an open alarm episode: the chart's arrays are replaced,
        never changed in place, by :meth:`update`, and the episode's per-block arrays are
        never changed once appended, so they are shared; the lists and the episode's
        dict are new."""
        other = copy.copy(self)
        other._pending = list(self._pending)
        if self._open is not None:
            other._open = dict(self._open)
            other._open["relative"] = list(self._open["relative"])
        return other

    def waiting_reason(self) -> str:
        """Why the reference is not learned yet (one line)."""
        if self._reference_start is None:
            return "forecast has no 'forecast' phase rows; give reference_start_block"
        return (
            f"reference period of {self.options.reference_blocks} blocks from block "
            f"{self._reference_start} but the forecast has only {len(self._pending)} blocks "
            "from there"
        )

    def update(self, rows: pd.DataFrame) -> MonitorUpdate:
        """Chart the blocks of *rows* (FORECAST rows, one or more whole blocks).

        Returns
        -------
        MonitorUpdate
            The new HEALTH rows and the new or changed ALARMS rows.

        Raises
        ------
        ContractError
            *rows* violate the FORECAST contract.
        ValueError
            A block arrives out of order or again.
        """
        grid = recorded_grid(rows)
        if grid is not None and self._step_s is None:
            self._step_s = float(grid["step_s"])
            self._length_s = float(grid["length_s"])
        table = FORECAST.validate(rows)
        if self._option is None and len(table):
            if self.options.option is not None:
                self._option = self.options.option
            else:
                self._option = "A" if (table["option"] == "A").any() else "B"
        table = table[table["option"] == self._option]
        if table.empty:
            return self._empty()
        blocks = np.sort(table["block"].unique())
        if self._last_block is not None and blocks[0] <= self._last_block:
            raise ValueError(
                f"block {int(blocks[0])} arrives after block {self._last_block} "
                "(blocks must arrive in increasing order, each once)"
            )
        if self._reference_start is None:
            in_forecast = table.loc[table["phase"] == "forecast", "block"]
            if not in_forecast.empty:
                self._reference_start = int(in_forecast.min())
        self._last_block = int(blocks[-1])
        if self._reference_start is None:
            return self._empty()
        table = table[table["block"] >= self._reference_start]
        if table.empty:
            return self._empty()
        wide, relative, shift = _residual_matrix(table, common_shift=self.options.common_shift)
        if shift is None or not self.options.model_uncertainty:
            shift = wide * np.nan
        starts = table.groupby("block")["block_start"].first().reindex(wide.index)
        new = [
            {
                "block": int(block),
                "block_start": starts.loc[block],
                "residual": {int(m): float(v) for m, v in wide.loc[block].items()},
                "relative": {int(m): float(v) for m, v in relative.loc[block].items()},
                "shift_std": {int(m): float(v) for m, v in shift.loc[block].items()},
            }
            for block in wide.index
        ]
        health_rows: list[dict[str, Any]] = []
        changed: dict[int, dict[str, Any]] = {}
        if self.reference is None:
            self._pending.extend(new)
            if len(self._pending) < self.options.reference_blocks:
                return self._empty()
            self._learn()
            new, self._pending = self._pending, []
        for item in new:
            health_rows.append(self._chart(item, changed))
        return MonitorUpdate(self._health_frame(health_rows), self._alarm_frame(changed))

    # ------------------------------------------------------------------ state
    def state(self) -> dict[str, Any]:
        """The monitor's state as plain JSON types."""
        reference = None if self.reference is None else reference_state(self.reference)

        def item_state(item: dict[str, Any]) -> dict[str, Any]:
            return {
                "block": item["block"],
                "block_start": item["block_start"].isoformat(),
                "residual": {str(m): _num(v) for m, v in item["residual"].items()},
                "relative": {str(m): _num(v) for m, v in item["relative"].items()},
                "shift_std": {str(m): _num(v) for m, v in item["shift_std"].items()},
            }

        open_episode = None
        if self._open is not None:
            open_episode = {
                **{
                    k: v
                    for k, v in self._open.items()
                    if k not in ("shares", "relative", "cusum_shift")
                },
                "cusum_shift": _arr(self._open.get("cusum_shift", [])),
                "start_time": self._open["start_time"].isoformat(),
                "end_time": self._open["end_time"].isoformat(),
                "shares": _arr(self._open["shares"]),
                "relative": [_arr(r) for r in self._open["relative"]],
            }
        return {
            "version": STATE_VERSION,
            "options": dataclasses.asdict(self.options),
            "given_reference": self._given_reference,
            "option": self._option,
            "reference_start": self._reference_start,
            "step_s": self._step_s,
            "length_s": self._length_s,
            "pending": [item_state(item) for item in self._pending],
            "last_block": self._last_block,
            "charted": self._charted,
            "chart_state": None if self._chart_state is None else _arr(self._chart_state),
            "location": None if self._location is None else _arr(self._location),
            "slope": None if self._slope is None else _arr(self._slope),
            "baseline_block": self._baseline_block,
            "run_sum": None if self._run_sum is None else _arr(self._run_sum),
            "run_count": None if self._run_count is None else _arr(self._run_count),
            "episodes": self._episodes,
            "open": open_episode,
            "reference": reference,
        }

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> HealthMonitor:
        """Rebuild a monitor from :meth:`state`."""
        if state.get("version") != STATE_VERSION:
            raise ValueError(
                f"health monitor state version {state.get('version')!r} is not {STATE_VERSION}"
            )
        monitor = cls(HealthOptions(**state["options"]))
        monitor._given_reference = bool(state["given_reference"])
        monitor._option = state["option"]
        monitor._reference_start = state["reference_start"]
        monitor._step_s = state.get("step_s")
        monitor._length_s = state.get("length_s")
        monitor._pending = [
            {
                "block": int(item["block"]),
                "block_start": pd.Timestamp(item["block_start"]),
                "residual": {int(m): _nan(v) for m, v in item["residual"].items()},
                "relative": {int(m): _nan(v) for m, v in item["relative"].items()},
                "shift_std": {int(m): _nan(v) for m, v in item["shift_std"].items()},
            }
            for item in state["pending"]
        ]
        monitor._last_block = state["last_block"]
        monitor._charted = int(state["charted"])
        chart_state = state["chart_state"]
        monitor._chart_state = None if chart_state is None else _from_json(chart_state)
        location = state["location"]
        monitor._location = None if location is None else _from_json(location)
        monitor._slope = None if state["slope"] is None else _from_json(state["slope"])
        monitor._baseline_block = state["baseline_block"]
        for name in ("run_sum", "run_count"):
            values = state[name]
            setattr(monitor, f"_{name}", None if values is None else _from_json(values))
        monitor._episodes = int(state["episodes"])
        episode = state["open"]
        if episode is not None:
            monitor._open = {
                **episode,
                "start_time": pd.Timestamp(episode["start_time"]),
                "end_time": pd.Timestamp(episode["end_time"]),
                "shares": _from_json(episode["shares"]),
                "relative": [_from_json(r) for r in episode["relative"]],
                "cusum_shift": _from_json(episode["cusum_shift"]),
            }
        if state["reference"] is not None:
            monitor.reference = reference_from_state(state["reference"])
        return monitor

    def save_state(self, path: str | os.PathLike) -> Path:
        """Write :meth:`state` to *path* as JSON, atomically."""
        path = Path(path)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.state(), allow_nan=False), encoding="utf-8")
        return path

    @classmethod
    def load_state(cls, path: str | os.PathLike) -> HealthMonitor:
        """Read a monitor saved by :meth:`save_state`."""
        try:
            state = json.loads(Path(path).read_text(encoding="utf-8"))
            return cls.from_state(state)
        except (json.JSONDecodeError, KeyError, TypeError) as error:
            raise ValueError(f"{path}: not a health monitor state ({error})") from None

    # ------------------------------------------------------------------ internals
    def _empty(self) -> MonitorUpdate:
        return MonitorUpdate(self._health_frame([]), self._alarm_frame({}))

    def _learn(self) -> None:
        n = self.options.reference_blocks
        items = self._pending[:n]
        modes = tuple(sorted({m for item in items for m in item["residual"]}))
        residuals = np.array([[item["residual"].get(m, np.nan) for m in modes] for item in items])
        relative = np.array([[item["relative"].get(m, np.nan) for m in modes] for item in items])
        model_shift = np.array(
            [[item["shift_std"].get(m, np.nan) for m in modes] for item in items]
        )
        blocks = np.array([item["block"] for item in items])
        starts = pd.DatetimeIndex([item["block_start"] for item in items])
        if self._step_s is not None:  # the recorded grid, not the blocks present
            step_s = self._step_s
        else:
            step_s = float(np.median(np.diff(starts.as_unit("ns").asi8))) / 1e9
        if not step_s > 0:
            raise ValueError("forecast: cannot infer the block step from block_start")
        if self._length_s is not None and self._step_s is not None:
            overlap_ratio = self._length_s / self._step_s
        else:  # no recorded grid: the project's blocks (20 min every 5 min)
            overlap_ratio = DEFAULT_BLOCK_LENGTH_S / DEFAULT_BLOCK_STEP_S
        reference = learn_reference(
            residuals,
            relative,
            modes,
            blocks,
            86400.0 / step_s,
            self.options,
            overlap_ratio,
            model_shift=model_shift,
        )
        self._start_chart(reference)
        self._step_s = step_s

    def _start_chart(self, reference: HealthReference) -> None:
        """Charting with *reference*: statistics at 0, the baseline at its level."""
        self.reference = reference
        self._chart_state = np.zeros(len(reference.modes))
        if reference.trend_slope is not None:
            self._location = reference.location.copy()
            self._slope = reference.trend_slope.copy()
            # a reference of this voyage: carried from its end; a saved one: from the
            # first block charted (its level at the earlier reference's end)
            self._baseline_block = None if self._given_reference else reference.end_block
        self._run_sum = np.zeros(len(reference.modes))
        self._run_count = np.zeros(len(reference.modes))

    def _chart(self, item: dict[str, Any], changed: dict[int, dict[str, Any]]) -> dict[str, Any]:
        ref = self.reference
        options = self.options
        assert ref is not None and self._chart_state is not None
        raw = np.array([item["residual"].get(m, np.nan) for m in ref.modes])
        in_reference = not self._given_reference and self._charted < options.reference_blocks
        phase = "reference" if in_reference else "monitor"
        if self._baseline_block is None and ref.trend_slope is not None:
            self._baseline_block = int(item["block"])
        location = ref.location
        if ref.trend_slope is not None:
            if phase == "reference":  # the reference's own drift line
                location = ref.location - ref.trend_slope * (ref.end_block - item["block"])
            else:  # the baseline's level and slope, carried to this block
                assert self._location is not None and self._slope is not None
                location = self._location + self._slope * (item["block"] - self._baseline_block)
        with np.errstate(invalid="ignore"):
            x = np.clip((raw - location) / ref.scale, -options.clip_sigma, options.clip_sigma)
        # the model's persistent error at this block, in the chart's units
        model = np.array([item["shift_std"].get(m, np.nan) for m in ref.modes]) / ref.scale
        model = np.nan_to_num(model, nan=0.0)
        if ref.statistic == "cusum":
            assert ref.allowance is not None and ref.mode_limits is not None
            # S_k = max(0, S_{k-1} - x_k - K_k), K_k = K + g·s_model: the allowance grows
            # by what the model cannot know (a persistent error would accumulate)
            # (beyond the reference's own, which the limits H_j already hold against)
            if ref.model_offset_std is not None:
                model = np.sqrt(np.maximum(model**2 - ref.model_offset_std**2, 0.0))
            allowance = ref.allowance + options.model_error_sigma * model
            self._chart_state = cusum_step(self._chart_state, x, allowance)
            parts = self._chart_state / ref.mode_limits
            t2 = float(parts.max())
            # the change's size: mean x since S last left 0 (Page's change-point
            # estimate), in relative frequency (K is half detect_shift in x units)
            running = self._chart_state > 0
            seen = running & np.isfinite(x)
            self._run_sum = np.where(running, self._run_sum + np.where(seen, x, 0.0), 0.0)
            self._run_count = np.where(running, self._run_count + seen, 0.0)
        else:
            # z_k = z_{k-1} + λ (x_k - z_{k-1}); a missing mode keeps its z
            self._chart_state = ewma_step(
                self._chart_state, x, options.ewma_lambda, ceiling=options.ewma_ceiling
            )
            # the persistent model error widens the in-control covariance of z (the EWMA
            # passes a persistent error through unattenuated)
            covariance = ref.ewma_covariance + np.diag(model**2)
            t2_row, parts_row = hotelling(self._chart_state[None, :], covariance)
            t2, parts = float(t2_row[0]), parts_row[0]
        self._charted += 1
        alarm = bool(t2 > ref.limit) and phase == "monitor"
        if ref.trend_slope is not None and not alarm and phase == "monitor":
            # Brown's linear exponential smoothing, ω = exp(-step / T): level
            # μ_k = p_k + (1 - ω²) e_k and slope β_k = β_{k-1} + (1 - ω)² e_k with p_k the
            # carried level and e_k = σ x_k (clipped: a wrong pole cannot drag it); a
            # drift, even a steady rise, is followed without lag, a step only slowly
            omega = math.exp(-float(self._step_s) / (3600.0 * float(options.baseline_hours)))
            error = ref.scale * np.nan_to_num(x, nan=0.0)
            self._location = location + (1.0 - omega**2) * error
            self._slope = self._slope + (1.0 - omega) ** 2 * error
            self._baseline_block = int(item["block"])
        with np.errstate(invalid="ignore", divide="ignore"):
            shares = parts / (parts.sum() if ref.statistic == "cusum" else t2)
        row = {
            "block": item["block"],
            "block_start": item["block_start"],
            "phase": phase,
            "n_modes": int(np.isfinite(raw).sum()),
            "statistic": max(t2, 0.0),
            "limit": ref.limit,
            "alarm": alarm,
        }
        for j, mode in enumerate(ref.modes):
            row[f"contribution_{mode}"] = shares[j] if t2 > 0 else np.nan
        relative = np.array([item["relative"].get(m, np.nan) for m in ref.modes])
        if alarm:
            if self._open is None:
                self._episodes += 1
                self._open = {
                    "alarm": self._episodes,
                    "start_block": item["block"],
                    "start_time": item["block_start"],
                    "peak_block": item["block"],
                    "peak_statistic": t2,
                    "shares": shares,
                    "relative": [],
                }
            elif t2 > self._open["peak_statistic"]:
                self._open.update(peak_block=item["block"], peak_statistic=t2, shares=shares)
            self._open.update(end_block=item["block"], end_time=item["block_start"])
            if ref.statistic == "cusum":
                with np.errstate(invalid="ignore", divide="ignore"):
                    mean_x = self._run_sum / self._run_count
                relative_scale = 0.5 * options.detect_shift / ref.allowance
                self._open["cusum_shift"] = 100.0 * mean_x * relative_scale
            self._open["relative"].append(relative)
            changed[self._open["alarm"]] = self._episode_row(self._open)
        else:
            self._open = None
        return row

    def _episode_row(self, episode: dict[str, Any]) -> dict[str, Any]:
        ref = self.reference
        assert ref is not None and ref.relative_median is not None
        shares = episode["shares"]
        order = np.argsort(-shares)
        named = [
            f"{ref.modes[j]} ({100 * shares[j]:.0f} %)" for j in order[:3] if shares[j] >= 0.05
        ]
        top = int(order[0])
        if ref.statistic == "cusum" and len(episode.get("cusum_shift", ())):
            shift = float(episode["cusum_shift"][top])  # mean since the change point
        else:  # median over the episode (read only here: the episode grows per block)
            values = np.array([r[top] for r in episode["relative"]])
            values = values[np.isfinite(values)]
            if values.size:
                shift = 100.0 * (float(np.median(values)) - float(ref.relative_median[top]))
            else:
                shift = np.nan
        return {
            "alarm": episode["alarm"],
            "start_block": episode["start_block"],
            "end_block": episode["end_block"],
            "start_time": episode["start_time"],
            "end_time": episode["end_time"],
            "peak_block": episode["peak_block"],
            "peak_statistic": float(episode["peak_statistic"]),
            "limit": ref.limit,
            "modes": "; ".join(named),
            "top_mode": ref.modes[top],
            "top_mode_shift_percent": shift if math.isfinite(shift) else np.nan,
        }

    def _health_frame(self, rows: list[dict[str, Any]]) -> pd.DataFrame:
        columns = list(HEALTH.column_names)
        if self.reference is not None:
            columns += [f"contribution_{m}" for m in self.reference.modes]
        frame = pd.DataFrame(rows, columns=columns)
        if frame.empty:
            return frame
        frame["block_start"] = pd.to_datetime(frame["block_start"], utc=True)
        return HEALTH.validate(frame)

    def _alarm_frame(self, changed: dict[int, dict[str, Any]]) -> pd.DataFrame:
        if not changed:
            return _no_alarms().copy()
        frame = pd.DataFrame(list(changed.values()), columns=list(ALARMS.column_names))
        return ALARMS.validate(frame)


@functools.cache
def _no_alarms() -> pd.DataFrame:
    """An empty ALARMS table (validated once: most blocks change no alarm)."""
    return ALARMS.validate(pd.DataFrame(columns=list(ALARMS.column_names)))


def reference_state(ref: HealthReference) -> dict[str, Any]:
    """*ref* as plain JSON types (:func:`reference_from_state` reads it back)."""
    return {
        "modes": list(ref.modes),
        "start_block": ref.start_block,
        "end_block": ref.end_block,
        "location": _arr(ref.location),
        "scale": _arr(ref.scale),
        "correlation": _arr(ref.correlation),
        "ewma_covariance": _arr(ref.ewma_covariance),
        "limit": ref.limit,
        "blocks_per_day": ref.blocks_per_day,
        "bootstrap_false_alarms_per_day": ref.bootstrap_false_alarms_per_day,
        "excluded_modes": list(ref.excluded_modes),
        "relative_median": _arr(ref.relative_median),
        "statistic": ref.statistic,
        "allowance": None if ref.allowance is None else _arr(ref.allowance),
        "mode_limits": None if ref.mode_limits is None else _arr(ref.mode_limits),
        "trend_slope": None if ref.trend_slope is None else _arr(ref.trend_slope),
        "model_offset_std": (None if ref.model_offset_std is None else _arr(ref.model_offset_std)),
    }


def reference_from_state(ref: dict[str, Any]) -> HealthReference:
    """The :class:`HealthReference` of :func:`reference_state`."""
    p = len(ref["modes"])

    def vector(name: str) -> np.ndarray | None:
        return None if ref.get(name) is None else _from_json(ref[name])

    return HealthReference(
        modes=tuple(int(m) for m in ref["modes"]),
        start_block=int(ref["start_block"]),
        end_block=int(ref["end_block"]),
        location=_from_json(ref["location"]),
        scale=_from_json(ref["scale"]),
        correlation=_from_json(ref["correlation"]).reshape(p, p),
        ewma_covariance=_from_json(ref["ewma_covariance"]).reshape(p, p),
        limit=float(ref["limit"]),
        blocks_per_day=float(ref["blocks_per_day"]),
        bootstrap_false_alarms_per_day=float(ref["bootstrap_false_alarms_per_day"]),
        excluded_modes=tuple(int(m) for m in ref["excluded_modes"]),
        relative_median=_from_json(ref["relative_median"]),
        statistic=str(ref["statistic"]),
        allowance=vector("allowance"),
        mode_limits=vector("mode_limits"),
        trend_slope=vector("trend_slope"),
        model_offset_std=vector("model_offset_std"),
    )


def _nan(value) -> float:
    return np.nan if value is None else float(value)
