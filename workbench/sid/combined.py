"""One modal model of a block from several identifications (SSI-cov, LSCF, SSI-data).

Each method's selection (:func:`~workbench.sid.selection.select_modes`, clustering rule)
reports a mode by the median over the model orders of its cluster and the scatter over
those orders (``frequency_std_hz``, ``damping_std``). :func:`combine_modes` pairs the
modes of the methods one-to-one (the pairing of :func:`~workbench.sid.crosscheck.
cross_check`: relative frequency difference below ``frequency_tol``, MAC at least
``mac_min``, Hungarian assignment on |Δf|/f + 1 - MAC) and gives each mode one estimate:

.. math::

    \\hat f = \\frac{\\sum_m w_m f_m}{\\sum_m w_m}, \\quad w_m = 1/σ_m^2, \\qquad
    σ^2 = \\frac{1}{\\sum_m w_m} + \\frac{\\sum_m w_m (f_m - \\hat f)^2}{\\sum_m w_m}

with σ_m a method's scatter over its orders (floored at :data:`RELATIVE_FLOOR` x f): the
inverse-variance mean (``estimate="weighted"``), and an uncertainty σ from each method's
scatter (first term) and from their disagreement (second term: methods that differ by more
than their scatter make the estimate less certain). By default (``estimate="reference"``)
each method is used where it is strong: the mode's frequency and damping are the first
method's (SSI) where it found the mode, the other methods add the modes it missed (close
and weakly excited ones, which LSCF's frequency-domain fit often separates) and their
agreement to σ. A mode seen by one method keeps that method's estimate and scatter. The
damping ratio is combined the same way with ``damping_std``.

A mode enters the model on the evidence of one method only when that method's main rule
(stage 3 of the clustering: a column over most model orders) found it; a column the
selection's second look found (shorter, looser, for close and weak modes) needs a mode of
another method paired with it (within ``frequency_tol``, MAC at least ``mac_min``). On the
simulated close and weak modes of ``benchmarks/bench_close_weak.py`` every spurious
second-look mode was unconfirmed, and few true ones were (upper modes of the closest
pairs, the price of the rule; ``benchmarks/results/identification_32c.txt``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from .assurance import mac

__all__ = ["COMBINED_COLUMNS", "RELATIVE_FLOOR", "combine_modes"]

#: Smallest scatter a method's estimate is credited with, relative to its frequency (and
#: to its damping ratio for the damping): a cluster of identical poles is not exact. [-]
RELATIVE_FLOOR = 1e-4

#: Columns of :func:`combine_modes` besides ``<method>_frequency_hz`` per method.
COMBINED_COLUMNS = (
    "frequency_hz",
    "damping_ratio",
    "frequency_std_hz",
    "damping_std",
    "n_methods",
    "methods",
)


def combine_modes(
    selections: Mapping[str, object],
    *,
    frequency_tol: float = 0.01,
    mac_min: float = 0.8,
    estimate: Literal["reference", "weighted"] = "reference",
) -> pd.DataFrame:
    """Combine the selected modes of several methods of one block into one estimate each.

    Parameters
    ----------
    selections : mapping of str to ModeSelection
        Method name (e.g. ``"ssi"``, ``"lscf"``) to its selection, on the same channels;
        the first method is the reference the others are paired with, one after the
        other (a mode of a later method pairs with at most one earlier mode). A mode that
        only one method found, and that one only by its second look (close and weak
        modes, :mod:`~workbench.sid.selection`: a looser test of order consistency), is
        not taken when other methods were run: unconfirmed it is too weak a case (with
        one method its selection stands).
    frequency_tol : float
        Largest relative frequency difference of a pair. [-]
    mac_min : float
        Smallest MAC of a pair. [-]
    estimate : {"reference", "weighted"}
        The mode's frequency and damping ratio: those of the first method that found it
        (``"reference"``; the others add modes it missed and their agreement to the
        uncertainty), or the inverse-variance mean of all methods (``"weighted"``; a
        method's scatter over its orders does not show its bias, see
        ``benchmarks/results/identification_32.txt`` for how the two compare).

    Returns
    -------
    pandas.DataFrame
        One row per mode, sorted by frequency: :data:`COMBINED_COLUMNS` (``frequency_std_hz``
        and ``damping_std`` the combined uncertainties, ``methods`` the names joined by
        ``+``), and for every method ``<method>_frequency_hz`` (NaN where it has no mode)
        and ``<method>_mode`` (the mode's row in that method's selection, -1 if none).
    """
    if not (np.isfinite(frequency_tol) and frequency_tol > 0):
        raise ValueError(f"frequency_tol={frequency_tol} must be a positive number")
    if not 0.0 <= mac_min <= 1.0:
        raise ValueError(f"mac_min={mac_min} must lie in [0, 1]")
    if estimate not in ("reference", "weighted"):
        raise ValueError(f"estimate={estimate!r} must be 'reference' or 'weighted'")
    names = list(selections)
    if not names:
        raise ValueError("selections is empty: give at least one method's selection")
    # groups: one dict per mode, method -> (f, zeta, sigma_f, sigma_zeta); shape of the first
    groups: list[dict] = []
    shapes: list[np.ndarray] = []
    unconfirmed: list[bool] = []  # the group was opened by a second-look mode
    for name in names:
        selection = selections[name]
        modes = selection.modes
        f = modes["frequency_hz"].to_numpy(dtype=float)
        z = modes["damping_ratio"].to_numpy(dtype=float)
        sf = _column(modes, "frequency_std_hz", f.size)
        sz = _column(modes, "damping_std", f.size)
        shape = np.asarray(selection.mode_shapes)
        paired = np.full(f.size, -1)
        if groups and f.size:
            centre = np.array([_estimate(g)[0] for g in groups])
            reference = np.column_stack(shapes)
            macs = np.atleast_2d(mac(reference, shape)).reshape(centre.size, f.size)
            distance = np.abs(f[None, :] / centre[:, None] - 1.0)
            taken = np.array([name in g for g in groups])
            admissible = (distance < frequency_tol) & (macs >= mac_min) & ~taken[:, None]
            if admissible.any():
                cost = np.where(admissible, distance + 1.0 - macs, 1e6)
                rows, cols = linear_sum_assignment(cost)
                ok = admissible[rows, cols]
                paired[cols[ok]] = rows[ok]
        second_look = _second_look_rows(selection)
        for k in range(f.size):
            entry = (f[k], z[k], sf[k], sz[k], k)
            if paired[k] >= 0:
                groups[paired[k]][name] = entry
            else:
                groups.append({name: entry})
                shapes.append(shape[:, k])
                unconfirmed.append(bool(second_look[k]))
    if len(names) > 1:  # a second-look mode stands only with another method's support
        groups = [g for g, weak in zip(groups, unconfirmed, strict=True) if not weak or len(g) > 1]
    rows = []
    for group in groups:
        frequency, frequency_std, damping, damping_std = _estimate(group, estimate)
        row = {
            "frequency_hz": frequency,
            "damping_ratio": damping,
            "frequency_std_hz": frequency_std,
            "damping_std": damping_std,
            "n_methods": len(group),
            "methods": "+".join(n for n in names if n in group),
        }
        row.update({f"{n}_frequency_hz": group[n][0] if n in group else np.nan for n in names})
        row.update({f"{n}_mode": group[n][4] if n in group else -1 for n in names})
        rows.append(row)
    columns = [
        *COMBINED_COLUMNS,
        *(f"{n}_frequency_hz" for n in names),
        *(f"{n}_mode" for n in names),
    ]
    frame = pd.DataFrame(rows, columns=columns)
    for column in ["n_methods", *(f"{n}_mode" for n in names)]:
        frame[column] = frame[column].astype(np.int64)
    return frame.sort_values("frequency_hz", kind="stable").reset_index(drop=True)


def _second_look_rows(selection) -> np.ndarray:
    """Which modes of a selection its second look added (``thresholds["second_look_poles"]``
    of :func:`~workbench.sid.selection.select_modes`)."""
    modes = selection.modes
    poles = getattr(selection, "thresholds", {}).get("second_look_poles", ())
    if not len(poles) or "pole_index" not in modes.columns:
        return np.zeros(len(modes), dtype=bool)
    return modes["pole_index"].isin(poles).to_numpy()


def _column(modes: pd.DataFrame, name: str, n: int) -> np.ndarray:
    """A scatter column of a selection (NaN where the rule does not give one)."""
    if name in modes.columns:
        return modes[name].to_numpy(dtype=float)
    return np.full(n, np.nan)


def _weighted(values: np.ndarray, scatter: np.ndarray) -> tuple[float, float]:
    """Inverse-variance mean and its uncertainty (scatter and disagreement terms)."""
    sigma = np.where(np.isfinite(scatter), scatter, 0.0)
    sigma = np.maximum(sigma, RELATIVE_FLOOR * np.abs(values))
    sigma = np.where(sigma > 0, sigma, np.finfo(float).tiny)
    weight = 1.0 / sigma**2
    mean = float(np.sum(weight * values) / np.sum(weight))
    spread = float(np.sum(weight * (values - mean) ** 2) / np.sum(weight))
    return mean, float(np.sqrt(1.0 / np.sum(weight) + spread))


def _estimate(group: dict, estimate: str = "weighted") -> tuple[float, float, float, float]:
    """Combined frequency, its uncertainty, damping ratio and its uncertainty of a group
    (``estimate="reference"``: the first method's frequency and damping where it has the
    mode, with the combined uncertainties)."""
    entries = np.array([entry[:4] for entry in group.values()], dtype=float)
    frequency, frequency_std = _weighted(entries[:, 0], entries[:, 2])
    damping, damping_std = _weighted(entries[:, 1], entries[:, 3])
    if estimate == "reference":
        frequency, damping = float(entries[0, 0]), float(entries[0, 1])
    return frequency, frequency_std, damping, damping_std
