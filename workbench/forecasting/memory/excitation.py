"""Excitation bias of the memory forecast: κ pooled over the modes, de-biased refits, and
the model of what SSI sees in a block whose speed changes.

Physics in :mod:`workbench.forecasting.excitation`; used by
:func:`~workbench.forecasting.memory.forecast.memory_forecast`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..excitation import sub_windows_per_block, within_block_variance
from ..options import ForecastOptions
from .model import MemoryModel

__all__ = ["ExcitationBias", "excitation_bias"]

#: Largest excitation sensitivity d ln P / dv accepted: the response power at most
#: doubling per knot. [1/kn]
_MAX_KAPPA = float(np.log(2.0))


def _excitation_statistics(fitted, X, y, age, speed_col, speed_var, memory, limit):
    """Weighted normal-equation terms of κ for one mode, and the model's speed slope.

    With d_k = ∂m/∂v the model's speed slope at block k (1-kn difference) the
    measurement's excitation bias is d_k κ σ_k² (:mod:`~workbench.forecasting.excitation`);
    the least-squares κ of the residuals r_k on g_k = d_k σ_k², with forgetting weights
    w_k, is Σ w g r / Σ w g². Each mode's sums are divided by its residual variance, so
    that κ (a property of the excitation, common to all modes) is pooled by precision.

    Returns
    -------
    (numerator, denominator, slope) or None
    """
    ok = np.isfinite(y) & (speed_var > 0)
    if ok.sum() < 3:
        return None
    Xp = X.copy()
    Xp[:, speed_col] += 1.0
    base = fitted.predict(X, limit)[0]
    slope = fitted.predict(Xp, limit)[0] - base  # ∂m/∂v [Hz/kn]
    g = slope * speed_var
    w = np.exp(-age / memory) / fitted.residual_variance
    good = ok & np.isfinite(g) & np.isfinite(base)
    if not good.any():
        return None
    numerator = float((w[good] * g[good] * (y[good] - base[good])).sum())
    denominator = float((w[good] * g[good] ** 2).sum())
    return numerator, denominator, slope


def _debiased_refit(fitted, X, y, age, bias, memory, limit):
    """Refit *fitted*'s terms on the targets minus the excitation bias (time averages)."""
    debiased = y - np.where(np.isfinite(bias), bias, 0.0)
    refitted = fitted.refit(X, debiased, age, memory_blocks=memory, limit=limit)
    return fitted if refitted is None else refitted


@dataclass
class ExcitationBias:
    """κ per mode and the within-block speed variance of one forecast's predictor grid."""

    X_all: np.ndarray
    speed_col: int | None
    speed_var: np.ndarray | None  # within-block speed variance σ_v² [kn²]; None: no term
    shift_cap: np.ndarray | None  # largest speed shift sqrt(n - 1) σ_v [kn]
    kappa: np.ndarray  # excitation sensitivity d ln P / dv per mode [1/kn]
    first: int
    history_limit: int
    memory: float
    limit: float

    def refit(self, fits: list, i: int, train_y: list) -> None:
        """κ pooled over the modes whose model has a speed term; refit those de-biased.

        κ is constrained to [0, ln 2 per kn]: excitation grows with speed (κ >= 0), and no
        realistic hull response more than doubles its power per knot. The shift κ σ_k² is
        capped at sqrt(n - 1) σ_k (a weighted mean of the block's n sub-windows cannot lie
        further from their mean). The refit on y - d κ σ² makes the state model a model of
        the time averages, not of the excitation-weighted history.
        """
        kappa, speed_var, shift_cap = self.kappa, self.speed_var, self.shift_cap
        first, history_limit, X_all = self.first, self.history_limit, self.X_all
        speed_col, memory, limit = self.speed_col, self.memory, self.limit
        kappa[:] = 0.0
        if speed_var is None:
            return
        lo = max(first, i - history_limit)
        age = (i - 1 - np.arange(lo, i)).astype(float)
        stats = {}
        for j, fitted in enumerate(fits):
            if fitted is None or fitted.kind == "constant" or speed_col not in fitted.columns:
                continue
            found = _excitation_statistics(
                fitted,
                X_all[lo:i],
                train_y[j],
                age,
                speed_col,
                speed_var[lo:i],
                memory,
                limit,
            )
            if found is not None:
                stats[j] = found
        denominator = sum(d for _, d, _ in stats.values())
        if not denominator > 0:
            return
        # constrained least squares: the sign of the bias is known from physics, so no
        # significance gate (on the block-level regimes a 2-standard-error gate changed the
        # scores by less than 1 point; it only withheld the term on short histories)
        pooled = sum(n for n, _, _ in stats.values()) / denominator
        pooled = min(max(pooled, 0.0), _MAX_KAPPA)
        if pooled == 0.0:
            return
        shift = np.minimum(pooled * speed_var[lo:i], shift_cap[lo:i])
        for j, (_, _, slope) in stats.items():
            fits[j] = _debiased_refit(
                fits[j], X_all[lo:i], train_y[j], age, slope * shift, memory, limit
            )
            kappa[j] = pooled

    def seen_by_ssi(self, m: MemoryModel, rows_: np.ndarray, j: int, mean: np.ndarray):
        """Model of the measurement: the model at the excitation-weighted speed."""
        kappa, speed_var, shift_cap = self.kappa, self.speed_var, self.shift_cap
        X_all, speed_col, limit = self.X_all, self.speed_col, self.limit
        if kappa[j] <= 0 or speed_var is None:
            return mean
        X = X_all[rows_].copy()
        X[:, speed_col] += np.minimum(kappa[j] * speed_var[rows_], shift_cap[rows_])
        seen = m.predict(X, limit)[0]
        return np.where(np.isfinite(seen), seen, mean)


def excitation_bias(
    grid,
    X_all: np.ndarray,
    columns: list[str],
    options: ForecastOptions,
    *,
    n_modes: int,
    first: int,
    history_limit: int,
) -> ExcitationBias:
    """The :class:`ExcitationBias` of a predictor grid (no term without speed or sub-windows,
    none unless ``options.excitation_bias``)."""
    # SSI's excitation weighting: in a block whose speed changes, SSI sees the frequency at
    # about v̄ + κ σ_v² (workbench.forecasting.excitation); σ_v² from the overlapping blocks
    speed_col = columns.index("speed_kn") if "speed_kn" in columns else None
    n_sub = sub_windows_per_block(grid) if options.excitation_bias else None
    speed_var = shift_cap = None
    if n_sub is not None and speed_col is not None:
        speed_var = within_block_variance(X_all[:, speed_col], n_sub)
        speed_var = np.where(np.isfinite(speed_var), speed_var, 0.0)
        # a weighted mean of n sub-windows lies at most sqrt(n - 1) σ from their mean
        shift_cap = np.sqrt((n_sub - 1) * speed_var)
        if not speed_var.max(initial=0.0) > 0:
            speed_var = None
    return ExcitationBias(
        X_all,
        speed_col,
        speed_var,
        shift_cap,
        np.zeros(n_modes),
        first,
        history_limit,
        float(options.memory_blocks),
        float(options.extrapolation_limit),
    )
