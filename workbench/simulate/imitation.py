"""Imitations of what identification and tracking produce: tracked modal table and poles.

They let the statistical stages be built and tested before SSI exists. Built from the
block truth with documented imperfections (see :func:`tracked_modal_table` and
:func:`pole_table`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from data_contracts import shapes_to_frame

from ..sid.assurance import mac, mac_pairs
from ..sid.modal import modal_phase_collinearity, normalise_shapes

__all__ = [
    "FREQUENCY_SCATTER",
    "DAMPING_SCATTER",
    "IdentificationImitation",
    "imitate_identification",
]

#: Relative standard deviation of the identified frequency, per mode. [-]
FREQUENCY_SCATTER = np.array([0.002, 0.003, 0.004, 0.005, 0.003, 0.004, 0.003])
#: Standard deviation of the log of the identified damping ratio (≈ 20 % relative). [-]
DAMPING_SCATTER = 0.2
#: Share of (block, mode) pairs missing at random from the tracked table.
MISSING_FRACTION = 0.10
#: Share of blocks in which modes 3 and 4 (5.2 and 5.4 Hz) swap labels.
MISLABEL_FRACTION = 0.01
#: Mode (1-based) missing over a long stretch, and that stretch as fractions of the blocks.
WEAK_MODE = 4
WEAK_STRETCH = (0.40, 0.52)
#: Model orders of the stabilisation diagrams.
ORDERS = np.arange(10, 61, 2)
#: Order from which each mode shows up in the diagram (±2 per block).
ONSET_ORDERS = np.array([12, 16, 18, 24, 20, 22, 26])
#: Stability criteria against the previous order: relative frequency change, relative
#: damping change, MAC.
STABILITY_CRITERIA = (0.01, 0.10, 0.98)
#: Shaft-harmonic frequency per knot. [Hz/kn]
SHAFT_HZ_PER_KN = 0.3


def _normalised(shapes: np.ndarray) -> np.ndarray:
    """Shapes given as rows, normalised by :func:`workbench.sid.normalise_shapes`."""
    return normalise_shapes(np.atleast_2d(shapes).T).T


@dataclass(frozen=True)
class IdentificationImitation:
    """Tracked modal table, pole table and where the imperfections were put.

    Parameters
    ----------
    tracked : DataFrame
        MODAL contract.
    poles : DataFrame
        POLES contract.
    mislabelled_blocks : tuple of int
        Blocks in which modes 3 and 4 carry each other's labels.
    weak_mode_blocks : tuple of int
        First and last block of the stretch without mode :data:`WEAK_MODE`.
    """

    tracked: pd.DataFrame
    poles: pd.DataFrame
    mislabelled_blocks: tuple[int, ...]
    weak_mode_blocks: tuple[int, int]


def _noisy_shapes(rng, shapes, n, real_std, imag_std):
    noise = real_std * rng.standard_normal((n, shapes.shape[-1])) + 1j * imag_std * (
        rng.standard_normal((n, shapes.shape[-1]))
    )
    return _normalised(shapes + noise)


def imitate_identification(
    blocks: pd.DataFrame,
    truth_frequency_hz: np.ndarray,
    truth_damping_ratio: np.ndarray,
    mode_shapes: np.ndarray,
    channels: tuple[str, ...],
    block_speed: np.ndarray,
    block_speed_std: np.ndarray,
    *,
    tracked_rng: np.random.Generator,
    poles_rng: np.random.Generator,
) -> IdentificationImitation:
    """Tracked modal table and stabilisation diagrams imitating SSI and tracking.

    Parameters
    ----------
    blocks : DataFrame
        block, block_start, block_end for every block.
    truth_frequency_hz, truth_damping_ratio : ndarray, shape (n_blocks, n_modes)
        Block truth. [Hz], [-]
    mode_shapes : ndarray, shape (n_modes, n_channels)
        True shapes.
    channels : tuple of str
    block_speed, block_speed_std : ndarray, shape (n_blocks,)
        Mean and standard deviation of the true speed in each block (shaft harmonic). [kn]

    Notes
    -----
    Per block and mode the *identified* values are f (1 + s_m ε), ζ exp(0.2 η) and the
    true shape plus complex noise (0.03 real, 0.01 imaginary) renormalised; s_m is
    :data:`FREQUENCY_SCATTER`. The tracked table drops 10 % of (block, mode) pairs at
    random and mode 4 over :data:`WEAK_STRETCH` of the blocks, and swaps the labels of
    modes 3 and 4 in 1 % of the blocks (at least one). ``mac`` is the MAC between the
    row's shape and the true shape of its label; ``model_order`` the order the pole was
    taken from.

    Pole table: orders :data:`ORDERS`; a present mode appears from its onset order
    (:data:`ONSET_ORDERS` ± 2) with a scatter around the identified value that shrinks
    as 4 exp(-(n - onset)/6) (frequency, in units of s_m), 0.3 exp(-(n - onset)/6)
    (log damping) and 0.05 exp(-(n - onset)/6) (shape); the pole at the tracked
    ``model_order`` is exactly the tracked row. A randomly missing mode shows up only at
    a few orders with 2 % scatter. Spurious poles: Poisson(1.5 + n/15) per order, uniform
    in 0.3-31.5 Hz, damping 3-30 % (10 % of them negative), random complex shapes. When
    the block speed is steady (> 3 kn, std < 0.5 kn) the shaft harmonic appears as a
    nearly undamped pole at 0.3 Hz/kn x speed from order 14. ``stable``: a pole of the
    previous order lies within :data:`STABILITY_CRITERIA` (frequency 1 %, damping 10 %,
    MAC 0.98).
    """
    n_blocks, n_modes = truth_frequency_hz.shape
    rng = tracked_rng
    # identified values per block and (physical) mode
    frequency = truth_frequency_hz * (
        1 + FREQUENCY_SCATTER * rng.standard_normal((n_blocks, n_modes))
    )
    damping = truth_damping_ratio * np.exp(
        DAMPING_SCATTER * rng.standard_normal((n_blocks, n_modes))
    )
    shapes = np.stack(
        [_noisy_shapes(rng, mode_shapes[m], n_blocks, 0.03, 0.01) for m in range(n_modes)], axis=1
    )  # (n_blocks, n_modes, n_channels)
    onset = ONSET_ORDERS + 2 * rng.integers(-1, 2, (n_blocks, n_modes))
    order_choice = rng.integers(0, 1 << 30, (n_blocks, n_modes))
    present = rng.random((n_blocks, n_modes)) >= MISSING_FRACTION
    weak_first = int(np.floor(WEAK_STRETCH[0] * n_blocks))
    weak_last = max(weak_first, int(np.ceil(WEAK_STRETCH[1] * n_blocks)) - 1)
    weak = np.zeros(n_blocks, bool)
    weak[weak_first : weak_last + 1] = True
    present[weak, WEAK_MODE - 1] = False
    # tracked model order: a stable order well above the onset
    model_order = np.empty((n_blocks, n_modes), int)
    for b in range(n_blocks):
        for m in range(n_modes):
            candidates = ORDERS[ORDERS >= onset[b, m] + 16]
            model_order[b, m] = candidates[order_choice[b, m] % len(candidates)]
    # labels: modes 3 and 4 swap in a few blocks where both are present
    label = np.tile(np.arange(1, n_modes + 1), (n_blocks, 1))
    both = np.nonzero(present[:, 2] & present[:, 3])[0]
    n_swaps = min(len(both), max(1, int(round(MISLABEL_FRACTION * n_blocks))))
    swapped = np.sort(rng.choice(both, n_swaps, replace=False)) if n_swaps else np.array([], int)
    label[swapped, 2], label[swapped, 3] = 4, 3

    rows_b, rows_m = np.nonzero(present)
    tracked = pd.DataFrame(
        {
            "block": blocks["block"].to_numpy()[rows_b],
            "block_start": blocks["block_start"].to_numpy()[rows_b],
            "block_end": blocks["block_end"].to_numpy()[rows_b],
            "mode": label[rows_b, rows_m],
            "frequency_hz": frequency[rows_b, rows_m],
            "damping_ratio": damping[rows_b, rows_m],
            "mac": mac_pairs(shapes[rows_b, rows_m].T, mode_shapes[label[rows_b, rows_m] - 1].T),
            "model_order": pd.array(model_order[rows_b, rows_m], dtype="Int64"),
        }
    )
    tracked["block_start"] = pd.to_datetime(tracked["block_start"], utc=True)
    tracked["block_end"] = pd.to_datetime(tracked["block_end"], utc=True)
    tracked = pd.concat(
        [tracked, shapes_to_frame(channels, shapes[rows_b, rows_m], index=tracked.index)], axis=1
    )
    tracked = tracked.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)

    poles = _poles(
        blocks["block"].to_numpy(),
        frequency,
        damping,
        shapes,
        present,
        onset,
        model_order,
        block_speed,
        block_speed_std,
        channels,
        poles_rng,
    )
    return IdentificationImitation(
        tracked,
        poles,
        tuple(int(b) for b in blocks["block"].to_numpy()[swapped]),
        (int(weak_first), int(weak_last)),
    )


def _poles(
    block_ids,
    frequency,
    damping,
    shapes,
    present,
    onset,
    model_order,
    speed,
    speed_std,
    channels,
    rng,
):
    n_blocks, n_modes, n_channels = shapes.shape
    out_block, out_order, out_f, out_z, out_shape = [], [], [], [], []
    for b in range(n_blocks):
        f_rows, z_rows, o_rows, s_rows = [], [], [], []
        for m in range(n_modes):
            if present[b, m]:
                orders = ORDERS[ORDERS >= onset[b, m]]
                decay = np.exp(-(orders - onset[b, m]) / 6.0)
                f = frequency[b, m] * (
                    1 + FREQUENCY_SCATTER[m] * 4 * decay * rng.standard_normal(len(orders))
                )
                z = damping[b, m] * np.exp(0.3 * decay * rng.standard_normal(len(orders)))
                s = _normalised(
                    shapes[b, m]
                    + 0.05
                    * decay[:, None]
                    * (
                        rng.standard_normal((len(orders), n_channels))
                        + 1j * rng.standard_normal((len(orders), n_channels))
                    )
                )
                at = orders == model_order[b, m]
                f[at], z[at], s[at] = frequency[b, m], damping[b, m], shapes[b, m]
            else:
                orders = np.sort(rng.choice(ORDERS, 3, replace=False))
                f = frequency[b, m] * (1 + 0.02 * rng.standard_normal(3))
                z = damping[b, m] * np.exp(0.5 * rng.standard_normal(3))
                s = _normalised(shapes[b, m] + 0.2 * rng.standard_normal((3, n_channels)))
            f_rows.append(f), z_rows.append(z), o_rows.append(orders), s_rows.append(s)
        if speed[b] > 3.0 and speed_std[b] < 0.5:
            orders = ORDERS[ORDERS >= 14]
            f_rows.append(
                SHAFT_HZ_PER_KN * speed[b] * (1 + 1e-4 * rng.standard_normal(len(orders)))
            )
            z_rows.append(0.0008 * np.exp(0.05 * rng.standard_normal(len(orders))))
            o_rows.append(orders)
            stern = np.exp(-3.0 * np.linspace(0, 1, n_channels))
            s_rows.append(
                _normalised(stern + 0.01 * rng.standard_normal((len(orders), n_channels)))
            )
        counts = rng.poisson(1.5 + ORDERS / 15.0)
        n_spurious = int(counts.sum())
        o_rows.append(np.repeat(ORDERS, counts))
        f_rows.append(rng.uniform(0.3, 31.5, n_spurious))
        z_rows.append(
            np.where(
                rng.random(n_spurious) < 0.1,
                -rng.uniform(0.0, 0.05, n_spurious),
                rng.uniform(0.03, 0.3, n_spurious),
            )
        )
        s_rows.append(
            _normalised(
                rng.standard_normal((n_spurious, n_channels))
                + 1j * rng.standard_normal((n_spurious, n_channels))
            )
            if n_spurious
            else np.empty((0, n_channels), complex)
        )
        orders = np.concatenate(o_rows)
        sort = np.lexsort((np.concatenate(f_rows), orders))
        out_block.append(np.full(len(orders), block_ids[b]))
        out_order.append(orders[sort])
        out_f.append(np.concatenate(f_rows)[sort])
        out_z.append(np.concatenate(z_rows)[sort])
        out_shape.append(np.concatenate(s_rows)[sort])
    order = np.concatenate(out_order)
    block = np.concatenate(out_block)
    f = np.concatenate(out_f)
    z = np.concatenate(out_z)
    s = np.concatenate(out_shape)
    stable = _stability(block, order, f, z, s)
    frame = pd.DataFrame(
        {
            "block": block,
            "model_order": order,
            "frequency_hz": f,
            "damping_ratio": z,
            "stable": stable,
            "mpc": modal_phase_collinearity(s.T),
        }
    )
    return pd.concat([frame, shapes_to_frame(channels, s, index=frame.index)], axis=1)


def _stability(block, order, frequency, damping, shapes) -> np.ndarray:
    """Flag poles with a close pole (criteria :data:`STABILITY_CRITERIA`) at the previous order."""
    df_max, dz_max, mac_min = STABILITY_CRITERIA
    stable = np.zeros(len(order), bool)
    key = block.astype(np.int64) * 10_000 + order
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    stops = np.r_[starts[1:], len(key)]
    previous = {}
    for lo, hi in zip(starts, stops, strict=True):
        previous[key[lo]] = (lo, hi)
    for lo, hi in zip(starts, stops, strict=True):
        before = previous.get(key[lo] - 2)
        if before is None:
            continue
        plo, phi = before
        fa, fb = frequency[lo:hi, None], frequency[None, plo:phi]
        za, zb = damping[lo:hi, None], damping[None, plo:phi]
        close_f = np.abs(fa - fb) <= df_max * np.abs(fb)
        close_z = np.abs(za - zb) <= dz_max * np.abs(zb)
        same_shape = mac(shapes[lo:hi].T, shapes[plo:phi].T) >= mac_min
        stable[lo:hi] = np.any(close_f & close_z & same_shape, axis=1)
    return stable
