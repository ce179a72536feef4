"""The memory forecast carried from block to block: constant cost per new block.

:func:`~workbench.forecasting.memory.forecast.memory_forecast` runs its windows (``horizon`` blocks
each, method 2) in order; a window reads the state the windows before it left (Kalman
state, noise models, term selections, the model-trust filters, the innovation record) and
the measurements of at most the last ``history_limit`` = 6 x ``memory_blocks`` blocks
(the refits' exponentially weighted history; the noise, selection and consistency windows
are shorter). :class:`IncrementalMemoryForecast` keeps that state between calls: a call
with a few more blocks runs only the windows they complete, so its cost does not grow with
the voyage, and the table it returns equals the batch forecast's over the same tables to
round-off (``tests/monitor/test_incremental_outlook.py``, and over a 51-day replay in
``benchmarks/bench_monitor_blocks.py``).

The state is the batch forecast's own :class:`~workbench.forecasting.memory.forecast.
MemoryRun`, and :meth:`IncrementalMemoryForecast._window` runs a window with its
:meth:`~workbench.forecasting.memory.forecast.MemoryRun.model_rows` and
:meth:`~workbench.forecasting.memory.forecast.MemoryRun.kalman_pass`, as
:func:`~workbench.forecasting.memory.forecast.memory_forecast` does: one implementation of
the window. What this module adds is the bookkeeping: the rows appended as blocks come and
dropped once older than every window's history, the copies of committed states, the
checkpoint.

Why the history is carried as rows and not as discounted cross-product sums (recursive
least squares): every refit z-scores the candidate predictors with the mean and standard
deviation of the newest ``selection_blocks`` blocks and *clips* the z-scores at
±``extrapolation_limit`` before it forms the design, and the history is cut at
``history_limit`` blocks. A clipped term is not a linear combination of the raw terms, so
sums of raw cross-products reproduce the batch estimate only while no old block falls
outside the newest normalisation's clip range; the last ``history_limit`` rows are the
exact sufficient statistic, and their size is fixed (3456 blocks with the defaults).

What a call must be told, and what it re-runs:

* the windows whose blocks all have final inputs (``final_through``: the ship log covers
  them) are committed: their output rows are kept, and a copy of the state after them is
  kept (the newest ``snapshots`` of them);
* the blocks after the newest committed window are provisional: they are run again at the
  next call (the newest block's predictors change while the ship log grows, the last
  window is partial);
* inputs of a committed block that changed (a late assignment of the tracker, a block's
  predictors recomputed) take the state back to the newest copy before it; a change before
  the oldest copy, another set of modes or predictor columns, or another block grid
  starts over from the voyage's first block (:class:`NeedsFullHistory`: the caller then
  passes the whole tables once).

Supported: model ``"memory"``, method 2 (rolling), option A (the tracked pole), without
pole table or operating cases - the monitor's defaults. Other settings are run in batch by
the caller.
"""

from __future__ import annotations

import copy
import json
import math
import os
import warnings
from collections import Counter, deque
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import PredictorError
from .assembly import log_coverage_of, with_log_coverage
from .excitation import sub_windows_per_block, within_block_profile
from .innovation_consistency import InnovationConsistency
from .memory.excitation import ExcitationBias
from .memory.forecast import MemoryRun, never_explained_notes
from .memory.model import MemoryModel
from .memory.output import OUTPUT_ARRAYS
from .memory.terms import MemoryRefits
from .model_trust import ModelTrust
from .noise import NoiseModel
from .options import ForecastOptions, NoiseOptions
from .predictor_grid import (
    NS_PER_HOUR,
    block_centre_ns,
    block_column_coverage,
    block_log_coverage,
    mode_matrix,
    predictor_matrix,
)
from .ssi_guard import GuardWindow, SSIGuard

__all__ = [
    "CHECKPOINT_SCHEMA",
    "IncrementalMemoryForecast",
    "NeedsFullHistory",
    "load_state",
    "save_state",
]

#: ``schema`` of the checkpoint's JSON part (:meth:`IncrementalMemoryForecast.save`);
#: /3: block times in nanoseconds whatever the tables' resolution (/2 could hold
#: microseconds, which put the time trend in thousands of hours), the filter's
#: identification error as the overlap's segment states, the noise model's
#: ``error_segments`` and the model-trust lead test (issue 27); /4: the SSI guard's
#: windows (:mod:`workbench.forecasting.ssi_guard`); /5: the blocks' ``log_coverage``
#: (the model variance at a log outage's edges), the model correction before a log
#: outage's filled blocks and the state's unweighted move (issue 27), option B's run of
#: missed columns; /6: the log's coverage of the blocks per predictor column too
#: (``column_coverage``: the shares an outage edge's warning names); /7: the rows without
#: any mode measured (``record_gap``: a hole in the acceleration record); /8: each mode's
#: predictor range over its newest refit (``fit_range``: the extrapolation variance); /9: the
#: rows measured since a hole in the record ended (``since_hole``: a refit keeps the estimate
#: then); /10: the model-trust hull-wide change test's CUSUM sums, its flag and the block's
#: measurement (``change_sums``, ``change``, ``measured``); /11: the predictor columns and
#: matrix hold a direction as its cosine (``wind_dir_rel_cos``), not in degrees; /12: the
#: model-trust lead test against SSI (``lead_ssi``, ``ssi_scale``, ``ssi_probability``).
CHECKPOINT_SCHEMA = "workbench.forecasting.incremental/12"

#: Rows kept before the newest committed window beyond the refits' history. [blocks]
_MARGIN_ROWS = 64


class NeedsFullHistory(Exception):
    """The state cannot be resumed with the tables given: pass the whole voyage's tables."""


class IncrementalMemoryForecast:
    """Option A, method 2 memory forecast, resumed from block to block (module notes).

    Parameters
    ----------
    train_blocks : int
        First training window. [blocks]
    horizon : int
        Blocks per window (method 2's refit interval). [blocks]
    options : ForecastOptions, optional
        As :func:`~workbench.forecasting.sliding_forecast` takes them: ``model="memory"``
        (or None), ``scheme=2``, ``options=("A",)``, no ``predictor_columns``; its
        ``train_blocks``, ``horizon_blocks``, ``gap_warning_blocks`` and ``noise`` apply.
    snapshots : int
        Committed windows whose state is kept to go back to (a changed input up to about
        ``snapshots x horizon`` blocks back is followed without starting over).
    """

    def __init__(self, options: ForecastOptions | None = None, *, snapshots: int = 16) -> None:
        options = options or ForecastOptions()
        if options.model not in (None, "memory"):
            raise ValueError(f"model={options.model!r}: only the memory forecast is resumed")
        if options.scheme != 2 or tuple(options.options) != ("A",):
            raise ValueError(
                f"scheme={options.scheme!r}, options={options.options!r}: only scheme 2 "
                "with option A is resumed"
            )
        if options.predictor_columns is not None:
            raise ValueError("predictor_columns: only the default predictor columns are resumed")
        self.options = options
        self.model = options  # the settings the window loop reads (as the batch's MemoryRun)
        self.noise = options.noise
        self.horizon = options.horizon_blocks
        self.gap_warning_blocks = int(options.gap_warning_blocks)
        self.n_snapshots = int(snapshots)
        if self.n_snapshots < 1:
            raise ValueError(f"snapshots={snapshots} must be >= 1")
        self.restarts = 0  # starts from the first block after a committed window
        self._committed = False
        self.rollbacks = 0  # returns to an earlier committed window
        #: The last :meth:`update`'s table has the rows of the table before it for the
        #: blocks before this one (None: it started over, any row may have changed).
        self.changed_from: int | None = None
        #: Rows of the last :meth:`update`'s whole table (also when it returned a tail).
        self.table_rows = 0
        #: The ship log's coverage of the blocks of the last :meth:`update`'s predictors.
        self._coverage: pd.Series | None = None
        self.reset()

    # ------------------------------------------------------------------ bookkeeping
    def reset(self) -> None:
        """Forget everything: the next :meth:`update` starts at the voyage's first block."""
        self._snapshots: deque[tuple[int, MemoryRun, int]] = deque()  # (i0 block, core, chunks)
        self._chunks: list[tuple[int, pd.DataFrame]] = []  # committed output per window
        self._old: list[pd.DataFrame] = []  # output older than every snapshot, consolidated
        self._core: MemoryRun | None = None
        self._first_block: int | None = None  # the voyage's first block

    @property
    def inputs_from(self) -> int | None:
        """First block whose inputs :meth:`update` needs (None: the whole voyage)."""
        if not self._snapshots:
            return None
        return int(self._snapshots[0][0])

    # ------------------------------------------------------------------ inputs
    def _inputs(self, modal, predictors, modes):
        """The arrays of one call's tables, read as the batch forecast reads them."""
        grid, blocks, block_start, columns, X = predictor_matrix(predictors, None)
        if blocks.size and not (np.diff(blocks) == 1).all():
            raise NeedsFullHistory("the predictor blocks are not consecutive")
        labels = np.asarray(modes, dtype=np.int64)
        tracked = mode_matrix(modal, blocks, labels, "frequency_hz")
        combined = (
            mode_matrix(modal, blocks, labels, "combined_frequency_std_hz")
            if "combined_frequency_std_hz" in modal.columns
            else None
        )
        halves = (
            mode_matrix(modal, blocks, labels, "half_difference_hz")
            if "half_difference_hz" in modal.columns
            else None
        )
        damping = (
            mode_matrix(modal, blocks, labels, "damping_ratio")
            if "damping_ratio" in modal.columns
            else np.full((blocks.size, labels.size), np.nan)
        )
        return SimpleInputs(
            grid,
            blocks,
            block_start,
            block_centre_ns(grid),
            columns,
            X,
            labels,
            tracked,
            combined,
            damping,
            halves,
        )

    # ------------------------------------------------------------------ the call
    def update(
        self,
        modal: pd.DataFrame,
        predictors: pd.DataFrame,
        *,
        modes,
        final_through: int | None = None,
        tail: bool = False,
    ) -> tuple[pd.DataFrame, list[str]]:
        """The forecast table of the voyage so far and the forecast's notes.

        Parameters
        ----------
        modal : DataFrame
            Tracked modal table (MODAL contract), at least the blocks of *predictors*.
        predictors : DataFrame
            Block predictors on consecutive blocks, from :attr:`inputs_from` (or the
            voyage's first block) to the newest block.
        modes : sequence of int
            The modes to forecast (the forecast stage's persistent modes).
        final_through : int, optional
            Newest block whose inputs no longer change (default: none is final, nothing
            is committed).
        tail : bool
            Return only the rows from :attr:`changed_from` on (all when it is None): a
            writer of the parts that changed needs no more, and the whole table is not
            assembled (its cost grows with the voyage).

        Raises
        ------
        NeedsFullHistory
            When the tables must start at the voyage's first block (module notes).
        ValueError
            As the batch forecast: too few blocks for the first training window.
        """
        new = self._inputs(modal, predictors, modes)
        self._coverage = log_coverage_of(predictors)
        final_through = -(10**18) if final_through is None else int(final_through)
        # rows before the oldest committed copy can no longer change (unless started over)
        self.changed_from = self.inputs_from
        core = self._resume_point(new)
        if core is None:
            self.changed_from = None
            if self._first_block is not None and int(new.blocks[0]) != self._first_block:
                raise NeedsFullHistory(
                    f"the state starts over: the tables must start at block {self._first_block}"
                )
            # a start over once a window was committed (before: every update starts at 0)
            restarted = self._committed
            self.reset()
            self.restarts += restarted
            core = self._start(modal, predictors, new)
            self._first_block = int(new.blocks[0])
        self._append(core, new)
        provisional: list[pd.DataFrame] = []
        committing = True
        while core.i0 <= core.n - 1:
            f1 = min(core.i0 + self.horizon, core.n)
            start_block = int(core.blocks[core.i0 if not core.is_first else core.first])
            complete = f1 == core.i0 + self.horizon and int(core.blocks[f1 - 1]) <= final_through
            chunk = self._window(core, f1)
            core.is_first = False
            core.i0 = f1
            if committing and complete:
                self._chunks.append((start_block, chunk))
                self._commit(core)
            else:
                committing = False
                provisional.append(chunk)
        self._core = core
        pieces = [*self._old, *(c for _, c in self._chunks), *provisional]
        self.table_rows = sum(len(p) for p in pieces)
        if tail and self.changed_from is not None:
            pieces = pieces_from(pieces, self.changed_from)
        # each piece is sorted by (block, mode) and follows the one before: no sort needed
        table = pd.concat(pieces, ignore_index=True) if pieces else pd.DataFrame()
        return table, self._messages(core)

    # ------------------------------------------------------------------ checkpoint
    def checkpoint(self) -> dict | None:
        """The state to resume from (the newest committed window's), or None before the
        first committed window. The committed output rows are not in it: the caller keeps
        them (the forecast table's rows before :attr:`inputs_from`)."""
        if not self._snapshots:
            return None
        block, core, _ = self._snapshots[-1]
        return {"block": int(block), "first_block": self._first_block, "core": core}

    def resume(self, checkpoint: dict, committed: pd.DataFrame) -> None:
        """Take up *checkpoint* (:meth:`checkpoint`) with *committed*, the forecast table's
        rows of the blocks before the checkpoint's block.

        Raises
        ------
        ValueError
            When *committed* does not end at the checkpoint's block.
        """
        block, core = int(checkpoint["block"]), checkpoint["core"]
        if not isinstance(core, MemoryRun):
            raise ValueError("checkpoint without a forecast state")
        committed = committed[committed["block"] < block]
        if not len(committed):
            raise ValueError(f"the forecast table has no rows before block {block}")
        if int(committed["block"].max()) != block - 1:
            raise ValueError(
                f"the forecast table ends at block {int(committed['block'].max())}, the "
                f"checkpoint at block {block}"
            )
        self.reset()
        self._point(core)
        self._first_block = int(checkpoint["first_block"])
        self._core = core
        self._snapshots.append((block, copy.deepcopy(core), 0))
        self._committed = True
        self._old = [committed.reset_index(drop=True)]

    def _messages(self, core) -> list[str]:
        notes = Counter(core.notes) + never_explained_notes(core)
        return [f"{kind} (x{count})" for kind, count in notes.items()]

    # ------------------------------------------------------------------ resume or start
    def _resume_point(self, new) -> MemoryRun | None:
        """A copy of the newest committed state whose inputs *new* leaves unchanged, with
        the chunks after it dropped; None: start over."""
        if self._core is None or not self._snapshots:
            return None
        last = self._core
        if (
            list(new.columns) != list(last.input_columns)
            or not np.array_equal(new.labels, last.mode_labels)
            or new.blocks.size == 0
        ):
            return None
        if new.blocks[0] > self._snapshots[0][0]:
            raise NeedsFullHistory(
                f"the tables start at block {new.blocks[0]}, the state needs them from "
                f"block {self._snapshots[0][0]}"
            )
        if sub_windows_per_block(new.grid) != last.n_sub and new.blocks.size >= 3:
            return None
        # the earliest block whose inputs differ from those the state was run with
        changed = self._first_change(last, new)
        while self._snapshots and self._snapshots[-1][0] > changed:
            self._snapshots.pop()
            self.rollbacks += 1
        if not self._snapshots:
            return None
        i0_block, saved, n_chunks = self._snapshots[-1]
        del self._chunks[n_chunks:]
        return copy.deepcopy(saved)

    @staticmethod
    def _first_change(core, new) -> int:
        """First block of *new* whose inputs differ from *core*'s (beyond: no change)."""
        lo = max(int(new.blocks[0]), core.base_block)
        hi = min(int(new.blocks[-1]), core.base_block + core.n - 1)
        if hi < lo:
            return lo
        a = slice(lo - core.base_block, hi - core.base_block + 1)
        b = slice(lo - int(new.blocks[0]), hi - int(new.blocks[0]) + 1)
        differ = ~_same(core.X_all[a, : len(core.input_columns)], new.X[b]).all(axis=1)
        differ |= ~_same(core.tracked[a], new.tracked[b]).all(axis=1)
        differ |= ~_same(core.tracked_damping[a], new.damping[b]).all(axis=1)
        if (core.combined_std is None) != (new.combined is None):
            return lo
        if core.combined_std is not None:
            differ |= ~_same(core.combined_std[a], new.combined[b]).all(axis=1)
        if (core.half_difference is None) != (new.halves is None):
            return lo
        if core.half_difference is not None:
            differ |= ~_same(core.half_difference[a], new.halves[b]).all(axis=1)
        differ |= core.block_start[a] != new.block_start[b]
        coverage = block_log_coverage(new.grid)
        if (core.log_coverage is None) != (coverage is None):
            return lo
        if coverage is not None:
            differ |= ~_same(core.log_coverage[a], coverage[b])
            columns = block_column_coverage(new.grid, core.columns)
            differ |= ~_same(core.column_coverage[a], columns[b]).all(axis=1)
        where = np.flatnonzero(differ)
        first = lo + int(where[0]) if where.size else hi + 1
        if coverage is not None:
            first = min(first, _outage_reaches_back(core, new, coverage, hi + 1))
        return first

    def _start(self, modal, predictors, new) -> MemoryRun:
        """The state before the first window: the batch forecast's set-up
        (:class:`~workbench.forecasting.memory.forecast.MemoryRun`) over the first call's
        tables, with what carrying it from call to call needs."""
        options = self.options
        if new.blocks.size == 0:
            raise PredictorError("the predictor table has no blocks")
        core = MemoryRun(modal, predictors, options, None, new.labels, None, None, None)
        core.grid = None  # read by the set-up only (not kept in a checkpoint)
        core.input_columns = list(new.columns)  # the predictor columns, without the trend
        core.t0_ticks = int(new.ticks[0])
        core.time_trend = bool(options.time_trend and options.predictor_columns is None)
        core.n_sub = sub_windows_per_block(new.grid)
        core.speed_col = core.bias.speed_col
        # the excitation term from the rows as they come (the batch leaves it out when the
        # whole voyage's speed never changes within a block: a future no update knows)
        core.has_speed_var = bool(
            options.excitation_bias and core.n_sub and core.speed_col is not None
        )
        core.speed_var = np.empty(0) if core.has_speed_var else None
        core.shift_cap = np.empty(0) if core.has_speed_var else None
        core.base_block = int(new.blocks[0])
        core.n = 0
        core.i0 = core.first + core.train
        core.is_first = True
        return core

    # ------------------------------------------------------------------ rows
    def _append(self, core: MemoryRun, new) -> None:
        """Replace the rows from the newest block *core* has not run yet with *new*'s."""
        keep = core.i0 if not core.is_first else 0
        end_block = core.base_block + keep  # first block taken from *new*
        take = slice(int(end_block - new.blocks[0]), None)
        if take.start < 0:
            raise NeedsFullHistory(f"the tables start after block {end_block}")
        n_new = new.blocks.size - take.start
        n_modes = core.mode_labels.size
        X = new.X[take]
        if core.time_trend:
            X = np.column_stack([X, (new.ticks[take] - core.t0_ticks) / NS_PER_HOUR])
        rows = {
            "X_all": X,
            "blocks": new.blocks[take],
            "block_start": new.block_start[take],
            "tracked": new.tracked[take],
            "tracked_damping": new.damping[take],
        }
        if core.combined_std is not None:
            rows["combined_std"] = new.combined[take]
        if core.half_difference is not None:
            rows["half_difference"] = new.halves[take]
        if core.log_coverage is not None:
            rows["log_coverage"] = block_log_coverage(new.grid)[take]
            rows["column_coverage"] = block_column_coverage(new.grid, core.columns)[take]
        for name, value in rows.items():
            setattr(core, name, np.concatenate([getattr(core, name)[:keep], value]))
        for name in ("meas", "resid", "scatter"):
            old = getattr(core, name)[:keep]
            setattr(core, name, np.concatenate([old, np.full((n_new, n_modes), np.nan)]))
        for k in OUTPUT_ARRAYS:
            core.out[k] = np.concatenate([core.out[k][:keep], np.full((n_new, n_modes), np.nan)])
        for name in ("out_phase", "out_w0", "out_w1"):
            old = getattr(core, name)[:keep]
            setattr(core, name, np.concatenate([old, np.zeros((n_new, n_modes), old.dtype)]))
        core.out_warning = {key: v for key, v in core.out_warning.items() if key[0] < keep}
        core.n = keep + n_new
        if core.has_speed_var:
            # σ_v² of a block from it and the 2 n_sub blocks before (no look-ahead)
            history = 2 * core.n_sub + 1
            at = keep - (history - 1)
            speed = core.X_all[:, core.speed_col]
            if at <= 0 and core.base_block == core.blocks[0] and core.first == 0:
                variance = within_block_profile(speed, core.n_sub).var(axis=1)
                variance = variance[keep:]
            else:
                at = max(at, 0)
                variance = within_block_profile(speed[at:], core.n_sub).var(axis=1)
                variance = variance[keep - at :]
            variance = np.where(np.isfinite(variance), variance, 0.0)
            core.speed_var = np.concatenate([core.speed_var[:keep], variance])
            core.shift_cap = np.sqrt((core.n_sub - 1) * core.speed_var)
        self._consistency_rows(core, keep)
        if core.is_first:
            first, train = core.first, core.train
            core.meas[first : first + train] = core.tracked[first : first + train]
            with warnings.catch_warnings():  # a mode without data in the first window: NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                core.reference_hz = np.nanmedian(core.tracked[first : first + train], axis=0)
                core.damping_ref = np.nanmedian(core.tracked_damping[first : first + train], axis=0)
        self._point(core)

    @staticmethod
    def _consistency_rows(core, keep: int) -> None:
        """The innovation record's rows: those before *keep* kept, the rest empty."""
        c = core.consistency
        n_new = core.n - keep
        n_modes = core.mode_labels.size
        for name, fill in (("_nu", np.nan), ("_variance", np.nan), ("_residual2", np.nan)):
            old = getattr(c, name)[:keep]
            setattr(c, name, np.concatenate([old, np.full((n_new, n_modes), fill)]))
        c._used = np.concatenate([c._used[:keep], np.zeros((n_new, n_modes))])
        c._measured = [[r for r in rows if r < keep] for rows in c._measured]
        c.n_blocks = core.n

    @staticmethod
    def _point(core) -> None:
        """Point the refits and the excitation term at the core's arrays."""
        core.refits.X_all = core.X_all
        core.refits.meas = core.meas
        core.refits.first = core.first
        core.bias.X_all = core.X_all
        core.bias.speed_var = core.speed_var
        core.bias.shift_cap = core.shift_cap
        core.bias.first = core.first

    def _commit(self, core: MemoryRun) -> None:
        """Keep a copy of the state after a committed window; drop old rows and copies."""
        drop = core.i0 - (self._rows_read(core) + _MARGIN_ROWS + self.horizon * self.n_snapshots)
        if drop > 2 * _MARGIN_ROWS:
            self._rebase(core, drop)
        # rows before the window are in the committed output; the innovation test reads
        # only the newest window_blocks measured rows
        core.out_warning = {key: v for key, v in core.out_warning.items() if key[0] >= core.i0}
        keep = 2 * core.consistency.window_blocks
        core.consistency._measured = [rows[-keep:] for rows in core.consistency._measured]
        self._snapshots.append(
            (int(core.base_block + core.i0), copy.deepcopy(core), len(self._chunks))
        )
        self._committed = True
        while len(self._snapshots) > self.n_snapshots:
            self._snapshots.popleft()
            # the output of windows before the oldest copy can no longer change
            n_old = self._snapshots[0][2]
            if n_old > 4 * self.n_snapshots:
                self._old = consolidate([*self._old, *(c for _, c in self._chunks[:n_old])])
                del self._chunks[:n_old]
                self._snapshots = deque((b, s, n - n_old) for b, s, n in self._snapshots)

    def _rows_read(self, core: MemoryRun) -> int:
        """Rows before a window that the window reads: the refits' history, the noise and
        term selection windows, the innovation record (whichever is longest). [blocks]"""
        return max(
            core.history_limit,
            int(self.noise.noise_blocks),
            int(self.options.selection_blocks),
            2 * core.consistency.window_blocks,
        )

    @staticmethod
    def _rebase(core: MemoryRun, drop: int) -> None:
        """Forget the oldest *drop* rows (never read again: older than every window's
        history)."""
        for name in (
            "X_all",
            "blocks",
            "block_start",
            "tracked",
            "tracked_damping",
            "combined_std",
            "half_difference",
            "log_coverage",
            "column_coverage",
            "speed_var",
            "shift_cap",
            "meas",
            "resid",
            "scatter",
            "out_phase",
            "out_w0",
            "out_w1",
        ):
            value = getattr(core, name)
            if value is not None:
                setattr(core, name, value[drop:].copy())
        core.out = {k: v[drop:].copy() for k, v in core.out.items()}
        core.out_warning = {(r - drop, j): v for (r, j), v in core.out_warning.items() if r >= drop}
        c = core.consistency
        for name in ("_nu", "_variance", "_residual2", "_used"):
            setattr(c, name, getattr(c, name)[drop:].copy())
        c._measured = [[r - drop for r in rows if r >= drop] for rows in c._measured]
        core.base_block += drop
        core.first -= drop
        core.i0 -= drop
        core.n -= drop
        c.n_blocks = core.n
        core.noise_at = core.noise_at - drop
        core.refits.selected_at = core.refits.selected_at - drop
        IncrementalMemoryForecast._point(core)

    # ------------------------------------------------------------------ one window
    def _window(self, core: MemoryRun, f1: int) -> pd.DataFrame:
        """Run one window (the batch's :meth:`~workbench.forecasting.memory.forecast.
        MemoryRun.model_rows` and :meth:`~workbench.forecasting.memory.forecast.MemoryRun.
        kalman_pass`, as :func:`~workbench.forecasting.memory.forecast.memory_forecast`
        runs them) and return its rows of the forecast table."""
        i0 = core.i0
        k_first = core.first if core.is_first else i0
        rows = core.model_rows(i0, k_first, f1, core.is_first)
        core.models_out.clear()  # the window models are not part of the monitor's output
        core.kalman_pass(i0, np.arange(k_first, f1), rows)
        return with_log_coverage(self._table(core, k_first, f1), self._coverage)

    @staticmethod
    def _table(core: MemoryRun, start: int, stop: int) -> pd.DataFrame:
        """Rows *start*..*stop* of the forecast table (:func:`~workbench.forecasting.
        memory.output.assemble_table`'s columns, without its merge)."""
        from .assembly import assemble_rows, drop_unusable

        rows = slice(start, stop)
        phase = core.out_phase[rows].copy()
        out = {k: v[rows] for k, v in core.out.items()}
        drop_unusable(phase, out["model"], out["kalman"], core.notes)
        warning_rows = {
            (r - start, j): v for (r, j), v in core.out_warning.items() if start <= r < stop
        }
        blocks = core.blocks[rows]
        table = assemble_rows(
            blocks,
            core.block_start[rows],
            core.mode_labels,
            "A",
            phase,
            out,
            (core.out_w0[rows], core.out_w1[rows]),
            warning_rows,
        )
        # assemble_rows' rows: np.nonzero order, sorted stably by (mode, block)
        found, modes = np.nonzero(phase)
        order = np.lexsort((blocks[found], core.mode_labels[modes]))
        table["model_probability"] = out["probability"][found, modes][order]
        table["guard_weight"] = out["guard"][found, modes][order]
        # the forecast stage's order: by block, then mode
        return table.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)


class SimpleInputs:
    """The arrays of one call's tables (see :meth:`IncrementalMemoryForecast._inputs`)."""

    __slots__ = (
        "grid",
        "blocks",
        "block_start",
        "ticks",
        "columns",
        "X",
        "labels",
        "tracked",
        "combined",
        "damping",
        "halves",
    )

    def __init__(self, *values) -> None:
        for name, value in zip(self.__slots__, values, strict=True):
            setattr(self, name, value)


#: A consolidated piece of a table kept in pieces is left alone from this many rows on.
CONSOLIDATED_ROWS = 4096


def consolidate(pieces: list[pd.DataFrame]) -> list[pd.DataFrame]:
    """*pieces* (frames of one table, in order) with the pieces after the last one of
    :data:`CONSOLIDATED_ROWS` rows or more joined into one: a few frames instead of one
    per update, and a cost bounded by that size (not the whole table's, as joining them
    all would be)."""
    first = len(pieces)
    while first > 0 and len(pieces[first - 1]) < CONSOLIDATED_ROWS:
        first -= 1
    if len(pieces) - first < 2:
        return list(pieces)
    return [*pieces[:first], pd.concat(pieces[first:], ignore_index=True)]


def pieces_from(pieces: list[pd.DataFrame], block: int) -> list[pd.DataFrame]:
    """The rows of the blocks from *block* on of *pieces* (frames sorted by block, each
    after the one before)."""
    kept = []
    for piece in pieces:
        if not len(piece):
            continue
        blocks = piece["block"].to_numpy()
        if blocks[-1] < block:
            continue
        kept.append(
            piece if blocks[0] >= block else piece.iloc[int(np.searchsorted(blocks, block)) :]
        )
    return kept


def _outage_reaches_back(core, new, coverage: np.ndarray, first_new: int) -> int:
    """The first block of *core* whose outage-edge variance (the batch's
    ``MemoryRun._outage_edge_variance``) the blocks of *new* from *first_new* on can
    change: a partly logged block sharing data with a new block that misses a predictor
    (beyond: none)."""
    reach = max(core.overlap - 1, 1)
    new_rows = slice(max(first_new - int(new.blocks[0]), 0), None)
    missing = ~np.isfinite(new.X[new_rows]).all(axis=1)
    if not missing.any():
        return first_new
    first_missing = first_new + int(np.flatnonzero(missing)[0])
    lo = max(first_missing - reach, core.base_block)
    rows = np.arange(lo, first_new) - core.base_block
    partial = rows[core.log_coverage[rows] < 1.0] if rows.size else rows
    return int(partial[0]) + core.base_block if partial.size else first_new


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise equality with NaN equal to NaN."""
    equal = a == b
    if np.issubdtype(np.asarray(a).dtype, np.floating):
        equal |= np.isnan(a) & np.isnan(b)
    return equal


# --------------------------------------------------------------------------- checkpoint
def _classes() -> dict[str, type]:
    """The classes a checkpoint may hold (nothing else is ever constructed from one)."""
    return {
        cls.__name__: cls
        for cls in (
            MemoryRun,
            MemoryModel,
            NoiseModel,
            MemoryRefits,
            ExcitationBias,
            InnovationConsistency,
            ModelTrust,
            SSIGuard,
            GuardWindow,
            ForecastOptions,
            NoiseOptions,
        )
    }


class _Encoder:
    """Plain JSON for the state's Python objects, ``.npy`` entries for its arrays (shared
    arrays stored once and shared again when read)."""

    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray] = {}
        self._seen: dict[int, str] = {}
        self._classes = _classes()

    def encode(self, value):
        if value is None or isinstance(value, bool | str):
            return value
        if isinstance(value, int | np.integer):
            return int(value)
        if isinstance(value, float | np.floating):
            value = float(value)
            return value if math.isfinite(value) else {"float": repr(value)}
        if isinstance(value, np.ndarray):
            if value.dtype == object:
                if not all(isinstance(v, pd.Timestamp) for v in value.ravel()):
                    raise TypeError("object arrays other than of times are not stored")
                # block starts (tz-aware, as the batch forecast holds them)
                return {"times": [v.isoformat() for v in value.ravel()], "shape": value.shape}
            key = self._seen.get(id(value))
            if key is None:
                key = self._seen[id(value)] = f"a{len(self.arrays)}"
                self.arrays[key] = value
            return {"array": key}
        if isinstance(value, pd.Timestamp):
            return {"time": value.isoformat()}
        if isinstance(value, Counter):
            return {"counter": [[k, int(n)] for k, n in value.items()]}
        if isinstance(value, tuple):
            return {"tuple": [self.encode(v) for v in value]}
        if isinstance(value, list):
            return [self.encode(v) for v in value]
        if isinstance(value, dict):
            return {"dict": [[self.encode(k), self.encode(v)] for k, v in value.items()]}
        name = type(value).__name__
        if self._classes.get(name) is type(value):
            state = vars(value)  # every stored class keeps its fields in __dict__
            return {"object": name, "state": {k: self.encode(v) for k, v in state.items()}}
        raise TypeError(f"{name} is not stored in a checkpoint")


class _Decoder:
    def __init__(self, arrays) -> None:
        self.arrays = arrays
        self._loaded: dict[str, np.ndarray] = {}
        self._classes = _classes()

    def decode(self, value):
        if isinstance(value, list):
            return [self.decode(v) for v in value]
        if not isinstance(value, dict):
            return value
        if "float" in value:
            return float(value["float"])
        if "times" in value:
            times = np.empty(len(value["times"]), dtype=object)
            times[:] = [pd.Timestamp(str(t)) for t in value["times"]]
            return times.reshape(tuple(value["shape"]))
        if "time" in value:
            return pd.Timestamp(str(value["time"]))
        if "array" in value:
            key = str(value["array"])
            if key not in self._loaded:
                self._loaded[key] = np.array(self.arrays[key])
            return self._loaded[key]
        if "counter" in value:
            return Counter({str(k): int(n) for k, n in value["counter"]})
        if "tuple" in value:
            return tuple(self.decode(v) for v in value["tuple"])
        if "dict" in value:
            return {_hashable(self.decode(k)): self.decode(v) for k, v in value["dict"]}
        if "object" in value:
            cls = self._classes.get(str(value["object"]))
            if cls is None:
                raise ValueError(f"class {value['object']!r} is not stored in a checkpoint")
            obj = cls.__new__(cls)
            for name, item in value["state"].items():
                object.__setattr__(obj, str(name), self.decode(item))
            return obj
        raise ValueError(f"unreadable checkpoint entry {sorted(value)}")


def _hashable(key):
    return tuple(_hashable(k) for k in key) if isinstance(key, list | tuple) else key


def save_state(path: str | os.PathLike, payload: dict) -> None:
    """Write *payload* (JSON types, the state's objects and arrays) to *path* (``.json``)
    and its arrays beside it (``.npz``), each atomically; the JSON names the arrays' file
    and is written last, so a reader never pairs a JSON with another write's arrays."""
    from data_contracts import atomic_path

    path = Path(path)
    encoder = _Encoder()
    document = {"schema": CHECKPOINT_SCHEMA, "state": encoder.encode(payload)}
    arrays = path.with_name(f"{path.stem}.{os.getpid()}.{id(document)}.npz")
    with atomic_path(arrays) as tmp:
        with open(tmp, "wb") as handle:
            np.savez(handle, **encoder.arrays)
    document["arrays"] = arrays.name
    previous = _arrays_file(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(document), encoding="utf-8")
    if previous is not None and previous != arrays and previous.exists():
        previous.unlink()


def _arrays_file(path: Path) -> Path | None:
    try:
        name = json.loads(path.read_text(encoding="utf-8"))["arrays"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return path.with_name(Path(str(name)).name)


def load_state(path: str | os.PathLike) -> dict:
    """The payload :func:`save_state` wrote to *path*.

    Raises
    ------
    ValueError
        When *path* or its arrays are unreadable or of another schema (one line).
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        if document.get("schema") != CHECKPOINT_SCHEMA:
            raise ValueError(f"schema {document.get('schema')!r}, expected {CHECKPOINT_SCHEMA!r}")
        arrays_path = path.with_name(Path(str(document["arrays"])).name)
        with np.load(arrays_path, allow_pickle=False) as arrays:
            return _Decoder(arrays).decode(document["state"])
    except (OSError, KeyError, TypeError, AttributeError, ValueError) as error:
        raise ValueError(f"{path}: unreadable checkpoint ({error})") from None
