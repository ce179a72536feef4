"""Stabilisation diagram: which poles are stable between consecutive model orders.

A pole of model order n is *stable* when the previous order of the diagram (the order
before n in ``result.orders``) has a pole with

- relative frequency difference |f_n - f_p| / f_p < ``frequency_tol`` (default 1 %),
- relative damping difference |ζ_n - ζ_p| / ζ_p < ``damping_tol`` (default 5 %),
- MAC(φ_n, φ_p) > ``mac_min`` (default 0.98),

and positive damping itself (ζ_n > 0 and ζ_p > 0: a growing pole is not physical for a
passive structure). Poles of the lowest order are never stable (nothing to compare with).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .assurance import mac, mac_pairs

if TYPE_CHECKING:
    from .ssi import SSIResult

__all__ = ["StabilityCriteria", "stabilise", "stability_flags"]


@dataclass(frozen=True)
class StabilityCriteria:
    """Tolerances for calling a pole stable against a pole of the previous model order.

    Parameters
    ----------
    frequency_tol : float
        Largest relative frequency difference |Δf|/f. [-]
    damping_tol : float
        Largest relative damping difference |Δζ|/ζ. [-]
    mac_min : float
        Smallest MAC between the two shapes. [-]
    """

    frequency_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.98

    def __post_init__(self):
        for name in ("frequency_tol", "damping_tol"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name}={value} must be a positive number")
        if not 0.0 <= self.mac_min <= 1.0:
            raise ValueError(f"mac_min={self.mac_min} must lie in [0, 1]")

    def _close(self, frequency_a, damping_a, frequency_b, damping_b) -> np.ndarray:
        """Frequency and damping criteria (relative to pole b, both dampings positive),
        elementwise with broadcasting."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return (
                (np.abs(frequency_a - frequency_b) < self.frequency_tol * frequency_b)
                & (np.abs(damping_a - damping_b) < self.damping_tol * damping_b)
                & (damping_a > 0)
                & (damping_b > 0)
            )

    def consistent(
        self,
        frequency_a: np.ndarray,
        damping_a: np.ndarray,
        shapes_a: np.ndarray,
        frequency_b: np.ndarray,
        damping_b: np.ndarray,
        shapes_b: np.ndarray,
    ) -> np.ndarray:
        """Elementwise: pole a[k] is consistent with pole b[k] (shapes are columns k).

        Relative differences are taken with respect to pole b (the reference order). MAC is
        computed only where the frequency and damping criteria hold.
        """
        candidates = self._close(
            np.asarray(frequency_a),
            np.asarray(damping_a),
            np.asarray(frequency_b),
            np.asarray(damping_b),
        )
        pairs = np.flatnonzero(candidates)
        if pairs.size:
            shapes_a, shapes_b = np.asarray(shapes_a), np.asarray(shapes_b)
            candidates[pairs] = mac_pairs(shapes_a[:, pairs], shapes_b[:, pairs]) > self.mac_min
        return candidates

    def matches(
        self,
        frequency_a: np.ndarray,
        damping_a: np.ndarray,
        shapes_a: np.ndarray,
        frequency_b: np.ndarray,
        damping_b: np.ndarray,
        shapes_b: np.ndarray,
    ) -> np.ndarray:
        """Boolean matrix (n_a, n_b): pole a of one order is consistent with pole b of another
        (the criteria of :meth:`consistent` for every pair)."""
        candidates = self._close(
            np.asarray(frequency_a)[:, None],
            np.asarray(damping_a)[:, None],
            np.asarray(frequency_b)[None, :],
            np.asarray(damping_b)[None, :],
        )
        if not np.any(candidates):
            return candidates
        return candidates & (np.atleast_2d(mac(shapes_a, shapes_b)) > self.mac_min)


def stability_flags(
    model_order: np.ndarray,
    frequency_hz: np.ndarray,
    damping_ratio: np.ndarray,
    mode_shapes: np.ndarray,
    orders: Sequence[int],
    criteria: StabilityCriteria | None = None,
) -> np.ndarray:
    """Stable flag of every pole of a stabilisation diagram.

    Parameters
    ----------
    model_order : ndarray of int, shape (n_poles,)
        Model order of each pole.
    frequency_hz : ndarray, shape (n_poles,)
        Natural frequencies. [Hz]
    damping_ratio : ndarray, shape (n_poles,)
        Damping ratios. [-]
    mode_shapes : ndarray of complex, shape (n_channels, n_poles)
        Mode shapes, column k for pole k. [-]
    orders : sequence of int
        The orders of the diagram in increasing order (also those without poles); each
        order is compared with the one before it in this sequence.
    criteria : StabilityCriteria, optional
        Tolerances; defaults Δf < 1 %, Δζ < 5 %, MAC > 0.98.

    Returns
    -------
    ndarray of bool, shape (n_poles,)
    """
    criteria = criteria or StabilityCriteria()
    model_order = np.asarray(model_order)
    frequency_hz = np.asarray(frequency_hz, dtype=float)
    damping_ratio = np.asarray(damping_ratio, dtype=float)
    stable = np.zeros(model_order.size, dtype=bool)
    levels = np.array(sorted({int(n) for n in orders}), dtype=np.int64)
    if model_order.size == 0 or levels.size < 2:
        return stable
    # rank of each pole's order in the diagram; poles of other orders take no part
    rank = np.searchsorted(levels, model_order)
    known = (rank < levels.size) & (levels[np.minimum(rank, levels.size - 1)] == model_order)
    # candidates b (order rank r - 1) of pole a (rank r) by frequency, |f_a - f_b| < tol f_b
    # ⟺ f_a / (1 + tol) < f_b < f_a / (1 - tol): a window search in poles sorted by
    # (rank, frequency), through the key rank·span + f (span > every |f|, f finite)
    finite = known & np.isfinite(frequency_hz)
    span = 4.0 * np.max(np.abs(frequency_hz[finite]), initial=1.0) + 1.0
    # a reference pole with f_b <= 0 can never match (|Δf| < tol·f_b <= 0)
    reference = np.flatnonzero(finite & (frequency_hz > 0))
    key = rank[reference] * span + frequency_hz[reference]
    order = np.argsort(key, kind="stable")
    reference, key = reference[order], key[order]
    current = np.flatnonzero(finite & (rank > 0) & (damping_ratio > 0))
    base = (rank[current] - 1) * span
    tol = criteria.frequency_tol
    low = np.searchsorted(key, base + frequency_hz[current] / (1 + tol) * (1 - 1e-12), "left")
    high_bound = frequency_hz[current] / (1 - tol) if tol < 1 else np.full(current.size, span)
    high = np.searchsorted(key, base + np.minimum(high_bound, span / 2) * (1 + 1e-12), "right")
    counts = np.maximum(high - low, 0)
    if not counts.any():
        return stable
    a = np.repeat(current, counts)
    b = reference[np.repeat(low - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())]
    same_step = rank[b] == rank[a] - 1  # windows may reach into lower ranks
    a, b = a[same_step], b[same_step]
    shapes = np.asarray(mode_shapes)
    consistent = criteria.consistent(
        frequency_hz[a],
        damping_ratio[a],
        shapes[:, a],
        frequency_hz[b],
        damping_ratio[b],
        shapes[:, b],
    )
    stable[a[consistent]] = True
    return stable


def stabilise(
    result: SSIResult,
    *,
    frequency_tol: float = 0.01,
    damping_tol: float = 0.05,
    mac_min: float = 0.98,
) -> SSIResult:
    """Recompute the ``stable`` column of an SSI result with other criteria.

    Parameters
    ----------
    result : SSIResult
        Output of :func:`~workbench.sid.ssi.ssi_cov` or :func:`~workbench.sid.ssi.ssi_data`
        (which already flag poles with the default criteria).
    frequency_tol : float
        Largest relative frequency change between consecutive orders. [-]
    damping_tol : float
        Largest relative damping change between consecutive orders. [-]
    mac_min : float
        Smallest MAC between the shapes at consecutive orders. [-]

    Returns
    -------
    SSIResult
        A copy with the new ``stable`` column and ``criteria``.
    """
    criteria = StabilityCriteria(frequency_tol, damping_tol, mac_min)
    poles = result.poles.copy()
    poles["stable"] = stability_flags(
        poles["model_order"].to_numpy(),
        poles["frequency_hz"].to_numpy(),
        poles["damping_ratio"].to_numpy(),
        result.mode_shapes,
        result.orders,
        criteria,
    )
    return dataclasses.replace(result, poles=poles, criteria=criteria)
