"""Each mode's reference shape for option B's MAC check: the consensus of its recent shapes.

A single tracked shape is one pole's shape and carries that pole's identification noise.
Comparing a pole with it compares two noisy shapes: with a relative noise of σ on each
(``‖noise‖ / ‖shape‖``), MAC(pole, reference) is about 1 / (1 + σ²)², against
1 / (1 + σ²) for the same pole and the mode's true shape. With noisy sensors (ice: impulsive
excitation, σ ≈ 0.25) the two-noisy-shapes MAC falls near a threshold of 0.9 for about
half of the mode's own poles, and the MAC check then removes half of the mode's column:
the cluster chosen is shorter, partly the wrong one, or none.

The reference used here is the *consensus* of the mode's last few confirmed tracked shapes,
the phase-aligned mean (the estimate of the common shape, whose noise falls as 1/n), so
that the check compares a pole with (nearly) the mode's shape:

* a tracked shape is confirmed when its MAC with the consensus so far is at least
  ``mac_min`` (a mislabelled tracked pole does not enter the consensus);
* two consecutive tracked shapes that agree with each other (MAC >= ``mac_min``) but not
  with the consensus mean the mode's shape has changed (modes swapped, a loading change):
  the consensus restarts from them;
* only tracked rows at or before a grid row's block are used (no look-ahead).
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pandas as pd

from .pole_selection import _MIN_SHAPE_CHANNELS, _shape_matrix

__all__ = ["CONSENSUS_SHAPES", "consensus_references"]

#: Confirmed tracked shapes averaged into a mode's reference (the last ones). [-]
CONSENSUS_SHAPES = 12


def _mac(a: np.ndarray, b: np.ndarray) -> float:
    """MAC of two shapes on the channels both have (NaN: fewer than 3 shared)."""
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < _MIN_SHAPE_CHANNELS:
        return float("nan")
    a, b = a[ok], b[ok]
    # MAC = |a^H b|² / ((a^H a)(b^H b))
    denominator = np.vdot(a, a).real * np.vdot(b, b).real
    return float(abs(np.vdot(a, b)) ** 2 / denominator) if denominator > 0 else float("nan")


def _aligned_mean(members) -> np.ndarray:
    """Phase-aligned mean of unit-norm complex shapes (NaN: channel missing).

    Each shape is rotated by the phase of its inner product with the newest one (a mode
    shape is defined up to a complex factor), then averaged channel by channel over the
    shapes that have the channel, and scaled to unit norm.
    """
    stack = np.array(members)
    anchor = stack[-1]
    finite = np.isfinite(stack)
    values = np.where(finite, stack, 0.0)
    # rotate each shape by the phase of its inner product with the newest one
    inner = values @ np.conj(np.where(np.isfinite(anchor), anchor, 0.0))
    size = np.abs(inner)
    phase = np.where(size > 0, np.conj(inner) / np.maximum(size, 1e-300), 1.0)
    count = finite.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, (values * phase[:, None]).sum(axis=0) / count, np.nan)
    norm = np.sqrt(np.nansum(np.abs(mean) ** 2))
    return mean / norm if norm > 0 else mean


def _unit(shape: np.ndarray) -> np.ndarray:
    norm = np.sqrt(np.nansum(np.abs(shape) ** 2))
    return shape / norm if norm > 0 else shape


def consensus_references(
    modal: pd.DataFrame,
    blocks: np.ndarray,
    mode_labels: np.ndarray,
    channels,
    *,
    mac_min: float,
    n_shapes: int = CONSENSUS_SHAPES,
) -> tuple[np.ndarray, np.ndarray]:
    """Consensus reference shapes (module docstring) of every mode at every grid row.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table with ``shape_re_<channel>``/``shape_im_<channel>`` columns.
    blocks : ndarray of int
        Grid blocks, ascending.
    mode_labels : ndarray
        Modes, one column each of ``reference_row``.
    channels : sequence of str
        Channels compared (those the pole table has too).
    mac_min : float
        MAC that confirms a tracked shape.
    n_shapes : int
        Confirmed shapes averaged.

    Returns
    -------
    reference_shapes : ndarray, shape (n_references, n_channels), complex
        One consensus per tracked row with a usable shape.
    reference_row : ndarray, shape (n_blocks, n_modes), int
        Row of ``reference_shapes`` in force at each grid row; -1 before the mode's first
        tracked shape.
    """
    n_modes = len(mode_labels)
    reference_row = np.full((blocks.size, n_modes), -1, dtype=np.int64)
    parts = []
    offset = 0
    for j, label in enumerate(mode_labels):
        same = (modal["mode"] == label).to_numpy(dtype=bool, na_value=False)
        rows = modal[same].sort_values("block", kind="stable").drop_duplicates("block", keep="last")
        if rows.empty:
            continue
        shapes = _shape_matrix(rows, channels)
        usable = np.isfinite(shapes).sum(axis=1) >= _MIN_SHAPE_CHANNELS
        shapes = shapes[usable]
        track_blocks = rows["block"].to_numpy(dtype=np.int64)[usable]
        if track_blocks.size == 0:
            continue
        consensus = np.empty_like(shapes)
        members: deque[np.ndarray] = deque(maxlen=int(n_shapes))
        pending = None  # the last tracked shape unlike the consensus
        for r, shape in enumerate(shapes):
            shape = _unit(shape)
            if not members:
                members.append(shape)
            elif _mac(consensus[r - 1], shape) >= mac_min:
                members.append(shape)
                pending = None
            elif pending is not None and _mac(pending, shape) >= mac_min:
                members.clear()  # the mode's shape has changed: restart from the two
                members.extend((pending, shape))
                pending = None
            else:
                pending = shape
            consensus[r] = _aligned_mean(members)
        position = np.searchsorted(track_blocks, blocks, side="right") - 1
        reference_row[:, j] = np.where(position >= 0, offset + np.maximum(position, 0), -1)
        parts.append(consensus)
        offset += consensus.shape[0]
    reference_shapes = (
        np.concatenate(parts) if parts else np.empty((0, len(channels)), dtype=complex)
    )
    return reference_shapes, reference_row
