"""The reference forecast (``model="window"``): a short orchestrator of named steps.

:func:`window_forecast` runs, window after window (method 1: one window; method 2: slide by
*horizon* blocks, the Kalman estimates as the next targets):

1. the window's candidate predictors and each mode's model and predictions
   (:mod:`workbench.forecasting.window.model`);
2. the Kalman noise levels R and Q (:mod:`workbench.forecasting.window.noise`);
3. the Kalman pass over the rows the window reports, with option A's or B's measurement
   (:mod:`workbench.forecasting.window.kalman`).

Everything the steps share lives on one :class:`WindowRun`: the block grid, the settings
and the output arrays, so a step reads like the equations in the
:mod:`workbench.forecasting.sliding` docstring. Arguments arrive validated.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..assembly import ASSEMBLED, assemble_rows, drop_unusable
from ..fitted_model import _coefficients, _Model
from ..kalman import ModeKalmanBank
from ..options import ForecastOptions
from ..pole_selection import _MIN_SHAPE_CHANNELS, _PoleSelector
from ..predictor_grid import forecast_span, mode_matrix, modes_to_forecast, predictor_matrix
from ..results import ForecastResult, ForecastWarning, WindowModel
from .kalman import kalman_pass, next_targets
from .model import WindowFrame, fit_window_model, predict_window
from .noise import window_noise_levels

__all__ = ["WindowRun", "forecast_data", "window_forecast"]


@dataclass
class ForecastData:
    """The matrices of a window forecast on its blocks: predictors and tracked frequencies
    per mode (the grid itself is :class:`workbench.blocks.BlockGrid`)."""

    blocks: np.ndarray  # block numbers, sorted
    block_start: np.ndarray
    columns: list[str]  # candidate predictor columns
    X_all: np.ndarray  # (n_blocks, n_columns) raw predictors
    mode_labels: np.ndarray
    tracked: np.ndarray  # (n_blocks, n_modes) tracked frequency, NaN where missing [Hz]


def forecast_data(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    predictor_columns: Sequence[str] | None,
    modes: Sequence[int] | None,
) -> ForecastData:
    """Predictor and tracked-frequency matrices on the blocks of *predictors* (consecutive
    rows: consecutive Kalman steps)."""
    _, blocks, block_start, columns, X_all = predictor_matrix(predictors, predictor_columns)
    mode_labels = modes_to_forecast(modal, modes)
    tracked = mode_matrix(modal, blocks, mode_labels, "frequency_hz")
    return ForecastData(blocks, block_start, columns, X_all, mode_labels, tracked)


@dataclass
class WindowRun:
    """Settings, grid, running filter state and outputs of one reference forecast."""

    grid: ForecastData
    options: ForecastOptions  # one measurement option
    first: int
    last: int
    labels: np.ndarray | None = None  # operating case per grid row
    selector: _PoleSelector | None = None
    notes: Counter = field(default_factory=Counter)
    out_warning: dict = field(default_factory=dict)

    def __post_init__(self):
        # the settings the steps read, from the one options object
        o = self.options
        self.option, self.method, self.train_blocks = o.options[0], o.scheme, int(o.train_blocks)
        self.horizon, self.trust, self.phi = o.horizon_blocks, o.window_trust, o.transition
        self.gate_sigma, self.reacquire_blocks = o.gate_sigma, int(o.reacquire_blocks)
        self.min_train, self.alpha = o.min_train, o.alpha
        self.extrapolation_limit, self.gap_warning_blocks = (
            o.extrapolation_limit,
            o.gap_warning_blocks,
        )
        # a window's model uses the rows complete in every candidate predictor (the rule
        # the forecast was validated with); {"missing": "candidate"} for MATLAB's
        self.stepwise_options = {"missing": "complete", **dict(o.stepwise_options or {})}
        g = self.grid
        n_blocks, n_modes = g.tracked.shape
        shape = (n_blocks, n_modes)
        self.blocks, self.X_all, self.columns = g.blocks, g.X_all, g.columns
        self.mode_labels, self.tracked = g.mode_labels, g.tracked
        self.out_phase = np.zeros(shape, dtype=np.int8)  # 0 none, 1 train, 2 forecast
        for name in ("ssi", "model", "lower", "upper", "kalman", "std", "order", "damping"):
            setattr(self, f"out_{name}", np.full(shape, np.nan))
        self.out_mac = np.full(shape, np.nan)
        self.out_w0 = np.zeros(shape, dtype=np.int64)
        self.out_w1 = np.zeros(shape, dtype=np.int64)
        # training targets: tracked, then Kalman estimates (method 2)
        self.targets = self.tracked.copy()
        self.measured = np.full(shape, np.nan)  # measurement used in each block (for R)
        window = slice(self.first, self.first + self.train_blocks)
        self.measured[window] = self.tracked[window]
        self.bank = ModeKalmanBank(n_modes, transition=self.phi)
        self.last_good: list[_Model | None] = [None] * n_modes
        self.last_r = np.full(n_modes, np.nan)
        self.previous_model_value = np.full(n_modes, np.nan)  # m_{k-1}, current model
        self.gap = np.zeros(n_modes, dtype=np.int64)
        self.models_out: list[WindowModel] = []
        self.started = np.zeros(n_modes, dtype=bool)
        self.reference_hz = np.full(n_modes, np.nan)  # first window's median: plausibility

    @property
    def n_modes(self) -> int:
        return self.tracked.shape[1]

    def warn_rows(self, row_slice, j: int, message: str, kind: str) -> None:
        self.notes[kind] += 1
        for i in row_slice:
            self.out_warning.setdefault((i, j), []).append(message)


def window_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    options: ForecastOptions,
    *,
    poles: pd.DataFrame | None,
    modes: Sequence[int] | None,
    start_block: int | None,
    end_block: int | None,
    cases,
) -> ForecastResult:
    """The reference forecast of the one measurement option of *options* (module
    docstring; arguments as :func:`~workbench.forecasting.sliding_forecast`, checked there
    and by :class:`~workbench.forecasting.options.ForecastOptions`)."""
    from workbench.stats import case_labels

    grid = forecast_data(modal, predictors, options.predictor_columns, modes)
    frame = predictors.sort_values("block").drop_duplicates("block", keep="last")
    labels = None if cases is None else case_labels(frame, cases).to_numpy()
    notes: Counter[str] = Counter()
    selector = None
    if options.options[0] == "B":
        selector = _PoleSelector(
            poles,
            modal,
            grid.blocks,
            grid.mode_labels,
            shape_mac_min=options.mac_min,
            reacquire_blocks=int(options.reacquire_blocks),
            reacquire_band=options.reacquire_band,
        )
        if not selector.uses_shapes:
            notes[
                "option B without mode shapes (poles or modal lack shape_re_<channel> columns "
                f"for {_MIN_SHAPE_CHANNELS}+ shared channels): nearest pole in the gate, "
                "no MAC check"
            ] += 1
    first, last = forecast_span(
        grid.blocks, start_block, end_block, int(options.train_blocks), modal["block"]
    )
    run = WindowRun(
        grid=grid,
        options=options,
        first=first,
        last=last,
        labels=labels,
        selector=selector,
        notes=notes,
    )
    train_blocks, horizon, method, min_train = (
        run.train_blocks,
        run.horizon,
        run.method,
        run.min_train,
    )
    n_blocks = len(grid.blocks)
    window_start = first
    while True:
        w0, w1 = window_start, window_start + train_blocks  # training rows [w0, w1)
        f0 = w1
        f1 = min(f0 + horizon, last + 1) if method == 2 else min(f0 + horizon, n_blocks)
        if f0 >= f1:
            break
        window = WindowFrame(run.X_all, run.columns, w0, w1, f1)
        window.select(min_train, notes)
        for j in range(run.n_modes):
            model_window(run, j, window)
        is_first = w0 == first
        kalman_pass(run, w0 if is_first else f0, f1)
        if method == 2:
            next_targets(run, f0, f1)
        if method == 1 or f1 > last:
            break
        window_start += horizon

    drop_unusable(run.out_phase, run.out_model, run.out_kalman, notes)
    table = assemble_rows(
        grid.blocks,
        grid.block_start,
        grid.mode_labels,
        run.option,
        run.out_phase,
        {name: getattr(run, f"out_{name}") for name in ASSEMBLED},
        (run.out_w0, run.out_w1),
        run.out_warning,
    )
    messages = tuple(f"{kind} (x{count})" for kind, count in notes.items())
    for message in messages:
        warnings.warn(message, ForecastWarning, stacklevel=3)
    return ForecastResult(
        table=table, options=options, warnings=messages, models=tuple(run.models_out)
    )


def model_window(run: WindowRun, j: int, window: WindowFrame) -> None:
    """Model, predictions and noise levels of mode *j* for one window; rows reported."""
    from workbench.stats import case_training_mask

    w0, w1, f0, f1 = window.w0, window.w1, window.w1, window.f1
    is_first = w0 == run.first
    y = run.targets[w0:w1, j]
    in_case = case_training_mask(run.labels, slice(w0, w1), f0, run.min_train, np.isfinite(y))
    if in_case is not None:  # the model of the current operating case
        y = np.where(in_case, y, np.nan)
    model, reason, n_valid = fit_window_model(run, j, window, y)
    if model is None:
        return
    mean_p, lower_p, upper_p, mvar = predict_window(run, j, model, window, y, n_valid)
    r, q = window_noise_levels(run, j, model, mean_p, mvar, w0, w1)
    run.bank.process_variance[j] = q
    run.bank.measurement_variance[j] = r
    blocks = run.blocks
    if reason:
        run.warn_rows(
            range(w0 if is_first else f0, f1),
            j,
            f"window {blocks[w0]}-{blocks[w1 - 1]}: {reason}",
            f"windows with a fallback model ({reason.split(' (')[0]})",
        )
    run.models_out.append(
        WindowModel(
            mode=int(run.mode_labels[j]),
            window_start_block=int(blocks[w0]),
            window_end_block=int(blocks[w1 - 1]),
            kind=model.kind,  # type: ignore[arg-type]
            terms=model.terms(),
            coefficients=_coefficients(model),
            n_train=n_valid,
            rmse_hz=float(model.rmse),
            measurement_variance=r,
            process_variance=q,
            normalisation={
                c: (float(a), float(b))
                for c, a, b in zip(model.columns, model.mean, model.scale, strict=True)
            },
            warning=reason,
        )
    )
    # the model track of the rows this window reports
    n_tr = w1 - w0
    report = slice(0, None) if is_first else slice(n_tr, None)
    rows_rep = np.arange(w0, f1)[report]
    run.out_model[rows_rep, j] = mean_p[report]
    run.out_lower[rows_rep, j] = lower_p[report]
    run.out_upper[rows_rep, j] = upper_p[report]
    run.out_w0[rows_rep, j] = blocks[w0]
    run.out_w1[rows_rep, j] = blocks[w1 - 1]
    run.out_phase[rows_rep, j] = np.where(rows_rep < w1, 1, 2)
    # m_{k-1} under this window's model for the first reported row's predict step
    run.previous_model_value[j] = mean_p[n_tr - 1] if not is_first else math.nan
