"""Automatic choice of the physical modes of one block from its stabilisation diagram.

Rule (issue 5, item 4), applied to the poles that pass the sanity limits (frequency band,
damping limits, optional MPC floor):

1. **Library.** Take the ``library_orders`` (default five) consecutive orders of the
   diagram just below the maximum order (the maximum order itself is left out). A mode
   is *present* in an order when that order has a pole matching it (criteria below). Each
   pole of these orders seeds a group: its best match in each of the five orders. A group
   with a member in all five orders is represented by its median-frequency pole (the
   *reference*), which must itself match a pole in all five orders. These references form
   the library; groups with the same reference, or with twin references (a mode split
   into two nearby poles), count once.
2. **Descent.** Go down the diagram order by order below the library orders, matching the
   library references one-to-one to the poles of each order (Hungarian assignment,
   smallest relative frequency difference among admissible pairs).
3. **Selection.** At the first order where a library member finds no match, stop and
   select the matched poles of the order before (the lowest order at which every library
   mode is still present). If no member is ever lost, select at the lowest order.

Matching criteria (pole against a reference pole): relative frequency difference below
``frequency_tol`` (1 %), relative damping difference below ``damping_tol`` (50 %), MAC
above ``mac_min`` (0.98), positive damping. Comparing with fixed references rather than
with the previous order keeps the selected poles close to the library even where a
spurious pole perturbs a few orders. The damping tolerance is much wider than the
diagram's 5 %: single-block damping estimates scatter by 5-20 % between orders near the
maximum order, and a mode must not drop out of the library for that alone (with 20 % a
simulated hull block lost one of its seven modes in a third of the trials; with 50 %
in one of twelve).

The lowest order at which all library modes exist is the most parsimonious model that
still holds every mode consistently seen at high order. Spurious noise poles are rarely
consistent over five orders; the damping limits remove harmonics (ζ ≈ 0, e.g. the shaft
line) and over-damped noise poles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from data_contracts import shapes_to_frame

from .mac import continuous_pole, mac
from .ssi import SSIResult
from .stabilisation import StabilityCriteria

__all__ = ["ModeSelection", "select_modes"]


@dataclass(frozen=True, eq=False)
class ModeSelection:
    """Modes chosen from one stabilisation diagram by :func:`select_modes`.

    Parameters
    ----------
    modes : pandas.DataFrame
        One row per selected mode, sorted by frequency: ``frequency_hz`` [Hz],
        ``damping_ratio`` [-], ``model_order``, ``mpc``, ``stable`` and ``pole_index``
        (row position in ``result.poles``).
    mode_shapes : ndarray of complex, shape (n_channels, n_modes)
        Shapes of the selected modes, column k for row k. [-]
    model_order : int or None
        Order the modes were selected at (None if the library is empty).
    library_orders : tuple of int
        Orders that formed the library.
    """

    modes: pd.DataFrame
    mode_shapes: np.ndarray
    model_order: int | None
    library_orders: tuple[int, ...]

    @property
    def continuous_poles(self) -> np.ndarray:
        """Continuous-time poles λ = -ζω + iω√(1-ζ²) of the modes. [rad/s]"""
        return continuous_pole(
            self.modes["frequency_hz"].to_numpy(), self.modes["damping_ratio"].to_numpy()
        )

    def modes_frame(self, channels: Sequence[str], block: int | None = None) -> pd.DataFrame:
        """The selected modes with mode-shape columns (``shape_re_<c>``, ``shape_im_<c>``).

        Parameters
        ----------
        channels : sequence of str
            Names of the identified channels (length n_channels).
        block : int, optional
            Block number; adds a ``block`` column first.
        """
        channels = list(channels)
        if len(channels) != self.mode_shapes.shape[0]:
            raise ValueError(
                f"channels has {len(channels)} names for {self.mode_shapes.shape[0]} "
                "identified channels"
            )
        frame = self.modes.reset_index(drop=True)
        if block is not None:
            frame.insert(0, "block", np.full(len(frame), int(block), dtype=np.int64))
        return pd.concat(
            [frame, shapes_to_frame(channels, self.mode_shapes.T, index=frame.index)], axis=1
        )


def _assign(
    references: np.ndarray,
    candidates: np.ndarray,
    frequency: np.ndarray,
    damping: np.ndarray,
    shapes: np.ndarray,
    criteria: StabilityCriteria,
) -> np.ndarray:
    """For each reference pole, the index of its one-to-one match among candidates, or -1.

    Hungarian assignment minimising the relative frequency difference among admissible
    pairs (those meeting *criteria* with respect to the reference).
    """
    match = np.full(references.size, -1)
    if references.size == 0 or candidates.size == 0:
        return match
    admissible = criteria.matches(
        frequency[candidates],
        damping[candidates],
        shapes[:, candidates],
        frequency[references],
        damping[references],
        shapes[:, references],
    ).T  # (references, candidates)
    if not admissible.any():
        return match
    distance = np.abs(frequency[candidates][None, :] / frequency[references][:, None] - 1.0)
    cost = np.where(admissible, distance, 1e6)
    rows, cols = linear_sum_assignment(cost)
    ok = admissible[rows, cols]
    match[rows[ok]] = candidates[cols[ok]]
    return match


def _library(
    window_candidates: list[np.ndarray],
    frequency: np.ndarray,
    damping: np.ndarray,
    shapes: np.ndarray,
    criteria: StabilityCriteria,
) -> np.ndarray:
    """Reference poles of the modes present in every order of the library window.

    Every eligible pole of the window seeds a group: its best match (closest frequency
    among the poles meeting *criteria* with respect to the seed) in each window order. A
    group with a pole in every order is re-centred on its median-frequency pole, and kept
    if that reference again has a match in every order. Groups sharing a reference, or
    whose references are twins (within ``frequency_tol`` and MAC above ``mac_min``), count
    once.
    """
    if not window_candidates or any(c.size == 0 for c in window_candidates):
        return np.zeros(0, dtype=int)
    poles = np.concatenate(window_candidates)
    order_of = np.concatenate([np.full(c.size, k) for k, c in enumerate(window_candidates)])
    n_orders = len(window_candidates)
    # admissible[i, j]: pole i matches reference pole j
    admissible = criteria.matches(
        frequency[poles],
        damping[poles],
        shapes[:, poles],
        frequency[poles],
        damping[poles],
        shapes[:, poles],
    )
    distance = np.abs(frequency[poles][:, None] / frequency[poles][None, :] - 1.0)
    distance = np.where(admissible, distance, np.inf)
    # best match of every reference (column) in every order: (n_orders, n_poles)
    best = np.full((n_orders, poles.size), -1)
    for k in range(n_orders):
        rows = np.flatnonzero(order_of == k)
        nearest = np.argmin(distance[rows], axis=0)
        found = np.isfinite(distance[rows][nearest, np.arange(poles.size)])
        best[k, found] = rows[nearest[found]]
    complete = np.all(best >= 0, axis=0)
    references: list[int] = []
    for seed in np.flatnonzero(complete):
        group = best[:, seed]
        centre = int(group[np.argsort(frequency[poles][group], kind="stable")[n_orders // 2]])
        if complete[centre] and centre not in references:
            references.append(centre)
    references_array = poles[np.array(references, dtype=int)]
    references_array = references_array[np.argsort(frequency[references_array], kind="stable")]
    return _drop_twins(references_array, frequency, shapes, criteria)


def _drop_twins(
    poles: np.ndarray, frequency: np.ndarray, shapes: np.ndarray, criteria: StabilityCriteria
) -> np.ndarray:
    """Keep the first of poles (in the given order) that are twins of each other."""
    if poles.size < 2:
        return poles
    close = np.abs(frequency[poles][:, None] / frequency[poles][None, :] - 1.0)
    twins = (close < criteria.frequency_tol) & (
        np.atleast_2d(mac(shapes[:, poles], shapes[:, poles])) > criteria.mac_min
    )
    keep = np.ones(poles.size, dtype=bool)
    for k in range(poles.size):
        if keep[k]:
            later = twins[k].copy()
            later[: k + 1] = False
            keep[later] = False
    return poles[keep]


def select_modes(
    result: SSIResult,
    *,
    frequency_band: tuple[float, float] | None = None,
    damping_limits: tuple[float, float] = (0.001, 0.10),
    library_orders: int = 5,
    frequency_tol: float = 0.01,
    damping_tol: float = 0.50,
    mac_min: float = 0.98,
    mpc_min: float = 0.0,
) -> ModeSelection:
    """Select the physical modes of a stabilisation diagram (library-and-descent rule).

    Parameters
    ----------
    result : SSIResult
        Output of :func:`~workbench.sid.ssi.ssi_cov` or :func:`~workbench.sid.ssi.ssi_data`.
    frequency_band : (float, float), optional
        Only poles with low <= f <= high are considered. [Hz]
    damping_limits : (float, float)
        Only poles with low <= ζ <= high are considered (sanity limits: harmonics have
        ζ ≈ 0, noise poles are often heavily damped). [-]
    library_orders : int
        Number of consecutive orders below the maximum that a mode must appear in to enter
        the library.
    frequency_tol : float
        Largest relative frequency difference between a pole and a reference pole. [-]
    damping_tol : float
        Largest relative damping difference between a pole and a reference pole. [-]
    mac_min : float
        Smallest MAC between a pole and a reference pole. [-]
    mpc_min : float
        Smallest modal phase collinearity of a considered pole (0 disables). [-]

    Returns
    -------
    ModeSelection
        The library members' poles at the selected order (empty if no mode qualifies).

    Raises
    ------
    ValueError
        Fewer than ``library_orders + 1`` orders in the diagram, or bad limits.

    Notes
    -----
    See the module docstring for the rule. With orders o_1 < … < o_K the library is built
    on o_{K-L}, …, o_{K-1} (L = ``library_orders``), then the descent visits o_{K-L-1},
    o_{K-L-2}, … and stops at the first order missing a member; the modes are the poles
    matched to the library at the last complete order.
    """
    orders = tuple(sorted(result.orders))
    if library_orders < 1 or len(orders) < library_orders + 1:
        raise ValueError(
            f"library_orders={library_orders} needs a diagram with at least "
            f"{library_orders + 1} orders, got {len(orders)}"
        )
    low_damping, high_damping = damping_limits
    if not low_damping < high_damping:
        raise ValueError(f"damping_limits={damping_limits} must be (low, high) with low < high")
    if frequency_band is not None and not frequency_band[0] < frequency_band[1]:
        raise ValueError(f"frequency_band={frequency_band} must be (low, high) with low < high")
    criteria = StabilityCriteria(frequency_tol, damping_tol, mac_min)

    poles = result.poles
    frequency = poles["frequency_hz"].to_numpy()
    damping = poles["damping_ratio"].to_numpy()
    model_order = poles["model_order"].to_numpy()
    shapes = result.mode_shapes
    eligible = (damping >= low_damping) & (damping <= high_damping)
    eligible &= poles["mpc"].to_numpy() >= mpc_min
    if frequency_band is not None:
        eligible &= (frequency >= frequency_band[0]) & (frequency <= frequency_band[1])

    def candidates(order: int) -> np.ndarray:
        return np.flatnonzero(eligible & (model_order == order))

    window = orders[-library_orders - 1 : -1]
    references = _library(
        [candidates(order) for order in window], frequency, damping, shapes, criteria
    )
    heads = _assign(references, candidates(window[0]), frequency, damping, shapes, criteria)
    references, heads = references[heads >= 0], heads[heads >= 0]  # one-to-one conflicts
    selected_order: int | None = window[0] if references.size else None
    for order in reversed(orders[: -library_orders - 1]):
        if not references.size:
            break
        match = _assign(references, candidates(order), frequency, damping, shapes, criteria)
        if np.any(match < 0):
            break
        heads, selected_order = match, order

    heads = heads[np.argsort(frequency[heads], kind="stable")]
    modes = pd.DataFrame(
        {
            "frequency_hz": frequency[heads],
            "damping_ratio": damping[heads],
            "model_order": model_order[heads].astype(np.int64),
            "mpc": poles["mpc"].to_numpy()[heads],
            "stable": poles["stable"].to_numpy()[heads],
            "pole_index": heads.astype(np.int64),
        }
    )
    return ModeSelection(modes, shapes[:, heads], selected_order, window)
