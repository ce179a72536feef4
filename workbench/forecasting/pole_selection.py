"""Option B's measurement: automatic pole selection from a block's stabilisation diagram.

For each mode, among the poles inside the Kalman gate around the a-priori estimate whose
mode shape matches the mode's reference shape (MAC on the channels both shapes have), the
best by a score; a mode seen only outside the gate is re-acquired there
(:class:`_PoleSelector`; the rules are written out in the Notes of
:func:`~workbench.forecasting.sliding_forecast`). Used by the window forecast
(:mod:`workbench.forecasting.window.forecast`) and the memory forecast (:mod:`workbench.forecasting.memory.forecast`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

#: Fewest channels two shapes must share for their MAC to count (one channel gives MAC = 1).
_MIN_SHAPE_CHANNELS = 3


def _mac_on_common_channels(reference: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """MAC of *reference* (n_channels,) with every row of *shapes* (n, n_channels).

    Each pair is compared on the channels both have (finite components); a pair sharing
    fewer than ``_MIN_SHAPE_CHANNELS`` channels gives NaN. Rows with the same set of
    available channels (usually every pole of a block) go to :func:`workbench.sid.assurance.mac`
    together.
    """
    from workbench.sid.assurance import mac

    out = np.full(shapes.shape[0], np.nan)
    if shapes.shape[0] == 0:
        return out
    ok = np.isfinite(shapes) & np.isfinite(reference)[None, :]
    if (ok == ok[0]).all():  # one set of channels for every row (the usual case)
        if ok[0].sum() < _MIN_SHAPE_CHANNELS:
            return out
        if ok[0].all():
            return np.asarray(mac(reference, shapes.T), dtype=float).reshape(-1)
        return np.asarray(mac(reference[ok[0]], shapes[:, ok[0]].T), dtype=float).reshape(-1)
    patterns, inverse = np.unique(ok, axis=0, return_inverse=True)
    inverse = np.asarray(inverse).reshape(-1)
    for p, pattern in enumerate(patterns):
        if pattern.sum() < _MIN_SHAPE_CHANNELS:
            continue
        rows = inverse == p
        out[rows] = np.asarray(mac(reference[pattern], shapes[rows][:, pattern].T)).reshape(-1)
    return out


def _shape_channels(modal: pd.DataFrame, poles: pd.DataFrame) -> list[str]:
    """Channels with shape columns in both tables, in the modal table's order."""
    in_poles = {str(c)[len("shape_re_") :] for c in poles.columns if str(c).startswith("shape_re_")}
    return [
        str(c)[len("shape_re_") :]
        for c in modal.columns
        if str(c).startswith("shape_re_") and str(c)[len("shape_re_") :] in in_poles
    ]


def _shape_matrix(frame: pd.DataFrame, channels: Sequence[str]) -> np.ndarray:
    """Complex shapes (n_rows, n_channels) of *channels* via :func:`shapes_from_frame`."""
    from data_contracts import shapes_from_frame

    names, shapes = shapes_from_frame(frame)
    if list(names) == list(channels):
        return shapes
    position = {name: k for k, name in enumerate(names)}
    return shapes[:, [position[c] for c in channels]]


@dataclass
class _BlockChoice:
    """Option B's measurements of one block (internal)."""

    frequency: np.ndarray  # chosen pole per mode, NaN: none
    mac: np.ndarray  # its MAC with the reference shape, NaN: not checked
    order: np.ndarray
    damping: np.ndarray
    reacquired: np.ndarray  # bool: chosen outside the gate (track re-acquired)
    no_reference: np.ndarray  # bool: shapes in use but the mode had no reference shape


class _PoleSelector:
    """Option B pole selection with mode-shape admissibility and track re-acquisition.

    Holds the pole table sorted by block, the pole shapes on the channels shared with the
    modal table, each mode's reference shape per grid row (see :func:`sliding_forecast`,
    Notes) and, per mode, the count of consecutive blocks with the mode seen only outside
    the gate and the frequency of the last chosen pole.
    """

    def __init__(
        self,
        poles: pd.DataFrame,
        modal: pd.DataFrame,
        blocks: np.ndarray,
        mode_labels: np.ndarray,
        *,
        shape_mac_min: float,
        reacquire_blocks: int,
        reacquire_band: float,
    ):
        needed = ("block", "model_order", "frequency_hz", "damping_ratio", "stable")
        missing = [c for c in needed if c not in poles.columns]
        if missing:
            raise ValueError(f"poles lacks column(s) {missing}")
        order = np.argsort(poles["block"].to_numpy(dtype=np.int64), kind="stable")
        pole_block = poles["block"].to_numpy(dtype=np.int64)[order]
        self.frequency = poles["frequency_hz"].to_numpy(dtype=float)[order]
        self.order = poles["model_order"].to_numpy(dtype=float)[order]
        self.damping = poles["damping_ratio"].to_numpy(dtype=float)[order]
        self.stable = poles["stable"].to_numpy(dtype=bool, na_value=False)[order]
        self.lo = np.searchsorted(pole_block, blocks, side="left")
        self.hi = np.searchsorted(pole_block, blocks, side="right")
        self.mac_min = float(shape_mac_min)
        self.reacquire_blocks = int(reacquire_blocks)
        self.band = float(reacquire_band)
        n_modes = mode_labels.size
        self.misses = np.zeros(n_modes, dtype=np.int64)
        self.anchor = np.full(n_modes, np.nan)  # frequency of the last chosen pole [Hz]
        self.channels = _shape_channels(modal, poles)
        self.shapes: np.ndarray | None = None
        self.reference_shapes = np.empty((0, 0), dtype=complex)
        self.reference_row = np.full((blocks.size, n_modes), -1, dtype=np.int64)
        if len(self.channels) < _MIN_SHAPE_CHANNELS:
            return
        self.shapes = _shape_matrix(poles, self.channels)  # table order: row self.rows[p]
        self.rows = order
        self._references(modal, blocks, mode_labels)

    @property
    def uses_shapes(self) -> bool:
        return self.shapes is not None

    def _references(self, modal: pd.DataFrame, blocks: np.ndarray, labels: np.ndarray) -> None:
        """Reference shape of each mode at each grid row: the latest confirmed tracked shape.

        A tracked shape is confirmed when its MAC with the mode's previous tracked shape is
        >= ``mac_min``; before the first confirmation, the mode's first tracked shape.
        Only tracked rows at or before the grid row's block are used (no look-ahead).
        """
        parts = []
        offset = 0
        for j, label in enumerate(labels):
            same = (modal["mode"] == label).to_numpy(dtype=bool, na_value=False)
            rows = modal[same].sort_values("block", kind="stable")
            rows = rows.drop_duplicates("block", keep="last")
            if rows.empty:
                continue
            shapes = _shape_matrix(rows, self.channels)
            usable = np.isfinite(shapes).sum(axis=1) >= _MIN_SHAPE_CHANNELS
            shapes = shapes[usable]
            track_blocks = rows["block"].to_numpy(dtype=np.int64)[usable]
            if track_blocks.size == 0:
                continue
            reference = np.zeros(track_blocks.size, dtype=np.int64)
            for r in range(1, track_blocks.size):
                agree = _mac_on_common_channels(shapes[r], shapes[r - 1 : r])[0]
                reference[r] = r if agree >= self.mac_min else reference[r - 1]
            position = np.searchsorted(track_blocks, blocks, side="right") - 1
            self.reference_row[:, j] = np.where(
                position >= 0, offset + reference[np.maximum(position, 0)], -1
            )
            parts.append(shapes)
            offset += shapes.shape[0]
        if parts:
            self.reference_shapes = np.concatenate(parts)

    def select(
        self, i: int, prior: np.ndarray, gate: np.ndarray, active: np.ndarray
    ) -> _BlockChoice:
        """Measurements of grid row *i* for the *active* modes (see sliding_forecast Notes).

        *prior* is x⁻ [Hz] and *gate* the gate half-width g = gate_sigma sqrt(P⁻ + R) [Hz]
        of each mode.
        """
        n_modes = prior.size
        choice = _BlockChoice(
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.zeros(n_modes, dtype=bool),
            np.zeros(n_modes, dtype=bool),
        )
        lo, hi = int(self.lo[i]), int(self.hi[i])
        if hi <= lo:
            return choice
        f = self.frequency[lo:hi]
        stable = self.stable[lo:hi]
        for j in np.flatnonzero(active & np.isfinite(prior)):
            distance = np.abs(f - prior[j])
            with np.errstate(invalid="ignore"):
                inside = distance <= gate[j]
            ref = int(self.reference_row[i, j])
            if self.shapes is None or ref < 0:
                pick = self._nearest(inside, stable, distance)
                choice.no_reference[j] = self.shapes is not None and pick is not None
                mac_pick = math.nan
            else:
                pick, mac_pick = self._admissible_in_gate(
                    lo, inside, stable, float(gate[j]), self.reference_shapes[ref]
                )
                if pick is None:
                    pick, mac_pick = self._outside_gate(
                        lo, j, f, inside, stable, prior[j], self.reference_shapes[ref]
                    )
                    choice.reacquired[j] = pick is not None
                else:
                    self.misses[j] = 0
            if pick is None:
                continue
            choice.frequency[j] = f[pick]
            choice.mac[j] = mac_pick
            choice.order[j] = self.order[lo + pick]
            choice.damping[j] = self.damping[lo + pick]
            self.anchor[j] = f[pick]
        return choice

    @staticmethod
    def _nearest(inside: np.ndarray, stable: np.ndarray, distance: np.ndarray) -> int | None:
        """Without shapes: the nearest pole inside the gate, stable poles first."""
        candidates = inside & stable
        if not candidates.any():
            candidates = inside
            if not candidates.any():
                return None
        return int(np.flatnonzero(candidates)[np.argmin(distance[candidates])])

    def _admissible_in_gate(self, lo, inside, stable, gate, reference):
        """Best admissible pole inside the gate: stable first, then the lowest score."""
        index = np.flatnonzero(inside)
        if index.size == 0:
            return None, math.nan
        macs = _mac_on_common_channels(reference, self.shapes[self.rows[lo + index]])
        with np.errstate(invalid="ignore"):
            ok = macs >= self.mac_min
        if not ok.any():
            return None, math.nan
        index, macs = index[ok], macs[ok]
        if stable[index].any():
            keep = stable[index]
            index, macs = index[keep], macs[keep]
        # s = |f - median(f)| / g + (1 - MAC) / (1 - MAC_min), lowest wins
        f = self.frequency[lo + index]
        score = np.abs(f - np.median(f)) / gate + (1.0 - macs) / max(1.0 - self.mac_min, 1e-12)
        best = int(np.argmin(score))
        return int(index[best]), float(macs[best])

    def _outside_gate(self, lo, j, f, inside, stable, prior, reference):
        """Count a block with the mode only outside the gate; re-acquire after k of them."""
        near = np.zeros(f.size, dtype=bool)
        for centre in (self.anchor[j], prior):
            if np.isfinite(centre):
                near |= np.abs(f - centre) <= self.band * abs(centre)
        index = np.flatnonzero(near & ~inside)
        if index.size == 0:
            return None, math.nan
        macs = _mac_on_common_channels(reference, self.shapes[self.rows[lo + index]])
        with np.errstate(invalid="ignore"):
            ok = macs >= self.mac_min
        if not ok.any():  # the mode is not seen in this block: no evidence either way
            return None, math.nan
        self.misses[j] += 1
        if self.misses[j] < self.reacquire_blocks:
            return None, math.nan
        self.misses[j] = 0
        index, macs = index[ok], macs[ok]
        if stable[index].any():
            keep = stable[index]
            index, macs = index[keep], macs[keep]
        best = int(np.argmax(macs))  # highest MAC with the reference shape
        return int(index[best]), float(macs[best])
