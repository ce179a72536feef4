"""Term selection, refits and predictions of the memory forecast's per-mode models.

For each mode and window of :func:`~workbench.forecasting.memory.forecast.memory_forecast`: the stepwise
terms (:func:`~workbench.forecasting.memory.select_terms`), reselected on a schedule, on a new
operating case or when the ship leaves the predictor range the selection saw; the
exponentially weighted refit of those terms over the history
(:meth:`~workbench.forecasting.memory.model.MemoryModel.refit`); the prediction with its interval,
widened where the ship's predictors leave the range the refit saw
(:meth:`MemoryRefits.extrapolation_variance`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...stats.distributions import t_quantile
from ..options import ForecastOptions
from .model import MemoryModel, constant_model, select_terms

__all__ = ["MemoryRefits"]

#: Fewest non-overlapping measured blocks for a stepwise term selection; with fewer the
#: model is the weighted mean (a 20-block window holds only 5 independent SSI estimates,
#: and a stepwise fit on its 20 overlapping ones extrapolates wildly).
_MIN_SELECTION_ROWS = 10
#: Entry p-value of the short-history selection before the division by the overlap.
_SHORT_P_ENTER = 0.05
#: Fewest history rows that measure the error of filling a missing predictor
#: (:meth:`MemoryRefits.fill_missing`). [blocks]
_MIN_FILL_ROWS = 12


@dataclass
class MemoryRefits:
    """Per-mode term selections and refits over one forecast's predictor grid.

    *meas* (grid rows x modes) is the measurement each block contributed; the caller fills
    it as the forecast runs and every refit reads the blocks before its grid row.
    """

    model: ForecastOptions  # the model's settings
    X_all: np.ndarray
    columns: list[str]
    meas: np.ndarray
    labels: np.ndarray | None
    first: int
    history_limit: int
    terms_of: list = field(init=False)
    selected_case: list = field(init=False)
    train_y: list = field(init=False)
    selected_at: np.ndarray = field(init=False)
    selection_range: list = field(init=False)
    fit_range: list = field(init=False)
    regional: np.ndarray = field(init=False)
    sensitivity: np.ndarray = field(init=False)
    t_cache: dict[int, float] = field(init=False)
    min_train: int = field(init=False)
    memory: float = field(init=False)
    limit: float = field(init=False)

    def __post_init__(self) -> None:
        n_modes = self.meas.shape[1]
        self.terms_of = [None] * n_modes  # (columns, names, (mean, scale), terms) per mode
        self.selected_case = [None] * n_modes  # operating case of each mode's term selection
        self.train_y = [None] * n_modes  # targets of each mode's last refit (case rows only)
        self.selected_at = np.full(n_modes, -(10**9))
        self.selection_range = [None] * n_modes  # predictor ranges of each term selection
        # (low, high, spread) of the predictors over the rows of each mode's newest refit
        # (:meth:`extrapolation_variance`)
        self.fit_range = [None] * n_modes
        # predictors whose range is not a question of operating region: the time trend
        # always leaves it, by design
        self.regional = np.array([name != "elapsed_hours" for name in self.columns])
        # prior relative frequency change per unit of each predictor beyond the refit's
        # range (:meth:`extrapolation_prior`) [1/unit]
        sensitivity = self.model.sensitivities()
        self.sensitivity = np.array([sensitivity.get(name, 0.0) for name in self.columns])
        self.sensitivity[~self.regional] = 0.0
        self.t_cache = {}
        self.min_train = self.model.min_train  # fewest targets of a fit [blocks]
        self.memory = float(self.model.memory_blocks)  # forgetting time constant [blocks]
        self.limit = float(self.model.extrapolation_limit)  # z-score clip [-]

    def left_selection_range(self, j: int, i: int, rows_ok: np.ndarray) -> int | None:
        """The newest measured block since mode j's term selection outside its range, or None.

        A term selection only judges predictors the history exercised: one made while the
        ship held one speed has no speed term, whatever the speed law, and keeps none until
        the next scheduled selection (``reselect_blocks`` later). When a measured block
        since the selection has a predictor the selected terms do not use outside the range
        the selection saw, widened by half its width on each side, the selection could not
        judge that predictor where the ship now is, and the terms are selected again (at
        most every ``reselect_blocks // 4`` blocks; the time trend is not watched, it leaves
        its range by design). Predictors in the terms extrapolate as their fit says.
        """
        selection_range, selected_at, model = self.selection_range, self.selected_at, self.model
        terms_of, regional, X_all = self.terms_of, self.regional, self.X_all
        if selection_range[j] is None or i - selected_at[j] < max(1, model.reselect_blocks // 4):
            return None
        since = rows_ok[rows_ok >= selected_at[j]]
        if since.size == 0:
            return None
        low, high = selection_range[j]
        margin = 0.5 * (high - low)
        watch = regional.copy()  # predictors outside the selected terms
        if terms_of[j] is not None:
            use_j, _, _, terms_j = terms_of[j]
            for term in terms_j:
                for c in term:
                    watch[use_j[c]] = False
        X = X_all[since][:, watch]
        with np.errstate(invalid="ignore"):
            outside = (X < (low - margin)[watch]) | (X > (high + margin)[watch])
        rows = since[outside.any(axis=1)]
        return int(rows[-1]) if rows.size else None

    def refit(self, j: int, i: int) -> MemoryModel | None:
        """Model of mode j from the measured blocks before grid row i."""
        first, history_limit, meas, labels = self.first, self.history_limit, self.meas, self.labels
        min_train, train_y, terms_of, model = (
            self.min_train,
            self.train_y,
            self.terms_of,
            self.model,
        )
        selected_at, selected_case, X_all = self.selected_at, self.selected_case, self.X_all
        selection_range, columns, regional = self.selection_range, self.columns, self.regional
        memory, limit = self.memory, self.limit
        left_selection_range = self.left_selection_range
        if labels is not None:
            from workbench.stats import case_training_mask
        lo = max(first, i - history_limit)
        y = meas[lo:i, j]
        case = None
        if labels is not None:  # the model of the current operating case
            in_case = case_training_mask(labels, slice(lo, i), i, min_train, np.isfinite(y))
            if in_case is not None:
                y = np.where(in_case, y, np.nan)
                case = labels[i]
        train_y[j] = y
        ok = np.isfinite(y)
        if ok.sum() < min_train:
            return None
        rows_ok = np.flatnonzero(ok) + lo
        self.fit_range[j] = _supported_range(X_all[rows_ok], int(model.selection_stride) - 1)
        newest_outside = left_selection_range(j, i, rows_ok)
        reselect = (
            terms_of[j] is None
            or i - selected_at[j] >= model.reselect_blocks
            or (labels is not None and case != selected_case[j])
            or newest_outside is not None
        )
        if reselect:
            # blocks the ship's log covers: in a gap of the log (every predictor missing) a
            # block can neither judge nor fit a term; a selection that would see fewer such
            # blocks than a fit needs waits for the log to come back, keeping its terms
            recent = rows_ok[rows_ok >= i - int(model.selection_blocks)]
            if regional.any():  # the time trend is never missing
                logged = recent[np.isfinite(X_all[recent][:, regional]).any(axis=1)]
            else:
                logged = recent
            reselect = terms_of[j] is None or logged.size >= min_train
        if reselect:
            selected_case[j] = case
            # non-overlapping blocks only (75 % overlap: every 4th block shares no data), so
            # the F-tests of the selection do not count one correlated error several times;
            # the spacing keeps the newest block, or the newest block of a new operating
            # region when that is what triggered the selection
            anchor = i - 1 if newest_outside is None else newest_outside
            recent = logged
            spaced = recent[(anchor - recent) % int(model.selection_stride) == 0]
            short = spaced.size < max(min_train, _MIN_SELECTION_ROWS)
            selection_options = model.stepwise_options
            if short and recent.size >= min_train and model.short_history_selection:
                # a short history (the first window): every measured block, main effects
                # only, and an entry p-value divided by the overlap (the F-tests count each
                # correlated error up to `stride` times)
                selection_options = {
                    "upper": "linear",
                    "p_enter": _SHORT_P_ENTER / int(model.selection_stride),
                    "p_remove": 2 * _SHORT_P_ENTER / int(model.selection_stride),
                    **dict(model.stepwise_options or {}),
                }
                few = False
            else:
                recent, few = spaced, short
            Xs = X_all[recent]
            selection_range[j] = None
            if Xs.shape[0]:
                with warnings.catch_warnings():  # an all-NaN column: no range, never "left"
                    warnings.simplefilter("ignore", RuntimeWarning)
                    selection_range[j] = (np.nanmin(Xs, axis=0), np.nanmax(Xs, axis=0))
            use, names = [], []
            for c, name in enumerate(columns):
                v = Xs[:, c]
                valid = np.isfinite(v)
                if valid.sum() < min_train:
                    continue
                if np.ptp(v[valid]) <= 1e-12 * max(1.0, float(np.abs(v[valid]).max())):
                    continue
                use.append(c)
                names.append(name)
            if use and not few:
                mean = np.nanmean(Xs[:, use], axis=0)
                scale = np.nanstd(Xs[:, use], axis=0, ddof=1)
                Z = pd.DataFrame((Xs[:, use] - mean) / scale, columns=names)
                try:
                    terms = select_terms(Z, meas[recent, j], selection_options)
                except Exception:  # singular selection: keep the last terms
                    terms = terms_of[j][3] if terms_of[j] is not None else ((),)
                terms_of[j] = (tuple(use), tuple(names), (mean, scale), terms)
            else:
                terms_of[j] = ((), (), (np.empty(0), np.empty(0)), ((),))
            selected_at[j] = i
        use, names, (mean, scale), terms = terms_of[j]
        if use:
            # z-scores from the newest history (not frozen at the selection): a speed first
            # seen after the selection is then inside the clipping range
            newest = X_all[rows_ok[rows_ok >= i - int(model.selection_blocks)]][:, list(use)]
            if newest.shape[0] >= 2 and np.isfinite(newest).all():  # the usual case: fast
                m_new = newest.mean(axis=0)
                s_new = newest.std(axis=0, ddof=1)
            else:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    m_new = np.nanmean(newest, axis=0)
                    s_new = np.nanstd(newest, axis=0, ddof=1)
            good = np.isfinite(s_new) & (s_new > 1e-12 * np.maximum(1.0, np.abs(m_new)))
            mean = np.where(good, m_new, mean)
            scale = np.where(good, s_new, scale)
        # the whole history slice (a view, no copy): the fits skip blocks without a
        # measurement themselves, so they use exactly the rows of rows_ok, in order
        age = (i - 1 - np.arange(lo, i)).astype(float)
        fitted = None
        if use and terms != ((),):
            fitted = MemoryModel.unfitted(use, names, terms, mean, scale).refit(
                X_all[lo:i], y, age, memory_blocks=memory, limit=limit
            )
        if fitted is None:
            fitted = constant_model(y, age, memory)
        return fitted

    def predict(self, m: MemoryModel, rows_: np.ndarray, added_variance=None):
        """Mean, interval bounds, rows with a needed predictor missing and s_m² of *m* at rows
        *rows_* (missing predictors filled, :meth:`fill_missing`); *added_variance* (per
        row, [Hz²]) is added to s_m² and widens the bounds."""
        X_all, limit, t_cache, model = self.X_all, self.limit, self.t_cache, self.model
        X = X_all[rows_]
        mean, mvar = m.predict(X, limit)
        bad = ~np.isfinite(mean)
        if bad.any() and m.kind != "constant":
            for r in np.flatnonzero(bad):
                filled = self.fill_missing(m, int(rows_[r]))
                if filled is None:  # no history to fill from: the weighted centre of the data
                    mean[r], mvar[r] = float(m.coefficients[0]), m.residual_variance
                else:
                    mean[r], mvar[r] = filled
        if added_variance is not None:
            mvar = mvar + added_variance
        dof = max(int(round(m.dof)), 1)
        t = t_cache.get(dof)
        if t is None:
            t = t_cache[dof] = t_quantile(1 - model.alpha / 2, dof)
        half = t * np.sqrt(m.residual_variance + mvar)
        return mean, mean - half, mean + half, bad, mvar

    def extrapolation_variance(self, j: int, m: MemoryModel, rows_: np.ndarray):
        """Variance added to mode *j*'s model *m* at grid rows *rows_* where the predictors
        leave the range of its newest refit's rows [Hz²], and the excess of each predictor
        beyond that range in its standard deviations there, at most 1 (rows x predictors,
        NaN-free).

        A model only knows the predictors' range its history covered: a term left out
        because its predictor hardly varied is no evidence that the predictor does not
        matter, and a term fitted on a narrow range says little of its law far beyond it
        (the prediction's own variance, s² x(XᵀWX)⁻¹xᵀ, stops growing at the z-score
        clipping). So every candidate predictor (the time trend excepted: it leaves its
        range by design) is watched, those in the terms and those not: its excess e beyond
        the range in units of its standard deviation σ over the refit's rows, at most 1,
        and the model's variance grows by s² Σ e², s² its residual variance: a predictor
        one σ or more outside the range adds as much error again as the model shows where
        it was fitted. Not more: a predictor that hardly varied (the speed in port) has a
        σ that makes any move many σ, and a variance growing with e² without bound took
        the blend from voyages where the model extrapolated well (the 12-h worked example's
        departure). The range leaves out the ``selection_stride`` - 1 most extreme values
        at each end: a value seen only in blocks that share data is one SSI estimate's
        evidence. The blend then leans on SSI as far as the model extrapolates
        (``benchmarks/results/forecast_extrapolation_52.txt``: the README's 6-h worked
        example, whose temperatures leave their range in the last hour).
        """
        added = np.zeros(len(rows_))
        fit_range = self.fit_range[j]
        if fit_range is None:
            return added, np.zeros((len(rows_), self.X_all.shape[1]))
        low, high, spread = fit_range
        X = self.X_all[rows_]
        with np.errstate(invalid="ignore", divide="ignore"):
            varied = self.regional & (spread > 1e-12 * np.maximum(1.0, np.abs(high)))
            # e = (x - high) / σ above the range, (low - x) / σ below it, 0 inside
            excess = np.maximum(np.maximum(X - high, low - X), 0.0) / spread
        excess = np.where(np.isfinite(excess) & varied, np.minimum(excess, 1.0), 0.0)
        added = m.residual_variance * (excess**2).sum(axis=1)  # s² Σ e²
        return added, excess

    def extrapolation_prior(self, j: int, rows_: np.ndarray) -> np.ndarray:
        """Prior variance of mode *j*'s relative frequency change at grid rows *rows_* from
        the predictors beyond the range of its newest refit's rows [-]: Σ (ρ d)² d / (d + w),
        d a predictor's distance beyond the range, w the range's width, ρ its
        ``extrapolation_sensitivity`` (NaN-free; 0 inside the range).

        Where the forecast measures nothing (a hole in the record) nothing it has seen says
        how far a mode moves with a predictor the model saw constant: the ship leaving port
        inside the hole while the model knows her at rest moves the modes by 1-3 % that
        :meth:`extrapolation_variance` (at most the model's residual variance) does not
        cover. A structural prior does: a relative sensitivity per unit of the predictor
        (the speed's added mass, the temperatures' stiffness), on the whole excursion where
        the model saw the predictor constant, on a share d / (d + w) of it where the model
        saw a range w: a law seen over a range wider than the step says most of the step
        (``benchmarks/results/forecast_hole_band_54.txt``)."""
        fit_range = self.fit_range[j]
        if fit_range is None or not self.sensitivity.any():
            return np.zeros(len(rows_))
        low, high, _ = fit_range
        X = self.X_all[rows_]
        with np.errstate(invalid="ignore"):
            d = np.maximum(np.maximum(X - high, low - X), 0.0)
            share = d / (d + (high - low))
        return self.prior_variance(d, share)

    def prior_variance(self, move: np.ndarray, share: np.ndarray | float = 1.0) -> np.ndarray:
        """The structural prior's variance of a relative frequency change [-]: Σ (ρ Δx)² s
        over the predictors (the last axis of *move*), Δx a predictor's move, ρ its
        ``extrapolation_sensitivity``, s the *share* of the move the prior speaks for (NaN
        terms 0): :meth:`extrapolation_prior` inside a hole, the model-free level's step in
        the rows after one (:meth:`~workbench.forecasting.memory.forecast.MemoryRun._level_step_variance`)."""
        relative = (self.sensitivity * move) ** 2 * share
        return np.where(np.isfinite(relative), relative, 0.0).sum(axis=-1)

    def fill_missing(self, m: MemoryModel, row: int) -> tuple[float, float] | None:
        """Prediction of *m* at grid row *row*, where a predictor it needs is missing (a gap
        in the ship's log), and its variance [Hz], [Hz²].

        Each missing predictor is filled with its newest value before the row (the last
        logged value) or with its mean over the history, whichever the history says errs
        less: the error of a fill is measured by applying the same fill to the history's
        rows (the model's output with the predictor lagged by the same number of blocks,
        or set to its mean, against its output with the logged value), over the newest
        ``selection_blocks`` rows before *row*. The variance added to the prediction is
        the larger of the two mean square errors: a history that held its predictors
        steady measures a small error of the last value that a change inside the gap need
        not keep, and knowing nothing of the missing predictors costs the mean fill's
        error. So the blend leans on SSI as far as the gap makes the model uncertain:
        little for a temperature term worth millihertz, much for the speed. None when
        the history has too few rows to measure it.
        """
        columns = np.asarray(m.needed_columns(), dtype=np.int64)
        missing = columns[~np.isfinite(self.X_all[row, columns])]
        filled = self._fill(m, row, missing)
        if filled is None:
            return None
        mean, variance, fill_variance = filled
        return mean, variance + fill_variance

    def fill_variance(self, m: MemoryModel, row: int, columns) -> float | None:
        """The variance :meth:`fill_missing` would add to *m*'s prediction at grid row *row*
        were the predictors *columns* (grid column indices) missing there [Hz²]; None when
        the history has too few rows to measure it (or none of *columns* is one *m* needs)."""
        needed = np.asarray(m.needed_columns(), dtype=np.int64)
        missing = needed[np.isin(needed, np.asarray(columns, dtype=np.int64))]
        filled = self._fill(m, row, missing)
        return None if filled is None else filled[2]

    def _fill(self, m: MemoryModel, row: int, missing: np.ndarray):
        """``(mean, variance, fill variance)`` of *m* at grid row *row* with the predictors
        *missing* filled (:meth:`fill_missing`), or None."""
        X_all, limit = self.X_all, self.limit
        x = X_all[row].copy()
        x[missing] = np.nan
        lo = max(self.first, row - int(self.model.selection_blocks))
        history = X_all[lo:row]
        if missing.size == 0 or history.shape[0] < _MIN_FILL_ROWS:
            return None
        logged = m.predict(history, limit)[0]  # the model's output where nothing is missing
        filled_rows, errors = [], []
        for fill in ("last", "mean"):
            filled_row = x.copy()
            filled_history = history.copy()
            for c in missing:
                values = history[:, c]
                finite = np.flatnonzero(np.isfinite(values))
                if finite.size == 0:
                    return None
                if fill == "last":
                    lag = history.shape[0] - int(finite[-1])  # blocks since the last value
                    filled_row[c] = values[finite[-1]]
                    filled_history[lag:, c] = values[:-lag]
                    filled_history[:lag, c] = np.nan
                else:
                    centre = float(values[finite].mean())
                    filled_row[c] = centre
                    filled_history[:, c] = centre
            error = logged - m.predict(filled_history, limit)[0]
            error = error[np.isfinite(error)]
            if error.size < _MIN_FILL_ROWS:
                return None
            filled_rows.append(filled_row)
            errors.append(float(np.mean(error**2)))
        best = int(np.argmin(errors))
        mean, variance = m.predict(filled_rows[best][None, :], limit)
        if not np.isfinite(mean[0]):
            return None
        return float(mean[0]), float(variance[0]), max(errors)


def _supported_range(X: np.ndarray, trim: int):
    """``(low, high, spread)`` of each column of *X* over its logged rows: the *trim* + 1-th
    smallest and largest value (NaN with no more than 2 *trim* + 1 values) and the standard
    deviation (NaN with fewer than two values)."""
    n = np.isfinite(X).sum(axis=0)
    ordered = np.sort(X, axis=0)  # NaN last
    low = np.full(X.shape[1], np.nan)
    high = np.full(X.shape[1], np.nan)
    enough = np.flatnonzero(n > 2 * trim + 1)
    low[enough] = ordered[trim, enough]
    high[enough] = ordered[n[enough] - 1 - trim, enough]
    with warnings.catch_warnings():  # a column with fewer than two values: no spread
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanstd(X, axis=0, ddof=1)
    return low, high, spread
