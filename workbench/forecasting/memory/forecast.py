"""Forecast with a model that has memory, noise from the data and the overlap's identification error.

The steps, each in its own module:

1. window model - :mod:`workbench.forecasting.memory.model` (stepwise terms, exponentially
   weighted least squares over the history, refit every *horizon* blocks);
2. noise estimation - :mod:`workbench.forecasting.noise` (covariance matching of the
   residuals, with the model error at least what the out-of-sample residuals show beyond
   the measurement noise: :func:`~workbench.forecasting.noise.model_error_floor`), and the
   safeguard :mod:`workbench.forecasting.innovation_consistency` (model variance added while
   the filter's innovations are larger or more one-sided than its noise model says); the
   identification error is capped at what the residuals' second difference across blocks
   that share no data allows (:func:`~workbench.forecasting.noise.identification_error_bound`),
   so a model error of a few blocks' time constant is not taken for SSI scatter;
3. measurement choice - :mod:`workbench.forecasting.measurement` (tracked pole or consistent
   pole cluster, per-block scatter);
4. Kalman pass - :func:`~workbench.forecasting.memory.kalman.kalman_predict` and
   :func:`~workbench.forecasting.memory.kalman.kalman_update`;
5. guard - :mod:`workbench.forecasting.model_trust`: the blend is weighed against a filter
   that does not use the model by how well each predicts the measurements out of sample;
   while the model does not explain a mode (an unrecorded change: fuel, ballast, ice) the
   estimate follows the model-free filter, a smoothed SSI (on blocks that overlap it can
   lag a mode that moves within minutes: ``benchmarks/results/ice_voyage_blend_42.txt``).
   The weight is the forecast table's
   ``model_probability``, and the run notes say when a mode's model stopped explaining it.

:func:`memory_forecast` below runs the windows (:class:`MemoryRun`: the models of a window,
the measurement of each row, the Kalman step) over their rows; each
mode's term selection, refits and predictions are in :mod:`workbench.forecasting.memory.terms`,
the excitation bias (κ) in :mod:`workbench.forecasting.memory.excitation`, the first window's
noise, the filter matrices and the runs of large innovations in
:mod:`workbench.forecasting.memory.noise`, option B's chooser in
:mod:`workbench.forecasting.memory.poles`, the output table in
:mod:`workbench.forecasting.memory.output`.

Kalman model per mode, with m_k the model's prediction and z_k the block's SSI estimate:

.. math::

    x_k = m_k + c_k, \\quad z_k = x_k + e_k + v_k, \\quad
    \\begin{bmatrix} c_k \\\\ e_k \\end{bmatrix} =
    \\begin{bmatrix} φ & 0 \\\\ 0 & ρ \\end{bmatrix}
    \\begin{bmatrix} c_{k-1} \\\\ e_{k-1} \\end{bmatrix} + w_k,

Q = diag(σ_c²(1 - φ²), σ_e²(1 - ρ²) s_k), R_k = σ_v² s_k, H = [1 1], with s_k the block's
measurement scale (pole scatter across model orders). That is the form for a grid whose
overlap is not known; for blocks of L steps, a new one every step (20 minutes every 5:
L = 4), e_k is the sum of the L segment terms g_k .. g_{k+L-1} of the data the block shares
with its neighbours, states of the filter (1 + L states, H = [1 ... 1]): from block to block
they shift by one, the newest is new with variance σ_e² s_k / L, so e is an MA(L - 1) with
correlation (L - h) / L and none from lag L, as the overlap makes it
(:func:`~workbench.forecasting.memory.kalman.transition_matrices`; the covariance matching
fits that shape, :func:`~workbench.forecasting.noise.estimate_noise`). With the excitation term
(:mod:`workbench.forecasting.excitation`) the measurement is about the model at the
excitation-weighted speed: z_k = m̃_k + c_k + e_k + v_k, m̃_k = m(v̄_k + κ σ²_{v,k}, ...),
while the state stays x_k = m_k + c_k: SSI's bias in a block whose speed changes goes into
the measurement equation, not into the estimate. The identification error e is a state
because 75 %-overlapping blocks share their data: a white R would count the same error
several times. The blended estimate is x̂ = m + ĉ.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter

import numpy as np
import pandas as pd

from ..assembly import drop_unusable
from ..excitation import sub_windows_per_block
from ..fitted_model import _plausible
from ..innovation_consistency import MIN_BLOCKS, InnovationConsistency
from ..measurement import PoleIndex, cluster_around, nearer_to_another_mode, scatter_scale
from ..model_trust import BlendStep, ModelTrust
from ..noise import NoiseModel, estimate_noise, model_error_floor
from ..options import ForecastOptions
from ..predictor_grid import (
    NS_PER_HOUR,
    block_centre_ns,
    block_column_coverage,
    block_log_coverage,
    forecast_span,
    mode_matrix,
    modes_to_forecast,
    predictor_matrix,
)
from ..results import ForecastResult, ForecastWarning, WindowModel
from ..ssi_guard import SSIGuard
from .excitation import excitation_bias
from .kalman import kalman_predict, kalman_update, n_states, stationary_covariance
from .model import MemoryModel
from .noise import filter_matrices, first_window_noise, run_after_hole, update_run
from .output import OUTPUT_ARRAYS, assemble_table
from .poles import option_b_chooser
from .terms import MemoryRefits

__all__ = ["memory_forecast"]

#: Fewest consecutive large innovations of one sign that mean the model is off (at least
#: one more than the blocks sharing data with the first: one corrupted stretch of data is
#: in all the blocks that overlap it).
_PERSIST_BLOCKS = 3
#: Oldest history a refit looks at, in forgetting time constants (weight e^-6 beyond).
_HISTORY_CONSTANTS = 6.0
#: Rows after a hole in the record (no mode measured for at least ``persist_blocks`` rows)
#: over which a refit keeps the estimate where it was (:meth:`MemoryRun.model_rows`): the
#: refits then move the model by what the hole hid, which the correction c has already
#: taken from the first measurements; 2 h of 5-minute blocks (4 h, or every row after the
#: hole, left the estimate on the old one's error longer: over the whole 12-h voyages with a
#: 3-h or 6-h hole 1-2 points less, ``benchmarks/results/forecast_hole_53.txt``). [blocks]
_REFIT_CONTINUITY_BLOCKS = 24


#: What the estimate follows where the model does not explain a mode: the model-free
#: filters of :mod:`~workbench.forecasting.model_trust` (close to SSI; how close, on blocks
#: that overlap, is not measured: ``benchmarks/results/ice_voyage_blend_42.txt``).
_FALLBACK = "a filter of the SSI estimates that does not use the model"


def never_explained_notes(run: MemoryRun) -> Counter:
    """The run note of each forecast mode whose model never reached probability 0.5."""
    notes: Counter = Counter()
    for j in np.flatnonzero((run.forecast_blocks > 0) & ~run.explained):
        notes[
            f"mode {run.mode_labels[j]}: the model never explained it well enough to be "
            f"leaned on (model probability below 0.5 in all {run.forecast_blocks[j]} "
            f"forecast blocks; the estimate follows {_FALLBACK})"
        ] += 1
    return notes


def memory_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    options: ForecastOptions,
    *,
    poles: pd.DataFrame | None,
    modes,
    start_block: int | None,
    end_block: int | None,
    cases=None,
) -> ForecastResult:
    """Forecast with :mod:`memory <workbench.forecasting.memory.model>` models (module
    docs) for the one measurement option of *options*.

    Called by :func:`~workbench.forecasting.sliding_forecast` for ``model="memory"``.
    """
    run = MemoryRun(modal, predictors, options, poles, modes, start_block, end_block, cases)
    method, last, n_blocks = options.scheme, run.last, run.blocks.size
    i0 = run.first + run.train
    is_first = True
    while i0 <= (last if method == 2 else n_blocks - 1):
        f1 = min(i0 + options.horizon_blocks, (last + 1) if method == 2 else n_blocks)
        k_first = run.first if is_first else i0
        rows = run.model_rows(i0, k_first, f1, is_first)
        run.kalman_pass(i0, np.arange(k_first, f1), rows)
        if method == 1 or f1 > last:
            break
        is_first = False
        i0 = f1
    return run.result()


class MemoryRun:
    """Data, settings, running filter state and outputs of one memory forecast.

    Built from the arguments of :func:`memory_forecast`; its steps are
    :meth:`model_rows` (each mode's model and noise levels for a window's rows) and
    :meth:`kalman_pass` (the measurement and the Kalman step of each row). The monitor's
    resumed forecast (:class:`~workbench.forecasting.incremental.IncrementalMemoryForecast`)
    runs the same steps window by window on a run whose rows it appends and trims.
    """

    def __init__(self, modal, predictors, options, poles, modes, start_block, end_block, cases):
        self.options, self.noise = options, options.noise
        self.option = options.options[0]
        self.notes: Counter[str] = Counter()
        self._grid_and_modes(modal, predictors, modes)
        self.first, self.last = forecast_span(
            self.blocks, start_block, end_block, int(options.train_blocks), modal["block"]
        )
        self.train = int(options.train_blocks)
        memory = float(options.memory_blocks)
        self.history_limit = int(math.ceil(_HISTORY_CONSTANTS * memory))
        self.bias = excitation_bias(
            self.grid,
            self.X_all,
            self.columns,
            options,
            n_modes=self.n_modes,
            first=self.first,
            history_limit=self.history_limit,
        )
        # ---- poles: per-block scatter and option B's chooser
        self.index = PoleIndex(poles, self.blocks) if poles is not None else None
        self.chooser = None
        if self.option == "B":
            if self.index is None:
                raise ValueError("option='B' needs poles (the stabilisation diagrams)")
            self.chooser = option_b_chooser(
                poles, modal, self.blocks, self.mode_labels, self.index, options, self.notes
            )
        self._outputs_and_state()
        labels = None
        if cases is not None:
            from workbench.stats import case_labels

            labels = case_labels(self.grid, cases).to_numpy()
        self.refits = MemoryRefits(
            options, self.X_all, self.columns, self.meas, labels, self.first, self.history_limit
        )

    def _grid_and_modes(self, modal, predictors, modes) -> None:
        """Predictor matrix (with the time trend), tracked matrices, mode labels."""
        options = self.options
        grid, blocks, block_start, columns, X_all = predictor_matrix(
            predictors, options.predictor_columns
        )
        if options.time_trend and options.predictor_columns is None:  # explicit: as given
            # slow drifts no log records (fuel burn, ballast): a trend term with memory
            # block centres: the same hours as the starts for blocks of one length, the
            # blocks' own times for blocks of varying length (--block-minutes auto)
            centre_ns = block_centre_ns(grid)
            hours = (centre_ns - centre_ns[0]) / NS_PER_HOUR
            X_all = np.column_stack([X_all, hours.astype(float)])
            columns = [*columns, "elapsed_hours"]
        self.grid, self.blocks, self.block_start = grid, blocks, block_start
        # the share of each block the ship log covers, the least over the log's columns
        # and per predictor column (None: the table does not say)
        self.log_coverage = block_log_coverage(grid)
        self.column_coverage = block_column_coverage(grid, columns)
        self.columns, self.X_all = columns, X_all
        # blocks that share data with a block: its identification error (an ice impact, a
        # badly excited stretch) is in all of them, so a run of large innovations is
        # evidence that the model is off only when it reaches a block that shares no data
        # with the first
        self.overlap = sub_windows_per_block(grid) or 1
        # identification errors of blocks this far apart are independent (None: not known,
        # no cap on the identification error's variance, :func:`~.noise.estimate_noise`)
        self.independent_lag = sub_windows_per_block(grid)
        # the identification error as the mean of the segments a block shares with its
        # neighbours (MA, zero correlation from the independent lag on), its L terms states
        # of the filter; without overlap (or an unknown grid) an AR(1) state
        lag = self.independent_lag or 0
        self.error_segments = lag if lag >= 2 else 0
        self.states = n_states(self.error_segments)
        self.mode_labels = mode_labels = modes_to_forecast(modal, modes)
        self.n_modes = n_modes = mode_labels.size
        self.tracked = mode_matrix(modal, blocks, mode_labels, "frequency_hz")
        # the combined modal model's uncertainty per block (identify --cross-check), when the
        # tracked table carries it: the block's measurement scatter instead of the cluster's
        self.combined_std = (
            mode_matrix(modal, blocks, mode_labels, "combined_frequency_std_hz")
            if "combined_frequency_std_hz" in modal.columns
            else None
        )
        # SSI's own error per block, from each half of the block (identify): the yardstick
        # of the guard (:mod:`~workbench.forecasting.ssi_guard`); None for a table without it
        self.half_difference = (
            mode_matrix(modal, blocks, mode_labels, "half_difference_hz")
            if "half_difference_hz" in modal.columns
            else None
        )
        self.tracked_damping = (
            mode_matrix(modal, blocks, mode_labels, "damping_ratio")
            if "damping_ratio" in modal.columns
            else np.full((blocks.size, n_modes), np.nan)
        )

    def _outputs_and_state(self) -> None:
        """Output arrays, the filter's state and the guards, before the first window."""
        first, train, n_modes, noise = self.first, self.train, self.n_modes, self.noise
        shape = (self.blocks.size, n_modes)
        self.out_phase = np.zeros(shape, dtype=np.int8)
        self.out = {k: np.full(shape, np.nan) for k in OUTPUT_ARRAYS}
        self.out_w0 = np.zeros(shape, dtype=np.int64)
        self.out_w1 = np.zeros(shape, dtype=np.int64)
        self.out_warning: dict[tuple[int, int], list[str]] = {}
        self.meas = np.full(shape, np.nan)  # measurement used per block (training: tracked)
        self.meas[first : first + train] = self.tracked[first : first + train]
        self.resid = np.full(shape, np.nan)  # z - m, out of sample after the first window
        self.scatter = np.full(shape, np.nan)  # cluster scatter of the block's measurement
        with warnings.catch_warnings():  # a mode without data in the first window: NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            self.reference_hz = np.nanmedian(self.tracked[first : first + train], axis=0)
            self.damping_ref = np.nanmedian(self.tracked_damping[first : first + train], axis=0)
        self.current: list[MemoryModel | None] = [None] * n_modes
        self.noise_of: list[NoiseModel | None] = [None] * n_modes
        self.noise_at = np.full(n_modes, -(10**9))  # grid row of each mode's last noise fit
        self.state = np.zeros((n_modes, self.states))
        self.P = np.zeros((n_modes, self.states, self.states))
        self.started = np.zeros(n_modes, dtype=bool)
        self.gap = np.zeros(n_modes, dtype=np.int64)
        # consecutive rows without a measurement of any mode: a hole in the acceleration
        # record (the recorder off), not one mode's missing pole
        self.record_gap = 0
        # rows with a measurement since the last hole in the record ended (a large number
        # before any hole; :meth:`_keep_estimate_after_hole`)
        self.since_hole = 10**9
        self._model_before_window = math.nan
        # option B: consecutive blocks with a tracked pole but no column near the
        # prediction, signed by the side the tracked poles lie on
        self.column_missed = np.zeros(n_modes, dtype=np.int64)
        self.models_out: list[WindowModel] = []
        self.persist_blocks = max(_PERSIST_BLOCKS, self.overlap + 1)
        # guard: the probability that the model explains each mode, against a model-free
        # filter
        self.trust = (
            ModelTrust(
                n_modes,
                float(noise.huber_sigma),
                persist_blocks=self.persist_blocks,
                states=self.states,
                # the lead test needs the lag from which identification errors are
                # independent: off when the grid does not say (no block_end)
                lead_blocks=int(self.independent_lag or 0),
            )
            if noise.model_trust
            else None
        )
        # do no harm: the estimate no farther from SSI than SSI's own error allows, where
        # blocks share no data (the guard's test needs SSI errors independent from block to
        # block; :mod:`~workbench.forecasting.ssi_guard`)
        self.ssi_guard = (
            SSIGuard(n_modes)
            if self.half_difference is not None and (self.independent_lag or 1) <= 1
            else None
        )
        self.explained_lost = np.zeros(n_modes, dtype=np.int64)  # first block below 0.5, + 1
        # a mode's model explains it once its probability reached 0.5 on unseen blocks; only
        # then is a fall below 0.5 news (the prior starts low,
        # :data:`~workbench.forecasting.model_trust.PRIOR_PROBABILITY`)
        self.explained = np.zeros(n_modes, dtype=bool)
        self.forecast_blocks = np.zeros(n_modes, dtype=np.int64)
        self.run = np.zeros(n_modes, dtype=np.int64)  # signed run of large innovations
        # the model correction c and its variance as they were before a stretch of blocks
        # whose model fills a missing predictor, carried on without the filled blocks'
        # updates, and the sum and count of the filled blocks' model variance
        # (:meth:`_outside_fill`); NaN: not in such a stretch
        self.before_fill = np.full((n_modes, 4), np.nan)
        # how far the states were moved by updates made without the Huber weight (the
        # prior's noise levels) on innovations the weight would have held back
        # (:meth:`_return_test`) [Hz]
        self.unweighted_move = np.zeros((n_modes, self.states))
        # safeguard: model variance added where the filter's innovations are inconsistent
        self.consistency = InnovationConsistency(
            self.blocks.size,
            n_modes,
            float(noise.huber_sigma),
            window_blocks=max(int(noise.consistency_blocks), MIN_BLOCKS),
        )

    def warn(self, i: int, j: int, message: str, kind: str) -> None:
        self.notes[kind] += 1
        self.out_warning.setdefault((i, j), []).append(message)

    # ------------------------------------------------------------------ models of a window
    def model_rows(self, i0: int, k_first: int, f1: int, is_first: bool):
        """Refit (first window, rolling scheme) and each mode's model of the state, of the
        measurement and its variance for rows *k_first*..*f1* - 1; noise levels from the
        out-of-sample residuals before row *i0*."""
        n_rows = f1 - k_first
        m_rows = np.full((n_rows, self.n_modes), np.nan)  # model of the state
        z_rows = np.full((n_rows, self.n_modes), np.nan)  # model of the measurement
        v_rows = np.zeros((n_rows, self.n_modes))
        p_rows = np.zeros((n_rows, self.n_modes))  # the prior where the mode is not measured
        if is_first or self.options.scheme == 2:
            fits = [self.refits.refit(j, i0) for j in range(self.n_modes)]
            self.bias.refit(fits, i0, self.refits.train_y)
            for j in range(self.n_modes):
                if fits[j] is not None:
                    self.current[j] = fits[j]
        for j in range(self.n_modes):
            m = self.current[j]
            if m is None:
                self.notes[
                    f"mode {self.mode_labels[j]}: too few measured blocks for a model (fewer "
                    f"than {self.refits.min_train}), no forecast until it has them"
                ] += 1
                continue
            before = self.out["model"][k_first - 1, j] if k_first > self.first else math.nan
            mean, seen, mvar, level_hz, prior = self._mode_predictions(j, m, i0, k_first, f1)
            self._keep_estimate_after_hole(j, before)
            m_rows[:, j], z_rows[:, j], v_rows[:, j], p_rows[:, j] = mean, seen, mvar, prior
            nz = self._mode_noise(j, i0, is_first, level_hz)
            self.models_out.append(self._window_model(j, m, nz, i0))
        return m_rows, z_rows, v_rows, p_rows

    def _keep_estimate_after_hole(self, j: int, before: float) -> None:
        """After a hole in the record, keep mode *j*'s estimate m + c where it was when a
        refit moves the model at the window's first row: c less the model's move.

        Elsewhere c carries over a refit unchanged (successive models are fitted on nearly
        the same history). After a hole they are not: across the hole the model only
        extrapolated (the ship may have left port there), the first measurements after it
        put the model's error into c at once (:meth:`_run_after_hole`), and the refits that
        take those measurements move the model by much of that error; with c unchanged the
        estimate then holds the error twice (the 12-h voyages with a 6-h hole: Kalman
        against SSI -5 to -15 % in the 2 h after it; ``benchmarks/results/forecast_hole_53.txt``).
        For :data:`_REFIT_CONTINUITY_BLOCKS` rows after the hole c takes the model's move
        at the row before the window (the old model's value there against the new one's),
        and the filter's decay of c hands the estimate over to the new model."""
        after = self._model_before_window
        if (
            self.since_hole >= _REFIT_CONTINUITY_BLOCKS
            or not self.started[j]
            or not (np.isfinite(before) and np.isfinite(after))
        ):
            return
        self.state[j, 0] += before - after

    def _mode_predictions(self, j: int, m: MemoryModel, i0: int, k_first: int, f1: int):
        """Mode *j*'s model of the state and of the measurement, and its variance, on rows
        *k_first*..*f1* - 1, its level [Hz] and the variance a row where the mode is not
        measured adds for the predictors beyond the model's range
        (:meth:`~workbench.forecasting.memory.terms.MemoryRefits.extrapolation_prior`) [Hz²];
        the reported model track and bounds written."""
        first, out = self.first, self.out
        # predictions from the row before (model switch) to the end of this window
        from_row = max(k_first - 1, first)
        rows = np.arange(from_row, f1)
        edge_variance = self._outage_edge_variance(m, rows)
        beyond_variance, excess = self.refits.extrapolation_variance(j, m, rows)
        mean, lower, upper, bad, mvar = self.refits.predict(
            m, rows, edge_variance + beyond_variance
        )
        # what SSI sees (measurement equation); the state is the time average
        seen = self.bias.seen_by_ssi(m, rows, j, mean)
        implausible = np.isfinite(mean) & ~_plausible(mean, self.reference_hz[j])
        implausible |= np.isfinite(seen) & ~_plausible(seen, self.reference_hz[j])
        if implausible.any():
            level = float(np.nanmedian(self.meas[max(first, i0 - 36) : i0, j]))
            mean[implausible] = level
            seen[implausible] = level
            lower[implausible] = level - (upper - lower)[implausible] / 2
            upper[implausible] = level + (upper - lower)[implausible] / 2
        # c carries over unchanged: successive models are fitted on nearly the same
        # history, so the model error c is the same quantity before and after a refit
        sl = slice(1, None) if from_row < k_first else slice(None)
        # the new model's value at the row before the window (NaN: none)
        self._model_before_window = float(mean[0]) if from_row < k_first else math.nan
        report = np.arange(k_first, f1)
        out["seen"][report, j] = seen[sl]
        out["model"][report, j] = mean[sl]
        out["lower"][report, j] = lower[sl]
        out["upper"][report, j] = upper[sl]
        self.out_w0[report, j] = self.blocks[max(first, i0 - self.history_limit)]
        self.out_w1[report, j] = self.blocks[i0 - 1]
        self.out_phase[report, j] = np.where(report < first + self.train, 1, 2)
        for k in report[bad[sl]]:
            self.warn(k, j, "predictor NaN: filled", "blocks with a needed predictor NaN")
        for k in report[edge_variance[sl] > 0]:
            self.warn(
                k,
                j,
                f"partly logged ({self._partly_logged(m, k)}) at the edge of a log outage: "
                "model variance raised",
                "partly logged blocks at the edge of a log outage (model variance raised)",
            )
        # a predictor a standard deviation or more beyond the range: the variance at least
        # doubled
        for r in np.flatnonzero(excess.max(axis=1, initial=0.0) >= 1.0):
            k = int(rows[r])
            if k < k_first:
                continue
            named = ", ".join(self.columns[c] for c in np.flatnonzero(excess[r] >= 1.0))
            self.warn(
                k,
                j,
                "beyond the range the model was fitted on by a standard deviation or more: "
                f"{named}; model variance raised",
                "blocks whose predictors leave the range the model was fitted on (model "
                "variance raised)",
            )
        prior = (
            self.refits.extrapolation_prior(j, rows) * np.where(np.isfinite(mean), mean, 0.0) ** 2
        )
        return mean[sl], seen[sl], mvar[sl], float(abs(np.nanmedian(mean))), prior[sl]

    def _partly_logged(self, m: MemoryModel, k: int) -> str:
        """What an outage edge's warning names of grid row *k*: the predictors *m* needs
        that the log covers only partly there, each with its own share of the block, and
        the least share over the log's columns (``log_coverage``), the c of
        :meth:`_outage_edge_variance` - e.g. ``"speed_kn 50%; log_coverage 0%"`` where the water
        temperature misses the block."""
        columns = m.needed_columns()
        shares = self.column_coverage[k, columns]
        named = [
            f"{self.columns[c]} {share:.0%}"
            for c, share in zip(columns, shares, strict=True)
            if share < 1.0
        ]
        least = f"log_coverage {self.log_coverage[k]:.0%}"
        return f"{', '.join(named)}; {least}" if named else least

    def _outage_edge_variance(self, m: MemoryModel, rows: np.ndarray) -> np.ndarray:
        """Model variance of *m* on grid rows *rows* from the unlogged share of a block at
        the edge of an outage of the ship log [Hz²] (0 elsewhere).

        A block the log covers partly has the means of its logged part as its predictors
        (``log_coverage`` c of the predictor table, at least the averaging's minimum
        coverage). At the edge of an outage - a block sharing data with (on a grid without
        overlap: next to) a block where a predictor *m* needs is missing - the unlogged
        part is the outage's: what the ship did there (a stop, a restart) is as unknown as
        in the missing block, and the block's mean errs by (1 - c) times the difference
        between the unlogged part's mean and the logged part's. With the fill's error
        variance V of the missing predictors there (:meth:`MemoryRefits.fill_variance`,
        what a filled block gets) the block's model variance grows by (1 - c)² V, so the
        blend leans on SSI as far as the unlogged share can hide a change
        (``benchmarks/results/forecast_partial_blocks_27n.txt``). A short hole inside
        logged data (no block missing a predictor: both sides of it known) adds nothing.
        c is the least share over the log's columns; each column's own share
        (``log_coverage_<column>``) is named in the row's warning, not used: the variance
        from it loses at the edge of an outage that hides a stop
        (``benchmarks/results/forecast_column_coverage_27r.txt``).
        The blocks after the row count (an outage's first edge is known only from the
        blocks after it): the monitor's resumed forecast goes back to before such a row when
        an update brings a block that misses a predictor
        (:func:`~workbench.forecasting.incremental._outage_reaches_back`).
        """
        added = np.zeros(len(rows))
        if self.log_coverage is None or m.kind == "constant":
            return added
        columns = np.asarray(m.needed_columns(), dtype=np.int64)
        reach = max(self.overlap - 1, 1)  # blocks sharing data with a block, at least 1
        n_blocks = self.blocks.size
        for r, k in enumerate(rows):
            coverage = self.log_coverage[k]
            # fully logged, not known, or filled (a needed predictor missing)
            if not coverage < 1.0 or not np.isfinite(self.X_all[k, columns]).all():
                continue
            near = self.X_all[max(k - reach, 0) : min(k + reach + 1, n_blocks)][:, columns]
            outage = columns[~np.isfinite(near).all(axis=0)]
            if outage.size == 0:
                continue
            fill = self.refits.fill_variance(m, int(k), outage)
            if fill is None:  # too little history to measure a fill: the fit's scatter
                fill = float(m.residual_variance)
            added[r] = (1.0 - coverage) ** 2 * fill
        return added

    def _mode_noise(self, j: int, i0: int, is_first: bool, level_hz: float) -> NoiseModel:
        """Mode *j*'s noise levels from the out-of-sample residuals before row *i0*."""
        first, noise = self.first, self.noise
        lo = max(first, i0 - int(noise.noise_blocks))
        r_hist = self.resid[lo:i0, j]
        if np.isfinite(r_hist).sum() == 0 and is_first:
            nz = first_window_noise(
                self.meas[first:i0, j],
                self.out["seen"][first:i0, j],
                level_hz,
                error_segments=self.error_segments,
            )
        elif (
            self.noise_of[j] is None
            or i0 - first < int(noise.noise_blocks)  # residual window still filling
            or i0 - self.noise_at[j] >= self.options.reselect_blocks
        ):  # then with the terms' schedule (the grid search is the costly part)
            nz = estimate_noise(
                r_hist,
                level_hz,
                correlated_lags=self.independent_lag,
                error_segments=self.error_segments,
            )
            if nz.n_residuals:  # fitted, not the prior: no less model error than shown
                nz = model_error_floor(nz, self.resid[max(lo, first + self.train) : i0, j])
            self.noise_at[j] = i0
        else:
            nz = self.noise_of[j]
        self.noise_of[j] = nz
        if not self.started[j]:
            self.P[j] = stationary_covariance(nz, self.states)
            self.state[j] = 0.0
            self.started[j] = True
        return nz

    def _window_model(self, j: int, m: MemoryModel, nz: NoiseModel, i0: int) -> WindowModel:
        """The record of mode *j*'s model for the window ending before row *i0*."""
        start = int(self.blocks[max(self.first, i0 - self.history_limit)])
        return WindowModel(
            mode=int(self.mode_labels[j]),
            window_start_block=start,
            window_end_block=int(self.blocks[i0 - 1]),
            kind="stepwise" if m.kind == "memory" else "constant",
            terms=m.term_names(),
            coefficients=dict(
                zip(["(Intercept)", *m.term_names()], map(float, m.coefficients), strict=False)
            ),
            n_train=m.n_train,
            rmse_hz=float(math.sqrt(m.residual_variance)),
            measurement_variance=float(nz.error_variance + nz.white_variance),
            process_variance=float(nz.correction_variance * (1 - nz.transition**2)),
            normalisation={
                n: (float(a), float(b)) for n, a, b in zip(m.names, m.mean, m.scale, strict=True)
            },
        )

    # ------------------------------------------------------------------ the Kalman pass
    def kalman_pass(self, i0: int, report: np.ndarray, rows) -> None:
        """Measurement and Kalman step of every row in *report* (the rows of the window
        whose models start at row *i0*)."""
        m_rows, z_rows, v_rows, p_rows = rows
        noise = self.noise
        typical = self._typical_scatter(i0)
        F, q_c, q_e, r_v, huber = filter_matrices(self.noise_of, noise.huber_sigma, self.states)
        added_variance = (
            self.consistency.update(i0).copy()
            if noise.consistency_blocks
            else np.zeros(self.n_modes)
        )
        have_model = np.array([c is not None for c in self.current])
        for r, k in enumerate(report):
            have = np.isfinite(m_rows[r]) & have_model
            if self.option == "A" or k < self.first + self.train:
                z, scale = self._tracked_measurement(k, have, typical)
            else:
                z, scale = self._cluster_measurement(
                    k, have, typical, z_rows[r], (F, q_c, q_e, r_v)
                )
            z[~have] = np.nan
            filter_step = (F, q_c, q_e, r_v, huber, v_rows[r] + added_variance)
            self._kalman_step(k, have, z, scale, m_rows[r], z_rows[r], filter_step, p_rows[r])
            # a mode without a model (too few measured blocks before i0, e.g. a gap in the
            # first window) keeps training: its tracked pole is the block's measurement,
            # as in the first window, so a later window fits it
            self.meas[k, ~have_model] = self.tracked[k, ~have_model]

    def _filled(self, k: int) -> np.ndarray:
        """Per mode: whether its current model needs a predictor row *k* lacks."""
        x = self.X_all[k]
        return np.array(
            [
                m is not None
                and m.kind != "constant"
                and not np.isfinite(x[m.needed_columns()]).all()
                for m in self.current
            ]
        )

    def _typical_scatter(self, i0: int) -> np.ndarray:
        """Typical cluster scatter per mode (RMS over the noise window before row *i0*)."""
        typical = np.full(self.n_modes, np.nan)
        if (self.index is not None or self.combined_std is not None) and self.noise.pole_scatter:
            lo = max(self.first, i0 - int(self.noise.noise_blocks))
            s = self.scatter[lo:i0]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                typical = np.sqrt(np.nanmean(s**2, axis=0))
        return typical

    def _tracked_measurement(self, k: int, have: np.ndarray, typical: np.ndarray):
        """Option A (and the first window): the tracked pole, scaled by its scatter."""
        z = self.tracked[k].copy()
        scale = np.ones(self.n_modes)
        if (self.index is not None or self.combined_std is not None) and self.noise.pole_scatter:
            for j in np.flatnonzero(np.isfinite(z) & have):
                if self.combined_std is not None and np.isfinite(self.combined_std[k, j]):
                    self.scatter[k, j] = self.combined_std[k, j]
                    scale[j] = scatter_scale(self.combined_std[k, j], typical[j])
                    continue
                if self.index is None:
                    continue
                self._scale_by_cluster(k, j, z[j], scale, typical)
        return z, scale

    def _scale_by_cluster(self, k, j, frequency_hz, scale, typical, *, use=True) -> None:
        """Scatter of the cluster around *frequency_hz* at row *k*, and the measurement
        scale of mode *j* from it (with *use*)."""
        cl = cluster_around(self.index, k, frequency_hz)
        if cl is not None and cl.n_orders >= 3:
            self.scatter[k, j] = cl.scatter_hz
            if use:
                scale[j] = scatter_scale(cl.scatter_hz, typical[j])
        elif np.isfinite(typical[j]) and use:
            scale[j] = scatter_scale(math.nan, typical[j])

    def _cluster_measurement(self, k, have, typical, z_now, matrices):
        """Option B: the pole cluster of each mode's gate, chosen by :attr:`chooser`."""
        measurement, out = self.options, self.out
        F, q_c, q_e, r_v = matrices
        z = np.full(self.n_modes, np.nan)
        scale = np.ones(self.n_modes)
        # gate on the innovation standard deviation of the a-priori state
        prior_state = np.einsum("nij,nj->ni", F, self.state)
        Pp = F @ self.P @ np.transpose(F, (0, 2, 1))
        S = Pp.sum(axis=(1, 2)) + q_c.sum(axis=1) + q_e.sum(axis=1) + r_v
        prior_z = z_now + prior_state.sum(axis=1)
        # g = gate_sigma sqrt(S), at most max_gate x the frequency: a filter that has
        # lost confidence must not open its gate onto other modes and harmonics
        gate = np.minimum(
            measurement.gate_sigma * np.sqrt(S), measurement.max_gate * np.abs(prior_z)
        )
        # without shapes a cluster in the gate may be a close neighbour's column:
        # each mode's anchor is its tracked pole of the block (else its prior)
        anchors = np.where(np.isfinite(self.tracked[k]), self.tracked[k], prior_z)
        for j in np.flatnonzero(have):
            choice = self.chooser.choose(k, j, prior_z[j], gate[j], self.damping_ref[j])
            if choice is None:
                self._tracked_instead(k, j, prior_z[j], z, scale, typical)
                continue
            self.column_missed[j] = 0
            cl = choice.cluster
            if self.chooser.shape_mac is None and nearer_to_another_mode(
                cl.frequency_hz, j, anchors
            ):
                self._refuse_neighbour(k, j, cl.frequency_hz, anchors, z, scale, typical)
                continue
            z[j] = cl.frequency_hz
            for key, value in (
                ("order", cl.max_order),
                ("damping", cl.damping_ratio),
                ("mac", choice.mac),
                ("n_orders", cl.n_orders),
                ("scatter", cl.scatter_hz),
                ("min_order", cl.min_order),
                ("max_order", cl.max_order),
            ):
                out[key][k, j] = value
            self.scatter[k, j] = cl.scatter_hz
            if self.noise.pole_scatter:
                scale[j] = scatter_scale(cl.scatter_hz, typical[j])
            self._follow_damping(j, cl.damping_ratio)
            if choice.outside_gate:  # measured, Huber-weighted; no reset
                self.warn(
                    k,
                    j,
                    f"measured outside the gate: column at {z[j]:.4f} Hz, gate "
                    f"{prior_z[j]:.4f} ± {gate[j]:.4f} Hz",
                    "option B measurements outside the gate",
                )
        return z, scale

    def _tracked_instead(self, k, j, prior_hz, z, scale, typical) -> None:
        """Option B with no column of mode *j* near its prediction: when that has lasted
        beyond the blocks sharing data and the model does not explain the mode, the
        tracked pole (option A's measurement).

        The chooser searches the gate and the re-acquire band about the prediction. A
        few blocks where the mode's column is not there but the tracking joined a pole to
        the mode are most often an identification outlier (an ice impact, a badly excited
        stretch: the blocks sharing its data all show it), and a predict-only step is
        option B's strength there. Three things together say instead that the prediction
        has left the mode (a single window carried past an unrecorded change, a refit on
        too few measurements), so that predict-only steps would follow the model wherever
        it drifts:

        * the miss outlasts the blocks sharing data (:attr:`persist_blocks` blocks with a
          tracked pole in a row, the Kalman update's run test);
        * the tracked poles of the run all lie on one side of the prediction (a mode that
          moved, not an outlier's scatter);
        * the model-trust guard gives the model a probability below 0.5 of explaining
          the mode.

        The tracked pole was joined to the mode by the tracking, not by the prediction;
        the Kalman update's Huber weight and run test decide how far the estimate follows
        it. Blocks without a tracked pole, or without any pole in the pole table (a table
        of part of the voyage: no evidence either way), neither count nor end the run; a
        column found near the prediction ends it."""
        tracked = self.tracked[k, j]
        part = self.index.block(k)
        if not np.isfinite(tracked) or part.stop <= part.start:  # nothing to compare
            return
        side = 1 if tracked > prior_hz else -1
        if self.column_missed[j] * side < 0:  # the other side: a new run
            self.column_missed[j] = 0
        self.column_missed[j] += side
        n_missed = abs(int(self.column_missed[j]))
        unexplained = self.trust is not None and self.trust.probability[j] < 0.5
        if n_missed < self.persist_blocks or not unexplained:
            return
        self.warn(
            k,
            j,
            f"option B: no pole column near the prediction {prior_hz:.4f} Hz for "
            f"{n_missed} blocks: tracked pole {tracked:.4f} Hz used",
            "option B rows without a pole column near the prediction for longer than the "
            "blocks sharing data (tracked pole used)",
        )
        z[j] = tracked
        self._scale_by_cluster(k, j, tracked, scale, typical, use=self.noise.pole_scatter)

    def _refuse_neighbour(self, k, j, pick_hz, anchors, z, scale, typical) -> None:
        """An option B pick nearer to another mode: the tracked pole instead, if any."""
        other = int(np.nanargmin(np.abs(np.delete(anchors, j) - pick_hz)))
        other += other >= j
        tracked = self.tracked[k, j]
        self.warn(
            k,
            j,
            f"option B pole {pick_hz:.4f} Hz nearer to mode {self.mode_labels[other]} than "
            f"to this mode's {anchors[j]:.4f} Hz: "
            + ("tracked pole used" if np.isfinite(tracked) else "refused"),
            "option B poles nearer to another mode (tracked pole used or predict-only)",
        )
        if not np.isfinite(tracked):
            return
        z[j] = tracked
        self._scale_by_cluster(k, j, z[j], scale, typical, use=self.noise.pole_scatter)

    def _follow_damping(self, j: int, damping_ratio: float) -> None:
        """Mode *j*'s reference damping follows the chosen poles' (geometric, 5 %)."""
        if np.isfinite(damping_ratio) and damping_ratio > 0:
            ref = self.damping_ref[j]
            self.damping_ref[j] = (
                math.exp(0.95 * math.log(ref) + 0.05 * math.log(damping_ratio))
                if np.isfinite(ref) and ref > 0
                else damping_ratio
            )

    def _run_after_hole(self, residual: np.ndarray, prior_state: np.ndarray) -> np.ndarray:
        """The runs of large innovations the update judges the measurements by: after a
        hole in the record (no mode measured for at least ``persist_blocks`` rows) each
        measured mode's run as if already ``persist_blocks`` - 1 long in its innovation's
        sign.

        Across the hole the filter only predicted: its state is as old as the hole, while
        the ship may have done anything there (left port, stopped) that the model, fitted
        on what it saw before, does not know. A large first innovation after it is the
        state's error, not an outlier of SSI: no Huber weight, and P_cc raised to y²
        (:func:`~workbench.forecasting.memory.kalman.kalman_update`), so the estimate goes
        to SSI at once instead of after ``persist_blocks`` blocks of large innovations
        (``benchmarks/results/forecast_hole_52.txt``). A run of the record without such a
        hole is judged as before."""
        if self.record_gap < self.persist_blocks:
            return self.run
        return run_after_hole(self.run, residual - prior_state.sum(axis=1), self.persist_blocks)

    def _kalman_step(self, k, have, z, scale, m_now, z_now, filter_step, prior) -> None:
        """Kalman update of row *k* with the measurements *z*; the guard, the outputs. Where a
        mode is not measured its variance grows by *prior* (the predictors beyond the
        model's range, :meth:`_mode_predictions`): neither the model nor the last
        measurement says how far the mode moved with them; the estimate is unchanged."""
        F, q_c, q_e, r_v, huber, model_variance = filter_step
        noise_huber = huber  # inf: the prior's noise levels (before a fill's or a return's)
        n_modes, in_sample = self.n_modes, k < self.first + self.train
        residual = z - z_now  # innovation about what SSI is expected to see
        # a model that fills a missing predictor (a gap in the log): a large innovation is
        # the fill's error more likely than SSI's, so no Huber weight on the measurement
        filled = self._filled(k)
        huber = np.where(filled, np.inf, huber)
        self._outside_fill(filled, have, F, q_c, model_variance)
        Q = q_c + q_e * scale[:, None]
        prior_state, prior_P = kalman_predict(self.state, self.P, F, Q)
        moved = self._return_test(F, prior_state, prior_P, residual, r_v * scale, model_variance)
        huber = np.where(moved, np.inf, huber)
        # the move is in doubt: P = P + uu' (the gain along it toward the return about 1)
        u = self.unweighted_move[moved]
        prior_P[moved] += u[:, :, None] * u[:, None, :]
        self.state, self.P, delta, nu, innovation_variance, variance = kalman_update(
            prior_state,
            prior_P,
            residual,
            r_v * scale,
            huber,
            model_variance=model_variance,
            previous_run=self._run_after_hole(residual, prior_state),
            persist_blocks=self.persist_blocks,
        )
        self._record_unweighted(prior_state, nu, huber, filled, moved)
        if not in_sample:  # out of sample: the model had not seen block k
            self.consistency.record(k, nu, innovation_variance, residual)
        self.run = update_run(self.run, nu, huber)
        estimate = m_now + self.state[:, 0] + delta
        lost = have & ~_plausible(estimate, self.reference_hz)
        for j in np.flatnonzero(lost):
            self.state[j] = 0.0
            self.unweighted_move[j] = 0.0
            self.P[j] = stationary_covariance(self.noise_of[j], self.states)
            estimate[j] = m_now[j]
            variance[j] = self.P[j, 0, 0] + model_variance[j]
            self.warn(
                k,
                j,
                "Kalman track implausible: restarted at the model",
                "Kalman tracks restarted at the model (estimate implausible)",
            )
        if self.trust is not None:
            self.trust.step(
                np.where(have, z, np.nan),
                F,
                q_e * scale[:, None],
                np.array([nz.error_variance if nz else 0.0 for nz in self.noise_of]) * scale,
                r_v * scale,
                BlendStep(
                    nu,
                    innovation_variance,
                    self.state,
                    z_now,
                    ~np.isfinite(noise_huber),
                    after_hole=self.record_gap >= self.persist_blocks,
                    # the refits after a hole move the model by the error c took at once
                    # (_keep_estimate_after_hole): no test of the hull's moves meanwhile
                    settling=self.since_hole < _REFIT_CONTINUITY_BLOCKS,
                    level_step_variance=self._level_step_variance(k, m_now),
                ),
                # a block whose model fills a missing predictor says nothing of whether
                # the model explains the mode: the probabilities wait for the log
                np.full(n_modes, not in_sample) & ~lost & ~filled,
            )
            estimate, variance = self.trust.combine(estimate, variance)
            # how much the estimate leaned on the model: nothing while the hull moves
            probability = 0.0 if self.trust.change else self.trust.probability
            self.out["probability"][k] = np.where(have, probability, np.nan)
            if self.trust.change and have.any():
                self.notes[
                    "a change of the whole hull that the model does not explain (the modes' "
                    "innovations of one sign together): the estimate follows SSI"
                ] += 1
            if not in_sample:
                self._explained(k, have)
        if self.ssi_guard is not None:
            estimate, variance = self.ssi_guard.step(
                estimate, variance, np.where(have, z, np.nan), self.half_difference[k], m_now
            )
            self.out["guard"][k] = np.where(have, self.ssi_guard.weight, np.nan)
            for j in np.flatnonzero(have & (self.ssi_guard.weight < 1.0)):
                self.notes[
                    f"mode {self.mode_labels[j]}: estimate drawn toward SSI (its distance "
                    "from SSI beyond SSI's own error, measured on the blocks' halves)"
                ] += 1
        variance = variance + np.where(np.isfinite(z), 0.0, prior)
        if not in_sample:
            self.meas[k] = z
        self.resid[k] = residual
        self.out["ssi"][k] = z
        self.out["kalman"][k] = np.where(have, estimate, np.nan)
        self.out["std"][k] = np.where(have, np.sqrt(variance), np.nan)
        self.gap = np.where(np.isfinite(z), 0, self.gap + have)
        if np.isfinite(z[have]).any():
            self.since_hole = 0 if self.record_gap >= self.persist_blocks else self.since_hole + 1
        self.record_gap = 0 if np.isfinite(z[have]).any() else self.record_gap + int(have.any())
        for j in np.flatnonzero(have & (self.gap >= self.options.gap_warning_blocks)):
            self.warn(
                k,
                j,
                f"no SSI estimate for {self.gap[j]} blocks: predict-only",
                "rows in a long stretch without SSI estimates (predict-only)",
            )

    def _level_step_variance(self, k: int, m_now: np.ndarray) -> np.ndarray | None:
        """What the model-free filters' level may step at row *k* beside its random walk,
        in the first rows after a hole in the record [Hz²] (None: nothing, elsewhere):
        f² Σ (ρ Δx)² (:meth:`~workbench.forecasting.memory.terms.MemoryRefits.prior_variance`), Δx
        each predictor's change a block, averaged over the blocks sharing data with this
        one (``overlap``: a single block's move is the log's jitter), ρ its
        ``extrapolation_sensitivity``, f the model's frequency.

        After a hole the blend's estimate is the model-free level's (the model's
        probability is the prior's again, :mod:`~workbench.forecasting.model_trust`), and a
        ship that changes speed right after it moves the modes faster than the level's
        random walk follows. The prior that widens the band inside the hole says how far
        the modes may step with the predictors; the level takes it as process noise while
        the refits settle (``since_hole`` below :data:`_REFIT_CONTINUITY_BLOCKS`; measured in
        ``benchmarks/results/forecast_after_hole_step_54.txt``)."""
        if self.since_hole >= _REFIT_CONTINUITY_BLOCKS or k <= self.first:
            return None
        X = self.refits.X_all
        span = min(self.overlap, k - self.first)
        move = (X[k] - X[k - span]) / span
        relative = self.refits.prior_variance(move)
        return relative * np.where(np.isfinite(m_now), m_now, 0.0) ** 2

    def _outside_fill(self, filled, have, F, q_c, model_variance) -> None:
        """Keep the model correction c from taking the fill's error of a log outage.

        On a block whose model fills a missing predictor the innovation holds the fill's
        error, and that error persists over the outage (one stop or restart the log does
        not record spans several blocks), while the filter's model error δ is white: the
        persistent part of the innovations goes into c. When the log returns the fill's
        error leaves the model's prediction, but c keeps it and carries it past the
        outage's edge (``benchmarks/results/forecast_outage_edges_27o.txt``). A persistent
        offset d of the innovations over the filled blocks is c + f, with c's variance
        P_s (c and P_cc saved before the first filled block and carried on by the
        filter's prediction, c = φc, P_cc = φ²P_cc + q_c, no update) and f the fill's
        error, of the filled blocks' mean model variance V; c's share of it is
        w = P_s / (P_s + V). So on the first block the model no longer fills, c is
        c_s + w (ĉ - c_s), with ĉ what the filled blocks' updates made of it, and
        P_cc = (1 - w) P_s + w² P̂_cc (the cross-covariances with the identification
        error's states 0): a fill that errs little (the ship held its speed) leaves c
        what it learned, one that can err much (a stop in the outage) takes it back.
        Inside the outage the estimate is the filter's as before.
        """
        before = self.before_fill
        inside = np.isfinite(before[:, 0])
        back = inside & ~filled & have
        for j in np.flatnonzero(back):
            c_s, P_s = before[j, 0], before[j, 1]
            V = before[j, 2] / before[j, 3]
            w = P_s / (P_s + V) if P_s + V > 0 else 0.0
            c_hat, P_hat = self.state[j, 0], self.P[j, 0, 0]
            self.state[j, 0] = c_s + w * (c_hat - c_s)
            self.P[j, 0, :] = 0.0
            self.P[j, :, 0] = 0.0
            self.P[j, 0, 0] = (1.0 - w) * P_s + w * w * P_hat
        before[~filled & have] = np.nan
        start = filled & ~inside
        before[start, 0] = self.state[start, 0]
        before[start, 1] = self.P[start, 0, 0]
        before[start, 2:] = 0.0
        # c = φc ; P_cc = φ²P_cc + q_c (the prediction of the filled block, no update)
        on = filled & np.isfinite(before[:, 0])
        phi = F[on, 0, 0]
        before[on, 0] = phi * before[on, 0]
        before[on, 1] = phi**2 * before[on, 1] + q_c[on, 0]
        before[on, 2] += model_variance[on]
        before[on, 3] += 1.0

    def _return_test(self, F, prior_state, prior_P, residual, R, model_variance) -> np.ndarray:
        """Per mode: whether this block's measurement undoes a move of the state that was
        made without the Huber weight (its update then gets none either).

        While a mode's noise levels are the prior's the filter has no Huber weight
        (:func:`~.noise.filter_matrices`): those blocks' innovations count in full, those
        the weight would have held back too, and c can jump on a misread block (SSI's
        pole of another column). Once the weight is on it holds back the measurement that
        is right, because it is judged against the state that jump made: the jump needed
        no test, the return cannot pass one. So the return is tested against the state
        without the move u (carried on by F as the state is): a measurement the weight
        would hold back (normalised innovation beyond huber_sigma, not in a run of them)
        whose innovation about x - u is within huber_sigma is a return. It updates without
        the weight, as the jump did, and with uu' added to P (the move is in doubt, as the
        persistence rule raises P_cc for a run), so the filter can take the return as it
        took the jump.
        """
        u = self.unweighted_move
        u[:] = np.einsum("nij,nj->ni", F, u)  # u = Fu, as x = Fx
        k_sigma = float(self.noise.huber_sigma)
        y = residual - prior_state.sum(axis=1)  # y = z - Hx
        S = prior_P.sum(axis=(1, 2)) + R + model_variance  # S = HPH' + R + s_m²
        with np.errstate(invalid="ignore"):
            bound = k_sigma * np.sqrt(S)
            held = np.abs(y) > bound
            # a run of large innovations of one sign is the persistence rule's
            run = self.run
            held &= ~((np.abs(run) >= self.persist_blocks - 1) & (np.sign(y) == np.sign(run)))
            back = np.abs(y + u.sum(axis=1)) <= bound  # y about x - u
        return held & back & (u != 0.0).any(axis=1) & np.isfinite(y)

    def _record_unweighted(self, prior_state, nu, huber, filled, moved) -> None:
        """The unweighted move u (:meth:`_return_test`) after this block: plus the
        update where it was made without the Huber weight on an innovation beyond
        huber_sigma (not on filled blocks, whose moves of c :meth:`_outside_fill`
        weighs against the fill's error); 0 after a return, and 0 after a measurement
        within huber_sigma of the moved state (it confirms the move: no longer in doubt)."""
        u = self.unweighted_move
        k_sigma = float(self.noise.huber_sigma)
        with np.errstate(invalid="ignore"):
            unweighted = ~np.isfinite(huber) & ~filled & ~moved & (np.abs(nu) > k_sigma)
            confirmed = np.abs(nu) <= k_sigma
        u[unweighted] += self.state[unweighted] - prior_state[unweighted]
        u[moved | confirmed] = 0.0

    def _explained(self, k: int, have: np.ndarray) -> None:
        """Count forecast blocks and note when a mode's model stops explaining it."""
        for j in np.flatnonzero(have):
            self.forecast_blocks[j] += 1
            below = self.trust.probability[j] < 0.5
            self.explained[j] |= not below
            if below and self.explained[j] and not self.explained_lost[j]:
                self.explained_lost[j] = int(self.blocks[k]) + 1
            if below and self.explained[j]:
                self.notes[
                    f"mode {self.mode_labels[j]}: the model stopped explaining it (model "
                    f"probability below 0.5, first at block {self.explained_lost[j] - 1}; "
                    f"blocks below, the estimate follows {_FALLBACK})"
                ] += 1

    def result(self) -> ForecastResult:
        """The forecast table, the warnings (also issued) and the window models."""
        self.notes.update(never_explained_notes(self))
        drop_unusable(self.out_phase, self.out["model"], self.out["kalman"], self.notes)
        table = assemble_table(
            self.blocks,
            self.block_start,
            self.mode_labels,
            self.option,
            self.out_phase,
            self.out,
            (self.out_w0, self.out_w1),
            self.out_warning,
        )
        messages = tuple(f"{kind} (x{count})" for kind, count in self.notes.items())
        for message in messages:
            warnings.warn(message, ForecastWarning, stacklevel=4)
        return ForecastResult(
            table=table, options=self.options, warnings=messages, models=tuple(self.models_out)
        )
