"""What SSI sees in a block whose speed changes: the within-block speed profile.

SSI estimates a block's modal frequency from the block's output covariances, sums over
time of y_t y_{t+i}ᵀ, so each part of the block counts with its response power. The power
grows with speed (wave and propeller excitation), so in a block in which the ship changes
speed SSI weights the faster part: the identified frequency is about the
excitation-weighted average of the frequency over the block, while the block's truth (and
the predictors, time averages) belong to the time average. To first order, with P(v) the
response power at speed v and w_i = P(v_i) / Σ P the weights of the block's parts,

.. math::

    \\tilde v - \\bar v = \\sum_i w_i (v_i - \\bar v)
        \\approx \\sigma_v^2 \\, \\frac{d \\ln P}{d v}, \\qquad
    z - f(\\bar v) \\approx f'(\\bar v) \\, \\sigma_v^2 \\, \\frac{d \\ln P}{d v},

with σ_v² the variance of the speed inside the block. The bias of the SSI estimate is
therefore proportional to σ_v² (and always towards the faster part's frequency, whatever
the sign of the speed change). The memory model (:mod:`workbench.forecasting.memory.forecast`) writes
the measurement equation as its model evaluated at the excitation-weighted speed
v̄ + κ σ_v², κ = d ln P / dv >= 0 estimated from the data and shared by the modes (it is a
property of the excitation), while the state, the block's time average, is the model at
v̄. No excitation law is assumed, only that power grows with speed.

σ_v² is not in a block predictor table, but overlapping blocks carry it: a block of L
seconds, a new one every L / n seconds, is the mean of n consecutive sub-windows, so the
block means of the last few blocks determine the sub-window means up to an n-periodic
pattern; the smoothest sub-window sequence that reproduces them
(:func:`within_block_profile`) uses only blocks that have ended (no look-ahead).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["sub_windows_per_block", "within_block_profile", "within_block_variance"]


def sub_windows_per_block(grid: pd.DataFrame) -> int | None:
    """n when the blocks are n-fold overlapping (length = n x step), else None.

    Needs ``block_start`` and ``block_end``; the step is the median spacing of
    consecutive block numbers' starts. Blocks of varying length (``identify
    --block-minutes auto``) are not the means of a fixed number of sub-windows: None (their
    predictors can be averaged with the excitation's weights instead,
    :func:`~workbench.predictors.averaging.excitation_weighted_predictors`).
    """
    if "block_end" not in grid.columns or len(grid) < 3:
        return None
    start = pd.to_datetime(grid["block_start"], utc=True)
    end = pd.to_datetime(grid["block_end"], utc=True)
    lengths = (end - start).dt.total_seconds().to_numpy()
    if np.ptp(lengths) > 1.0:
        return None
    length_s = float(np.median(lengths))
    blocks = grid["block"].to_numpy(dtype=np.int64)
    d_block = np.diff(blocks)
    d_start = start.diff().dt.total_seconds().to_numpy()[1:]
    step = d_start[d_block == 1]
    if step.size == 0:
        return None
    step_s = float(np.median(step))
    if not (step_s > 0 and length_s > 0):
        return None
    ratio = length_s / step_s
    n = int(round(ratio))
    if n < 2 or abs(ratio - n) > 0.02 or n > 12:
        return None
    return n


def _smoothest_map(n_sub: int, n_blocks: int) -> np.ndarray:
    """Linear map from *n_blocks* consecutive block means to the newest block's sub-windows.

    Unknowns s_0..s_{n_blocks + n_sub - 2}, block k the mean of s_k..s_{k + n_sub - 1};
    minimise Σ (s_{i+1} - s_i)² subject to the block means (KKT system). Returns the rows
    of the last *n_sub* unknowns, shape (n_sub, n_blocks).
    """
    n_unknown = n_blocks + n_sub - 1
    A = np.zeros((n_blocks, n_unknown))
    for k in range(n_blocks):
        A[k, k : k + n_sub] = 1.0 / n_sub
    D = np.diff(np.eye(n_unknown), axis=0)
    kkt = np.zeros((n_unknown + n_blocks, n_unknown + n_blocks))
    kkt[:n_unknown, :n_unknown] = 2.0 * D.T @ D
    kkt[:n_unknown, n_unknown:] = A.T
    kkt[n_unknown:, :n_unknown] = A
    rhs = np.zeros((n_unknown + n_blocks, n_blocks))
    rhs[n_unknown:] = np.eye(n_blocks)
    solution = np.linalg.solve(kkt, rhs)[:n_unknown]
    return solution[-n_sub:]


def within_block_profile(values: np.ndarray, n_sub: int, *, history: int | None = None):
    """Sub-window means of each block from the block means of it and the blocks before.

    Parameters
    ----------
    values : ndarray, shape (n_blocks,)
        Block means on a grid of consecutive blocks (NaN: unknown).
    n_sub : int
        Sub-windows per block (block length / block step).
    history : int, optional
        Blocks used per estimate (the block and the ones before); default 2 n_sub + 1.

    Returns
    -------
    ndarray, shape (n_blocks, n_sub)
        NaN where one of the blocks used is NaN or before the first *history* blocks
        (there the available blocks are used, at least 2).
    """
    values = np.asarray(values, dtype=float)
    history = 2 * n_sub + 1 if history is None else int(history)
    n = values.size
    out = np.full((n, n_sub), np.nan)
    for b in range(1, min(history - 1, n)):  # the first blocks: the blocks so far
        window = values[: b + 1]
        if np.isfinite(window).all():
            out[b] = _smoothest_map(n_sub, b + 1) @ window
    if n >= history:  # the rest at once: every window of *history* blocks
        windows = np.lib.stride_tricks.sliding_window_view(values, history)
        full = windows @ _smoothest_map(n_sub, history).T
        full[~np.isfinite(windows).all(axis=1)] = np.nan
        out[history - 1 :] = full
    return out


def within_block_variance(values: np.ndarray, n_sub: int) -> np.ndarray:
    """Variance of the sub-window means inside each block (:func:`within_block_profile`)."""
    profile = within_block_profile(values, n_sub)
    return profile.var(axis=1)
