"""Control charts of modal-frequency residuals (structural-health indicator): per-mode
CUSUM (default) or MEWMA Hotelling T².

The operational and environmental model of the forecast (speed, temperatures, fuel state)
explains how the modal frequencies move; what it leaves is identification scatter plus any
change of the structure. :func:`health_chart` learns the in-control state of those
residuals over a reference period and flags blocks where they leave it.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as _scipy_stats

from data_contracts import ALARMS, FORECAST, HEALTH, recorded_grid, set_grid, write_table

from ..results import StageResult, Summary, shown_once
from .options import HealthOptions
from .statistics import (
    OUTLIER_SIGMA,
    InControlResiduals,
    _limit_for_rate,
    _moving_block_bootstrap,
    _robust_location_scale,
    cusum_hold,
    cusum_limits,
    ewma_hold,
    hotelling,
    long_run_std,
    trimmed_location_scale,
    truncated_normal_variance,
    upcrossings_per_day,
)

__all__ = ["HealthReference", "HealthResult", "health_chart"]


@dataclass(frozen=True)
class HealthReference:
    """The in-control state learned over the reference period.

    Parameters
    ----------
    modes : tuple of int
        Charted modes, in the order of the vectors below.
    start_block, end_block : int
        First and last block of the reference period.
    location, scale : ndarray, shape (n_modes,)
        Median and normalised MAD (1.4826 MAD) of the prediction-standardised residuals
        over the reference blocks. [-]
    correlation : ndarray, shape (n_modes, n_modes)
        Correlation of the in-control EWMA across modes (bootstrap).
    ewma_covariance : ndarray, shape (n_modes, n_modes)
        Second moment about 0 of the in-control EWMA vector (bootstrap), Σ_z; its mean
        diagonal times the identity with ``covariance='pooled'``.
    limit : float
        Control limit of T².
    blocks_per_day : float
        Block steps per day. [1/day]
    bootstrap_false_alarms_per_day : float
        Upcrossings of the limit per day in the bootstrap series. [1/day]
    excluded_modes : tuple of int
        Modes with too few reference residuals to be charted.
    relative_median : ndarray, shape (n_modes,), optional
        Median relative residual (f_SSI / f_model - 1) of each charted mode over the
        reference, the zero of the alarms' frequency-shift estimate. [-]
    statistic : {"mewma", "cusum"}
        Which chart the limits are for.
    allowance : ndarray, shape (n_modes,), optional
        CUSUM: reference value K_j of each mode, half of ``detect_shift`` in the mode's
        standardised units. [-]
    mode_limits : ndarray, shape (n_modes,), optional
        CUSUM: decision interval H_j of each mode; the chart's statistic is
        max_j S_j / H_j and its limit 1. [-]
    trend_slope : ndarray, shape (n_modes,), optional
        With ``baseline_hours``: each mode's drift over the reference, per block; the
        location is then the line's value at the reference end, and a reference block
        k is charted about location - slope x (end_block - k). [-]
    model_offset_std : ndarray, shape (n_modes,), optional
        CUSUM: root mean square over the reference blocks of the model's persistent error
        (``model_shift_std``) in the chart's units. The limits H_j hold against a persistent
        offset of this size; a block's allowance grows only by the excess of its own
        ``model_shift_std`` over it. [-]
    """

    modes: tuple[int, ...]
    start_block: int
    end_block: int
    location: np.ndarray
    scale: np.ndarray
    correlation: np.ndarray
    ewma_covariance: np.ndarray
    limit: float
    blocks_per_day: float
    bootstrap_false_alarms_per_day: float
    excluded_modes: tuple[int, ...] = ()
    relative_median: np.ndarray | None = None
    statistic: str = "mewma"
    allowance: np.ndarray | None = None
    mode_limits: np.ndarray | None = None
    trend_slope: np.ndarray | None = None
    model_offset_std: np.ndarray | None = None


@dataclass(frozen=True)
class HealthResult(StageResult):
    """Result of the health stage (:func:`workbench.stages.health`, :func:`health_chart`,
    :meth:`HealthBaseline.chart <workbench.shm.HealthBaseline.chart>`).

    Parameters
    ----------
    table : DataFrame
        HEALTH contract, plus ``contribution_<mode>`` (share of T² of each mode, NaN when
        T² is 0).
    alarms : DataFrame
        ALARMS contract, one row per alarm episode.
    reference : HealthReference
        What was learned over the reference period.
    options : HealthOptions
    lines, warnings : list of str
        Further lines of the summary (none from the chart itself).
    """

    table: pd.DataFrame
    alarms: pd.DataFrame
    reference: HealthReference
    options: HealthOptions = field(default_factory=HealthOptions)
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "structural health"

    def save(self, out: str | os.PathLike) -> dict[str, Path]:
        """Write ``health.csv`` and ``alarms.csv`` into folder *out* (each atomically)."""
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        return {
            "health": write_table(self.table, folder / "health.csv", HEALTH),
            "alarms": write_table(self.alarms, folder / "alarms.csv", ALARMS),
        }

    def summary(self) -> Summary:
        """A few lines a structural engineer reads (``print`` it)."""
        return Summary(
            self.title,
            [*self._chart_lines(), *self.lines, *(f"warning: {w}" for w in self.warnings)],
        )

    def plot(self, ax=None):
        """The chart: statistic per block, the control limit, alarming blocks marked."""
        import matplotlib.pyplot as plt

        drawn_here = ax is None
        if ax is None:
            _, ax = plt.subplots(figsize=(9, 4), layout="constrained")
        table = self.table
        ax.plot(table["block"], table["statistic"], "-", lw=0.8, color="0.3", label="statistic")
        ax.plot(table["block"], table["limit"], "--", color="tab:red", lw=1, label="limit")
        alarm = table["alarm"].astype(bool)
        ax.plot(table.loc[alarm, "block"], table.loc[alarm, "statistic"], ".", color="tab:red")
        ax.set_xlabel("block")
        ax.set_ylabel("CUSUM max S/H" if self.reference.statistic == "cusum" else "MEWMA T²")
        ax.legend(fontsize=8)
        return shown_once(ax.figure) if drawn_here else ax.figure

    def _chart_lines(self) -> list[str]:
        """The chart run, its reference and every alarm episode, one line each."""
        ref = self.reference
        monitor = self.table[self.table["phase"] == "monitor"]
        hours = len(monitor) / ref.blocks_per_day * 24.0
        if ref.statistic == "cusum":
            title = "Structural-health chart (per-mode CUSUM of frequency residuals)"
            chart = (
                f"detect shift {100 * self.options.detect_shift:g} %; statistic max S/H, "
                f"limit {ref.limit:.2f}"
            )
            peak = "peak max S/H"
        else:
            title = "Structural-health chart (MEWMA of frequency residuals)"
            chart = f"EWMA lambda {self.options.ewma_lambda:g}; limit T2 = {ref.limit:.2f}"
            peak = "peak T2"
        lines = [
            title,
            f"  modes charted: {', '.join(map(str, ref.modes))}"
            + (
                f" (excluded: {', '.join(map(str, ref.excluded_modes))})"
                if ref.excluded_modes
                else ""
            ),
            f"  reference: blocks {ref.start_block}-{ref.end_block}; {chart} "
            f"(target {self.options.false_alarms_per_day:g} false alarms/day, "
            f"bootstrap {ref.bootstrap_false_alarms_per_day:.3f}/day)",
            f"  monitored: {len(monitor)} blocks ({hours:.1f} h), "
            f"{int(monitor['alarm'].sum())} alarming blocks, {len(self.alarms)} alarm episode(s)",
        ]
        for row in self.alarms.itertuples():
            lines.append(
                f"  alarm {row.alarm}: blocks {row.start_block}-{row.end_block} "
                f"({row.start_time:%Y-%m-%d %H:%M}Z), {peak} {row.peak_statistic:.1f}, "
                f"modes {row.modes}, mode {row.top_mode} shifted "
                f"{row.top_mode_shift_percent:+.2f} %"
            )
        return lines


# --------------------------------------------------------------------------- stage
def _residual_matrix(
    forecast: pd.DataFrame, *, common_shift: bool = False
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame | None]:
    """Prediction-standardised residuals, relative residuals and the prediction-standardised
    ``model_shift_std`` (None without that column), blocks x modes.

    With *common_shift*, each block's median relative residual over its modes is removed
    from every mode first (blocks with fewer than 3 modes get none).
    """
    z975 = _scipy_stats.norm.ppf(0.975)
    prediction_std = (forecast["model_upper_hz"] - forecast["model_lower_hz"]) / (2 * z975)
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = forecast["ssi_frequency_hz"] / forecast["model_frequency_hz"] - 1.0
        relative_std = (prediction_std / forecast["model_frequency_hz"]).where(prediction_std > 0)
    frame = forecast.assign(relative=relative, relative_std=relative_std)
    rel = frame.pivot(index="block", columns="mode", values="relative").sort_index()
    std = frame.pivot(index="block", columns="mode", values="relative_std").sort_index()
    if common_shift:
        enough = rel.notna().sum(axis=1) >= 3
        shift = rel.median(axis=1)
        centred = rel.sub(shift, axis=0).where(enough, np.nan)
    else:
        centred = rel
    with np.errstate(invalid="ignore", divide="ignore"):
        wide = centred / std
    shift = None
    if "model_shift_std" in forecast.columns:
        shift_std = frame.pivot(index="block", columns="mode", values="model_shift_std")
        with np.errstate(invalid="ignore", divide="ignore"):
            shift = shift_std.sort_index() / std
    return wide, rel, shift


def health_chart(
    forecast: pd.DataFrame,
    options: HealthOptions | None = None,
    *,
    reference: HealthReference | None = None,
) -> HealthResult:
    """Structural-health control chart of a forecast table's frequency residuals.

    Parameters
    ----------
    forecast : DataFrame
        FORECAST contract (:func:`workbench.forecasting.sliding_forecast`): per block and mode
        the SSI frequency, the model prediction and its 95 % bounds.
    options : HealthOptions, optional
    reference : HealthReference, optional
        The in-control state learned on an earlier voyage (a saved baseline,
        :mod:`workbench.shm.baseline`): every block is charted from the first, none
        is a reference block.

    Returns
    -------
    HealthResult

    Raises
    ------
    ContractError
        *forecast* violates the FORECAST contract.
    ValueError
        Too few blocks or modes for the reference period (message names the blocks).

    Notes
    -----
    1. *Residuals.* r = (f_SSI - f_model) / s_pred per block and mode, with s_pred the
       prediction standard deviation read from the 95 % bounds, (upper - lower) / (2 · 1.96).
       The model should be frozen over the reference and monitoring periods (method 1, or
       :func:`~workbench.shm.fit_operational_model`, trained before the reference
       period): a model re-trained on recent blocks (method 2) absorbs a persistent change
       within about one training window. With ``common_shift``, each block's median
       relative residual over its modes is removed first: a change of the whole hull's
       mass or stiffness (fuel, steel temperature) moves every frequency by about the same
       fraction, while a local stiffness loss moves the modes that strain the damaged
       region [4]_; the median over modes ignores a shift confined to one or two modes.
    2. *Reference.* Per mode, over the reference blocks that have it (missing modes per
       block are simply absent), location μ = median and scale σ = 1.4826 MAD, robust to
       wrong poles and mislabelled modes; x = clip((r - μ)/σ, ±c). Modes present in fewer
       than ``min_valid_fraction`` of the reference blocks with data (a residual of any
       mode) are not charted.
    3. *Chart.* MEWMA [1]_: z_k = z_{k-1} + λ (x_k - z_{k-1}) per mode, held where a mode
       has no residual; T²_k = z_kᵀ (Σ_z + D_k)⁻¹ z_k. D_k is diagonal, the squared
       ``model_shift_std`` of the forecast table (when it has that column and
       ``model_uncertainty`` is on) in the chart's units: the variance of the model's
       error at block k minus its mean error over the reference, which the location μ
       learned away. That error is persistent, so it reaches z undamped: when the ship
       operates outside what the model was trained on, the chart widens by what the
       model cannot know instead of alarming on it (a novelty test in the sense of
       [5]_ on the residuals, not on the operating conditions). With ``decrease_only``
       (default) each z_j is reflected at 0, z_j = min(0, ...): a loss of stiffness ΔK ⪰ 0
       can only lower the eigenvalues ω² of (K - ΔK) φ = ω² M φ (Courant-Fischer min-max),
       so only decreases are charted and model errors can alarm in half the directions.
    4. *Limit with autocorrelation and estimation error.* Residuals of 75 %-overlapping
       blocks are correlated, and model errors vary over hours, so neither λ/(2-λ) I nor a
       χ² quantile holds; and μ, σ come from a finite reference, whose error shifts the
       whole monitoring period [2]_. Each of ``bootstrap_days`` replicates resamples the
       reference residuals as moving blocks of ``bootstrap_block_length`` [3]_ (24 blocks,
       2 h, longer than the EWMA's memory, so the long-run variance is kept; 4-block runs
       lose a third of it) into a reference period of the same length, from which μ*, σ*
       are estimated, followed by one day standardised with them. Σ_z is the second moment
       of the replicates' EWMA on their day; ``covariance='pooled'`` (default) keeps only
       its mean diagonal, κ I: the reference holds too few independent stretches to
       estimate 28 covariances of a 7-mode, strongly autocorrelated series, and an
       underestimated variance in one direction alarms on it. The limit (``'day_max'``,
       default) is the exp(-``false_alarms_per_day``) quantile of the replicates' daily
       maximum of T², so that a day passes without a false alarm with probability
       exp(-rate) (``'upcrossings'``: the smallest h whose upcrossings stay at the rate).
       Measured over 10 seeds in ``benchmarks/bench_health.py`` (results in
       ``benchmarks/results/health.txt``).
    5. *Evidence.* T² = Σ_j z_j ((Σ_z + D_k)⁻¹ z)_j; the shares at the peak of an episode
       name the modes that moved; the top mode's median relative residual over the episode
       minus its reference median estimates its frequency shift (a stiffness loss k lowers
       the frequency by about k/2).
    6. *CUSUM* (``statistic='cusum'``, default). A damage lowers one or a few modes by a
       step; the CUSUM is the optimal chart for a step of known size [6]_ [7]_, and the
       maximum over per-mode charts does not dilute one mode's change among p - 1 quiet
       ones as T² does. Per mode, S_k = max(0, S_{k-1} - x_k - K_k) on the standardised
       residuals x (step 2; about a fixed location, their units are the mean and standard
       deviation of the reference's Gaussian core, the residuals within 3.5 robust
       standard deviations, :func:`trimmed_location_scale`), with the reference value
       K = δ/2 for the smallest drop worth detecting, δ = ``detect_shift`` over the mode's
       scale of relative residuals (at most ``clip_sigma``, the largest residual the chart
       takes at face value), and K_k = K + g e_k with e_k = √(max(0, s_k² - s̄²)): s_k
       the model's persistent error at the block (``model_shift_std`` in chart units),
       s̄ its root mean square over the reference, g = ``model_error_sigma``; what the
       model cannot know beyond what the limits hold against does not accumulate.
       Decision intervals H_j come from in-control residuals simulated as the reference's
       arise (:func:`cusum_limits`): each block's error is the mean of length/step
       independent segment errors (so the long-run variance is length/step times the
       variance, or more when the reference's Bartlett estimate pooled over the modes
       says so), with the variance of the reference's Gaussian core; wrong poles
       (standardised residuals beyond 3.5) at the reference's rate, clipped like the
       chart's; missing estimates at the reference's rate (the CUSUM holds); and in each
       simulated day a persistent offset N(0, s̄_j²), the model's error in the reference's
       own conditions. Each replicate re-estimates location and scale from a simulated
       reference of the real one's length (their estimation error is part of the
       limit [2]_), and H_j is the exp(-rate/p) quantile of mode j's daily maximum
       (Šidák's split of the daily rate over the p modes). The statistic is max_j S_j/H_j
       with limit 1; the shares are S_j/H_j over their sum; the shift of the top mode is
       its mean relative residual since S_j last left 0 (the CUSUM's change-point
       estimate [7]_). Calibrated by simulation rather than by bootstrap of the reference:
       the tail of a CUSUM's daily maximum from one reference day resampled varied by a
       factor 2-5 between modes and seeds, while the overlap structure is known. An
       earlier simulation inflated every residual to the total variance, left out the
       missing estimates, used the MAD's less efficient scale and counted no model error
       in the limits while adding 1.645 s_k to K: H was well above the value for known
       parameters and the fitted model had far fewer false alarms than designed. The
       false-alarm rate against the design (1 - exp(-0.1) = 9.5 % of days) and the
       detection delays are measured in ``benchmarks/results/health.txt`` ("CALIBRATED
       CUSUM LIMITS", fitted model, seeds 0-39). Neither prewhitening nor a window-limited
       GLR can do better here: the mean of four 5-min segment errors is a moving average
       with its roots on the unit circle (no stable innovations), and a CUSUM on the
       segment errors themselves, were they observed, has the same delays as the CUSUM of
       the blocks, as has a 48-block GLR (simulated with known parameters, same file). The
       CUSUM of the fixed location is the reference's; with a following
       baseline (step 7) the chart keeps the median and MAD and the simulation without
       the wrong poles' and model error's detail (the baseline's own error is not in it).
    7. *Following baseline* (``baseline_hours``): for a drift no logged predictor
       explains, the location follows Brown's linear exponential smoothing [8]_ of the
       residuals from the reference's straight line on (see :class:`HealthOptions`).

    References
    ----------
    .. [1] C. A. Lowry, W. H. Woodall, C. W. Champ, S. E. Rigdon, "A multivariate
       exponentially weighted moving average control chart", Technometrics 34(1), 1992.
       doi:10.1080/00401706.1992.10485232
    .. [2] W. A. Jones-Farmer, W. H. Woodall, S. H. Steiner, C. W. Champ, "An overview of
       Phase I analysis for process improvement and monitoring", Journal of Quality
       Technology 46(3), 2014. doi:10.1080/00224065.2014.11917969
    .. [3] H. R. Künsch, "The jackknife and the bootstrap for general stationary
       observations", Annals of Statistics 17(3), 1989. doi:10.1214/aos/1176347265
    .. [4] A.-M. Yan, G. Kerschen, P. De Boe, J.-C. Golinval, "Structural damage diagnosis
       under varying environmental conditions - Part I: a linear analysis", Mechanical
       Systems and Signal Processing 19(4), 2005. doi:10.1016/j.ymssp.2004.12.002
    .. [5] K. Worden, G. Manson, N. R. J. Fieller, "Damage detection using outlier
       analysis", Journal of Sound and Vibration 229(3), 2000. doi:10.1006/jsvi.1999.2514
    .. [6] E. S. Page, "Continuous inspection schemes", Biometrika 41(1/2), 1954.
       doi:10.1093/biomet/41.1-2.100
    .. [7] D. C. Montgomery, "Introduction to Statistical Quality Control", 7th ed.,
       Wiley, 2013, sections 9.1 (tabular CUSUM, K = δ/2, the change-point and shift
       estimates) and 10.4 (autocorrelated data).
    .. [8] R. G. Brown, "Smoothing, Forecasting and Prediction of Discrete Time
       Series", Prentice-Hall, 1963 (double exponential smoothing).
    """
    from .monitor import HealthMonitor

    options = options or HealthOptions()
    table = FORECAST.validate(forecast)
    if options.option is not None and not (table["option"] == options.option).any():
        raise ValueError(f"forecast has no rows for option {options.option!r}")
    monitor = HealthMonitor(options, reference=reference)
    update = monitor.update(table)
    if monitor.reference is None:
        raise ValueError(monitor.waiting_reason())
    return HealthResult(
        table=set_grid(update.health, recorded_grid(forecast)),
        alarms=update.alarms,
        reference=monitor.reference,
        options=options,
    )


def learn_reference(
    residuals: np.ndarray,
    relative: np.ndarray,
    modes: tuple[int, ...],
    blocks: np.ndarray,
    blocks_per_day: float,
    options: HealthOptions,
    overlap_ratio: float = 1.0,
    model_shift: np.ndarray | None = None,
) -> HealthReference:
    """Learn the in-control state from the reference blocks (steps 2 and 4 of
    :func:`health_chart`).

    Parameters
    ----------
    residuals, relative : ndarray, shape (n_reference_blocks, n_modes)
        Prediction-standardised and relative residuals of the reference blocks (NaN where
        a mode has no estimate), columns in the order of *modes*.
    modes : tuple of int
        Modes seen in the reference blocks.
    blocks : ndarray of int
        The reference blocks.
    blocks_per_day : float
        Block steps per day. [1/day]
    options : HealthOptions
    overlap_ratio : float
        Block length over block step (4 for 20-min blocks every 5 min): the floor of the
        residuals' long-run variance in units of their variance. [-]
    model_shift : ndarray, shape (n_reference_blocks, n_modes), optional
        The forecast's ``model_shift_std`` of the reference blocks in prediction-standardised
        units (as *residuals*); NaN or None where the forecast has none.
    """
    first_block, last_block = int(blocks[0]), int(blocks[-1])
    # a mode's share of the reference blocks with data: a block of a hole in the
    # accelerations (no mode has a residual) is no block a mode was absent from
    finite = np.isfinite(residuals)
    with_data = finite.any(axis=1)
    valid_share = finite[with_data].mean(axis=0) if with_data.any() else np.zeros(len(modes))
    keep = valid_share >= options.min_valid_fraction
    charted = tuple(m for m, k in zip(modes, keep, strict=True) if k)
    excluded = tuple(m for m, k in zip(modes, keep, strict=True) if not k)
    if not charted:
        raise ValueError(
            f"no mode has residuals in {options.min_valid_fraction:.0%} of the reference "
            f"blocks {first_block}-{last_block}"
        )
    ref = residuals[:, keep]
    trend_slope = None
    if options.baseline_hours is not None:
        # a following baseline: the reference may hold a drift the model does not explain
        # (fuel burn); the in-control scatter is measured about each mode's line, and the
        # baseline starts from the line's value at the reference end
        trend_slope, trend_end = _robust_lines(ref, blocks - blocks[-1])
        ref = ref - (trend_end + np.outer(blocks - blocks[-1], trend_slope))
    # the CUSUM about a fixed location is calibrated by a simulation of the reference's
    # own errors (Notes of health_chart, step 6): its units are the Gaussian core's mean
    # and standard deviation; the MEWMA and a following baseline keep the median and MAD
    detailed = options.statistic == "cusum" and options.baseline_hours is None
    estimate = trimmed_location_scale if detailed else _robust_location_scale
    location, scale = estimate(ref)
    if not np.all(scale > 0):
        raise ValueError(
            f"reference blocks {first_block}-{last_block}: a mode's residuals do not vary"
        )
    with np.errstate(invalid="ignore"):
        ref_x = np.clip((ref - location) / scale, -options.clip_sigma, options.clip_sigma)
    p = len(charted)
    rng = np.random.default_rng(options.seed)
    monitor_blocks = int(round(blocks_per_day))
    n_replicates = int(math.ceil(options.bootstrap_days))
    # replicate r: a resampled reference period of the same length (its own location and
    # scale) followed by one day resampled independently, standardised with them
    streams = np.stack(
        [
            _moving_block_bootstrap(
                ref, len(ref) + monitor_blocks, options.bootstrap_block_length, rng
            )
            for _ in range(n_replicates)
        ],
        axis=1,
    )  # (steps, replicates, modes)
    rep_location, rep_scale = _robust_location_scale(streams[: len(ref)])
    with np.errstate(invalid="ignore", divide="ignore"):
        rep_x = np.clip(
            (streams - rep_location) / rep_scale, -options.clip_sigma, options.clip_sigma
        )
    rep_ewma = ewma_hold(rep_x, options.ewma_lambda, ceiling=options.ewma_ceiling)[
        len(ref) :
    ]  # (day, replicates, modes)
    pooled = rep_ewma.reshape(-1, p)
    ewma_covariance = pooled.T @ pooled / len(pooled)  # second moment about the target 0
    if options.covariance == "diagonal":
        ewma_covariance = np.diag(np.diag(ewma_covariance))
    elif options.covariance == "pooled":
        ewma_covariance = float(np.mean(np.diag(ewma_covariance))) * np.eye(p)
    boot_t2 = hotelling(pooled, ewma_covariance)[0].reshape(monitor_blocks, n_replicates)
    if options.limit_method == "day_max":
        # P(some alarm in a day) = 1 - exp(-rate) for Poisson episodes at *rate* per day
        limit = float(np.quantile(boot_t2.max(axis=0), math.exp(-options.false_alarms_per_day)))
    else:
        limit = _limit_for_rate(boot_t2, options.false_alarms_per_day, blocks_per_day)
    boot_rate = upcrossings_per_day(boot_t2, limit, blocks_per_day)
    correlation = np.corrcoef(np.nan_to_num(pooled), rowvar=False).reshape(p, p)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        relative_median = np.nanmedian(relative[:, keep], axis=0)
    if trend_slope is not None:
        location = location + trend_end  # the line at the reference end
    allowance = mode_limits = offset_std = None
    if options.statistic == "cusum":
        # K_j: half the smallest drop worth detecting, in mode j's standardised units
        # (its relative residuals' robust scale is one unit)
        relative_ref = relative[:, keep]
        if trend_slope is not None:  # scatter about each mode's drift line, as above
            rel_slope, rel_end = _robust_lines(relative_ref, blocks - blocks[-1])
            relative_ref = relative_ref - (rel_end + np.outer(blocks - blocks[-1], rel_slope))
        relative_scale = estimate(relative_ref)[1]
        if not np.all(relative_scale > 0):
            raise ValueError(
                f"reference blocks {first_block}-{last_block}: a mode's relative residuals "
                "do not vary"
            )
        # capped at the clip: residuals beyond ±clip_sigma are not trusted (wrong poles),
        # so for a very precise mode the chart looks for a drop of clip_sigma scales
        # (smaller than detect_shift, found as fast)
        allowance = 0.5 * np.minimum(options.detect_shift / relative_scale, options.clip_sigma)
        # H_j from simulated in-control residuals with the reference's autocorrelation:
        # the blocks' overlap makes the long-run variance length/step times the variance
        # (a floor: slow model errors can only add); the kernel estimate pooled over the
        # modes (the overlap is common to them) raises it when the residuals wander more
        per_mode = long_run_std(ref_x, min(options.bootstrap_block_length, len(ref) // 4))
        variance = float(np.nanmean(np.nanvar(ref_x, axis=0)))
        ratio = max(float(np.mean(per_mode**2)) / variance, overlap_ratio)
        simulated = {"variance": variance, "trimmed": False}
        if detailed:
            # the reference's wrong poles (beyond OUTLIER_SIGMA) and missing estimates as
            # they are, the Gaussian core's variance, and the model's persistent error in
            # the reference's own conditions as a random offset of each simulated day
            # (the allowance then takes only what a block's model error exceeds it by)
            finite = np.isfinite(ref_x)
            wild = finite & (np.abs(np.nan_to_num(ref_x)) >= OUTLIER_SIGMA)
            core = np.where(finite & ~wild, ref_x, np.nan)
            offset_std = np.zeros(p)
            if model_shift is not None and options.model_uncertainty:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    mean_square = np.nanmean((model_shift[:, keep] / scale) ** 2, axis=0)
                offset_std = np.sqrt(np.nan_to_num(mean_square, nan=0.0))
            simulated = {
                "variance": float(np.nanmean(np.nanvar(core, axis=0)))
                / truncated_normal_variance(OUTLIER_SIGMA),
                "trimmed": True,
                "outlier_rate": float(wild.sum() / max(finite.sum(), 1)),
                "missing_rate": float(1.0 - finite.mean()),
                "offset_std": offset_std,
            }
        mode_limits = cusum_limits(
            allowance,
            InControlResiduals(segments=max(int(round(ratio)), 1), **simulated),
            reference_blocks=len(ref),
            blocks_per_day=blocks_per_day,
            false_alarms_per_day=options.false_alarms_per_day,
            replicates=n_replicates,
            clip_sigma=options.clip_sigma,
            rng=rng,
        )
        mode_limits = np.maximum(mode_limits, allowance)  # never 0: S/H stays defined
        rep_cusum = cusum_hold(rep_x, allowance)[len(ref) :]  # (day, replicates, modes)
        boot_statistic = (rep_cusum / mode_limits).max(axis=2)
        limit = 1.0
        boot_rate = upcrossings_per_day(boot_statistic, limit, blocks_per_day)
    return HealthReference(
        modes=charted,
        start_block=first_block,
        end_block=last_block,
        location=location,
        scale=scale,
        correlation=correlation,
        ewma_covariance=ewma_covariance,
        limit=limit,
        blocks_per_day=blocks_per_day,
        bootstrap_false_alarms_per_day=boot_rate,
        excluded_modes=excluded,
        relative_median=relative_median,
        statistic=options.statistic,
        allowance=allowance,
        mode_limits=mode_limits,
        trend_slope=trend_slope,
        model_offset_std=offset_std if allowance is not None else None,
    )


def _robust_lines(values: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column, slope and value at t = 0 of a least-squares line through the finite
    values, refitted once without those beyond 4 robust standard deviations (wrong poles).
    """
    slopes, ends = np.zeros(values.shape[1]), np.zeros(values.shape[1])
    for j in range(values.shape[1]):
        use = np.isfinite(values[:, j])
        for _ in range(2):
            if use.sum() < 3:
                break
            slope, end = np.polyfit(t[use], values[use, j], 1)
            residual = values[:, j] - (end + slope * t)
            scale = 1.4826 * np.nanmedian(np.abs(residual[use]))
            with np.errstate(invalid="ignore"):
                use = np.isfinite(values[:, j]) & (np.abs(residual) <= 4.0 * max(scale, 1e-12))
            slopes[j], ends[j] = slope, end
    return slopes, ends
