"""Cross-check of two identifications of one block: SSI against LSCF, mode by mode.

Two methods with different error mechanisms (SSI: a subspace of the time-domain
correlations; LSCF: a rational fit of their half-spectra in a band, see
:mod:`workbench.sid.plscf`) that find the same mode with the same frequency, damping and
shape give a much stronger case for it than either alone. :func:`cross_check` pairs the
selected modes of the two methods one-to-one; :func:`agreement_summary` condenses the
pairs of any number of blocks into the few numbers an identify summary or a report shows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from .assurance import mac

__all__ = [
    "CROSS_CHECK_COLUMNS",
    "agreement_by_block",
    "agreement_lines",
    "agreement_summary",
    "cross_check",
]

#: Columns of a cross-check table (one row per SSI mode, LSCF mode or pair).
CROSS_CHECK_COLUMNS = (
    "block",
    "ssi_frequency_hz",
    "lscf_frequency_hz",
    "frequency_difference",
    "ssi_damping_ratio",
    "lscf_damping_ratio",
    "damping_difference",
    "mac",
    "paired",
)


def cross_check(
    ssi_frequency_hz: Sequence[float],
    ssi_damping_ratio: Sequence[float],
    ssi_mode_shapes: np.ndarray,
    lscf_frequency_hz: Sequence[float],
    lscf_damping_ratio: Sequence[float],
    lscf_mode_shapes: np.ndarray,
    *,
    block: int = 0,
    frequency_tol: float = 0.01,
    mac_min: float = 0.8,
) -> pd.DataFrame:
    """Pair the modes of two identifications of one block one-to-one.

    Parameters
    ----------
    ssi_frequency_hz, ssi_damping_ratio : sequence of float
        Modes of the first method (SSI). [Hz], [-]
    ssi_mode_shapes : ndarray of complex, shape (n_channels, n_ssi)
        Their shapes (columns), on the same channels as *lscf_mode_shapes*.
    lscf_frequency_hz, lscf_damping_ratio, lscf_mode_shapes
        The same for the second method (LSCF).
    block : int
        Block number written in the ``block`` column.
    frequency_tol : float
        Largest relative frequency difference of a pair. [-]
    mac_min : float
        Smallest MAC of a pair. [-]

    Returns
    -------
    pandas.DataFrame
        :data:`CROSS_CHECK_COLUMNS`, sorted by frequency: one row per pair
        (``paired`` True) and one per mode found by only one method (the other method's
        columns NaN). ``frequency_difference`` = f_LSCF / f_SSI - 1 and
        ``damping_difference`` = ζ_LSCF / ζ_SSI - 1 (relative, signed).

    Notes
    -----
    Admissible pairs have |f_LSCF/f_SSI - 1| < *frequency_tol* and MAC >= *mac_min*;
    among them a Hungarian assignment minimises the sum of |Δf|/f + (1 - MAC), so a mode
    pairs with at most one mode of the other method.
    """
    if not (np.isfinite(frequency_tol) and frequency_tol > 0):
        raise ValueError(f"frequency_tol={frequency_tol} must be a positive number")
    if not 0.0 <= mac_min <= 1.0:
        raise ValueError(f"mac_min={mac_min} must lie in [0, 1]")
    f_a = np.asarray(ssi_frequency_hz, dtype=float)
    z_a = np.asarray(ssi_damping_ratio, dtype=float)
    f_b = np.asarray(lscf_frequency_hz, dtype=float)
    z_b = np.asarray(lscf_damping_ratio, dtype=float)
    shapes_a = _columns(ssi_mode_shapes, f_a.size)
    shapes_b = _columns(lscf_mode_shapes, f_b.size)
    if f_a.size and f_b.size and shapes_a.shape[0] != shapes_b.shape[0]:
        raise ValueError(
            f"mode shapes have {shapes_a.shape[0]} (SSI) and {shapes_b.shape[0]} (LSCF) "
            "channels: compare shapes on the same channels"
        )
    pairs: list[tuple[int, int, float]] = []
    if f_a.size and f_b.size:
        macs = np.atleast_2d(mac(shapes_a, shapes_b)).reshape(f_a.size, f_b.size)
        with np.errstate(divide="ignore", invalid="ignore"):
            distance = np.abs(f_b[None, :] / f_a[:, None] - 1)
        admissible = (distance < frequency_tol) & (macs >= mac_min)
        if admissible.any():
            cost = np.where(admissible, distance + (1 - macs), 1e6)
            rows, cols = linear_sum_assignment(cost)
            pairs = [
                (a, b, macs[a, b]) for a, b in zip(rows, cols, strict=True) if admissible[a, b]
            ]
    used_a = {a for a, _, _ in pairs}
    used_b = {b for _, b, _ in pairs}
    records = [(f_a[a], f_b[b], z_a[a], z_b[b], value, True) for a, b, value in pairs]
    records += [
        (f_a[a], np.nan, z_a[a], np.nan, np.nan, False) for a in range(f_a.size) if a not in used_a
    ]
    records += [
        (np.nan, f_b[b], np.nan, z_b[b], np.nan, False) for b in range(f_b.size) if b not in used_b
    ]
    frame = pd.DataFrame(
        records,
        columns=[
            "ssi_frequency_hz",
            "lscf_frequency_hz",
            "ssi_damping_ratio",
            "lscf_damping_ratio",
            "mac",
            "paired",
        ],
    )
    frame["paired"] = frame["paired"].astype(bool)
    frame.insert(0, "block", np.full(len(frame), int(block), dtype=np.int64))
    frame["frequency_difference"] = frame["lscf_frequency_hz"] / frame["ssi_frequency_hz"] - 1
    frame["damping_difference"] = frame["lscf_damping_ratio"] / frame["ssi_damping_ratio"] - 1
    key = frame["ssi_frequency_hz"].fillna(frame["lscf_frequency_hz"])
    frame = frame.iloc[np.argsort(key.to_numpy(), kind="stable")].reset_index(drop=True)
    return frame[list(CROSS_CHECK_COLUMNS)]


def _columns(shapes, n_modes: int) -> np.ndarray:
    """Shapes as (n_channels, n_modes); a 1-D array is one mode."""
    shapes = np.asarray(shapes)
    if shapes.ndim == 1 and n_modes == 1:
        shapes = shapes[:, None]
    if shapes.ndim != 2 or shapes.shape[1] != n_modes:
        raise ValueError(f"mode shapes of shape {shapes.shape} do not hold {n_modes} mode(s)")
    return shapes


def agreement_summary(table: pd.DataFrame, *, frequency_agreement: float = 0.001) -> dict:
    """Counts and statistics of a cross-check table (one or many blocks).

    Parameters
    ----------
    table : pandas.DataFrame
        Rows of :func:`cross_check` (any number of blocks).
    frequency_agreement : float
        A pair *agrees* when |f_LSCF/f_SSI - 1| is below this (default 0.1 %). [-]

    Returns
    -------
    dict
        ``blocks``, ``ssi_modes``, ``lscf_modes``, ``pairs``, ``agreeing`` (pairs within
        *frequency_agreement*), ``frequency_difference_median`` and ``_max`` (of |Δf|/f),
        ``damping_difference_median`` (of |Δζ|/ζ), ``mac_median`` and ``mac_min``; the
        statistics are NaN without pairs.
    """
    paired = table[table["paired"].astype(bool)]
    frequency = paired["frequency_difference"].abs().to_numpy(dtype=float)
    damping = paired["damping_difference"].abs().to_numpy(dtype=float)
    macs = paired["mac"].to_numpy(dtype=float)

    def stat(function, values):
        return float(function(values)) if values.size else float("nan")

    return {
        "blocks": int(table["block"].nunique()),
        "ssi_modes": int(table["ssi_frequency_hz"].notna().sum()),
        "lscf_modes": int(table["lscf_frequency_hz"].notna().sum()),
        "pairs": len(paired),
        "agreeing": int(np.sum(frequency < frequency_agreement)),
        "frequency_difference_median": stat(np.median, frequency),
        "frequency_difference_max": stat(np.max, frequency),
        "damping_difference_median": stat(np.median, damping),
        "mac_median": stat(np.median, macs),
        "mac_min": stat(np.min, macs),
    }


def agreement_lines(table: pd.DataFrame, *, frequency_agreement: float = 0.001) -> list[str]:
    """Human-readable summary of a cross-check table (for the identify summary)."""
    s = agreement_summary(table, frequency_agreement=frequency_agreement)
    lines = [
        f"SSI/LSCF cross-check over {s['blocks']} block(s): {s['pairs']} mode pair(s) "
        f"of {s['ssi_modes']} SSI and {s['lscf_modes']} LSCF modes; "
        f"{s['agreeing']} agree within {100 * frequency_agreement:g} % in frequency"
    ]
    if s["pairs"]:
        lines.append(
            f"  |df|/f median {100 * s['frequency_difference_median']:.3f} %, "
            f"max {100 * s['frequency_difference_max']:.3f} %; "
            f"|dzeta|/zeta median {100 * s['damping_difference_median']:.1f} %; "
            f"MAC median {s['mac_median']:.3f}, min {s['mac_min']:.3f}"
        )
    return lines


def agreement_by_block(table: pd.DataFrame, *, frequency_agreement: float = 0.001) -> pd.DataFrame:
    """One row per block of a cross-check table: the table a report shows.

    Returns
    -------
    pandas.DataFrame
        ``block``, ``ssi_modes``, ``lscf_modes``, ``pairs``, ``agreeing`` (pairs within
        *frequency_agreement* in frequency), ``frequency_difference_max`` (largest |Δf|/f
        of the pairs), ``damping_difference_median`` (|Δζ|/ζ), ``mac_min``.
    """
    keys = [
        "ssi_modes",
        "lscf_modes",
        "pairs",
        "agreeing",
        "frequency_difference_max",
        "damping_difference_median",
        "mac_min",
    ]
    rows = []
    for block, part in table.groupby("block", sort=True):
        summary = agreement_summary(part, frequency_agreement=frequency_agreement)
        rows.append({"block": int(block), **{key: summary[key] for key in keys}})
    return pd.DataFrame(rows, columns=["block", *keys])
