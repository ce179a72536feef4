"""Options of the structural-health chart (:func:`~workbench.shm.chart.health_chart`,
:class:`~workbench.shm.monitor.HealthMonitor`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = ["HealthOptions"]


@dataclass(frozen=True)
class HealthOptions:
    """Options of :func:`~workbench.shm.chart.health_chart`.

    Parameters
    ----------
    reference_blocks : int
        Length of the reference period, in blocks (72: 6 h of 5-min steps). It must be out
        of sample for the forecast model and span the operating conditions. [blocks]
    reference_start_block : int, optional
        First block of the reference period; default the first block in the forecast
        phase (the first block the model did not train on).
    option : {"A", "B"}, optional
        Forecast option whose rows are used; default A when present, else B.
    ewma_lambda : float
        EWMA weight λ of the newest block, z_k = z_{k-1} + λ (x_k - z_{k-1}). 0.1 averages
        over about (2 - λ)/λ = 19 blocks (1.6 h). [-]
    false_alarms_per_day : float
        Target rate of false alarm episodes in control; with ``limit_method='day_max'`` a
        day passes without one with probability exp(-rate). [1/day]
    clip_sigma : float
        Standardised residuals are clipped to ±this, so one wrong pole cannot raise an
        alarm alone. [-]
    bootstrap_block_length : int
        Length of the moving blocks resampled from the reference period to build the
        in-control series. 20-min blocks every 5 min share data with the next 3 blocks
        (errors correlated up to lag 3) and model errors vary over hours; runs of 24 blocks
        (2 h, longer than the EWMA's memory) keep the long-run variance. [blocks]
    bootstrap_days : float
        Number of resampled in-control days (replicates) the limit is read from. [day]
    min_valid_fraction : float
        A mode needs a residual in at least this share of the reference blocks to be
        charted. [-]
    seed : int
        Seed of the bootstrap.
    limit_method : {"day_max", "upcrossings"}
        Control limit from the bootstrap: the quantile of the daily maximum of T² (a day
        without false alarm with probability exp(-rate)), or the smallest limit whose
        upcrossings per day stay at the rate.
    common_shift : bool
        Remove each block's median relative residual over its modes (a change of the
        whole hull's mass or stiffness) before charting.
    covariance : {"pooled", "diagonal", "full"}
        In-control covariance of the EWMA vector from the bootstrap: its mean variance
        times the identity, its diagonal, or all of it.
    model_uncertainty : bool
        Add the forecast's ``model_shift_std`` (when present) to the covariance of each
        block (see Notes of :func:`~workbench.shm.chart.health_chart`).
    decrease_only : bool
        Chart only decreases of the frequencies: each mode's EWMA is reflected at 0,
        z_k = min(0, ...). A loss of stiffness can only lower natural frequencies, so this
        keeps the sensitivity to damage and halves the directions model errors can alarm
        in; an increase (a mode stiffening) is then not reported. The CUSUM charts
        decreases only.
    statistic : {"cusum", "mewma"}
        ``'cusum'`` (default): a lower one-sided CUSUM per mode, tuned to
        ``detect_shift``, the modes combined by their maximum with limits from the
        bootstrap (Notes of :func:`~workbench.shm.chart.health_chart`); the most powerful chart for a step
        change of one mode. ``'mewma'``: the MEWMA Hotelling T² of all modes together
        (better for a change spread thinly over many modes).
    detect_shift : float
        CUSUM: smallest relative drop of one mode's frequency worth detecting, 0.005 for
        a 1 % stiffness loss (f ∝ √k). Each mode's reference value (allowance) is half of
        it in that mode's residual units. [-]
    model_error_sigma : float
        CUSUM: the allowance of each block grows by this many of the model's persistent
        error standard deviations (``model_shift_std``) beyond the reference's own (which
        the limits hold against), so the chart does not accumulate what the model cannot
        know (1.645: one-sided 95 %; 1.0 let a transit out of the training range alarm,
        ``benchmarks/results/health.txt``, "model_error_sigma 1.0"). [-]
    baseline_hours : float, optional
        Let each mode's in-control location follow the residuals slowly (None: the
        reference's location, fixed), for a drift no logged predictor explains (fuel burn
        without tank soundings, ballast). The reference is then measured about each
        mode's straight line; from its end, the location is Brown's linear exponential
        smoothing of the residuals (Brown 1963, see :func:`~workbench.shm.chart.health_chart`) with ω = exp(-step/T): level and slope, so a
        steady drift is followed without lag; held while the chart alarms. The cost: a
        step is taken in at about 2/T per hour of its size until detected (17 % after 2 h
        with T = 24 h), and a loss that grows steadily is followed once T or so has
        passed: only its onset can be detected. [h]
    """

    reference_blocks: int = 72
    reference_start_block: int | None = None
    option: Literal["A", "B"] | None = None
    ewma_lambda: float = 0.1
    false_alarms_per_day: float = 0.1
    clip_sigma: float = 4.0
    bootstrap_block_length: int = 24
    bootstrap_days: float = 400.0
    min_valid_fraction: float = 0.5
    seed: int = 0
    limit_method: Literal["day_max", "upcrossings"] = "day_max"
    common_shift: bool = False
    covariance: Literal["pooled", "diagonal", "full"] = "pooled"
    model_uncertainty: bool = True
    decrease_only: bool = True
    statistic: Literal["cusum", "mewma"] = "cusum"
    detect_shift: float = 0.0075
    model_error_sigma: float = 1.645
    baseline_hours: float | None = None

    @property
    def ewma_ceiling(self) -> float | None:
        """Reflecting barrier of the EWMA: 0 when only decreases are charted."""
        return 0.0 if self.decrease_only else None

    def __post_init__(self) -> None:
        if int(self.reference_blocks) != self.reference_blocks or self.reference_blocks < 12:
            raise ValueError(f"reference_blocks={self.reference_blocks!r} must be an integer >= 12")
        if not 0.0 < self.ewma_lambda <= 1.0:
            raise ValueError(f"ewma_lambda={self.ewma_lambda!r} must be in (0, 1]")
        if not (math.isfinite(self.false_alarms_per_day) and self.false_alarms_per_day > 0):
            raise ValueError(
                f"false_alarms_per_day={self.false_alarms_per_day!r} must be finite and > 0"
            )
        if self.reference_start_block is not None and not (
            int(self.reference_start_block) == self.reference_start_block
            and self.reference_start_block >= 0
        ):
            raise ValueError(
                f"reference_start_block={self.reference_start_block!r} must be a block number "
                "(an integer >= 0)"
            )
        if not self.clip_sigma > 0:
            raise ValueError(f"clip_sigma={self.clip_sigma!r} must be > 0")
        if self.bootstrap_block_length < 1:
            raise ValueError(f"bootstrap_block_length={self.bootstrap_block_length!r} must be >= 1")
        if not self.bootstrap_days * self.false_alarms_per_day >= 10:
            raise ValueError(
                f"bootstrap_days={self.bootstrap_days!r} must give at least 10 expected false "
                f"alarms at false_alarms_per_day={self.false_alarms_per_day!r}"
            )
        if not 0.0 < self.min_valid_fraction <= 1.0:
            raise ValueError(f"min_valid_fraction={self.min_valid_fraction!r} must be in (0, 1]")
        if self.limit_method not in ("day_max", "upcrossings"):
            raise ValueError(
                f"limit_method={self.limit_method!r} must be 'day_max' or 'upcrossings'"
            )
        if self.covariance not in ("pooled", "diagonal", "full"):
            raise ValueError(
                f"covariance={self.covariance!r} must be 'pooled', 'diagonal' or 'full'"
            )
        if self.option not in (None, "A", "B"):
            raise ValueError(f"option={self.option!r} must be 'A', 'B' or None")
        if self.statistic not in ("cusum", "mewma"):
            raise ValueError(f"statistic={self.statistic!r} must be 'cusum' or 'mewma'")
        if self.statistic == "cusum" and not self.decrease_only:
            raise ValueError(
                "decrease_only=False needs statistic='mewma' (the CUSUM charts decreases only)"
            )
        if not (math.isfinite(self.detect_shift) and 0.0 < self.detect_shift < 0.5):
            raise ValueError(f"detect_shift={self.detect_shift!r} must be in (0, 0.5)")
        if not (math.isfinite(self.model_error_sigma) and self.model_error_sigma >= 0):
            raise ValueError(f"model_error_sigma={self.model_error_sigma!r} must be >= 0")
        if self.baseline_hours is not None and not (
            math.isfinite(self.baseline_hours) and self.baseline_hours > 0
        ):
            raise ValueError(f"baseline_hours={self.baseline_hours!r} must be positive or None")
