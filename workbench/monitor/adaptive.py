"""Block lengths by conditions in the monitor (``monitor --block-minutes auto``).

The rule is ``identify --block-minutes auto``'s (:mod:`workbench.identification.adaptive`):
the excitation power of every half-step, the ship log's speed over it and the voyage's
states decide each block's length, the longest candidate (35, 25, 15 or 5 min with the
default 5-min step) whose span is steady. A live run cannot look at the whole voyage, so
:class:`AdaptiveLengths` measures each half-step once its data can no longer change (the
monitor's rule for blocks, :func:`~workbench.monitor.readiness.settled`) and decides a
block once every half-step of its longest candidate span is measured
(:func:`~workbench.identification.adaptive.decision_span`: 17.5 min after the block's
centre by default) and the ship log covers them: the decision then reads exactly what the
batch run reads, so it is the batch run's.

Waiting never hangs: a ship log that stays behind is waited for until data ``late_s``
newer has landed (the late window of missing files), then the block is decided without
the speeds the log lacks; at the end of the input (``--once``, or no file for
``flush_after_s``) the blocks still waiting are decided with the data present, their
longer spans reaching past it left out, as the batch run over the same files decides
them. Either is said in the monitor's messages.

The half-steps' power is kept in ``<state>/excitation.csv`` (``start``, ``end``, ``power``,
``speed_kn``: the ``excitation.csv`` of ``identify --block-minutes auto``, written
atomically), read back after a restart so that no half-step is measured twice.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import atomic_path

from ..errors import WorkbenchError
from ..identification.adaptive import (
    AdaptiveBlockOptions,
    _read_cases,
    decision_span,
    half_step_grid,
    half_step_power,
    half_step_speeds,
    last_block,
    length_grid,
    plan_block_lengths,
)
from ..identification.engine import conditioning_options
from .readiness import settled

log = logging.getLogger("workbench")

__all__ = ["AdaptiveLengths", "LEFT_OUT"]

_NS = 1_000_000_000

#: Reason recorded for a block whose shortest span does not fit the data (a gap): the
#: batch run leaves it out of its tables; the monitor stores it as skipped so that the
#: blocks after it are tracked.
LEFT_OUT = "no block length fits the data (a gap): left out, as identify --block-minutes auto"


def _empty_plan(t0) -> pd.DataFrame:
    """A length plan without blocks (its columns and types)."""
    empty = pd.DataFrame({c: pd.Series([], dtype=float) for c in ("power", "speed_kn")})
    empty["start"] = empty["end"] = pd.Series([], dtype="datetime64[ns, UTC]")
    return plan_block_lengths(empty, t0)


class AdaptiveLengths:
    """Measure the half-steps as the data lands and decide the blocks' lengths.

    Parameters
    ----------
    adaptive : AdaptiveBlockOptions
    t0 : Timestamp
        Start of the data (the first file's first sample): block ``k`` is centred at
        ``t0 + step / 2 + k step``.
    channels : tuple of str
        The voyage's channels.
    options : IdentifyOptions
        The resolved identification options (the half-steps are conditioned as
        ``identify`` conditions them).
    path : path-like
        Where the half-steps' conditions are kept (``<state>/excitation.csv``).
    cases : path, optional
        The voyage's states (CSV with ``case``, ``start``, ``end``), read again when it
        changes.
    """

    def __init__(
        self,
        adaptive: AdaptiveBlockOptions,
        t0: pd.Timestamp,
        channels: tuple[str, ...],
        options,
        *,
        path: str | Path,
        cases: str | Path | None = None,
    ) -> None:
        self.adaptive = adaptive
        self.t0 = pd.Timestamp(t0)
        self.channels = tuple(channels)
        self.options = options
        self.half_grid = half_step_grid(self.t0, adaptive.step_s)
        self.path = Path(path)
        self.cases = None if cases is None else Path(cases)
        self._cases: tuple = (None, None)
        self.power: dict[int, float] = {}  # half-step -> power (NaN: could not be built)
        self.speed: dict[int, float] = {}  # half-step -> the log's mean speed, once final
        self._log_end: pd.Timestamp | None = None  # the log's end at the last decision
        #: A block's length waits for the ship log (:meth:`decide`): look again when it grows.
        self.waiting_for_log = False
        self.n_half = 0  # half-steps the data present spans
        self.messages: list[str] = []
        self._dship: pd.DataFrame | None = None  # the ship log of the last decision
        self._load()

    # ------------------------------------------------------------------ grids
    def grid(self, length_s: float):
        """The block grid of the blocks *length_s* long (numbers shared by every length)."""
        return length_grid(self.t0, length_s, self.adaptive.step_s)

    def horizon(self, block: int) -> int:
        """Half-steps before this one decide *block*'s length."""
        return decision_span(block, self.adaptive)[1]

    def horizon_end(self, block: int) -> pd.Timestamp:
        """End of the data that decides *block*'s length (UTC)."""
        return self.half_grid.start(self.horizon(block))

    # ------------------------------------------------------------------ half-steps
    def measure(self, files, *, flush: bool, late_s: float) -> int:
        """Measure every half-step whose data can no longer change (all with *flush*).

        Parameters
        ----------
        files : sequence of LandedFile
            The files taken, in time order, their headers as placed (re-timed for clock
            jitter, :func:`~workbench.signals.block_plan.place_files`).

        Returns
        -------
        int
            Half-steps measured now.
        """
        from ..signals.block_builder import load_block
        from ..signals.block_plan import EDGE_SHIFT_S, plan_file_infos

        infos = [f.info for f in files]
        plan = plan_file_infos(
            infos, self.half_grid, max_gap_s=self.options.max_gap_s, channels=self.channels
        )
        self.n_half = len(plan.blocks)
        starts = np.array([i.start_time.value for i in infos], dtype=np.int64)
        ends = np.array([i.end_time.value for i in infos], dtype=np.int64)
        newest = int(ends.max())
        rate = infos[0].sampling_rate_hz
        conditioning = conditioning_options(self.options)
        measured = 0
        for planned in plan.blocks:
            j = int(planned.block)
            if j in self.power:
                continue
            # a drifting record's block is cut at the data's edge within EDGE_SHIFT_S of
            # its span: known once data beyond landed
            margin = int(EDGE_SHIFT_S * 1e9) if planned.drifting else 0
            if not flush and not settled(
                planned.sample_start.value - margin,
                planned.sample_end.value + margin,
                starts,
                ends,
                newest=newest,
                first_ns=self.t0.value,
                sampling_rate_hz=rate,
                late_s=late_s,
            ):
                continue
            if planned.skipped_reason:
                power = math.nan
            else:
                header = {info.path: info for info in plan.files}
                block = load_block(
                    [header[path] for path in planned.files],  # as placed: not read again
                    j,
                    self.half_grid,
                    options=conditioning,
                    channels=self.channels,
                    sample_start=planned.sample_start if planned.drifting else None,
                )
                power = half_step_power(block)
            self.power[j] = power
            measured += 1
        if measured:
            self._save(self.conditions(self._dship))
        return measured

    def conditions(self, dship: pd.DataFrame | None, first: int = 0) -> pd.DataFrame:
        """Half-steps ``first .. n_half - 1`` as :func:`~workbench.identification.adaptive.
        block_conditions` gives them (power NaN where not measured yet).

        A half-step's speed is kept once the log reaches :data:`~workbench.monitor.outlook.
        FINAL_AFTER_S` past it (the log's spike filter looks at samples on both sides), so
        only the newest hour's are averaged again: the cost does not grow with the voyage.
        """
        from .outlook import FINAL_AFTER_S

        j = np.arange(int(first), self.n_half)
        start = self.half_grid.t0 + pd.to_timedelta(j * self.half_grid.step_s, unit="s")
        table = pd.DataFrame(
            {
                "start": start,
                "end": start + pd.Timedelta(seconds=self.half_grid.length_s),
                "power": [self.power.get(int(k), math.nan) for k in j],
                "speed_kn": [self.speed.get(int(k), math.nan) for k in j],
            }
        )
        if dship is None:
            return table
        fresh = np.array([int(k) not in self.speed for k in j], dtype=bool)
        if fresh.any():
            speeds = half_step_speeds(table.loc[fresh].reset_index(drop=True), dship)
            table.loc[fresh, "speed_kn"] = speeds
            if self._log_end is not None:
                final = self._log_end - pd.Timedelta(seconds=FINAL_AFTER_S)
                ends = table.loc[fresh, "end"].to_numpy()
                for k, value, end in zip(j[fresh], speeds, ends, strict=True):
                    if end <= final:
                        self.speed[int(k)] = float(value)
        return table

    # ------------------------------------------------------------------ decisions
    def decide(
        self,
        undecided,
        dship: pd.DataFrame | None,
        *,
        newest: pd.Timestamp,
        flush: bool,
        late_s: float,
    ) -> tuple[pd.DataFrame, list[int]]:
        """The lengths of the blocks in *undecided* that can be decided now.

        A block is decided once every half-step before its :meth:`horizon` is measured
        and the ship log covers them (or data *late_s* newer than the horizon has landed:
        then without the speeds the log lacks); with *flush* (the input has ended), every
        block the data present holds, its spans past the data left out.

        Returns
        -------
        (DataFrame, list of int)
            The plan rows (:func:`~workbench.identification.adaptive.plan_block_lengths`'
            columns) of the blocks decided, and the blocks decided without a length (no
            span fits the data: the batch run leaves them out).
        """
        self._dship = dship
        if self.n_half == 0:
            return _empty_plan(self.t0), []
        log_end = None
        if dship is not None and len(dship) and "speed_kn" in dship.columns:
            # the log covers up to its last sample and one sampling interval beyond
            times = pd.to_datetime(dship["time"], utc=True).iloc[-64:]
            interval = times.diff().median() if len(times) > 1 else pd.Timedelta(0)
            log_end = times.max() + (interval if pd.notna(interval) else pd.Timedelta(0))
        self._log_end = log_end
        self.waiting_for_log = False
        ready, truncated, without_log = [], [], []
        for block in sorted(int(b) for b in undecided):
            horizon = self.horizon(block)
            if horizon > self.n_half and not flush:
                break  # the blocks after it reach further still
            through = min(horizon, self.n_half)
            if not flush and any(
                j not in self.power for j in range(decision_span(block, self.adaptive)[0], through)
            ):
                continue  # a hole in it: its late file is waited for
            end = self.half_grid.start(through)
            if dship is not None and (log_end is None or log_end < end):
                if not flush and newest < end + pd.Timedelta(seconds=late_s):
                    self.waiting_for_log = True
                    continue  # the log's speed over the span is waited for
                without_log.append(block)
            if horizon > self.n_half:
                truncated.append(block)
            ready.append(block)
        if not ready:
            return _empty_plan(self.t0), []
        # the half-steps from the first span of the first block decided on (an even
        # number: the blocks keep their centres, numbered from that half-step's block)
        first = decision_span(ready[0], self.adaptive)[0]
        t0 = self.half_grid.start(first)
        window = self.conditions(dship, first)
        plan = plan_block_lengths(window, t0, self.adaptive, cases=self._read_cases())
        plan["block"] += first // 2
        self._save(self.conditions(dship) if first else window)
        decided = plan[plan["block"].isin(ready)].reset_index(drop=True)
        # blocks the plan holds no row for although their data is there: no span fits
        planned = set(decided["block"])
        present = self.last_block()
        left_out = [b for b in ready if b not in planned and b <= present]
        if truncated:
            kept = [b for b in truncated if b in planned]
            if kept:
                self._say(
                    f"block lengths of blocks {kept[0]}-{kept[-1]} decided at the end of the "
                    "data present (their longer spans reach past it)"
                )
        if without_log:
            self._say(
                f"block lengths of blocks {without_log[0]}-{without_log[-1]} decided without "
                "the ship log's speed over their span (the log ends at "
                f"{'-' if log_end is None else log_end.isoformat()})"
            )
        return decided, left_out

    def last_block(self) -> int:
        """The last block whose shortest span ends inside the data present (-1: none)."""
        return last_block(self.n_half, self.adaptive)

    def _say(self, message: str) -> None:
        if message not in self.messages:
            log.info("%s", message)
            self.messages.append(message)

    def _read_cases(self) -> pd.DataFrame | None:
        if self.cases is None:
            return None
        try:
            stat = self.cases.stat()
        except OSError:
            return None  # not there yet: no states known
        key = (stat.st_size, stat.st_mtime_ns)
        if self._cases[0] != key:
            try:
                self._cases = (key, _read_cases(self.cases))
            except WorkbenchError as error:  # being rewritten, or broken: said, not fatal
                self._say(f"{error}; the states read before are used")
                self._cases = (key, self._cases[1])
        return self._cases[1]

    # ------------------------------------------------------------------ persistence
    def _save(self, conditions: pd.DataFrame) -> None:
        """``excitation.csv``: the measured half-steps up to the first not measured (the
        whole of the batch run's file once the input has ended), atomically."""
        n = 0
        while n in self.power and n < len(conditions):
            n += 1
        table = conditions.iloc[:n]
        with atomic_path(self.path) as tmp:
            table.to_csv(tmp, index=False, date_format="%Y-%m-%dT%H:%M:%S.%fZ")

    def _load(self) -> None:
        """The half-steps measured before a restart (none when the file is missing or
        of another grid: they are measured again)."""
        if not self.path.is_file():
            return
        try:
            table = pd.read_csv(self.path)
            start = pd.to_datetime(table["start"], utc=True)
            power = table["power"].to_numpy(dtype=float)
        except (OSError, ValueError, KeyError) as error:
            self.messages.append(f"{self.path}: not read ({error}); half-steps measured again")
            return
        for when, value in zip(start, power, strict=True):
            offset = (when - self.t0) / pd.Timedelta(seconds=self.adaptive.step_s / 2)
            j = int(round(offset))
            if abs(offset - j) > 1e-6 or j < 0:
                self.messages.append(f"{self.path}: half-steps of another grid; measured again")
                self.power.clear()
                return
            self.power[j] = float(value)
