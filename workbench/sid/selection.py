"""Automatic choice of the physical modes of one block from its stabilisation diagram.

Two rules; :func:`select_modes` uses ``selection="cluster"`` by default.

Clustering of the poles of all model orders (``selection="cluster"``)
----------------------------------------------------------------------
In the spirit of the hierarchical clustering of Magalhães et al. [1]_ and the multi-stage
procedures of Reynders et al. [2]_ and Neu et al. [3]_, with every threshold taken from the
diagram itself:

1. **Eligible poles**: inside the frequency band, 0 < ζ <= the upper damping limit, MPC
   above an optional floor. The *lower* damping limit (harmonics have ζ ≈ 0) is applied to
   a cluster's median damping, not to single poles: a real mode whose damping reads below
   the limit at one over-fitted order keeps that order's pole.
2. **Physical or spurious pole** (stage 1): the distance between two poles is
   d = |f_a - f_b| / max(f_a, f_b) + 1 - MAC(φ_a, φ_b). Every pole gets the distance to
   its nearest pole in the neighbouring model orders. Physical poles reappear at the next
   order almost unchanged (d ~ 1e-5..1e-3), spurious ones do not (d ~ 0.01..1): the
   logarithms of these distances fall into two groups, split by Otsu's threshold (the
   split minimising the within-group variance [4]_; distances below 1e-5 count as 1e-5,
   so that an exactly recurring harmonic does not pull the split below the modes). The
   threshold d_cut is the least populated distance (minimum of a Gaussian kernel density
   estimate of the log-distances) between Otsu's split and 0.02, the fixed limit of [1]_:
   the split alone can fall inside the physical group when many poles recur very
   tightly, and would cut off the more scattered, more damped modes.
3. **Clusters** (stage 2): single-linkage hierarchical clustering of the physical poles
   cut at d_cut - the connected components of the graph joining poles closer than
   d_cut. Only poles within d_cut in frequency can be joined, so the graph is built from a
   frequency-sorted window search and costs little even for thousands of poles. A cluster
   keeps one pole per model order (the one closest to its median frequency).
4. **Modes** (stage 3): a cluster is a mode when it holds poles of many orders: its number
   of orders must reach Otsu's threshold on the clusters' numbers of orders (physical modes
   recur over most orders, spurious groups over a few), but never above half the largest
   cluster's (when every cluster is a mode there is no group of small ones to split off),
   and at least ``min_orders``.
   Its median damping must lie within the damping limits. Two accepted clusters with
   frequencies within ``frequency_tol`` or :data:`NEAR_MODE` (3 %), whichever is wider,
   and shapes that agree (MAC above ``mac_min``) are one mode, and the larger cluster is
   kept: the smaller is the second pole an over-fitted model puts beside a strong mode
   (pLSCF at its upper orders: a per cent or so off, with the mode's shape, at part of
   the orders; ``benchmarks/results/identification_32c.txt``), and two modes of one
   shape a few per cent apart could not be told apart from output-only data anyway. The
   second look tests its clusters the same way.

5. **Second look** (``second_look=True``, close and weakly excited modes): where most
   modes recur to 1e-5 the cut of stage 1 is tight, and the poles of a mode whose shape
   estimate wanders between orders (a close neighbour mixes into it) or that appears only
   from a higher order on (weakly excited) fall apart into chains shorter than stage 3's
   threshold. The poles left over that recur within 0.02 are clustered again by complete
   linkage at 0.02 (no chaining into a neighbour), fragments at complementary orders are
   joined into columns (two close modes have poles at the *same* orders; one mode's
   fragments do not), and a column is a mode when it is order-consistent: long enough
   (0.8 x stage 3's threshold and 0.4 x the median length of the stage-3 modes), present
   at 80 % of the orders it spans (beside a close mode, an order also holds the column
   where a pole nearer its head than any other head, with its shape, was pulled out of
   it by the neighbour), no more scattered in frequency than twice the least consistent
   stage-3 mode (or, beside a close mode of another shape it coexists with, than a third
   of their separation: the neighbour pulls it), with a consistent damping ratio; near a selected
   mode (3 %) it must coexist with it at the orders of the shorter of the two and differ
   in shape (MAC below ``mac_min``, and by more than 3 x the scatter of the two shapes
   over their orders); farther away but inside that mode's resonance (overlapping
   half-power bands) it must differ in shape the same way. See :func:`_second_look`.

Each mode is reported by the cluster's median frequency and median damping ratio, the shape
(and ``pole_index``, ``model_order``, ``mpc``) of its pole nearest the median frequency,
and the cluster scatter (all over the cluster's orders; with
``frequency_from="consistent_orders"``, what ``identify`` uses for pLSCF, the frequency of
a cluster that drifts with the model order is the median of its lower orders,
:func:`_consistent_orders`): ``frequency_std_hz``, ``damping_std`` (sample standard deviations
over the cluster's poles) and ``n_poles`` (orders in the cluster) - a measurement-noise
estimate for the forecast's Kalman filter.

Library and descent (``selection="library"``, the rule of issue 5)
------------------------------------------------------------------
Applied to the poles that pass the sanity limits (frequency band, damping limits, optional
MPC floor):

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
simulated hull block lost modes far more often than with 50 %,
``benchmarks/results/docstring_numbers.txt``).

The lowest order at which all library modes exist is the most parsimonious model that
still holds every mode consistently seen at high order. Spurious noise poles are rarely
consistent over five orders; the damping limits remove harmonics (ζ ≈ 0, e.g. the shaft
line) and over-damped noise poles. On real recordings the rule is fragile: over-fitted
orders near the maximum disturb real modes (MAC < 0.98, ζ < 0.1 % at one order) and lose
them, which is why clustering is the default.

References
----------
.. [1] F. Magalhães, Á. Cunha, E. Caetano, "Online automatic identification of the modal
   parameters of a long span arch bridge", Mechanical Systems and Signal Processing 23(2),
   316-329, 2009. doi:10.1016/j.ymssp.2008.05.003
.. [2] E. Reynders, J. Houbrechts, G. De Roeck, "Fully automated (operational) modal
   analysis", Mechanical Systems and Signal Processing 29, 228-250, 2012.
   doi:10.1016/j.ymssp.2012.01.007
.. [3] E. Neu, F. Janser, A. A. Khatibi, A. C. Orifici, "Fully automated operational modal
   analysis using multi-stage clustering", Mechanical Systems and Signal Processing 84,
   308-323, 2017. doi:10.1016/j.ymssp.2016.07.031
.. [4] N. Otsu, "A threshold selection method from gray-level histograms", IEEE
   Transactions on Systems, Man, and Cybernetics 9(1), 62-66, 1979.
   doi:10.1109/TSMC.1979.4310076
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from .assurance import continuous_pole, mac
from .pole_clustering import (
    DISTANCE_FLOOR,
    MAX_CLUSTER_DISTANCE,
    _components,
    _distance_cut,
    _neighbour_distance,
    otsu_threshold,
)
from .ssi import SSIResult
from .ssi.results import _with_shapes
from .stabilisation import StabilityCriteria

__all__ = ["ModeSelection", "confirmed_second_look", "select_modes"]


@dataclass(frozen=True, eq=False)
class ModeSelection:
    """Modes chosen from one stabilisation diagram by :func:`select_modes`.

    Parameters
    ----------
    modes : pandas.DataFrame
        One row per selected mode, sorted by frequency: ``frequency_hz`` [Hz],
        ``damping_ratio`` [-], ``model_order``, ``mpc``, ``stable`` and ``pole_index``
        (row position in ``result.poles``); with ``selection="cluster"`` also the cluster
        scatter ``frequency_std_hz`` [Hz], ``damping_std`` [-] and ``n_poles``.
    mode_shapes : ndarray of complex, shape (n_channels, n_modes)
        Shapes of the selected modes, column k for row k. [-]
    model_order : int or None
        Order the modes were selected at (None if the library is empty, and for the
        clustering rule, whose modes come from several orders).
    library_orders : tuple of int
        Orders that formed the library (all orders of the diagram for clustering).
    method : {"cluster", "library"}
        The rule used.
    thresholds : dict
        The data-derived thresholds of the clustering rule: ``pole_distance`` (d_cut),
        ``min_orders`` (smallest number of orders of an accepted cluster),
        ``second_look`` (number of modes added by the second look) and
        ``second_look_poles`` (their ``pole_index`` values).
    """

    modes: pd.DataFrame
    mode_shapes: np.ndarray
    model_order: int | None
    library_orders: tuple[int, ...]
    method: str = "library"
    thresholds: dict = field(default_factory=dict)

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
        return _with_shapes(self.modes, self.mode_shapes, channels, block)


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
    selection: Literal["cluster", "library"] = "cluster",
    band_hz: tuple[float, float] | None = None,
    damping_limits: tuple[float, float] = (0.001, 0.10),
    min_orders: int = 3,
    pole_distance: float | None = None,
    library_orders: int = 5,
    frequency_tol: float = 0.01,
    damping_tol: float = 0.50,
    mac_min: float = 0.98,
    mpc_min: float = 0.0,
    second_look: bool = True,
    frequency_from: Literal["all_orders", "consistent_orders"] = "all_orders",
) -> ModeSelection:
    """Select the physical modes of a stabilisation diagram.

    Parameters
    ----------
    result : SSIResult
        Output of :func:`~workbench.sid.ssi.ssi_cov` or :func:`~workbench.sid.ssi.ssi_data`.
    selection : {"cluster", "library"}
        ``"cluster"``: clustering of the poles of all orders with thresholds taken from the
        diagram; ``"library"``: the library-and-descent rule (see the module docstring).
    band_hz : (float, float), optional
        Only poles with low <= f <= high are considered. [Hz]
    damping_limits : (float, float)
        Sanity limits of the damping ratio (harmonics have ζ ≈ 0, noise poles are often
        heavily damped). [-] ``"library"`` applies both to every pole; ``"cluster"``
        applies the upper one to poles and both to a cluster's median damping.
    min_orders : int
        ``"cluster"``: smallest number of model orders of a mode's cluster (the
        data-derived threshold is never below it).
    pole_distance : float, optional
        ``"cluster"``: a fixed cut d_cut of the pole distance instead of the data-derived
        one (e.g. 0.02 as in Magalhães et al. 2009). [-]
    library_orders : int
        ``"library"``: number of consecutive orders below the maximum that a mode must
        appear in to enter the library.
    frequency_tol : float
        ``"library"``: largest relative frequency difference between a pole and a
        reference pole; ``"cluster"``: two clusters closer than this or than
        :data:`NEAR_MODE`, whichever is wider, with MAC above ``mac_min`` are one mode. [-]
    damping_tol : float
        ``"library"``: largest relative damping difference between a pole and a reference
        pole. [-]
    mac_min : float
        Smallest MAC between a pole and a reference pole (``"library"``), or between the
        shapes of twin clusters (``"cluster"``). [-]
    mpc_min : float
        Smallest modal phase collinearity of a considered pole (0 disables). [-]
    second_look : bool
        ``"cluster"``: look again at the poles left over for close and weakly excited
        modes (stage 4 of the module docstring).
    frequency_from : {"all_orders", "consistent_orders"}
        ``"cluster"``: a mode's frequency is the median over all the orders of its column,
        or (``"consistent_orders"``, for pLSCF) over its lower orders where the column
        drifts with the model order (:func:`_consistent_orders`). Which modes are
        selected, their damping ratio, shape and scatter do not depend on it.

    Returns
    -------
    ModeSelection
        The selected modes (empty if no mode qualifies).

    Raises
    ------
    ValueError
        Bad limits; for ``"library"`` fewer than ``library_orders + 1`` orders.
    """
    if selection not in ("cluster", "library"):
        raise ValueError(f"selection={selection!r} must be 'cluster' or 'library'")
    low_damping, high_damping = damping_limits
    if not low_damping < high_damping:
        raise ValueError(f"damping_limits={damping_limits} must be (low, high) with low < high")
    if band_hz is not None and not band_hz[0] < band_hz[1]:
        raise ValueError(f"band_hz={band_hz} must be (low, high) with low < high")
    if selection == "library":
        return _select_library(
            result,
            frequency_band=band_hz,
            damping_limits=damping_limits,
            library_orders=library_orders,
            frequency_tol=frequency_tol,
            damping_tol=damping_tol,
            mac_min=mac_min,
            mpc_min=mpc_min,
        )
    if int(min_orders) < 2:
        raise ValueError(f"min_orders={min_orders} must be at least 2")
    if pole_distance is not None and not 0 < pole_distance <= 1:
        raise ValueError(f"pole_distance={pole_distance} must lie in (0, 1]")
    if frequency_from not in ("all_orders", "consistent_orders"):
        raise ValueError(
            f"frequency_from={frequency_from!r} must be 'all_orders' or 'consistent_orders'"
        )
    return _select_clusters(
        result,
        frequency_band=band_hz,
        damping_limits=damping_limits,
        min_orders=int(min_orders),
        pole_distance=pole_distance,
        frequency_tol=frequency_tol,
        mac_min=mac_min,
        mpc_min=mpc_min,
        second_look=second_look,
        consistent_orders=frequency_from == "consistent_orders",
    )


def _select_clusters(
    result: SSIResult,
    *,
    frequency_band: tuple[float, float] | None,
    damping_limits: tuple[float, float],
    min_orders: int,
    frequency_tol: float,
    mac_min: float,
    mpc_min: float,
    pole_distance: float | None = None,
    second_look: bool = True,
    consistent_orders: bool = False,
) -> ModeSelection:
    """The clustering rule of the module docstring (*consistent_orders*: a mode's frequency
    from :func:`_consistent_orders`)."""
    orders = tuple(sorted(result.orders))
    poles = result.poles
    frequency = poles["frequency_hz"].to_numpy(dtype=float)
    damping = poles["damping_ratio"].to_numpy(dtype=float)
    model_order = poles["model_order"].to_numpy()
    mpc = poles["mpc"].to_numpy(dtype=float)
    shapes = result.mode_shapes
    low_damping, high_damping = damping_limits
    eligible = np.isfinite(frequency) & (frequency > 0) & (damping > 0)
    eligible &= damping <= high_damping
    eligible &= mpc >= mpc_min
    if frequency_band is not None:
        eligible &= (frequency >= frequency_band[0]) & (frequency <= frequency_band[1])
    index = np.flatnonzero(eligible)
    thresholds: dict = {"pole_distance": float("nan"), "min_orders": int(min_orders)}

    def empty() -> ModeSelection:
        return _mode_selection(poles, shapes, np.zeros(0, dtype=int), {}, orders, thresholds)

    if index.size < 2:
        return empty()
    f, z, shape = frequency[index], damping[index], shapes[:, index]
    rank = np.searchsorted(np.asarray(orders), model_order[index])
    # stage 1: physical poles recur at a neighbouring order
    nearest = _neighbour_distance(rank, f, shape, len(orders))
    # distances below the resolution floor are all "the same pole again": an undamped
    # harmonic recurring to 1e-9 must not make the split fall between it and the modes
    log_nearest = np.log10(np.maximum(nearest, DISTANCE_FLOOR))
    cut = _distance_cut(log_nearest)
    cut = min(cut, MAX_CLUSTER_DISTANCE) if pole_distance is None else float(pole_distance)
    thresholds["pole_distance"] = float(cut)
    physical = np.flatnonzero(nearest < cut)
    if physical.size < 2:
        return empty()
    # stage 2: single-linkage clusters of the physical poles
    labels = _components(f[physical], shape[:, physical], cut)
    clusters = []
    for label in np.unique(labels):
        members = physical[labels == label]
        centre = np.median(f[members])
        # one pole per model order: the one closest to the median frequency
        by_order = np.lexsort((np.abs(f[members] - centre), rank[members]))
        members = members[by_order]
        first = np.concatenate(([True], rank[members][1:] != rank[members][:-1]))
        clusters.append(members[first])
    sizes = np.array([c.size for c in clusters])
    # stage 3: modes recur over many orders
    # Otsu's split of the cluster sizes, never above half the largest cluster: when every
    # cluster is a mode (no small groups to split off) Otsu would cut between modes
    size_cut = min(otsu_threshold(sizes), 0.5 * sizes.max())
    needed = max(int(min_orders), int(np.ceil(size_cut)) if np.isfinite(size_cut) else 0)
    thresholds["min_orders"] = needed
    accepted = [
        c for c in clusters if c.size >= needed and low_damping <= np.median(z[c]) <= high_damping
    ]
    accepted.sort(key=lambda c: -c.size)
    heads, statistics, kept_members = [], {}, []
    for members in accepted:
        centre = np.median(f[members])
        head = int(members[np.argmin(np.abs(f[members] - centre))])
        twin = False
        for other in heads:
            # the window of the second look's fragment test: a pole 1-3 % beside a mode
            # with its shape is a second pole of that mode, not a mode
            close = abs(f[head] / f[other] - 1.0) < max(frequency_tol, NEAR_MODE)
            if close and mac(shape[:, head], shape[:, other]) > mac_min:
                twin = True
                break
        if twin:
            continue
        heads.append(head)
        statistics[int(index[head])] = _cluster_statistics(
            f, z, members, rank if consistent_orders else None
        )
        kept_members.append(members)
    # stage 4: a second look at the poles left over, for close and weakly excited modes
    if second_look:
        taken = np.concatenate(kept_members) if kept_members else np.zeros(0, dtype=int)
        rescued = _second_look(
            f,
            z,
            shape,
            rank,
            nearest,
            taken,
            kept_members,
            len(orders),
            min_orders=needed_second_look(min_orders, needed),
            damping_limits=(low_damping, high_damping),
            mac_min=mac_min,
        )
        second_look_poles = []
        for members in rescued:
            centre = np.median(f[members])
            head = int(members[np.argmin(np.abs(f[members] - centre))])
            heads.append(head)
            statistics[int(index[head])] = _cluster_statistics(
                f, z, members, rank if consistent_orders else None
            )
            second_look_poles.append(int(index[head]))
        thresholds["second_look"] = len(rescued)
        thresholds["second_look_poles"] = tuple(sorted(second_look_poles))
    chosen = index[np.array(heads, dtype=int)]
    return _mode_selection(poles, shapes, chosen, statistics, orders, thresholds)


#: The second look's clusters need at least this share of stage 3's number of orders. [-]
SECOND_LOOK_SHARE = 0.8
#: ... and at least this share of the median number of orders of the stage-3 modes. [-]
SECOND_LOOK_KEPT_SHARE = 0.4
#: ... and poles at this share of the orders between their lowest and highest. [-]
SECOND_LOOK_CONTINUITY = 0.8
#: A second-look cluster within NEAR_MODE (relative) of a mode is a mode of its own only
#: when both have poles at this share of its orders (two poles of one model). [-]
SECOND_LOOK_COEXISTENCE = 0.75
#: Relative frequency distance within which a second-look cluster is tested against a mode
#: for being a fragment of it. [-]
NEAR_MODE = 0.03
#: Largest relative spread (median absolute deviation / median) of a second-look cluster's
#: damping ratios. [-]
SECOND_LOOK_DAMPING_SPREAD = 0.25
#: The second look clusters at most this many leftover poles (those recurring most
#: tightly), bounding its distance matrix.
MAX_SECOND_LOOK_POLES = 3000


#: A second-look column's relative frequency scatter is at most this multiple of the
#: largest of the stage-3 modes. [-]
SECOND_LOOK_SCATTER = 2.0
#: Two fragments are one column when their frequencies differ by less than this multiple
#: of their relative scatter (floored at FRAGMENT_FLOOR), their shapes have a MAC of at
#: least FRAGMENT_MAC, and they share at most FRAGMENT_SHARED of the smaller's orders.
FRAGMENT_SIGMA = 3.0
FRAGMENT_FLOOR = 1e-4
FRAGMENT_MAC = 0.8
FRAGMENT_SHARED = 0.2


def _one_per_order(members, f, rank) -> np.ndarray:
    """*members* reduced to one pole per model order (the one closest to their median)."""
    if members.size == 0:
        return members
    centre = np.median(f[members])
    members = members[np.lexsort((np.abs(f[members] - centre), rank[members]))]
    first = np.concatenate(([True], rank[members][1:] != rank[members][:-1]))
    return members[first]


def _join_fragments(fragments, f, shape, rank) -> list[np.ndarray]:
    """Fragments of one column joined: the poles of a mode whose shape estimate wanders
    from order to order (a close neighbour mixes into it) fall into several tight
    clusters at complementary orders; two close modes instead have poles at the same
    orders. Largest fragments first, each joins the first column it matches."""
    columns: list[np.ndarray] = []
    for members in sorted(fragments, key=lambda m: -m.size):
        centre = np.median(f[members])
        scatter = 1.4826 * np.median(np.abs(f[members] - centre)) / centre
        head = members[np.argmin(np.abs(f[members] - centre))]
        for k, column in enumerate(columns):
            column_centre = np.median(f[column])
            column_scatter = 1.4826 * np.median(np.abs(f[column] - column_centre)) / column_centre
            tolerance = FRAGMENT_SIGMA * max(scatter, column_scatter, FRAGMENT_FLOOR)
            if abs(centre / column_centre - 1.0) >= tolerance:
                continue
            shared = np.intersect1d(rank[members], rank[column]).size
            if shared > FRAGMENT_SHARED * min(members.size, column.size):
                continue
            column_head = column[np.argmin(np.abs(f[column] - column_centre))]
            if float(mac(shape[:, head], shape[:, column_head])) < FRAGMENT_MAC:
                continue
            columns[k] = _one_per_order(np.concatenate([column, members]), f, rank)
            break
        else:
            columns.append(members)
    return columns


def _orders_held(columns, kept, f, shape, rank, taken, min_orders) -> list[np.ndarray]:
    """The model orders at which each of *columns* holds a pole: its own poles' orders and
    those of the orders inside its span where an eligible pole of no stage-3 mode (*taken*)
    lies nearer to this column's head than to any other column's or mode's head (pole
    distance |Δf|/f + 1 - MAC), within :data:`NEAR_MODE` of it and with a MAC of at least
    :data:`FRAGMENT_MAC`.

    Two modes a per cent apart mix their shapes at some orders: there the model still holds
    a pole of each, but one the neighbour has pulled (MAC 0.85-0.95 with the mode's own,
    frequency a few 1e-3 off), whose distance to the next order exceeds the second look's
    limit or whose fragment is too far in frequency to be joined. Counting these orders
    measures order consistency by shape, as the physical mode is present at every order
    from its first on; a column of noise has no pole of its shape in its gaps.
    """
    from .pole_clustering import _pole_distance

    heads = []
    for members in [*columns, *kept]:
        centre = np.median(f[members])
        heads.append(int(members[np.argmin(np.abs(f[members] - centre))]))
    heads = np.asarray(heads, dtype=int)
    head_mac = np.atleast_2d(mac(shape[:, heads], shape[:, heads]))
    # poles of no stage-3 mode and of no column (a column's poles are its own)
    free = np.setdiff1d(np.arange(f.size), np.concatenate([taken, *columns]))
    out = []
    for k, members in enumerate(columns):
        low, high = rank[members].min(), rank[members].max()
        head = heads[k]
        near = free[
            (rank[free] >= low)
            & (rank[free] <= high)
            & (np.abs(f[free] / f[head] - 1.0) < NEAR_MODE)
            & ~np.isin(rank[free], rank[members])
        ]
        orders = rank[members]
        if near.size:
            # the other heads a pole may belong to: every stage-3 mode, and every column
            # that is not a fragment of this one (a fragment has its shape at other orders)
            rivals = [k]
            for j, other in enumerate(columns):
                shared = np.intersect1d(rank[members], rank[other]).size
                fragment = head_mac[k, j] >= FRAGMENT_MAC and shared <= FRAGMENT_SHARED * min(
                    members.size, other.size
                )
                if j != k and not fragment:
                    rivals.append(j)
            rivals.extend(range(len(columns), heads.size))
            # gaps are filled only beside a close mode that can pull this one's poles: a
            # stage-3 mode or a column long enough to be a mode, within NEAR_MODE
            close = [
                j
                for j in rivals[1:]
                if abs(f[heads[j]] / f[head] - 1.0) < NEAR_MODE
                and (j >= len(columns) or columns[j].size >= min_orders)
            ]
            if not close:
                out.append(np.unique(orders))
                continue
            distance = _pole_distance(
                f[near], shape[:, near], f[heads[rivals]], shape[:, heads[rivals]]
            )
            nearest_head = np.argmin(distance, axis=1) == 0
            similar = np.atleast_2d(mac(shape[:, near], shape[:, [head]]))[:, 0] >= FRAGMENT_MAC
            orders = np.union1d(orders, rank[near[nearest_head & similar]])
        out.append(np.unique(orders))
    return out


def needed_second_look(min_orders: int, needed: int) -> int:
    """Fewest orders of a cluster found by the second look."""
    return max(int(min_orders), int(np.ceil(SECOND_LOOK_SHARE * needed)))


def _cluster_statistics(f, z, members, rank=None) -> dict:
    """Median frequency and damping, their scatter and the number of orders of a cluster;
    with the poles' order ranks *rank*, the frequency is the median over the orders
    :func:`_consistent_orders` picks."""
    ddof = 1 if members.size > 1 else 0
    frequency = f[members] if rank is None else f[_consistent_orders(members, f, rank)]
    return {
        "frequency_hz": float(np.median(frequency)),
        "damping_ratio": float(np.median(z[members])),
        "frequency_std_hz": float(np.std(f[members], ddof=ddof)),
        "damping_std": float(np.std(z[members], ddof=ddof)),
        "n_poles": int(members.size),
    }


#: A column drifts with the model order when the medians of its lower and upper orders
#: differ by more than this multiple of its pole-to-pole scatter. [-]
ORDER_DRIFT_SIGMA = 2.0


def _consistent_orders(members, f, rank) -> np.ndarray:
    """The poles of a column (one per model order) its frequency is read from: the lower
    half of its orders where the column drifts with the order, else all of them.

    An over-fitted frequency-domain model shifts its physical poles with the order. pLSCF
    [1]_ fits the half-spectra by linear least squares of the equation error, whose pole
    estimates are biased by noise (the bias of least-squares all-pole fits to noisy data,
    [2]_); every order beyond the one that holds the band's modes adds r poles that fit
    noise and the spectral window, and those that fall into a resonance share its peak
    with the mode and pull its pole - most where a close neighbour shares the peak too
    (the lower mode of a 1 % pair in ``benchmarks/bench_close_weak.py``: 3.389-3.392 Hz at
    polynomial orders 2-6, 3.356-3.376 Hz at 9-15, the truth 3.4 Hz). The estimates of
    the orders all come from the same spectra: their median over more orders averages
    out little noise, but takes in the drift of the over-fitted orders.

    The column's *pole-to-pole scatter* is the robust standard deviation of its steps from
    one order to the next about their median step (1.4826 x MAD / √2, so a steady drift
    does not count as scatter). When the median of the upper half of its orders lies more
    than :data:`ORDER_DRIFT_SIGMA` such scatters from the median of the lower half, the
    orders do not estimate one frequency and the lower half, the least over-fitted models
    that hold the mode, is kept; otherwise all orders are (a column that agrees with
    itself keeps the median of all its poles). A drift is kept with a low threshold
    because the two errors cost differently: the lower half of a column that does not
    drift is still a median of its estimates, a drift taken in is a bias. Columns of
    fewer than four orders are kept whole. What this does to the selected modes of pLSCF
    on the close and weak modes of ``bench_close_weak.py`` (and to SSI, where it is not
    used): ``benchmarks/results/identification_32g.txt``.

    References
    ----------
    .. [1] B. Peeters, H. Van der Auweraer, P. Guillaume, J. Leuridan, "The PolyMAX
       frequency-domain method: a new standard for modal parameter estimation?", Shock
       and Vibration 11(3-4), 395-409, 2004. doi:10.1155/2004/523692
    .. [2] D. P. McGinn, D. H. Johnson, "Estimation of all-pole model parameters from
       noise-corrupted sequences", IEEE Transactions on Acoustics, Speech, and Signal
       Processing 37(3), March 1989.
    """
    members = members[np.argsort(rank[members], kind="stable")]
    if members.size < 4:
        return members
    frequency = f[members]
    lower = (members.size + 1) // 2
    step = np.diff(frequency)
    scatter = 1.4826 * np.median(np.abs(step - np.median(step))) / np.sqrt(2.0)
    drift = abs(np.median(frequency[lower:]) - np.median(frequency[:lower]))
    return members[:lower] if drift > ORDER_DRIFT_SIGMA * scatter else members


def _second_look(
    f, z, shape, rank, nearest, taken, kept, n_ranks, *, min_orders, damping_limits, mac_min
) -> list[np.ndarray]:
    """Clusters of close and weakly excited modes among the poles stage 3 left over.

    The data-derived cut of stage 1 is tight where most modes recur to 1e-5: the poles of a
    mode close to another (whose shapes mix from order to order) or weakly excited
    (present only from a higher order on, with more scatter) then fall apart into short
    single-linkage chains below stage 3's threshold. The second look takes the poles not in
    a selected mode that recur within the fixed limit :data:`MAX_CLUSTER_DISTANCE` (0.02),
    joins them by complete linkage at that limit (every pair of a cluster within it: no
    chaining from one mode into its neighbour) and keeps a cluster, one pole per order, as a
    mode when it is *order-consistent*:

    * poles at no fewer than :func:`needed_second_look` orders and
      :data:`SECOND_LOOK_KEPT_SHARE` of the median orders of the stage-3 modes, and at
      :data:`SECOND_LOOK_CONTINUITY` of the orders from its lowest to its highest (a weak
      mode appears from some order on and stays; noise recurs in patches); the orders are
      those the column holds (:func:`_orders_held`: beside a close mode also the orders
      where the neighbour pulled its pole out of the column);
    * frequency scatter (1.4826 x the median absolute deviation, relative) no larger than
      :data:`SECOND_LOOK_SCATTER` x the largest relative standard deviation of a stage-3
      mode's frequencies (without stage-3 modes there is no second look); a column that
      wanders more is a mode only beside a mode of another shape (MAC below
      :data:`FRAGMENT_MAC`) it coexists with and is separated from by at least
      :data:`FRAGMENT_SIGMA` x its scatter (the converse of the fragment join: the
      neighbour's pull explains the wander, and the two columns cannot be one);
    * median damping within the limits, damping spread (MAD / median) at most
      :data:`SECOND_LOOK_DAMPING_SPREAD`;
    * near a mode (within :data:`NEAR_MODE`), a mode of its own only if the two have poles
      at the same orders (at :data:`SECOND_LOOK_COEXISTENCE` of the orders of the shorter
      of the two: one model holds both) and their shapes differ (MAC below *mac_min*, and
      a shape of its own, :func:`_shape_of_its_own`); otherwise it is a fragment of that
      mode. Farther than :data:`NEAR_MODE` from a mode but inside its resonance
      (|f₁ - f₂| < ζ₁f₁ + ζ₂f₂: the half-power bands overlap) it needs a shape of its own
      too.

    Returns the clusters as arrays of positions (into *f*), largest first.
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    from .pole_clustering import _pole_distance

    low_damping, high_damping = damping_limits
    # no looser in frequency than the least consistent mode of stage 3
    max_scatter = max(
        (float(np.std(f[m], ddof=1) / np.median(f[m])) for m in kept if m.size > 1),
        default=0.0,
    )
    typical_length = float(np.median([m.size for m in kept])) if kept else 0.0
    pool = np.setdiff1d(np.flatnonzero(nearest < MAX_CLUSTER_DISTANCE), taken)
    if pool.size > MAX_SECOND_LOOK_POLES:
        pool = np.sort(pool[np.argsort(nearest[pool], kind="stable")[:MAX_SECOND_LOOK_POLES]])
    if pool.size < max(min_orders, 2):
        return []
    distance = _pole_distance(f[pool], shape[:, pool], f[pool], shape[:, pool])
    distance = np.clip(0.5 * (distance + distance.T), 0.0, None)
    np.fill_diagonal(distance, 0.0)
    tree = linkage(squareform(distance, checks=False), method="complete")
    labels = fcluster(tree, MAX_CLUSTER_DISTANCE, criterion="distance")
    fragments = [_one_per_order(pool[labels == label], f, rank) for label in np.unique(labels)]
    fragments = [m for m in fragments if m.size >= 2]
    columns = _join_fragments(fragments, f, shape, rank)
    held = _orders_held(columns, kept, f, shape, rank, taken, min_orders)
    candidates = []  # (members, orders held, relative scatter, needs a pulling neighbour)
    for members, orders_held in zip(columns, held, strict=True):
        centre = np.median(f[members])
        span = rank[members].max() - rank[members].min() + 1
        damping = np.median(z[members])
        spread = np.median(np.abs(z[members] - damping)) / damping if damping > 0 else np.inf
        scatter = 1.4826 * np.median(np.abs(f[members] - centre)) / centre
        if (
            orders_held.size >= min_orders
            and orders_held.size >= SECOND_LOOK_KEPT_SHARE * typical_length
            and orders_held.size >= SECOND_LOOK_CONTINUITY * span
            and low_damping <= damping <= high_damping
            and spread <= SECOND_LOOK_DAMPING_SPREAD
            and scatter < NEAR_MODE / FRAGMENT_SIGMA
        ):
            wanders = scatter > SECOND_LOOK_SCATTER * max_scatter
            candidates.append((members, orders_held, scatter, wanders))
    candidates.sort(key=lambda c: -c[0].size)
    modes = [(m, rank[m]) for m in kept]
    rescued = []
    # columns as consistent as the stage-3 modes first; then those that wander more, each
    # only beside a mode that explains it (see _pulled_by_neighbour)
    for second_pass in (False, True):
        for members, orders_held, scatter, wanders in candidates:
            if wanders != second_pass:
                continue
            centre = np.median(f[members])
            head = members[np.argmin(np.abs(f[members] - centre))]
            fragment, pulled = False, False
            for other, other_orders in modes:
                other_centre = np.median(f[other])
                separation = abs(centre / other_centre - 1.0)
                other_head = other[np.argmin(np.abs(f[other] - other_centre))]
                if separation >= NEAR_MODE:
                    # farther than NEAR_MODE, but inside the other mode's resonance (the
                    # half-power bands overlap) with no shape of its own: the fit's
                    # second pole of that resonance
                    overlap = abs(centre - other_centre) < (
                        np.median(z[members]) * centre + np.median(z[other]) * other_centre
                    )
                    if overlap and not _shape_of_its_own(members, head, other, other_head, shape):
                        fragment = True
                        break
                    continue
                # one model holds both wherever the shorter of the two has a pole (a
                # neighbour with gaps at the orders where the pair's shapes mix is no
                # fragment)
                shared = np.intersect1d(orders_held, other_orders).size
                similar = float(mac(shape[:, head], shape[:, other_head])) >= mac_min
                similar |= not _shape_of_its_own(members, head, other, other_head, shape)
                if similar or shared < SECOND_LOOK_COEXISTENCE * min(
                    orders_held.size, other_orders.size
                ):
                    fragment = True
                    break
                # a neighbour of its own shape pulls nothing: a column with a mode's
                # shape wandering beside it is a ghost of that mode
                distinct = float(mac(shape[:, head], shape[:, other_head])) < FRAGMENT_MAC
                pulled |= distinct and separation >= FRAGMENT_SIGMA * scatter
            if not fragment and (not wanders or pulled):
                modes.append((members, orders_held))
                rescued.append(members)
    return rescued


def _shape_angle(shapes, reference) -> np.ndarray:
    """Angle between each column of *shapes* and the shape *reference*: arccos √MAC. [rad]"""
    value = np.atleast_1d(mac(shapes, reference)).ravel()
    return np.arccos(np.sqrt(np.clip(value, 0.0, 1.0)))


def _shape_of_its_own(members, head, other, other_head, shape) -> bool:
    """Whether a column's shape differs from a neighbouring mode's by more than the scatter
    of the two shapes over their model orders.

    The scatter of a column is the median angle (arccos √MAC) of its poles' shapes from
    its head's; the column has a shape of its own when the angle between the two heads is
    more than :data:`FRAGMENT_SIGMA` times the larger scatter (the shape counterpart of the
    frequency test of :func:`_join_fragments`). A column that fails is, in shape, the
    neighbour itself, estimated again: an over-fitted model (pLSCF at its upper orders)
    puts several poles with a strong mode's shape into that mode's resonance, and the
    second look can string one of them into a column (a numerical splitting of one mode).
    How far the spurious second-look columns and the close pairs' true second modes lie
    from their neighbours' shapes, in units of that scatter, on the close and weak cases of
    ``benchmarks/bench_close_weak.py``: ``benchmarks/results/identification_32f.txt`` (the
    closest true pairs, 1 % apart with MAC 0.9, lie just beyond the limit).
    """
    scatter = max(
        float(np.median(_shape_angle(shape[:, members], shape[:, head]))),
        float(np.median(_shape_angle(shape[:, other], shape[:, other_head]))),
    )
    distance = float(_shape_angle(shape[:, head], shape[:, other_head])[0])
    return distance > FRAGMENT_SIGMA * scatter


def _mode_selection(poles, shapes, heads, statistics, orders, thresholds) -> ModeSelection:
    """ModeSelection of the clustering rule from the representative poles *heads*."""
    heads = np.asarray(heads, dtype=int)
    stats = [statistics[int(h)] for h in heads]
    frequency = np.array([s["frequency_hz"] for s in stats], dtype=float)
    order = np.argsort(frequency, kind="stable")
    heads, stats, frequency = heads[order], [stats[k] for k in order], frequency[order]
    modes = pd.DataFrame(
        {
            "frequency_hz": frequency,
            "damping_ratio": np.array([s["damping_ratio"] for s in stats], dtype=float),
            "model_order": poles["model_order"].to_numpy()[heads].astype(np.int64),
            "mpc": poles["mpc"].to_numpy()[heads].astype(float),
            "stable": poles["stable"].to_numpy()[heads].astype(bool),
            "pole_index": heads.astype(np.int64),
            "frequency_std_hz": np.array([s["frequency_std_hz"] for s in stats], dtype=float),
            "damping_std": np.array([s["damping_std"] for s in stats], dtype=float),
            "n_poles": np.array([s["n_poles"] for s in stats], dtype=np.int64),
        }
    )
    return ModeSelection(modes, shapes[:, heads], None, orders, "cluster", dict(thresholds))


def _select_library(
    result: SSIResult,
    *,
    frequency_band: tuple[float, float] | None,
    damping_limits: tuple[float, float],
    library_orders: int,
    frequency_tol: float,
    damping_tol: float,
    mac_min: float,
    mpc_min: float,
) -> ModeSelection:
    """The library-and-descent rule of the module docstring (options checked and described
    by :func:`select_modes`).

    With orders o_1 < … < o_K the library is built on o_{K-L}, …, o_{K-1}
    (L = ``library_orders``), then the descent visits o_{K-L-1}, o_{K-L-2}, … and stops at
    the first order missing a member; the modes are the poles matched to the library at the
    last complete order.
    """
    orders = tuple(sorted(result.orders))
    if library_orders < 1 or len(orders) < library_orders + 1:
        raise ValueError(
            f"library_orders={library_orders} needs a diagram with at least "
            f"{library_orders + 1} orders, got {len(orders)}"
        )
    low_damping, high_damping = damping_limits
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
    return ModeSelection(modes, shapes[:, heads], selected_order, window, "library")


#: A second-look mode is confirmed by a mode of another estimate within this relative
#: frequency difference ... [-]
CONFIRM_FREQUENCY_TOL = 0.01
#: ... whose shape has at least this MAC with it (the pairing of
#: :func:`~workbench.sid.combined.combine_modes`). [-]
CONFIRM_MAC = 0.8
#: The frequency tolerance of a confirmation widens to this share of the mode's relative
#: distance to its nearest neighbouring mode in the block (at most NEAR_MODE): a mode
#: that moves inside a non-stationary block (ice: 1-2 % within minutes) differs between
#: the halves by more than CONFIRM_FREQUENCY_TOL, and a half's mode nearer to it than to
#: any other mode cannot be another mode's. [-]
CONFIRM_NEIGHBOUR_SHARE = 0.5


def confirmed_second_look(
    selection: ModeSelection,
    others: Sequence[ModeSelection],
    *,
    frequency_tol: float = CONFIRM_FREQUENCY_TOL,
    mac_min: float = CONFIRM_MAC,
    neighbour_share: float = CONFIRM_NEIGHBOUR_SHARE,
) -> ModeSelection:
    """*selection* without the second-look modes that no estimate in *others* confirms.

    The second look (:func:`_second_look`) finds shorter, looser columns than stage 3: the
    modes of close pairs and weakly excited modes, and now and then a column of the
    estimator's own (a noise pattern of this record's model). A structural mode is in the
    data throughout a stationary block, so an independent estimate - another method on the
    same block (:func:`~workbench.sid.combined.combine_modes`), or the same method on each
    half of the block (``identify``'s default, :func:`~workbench.identification.engine.
    identify_block`) - shows it too. A second-look mode is kept when a mode of one of
    *others* lies near it with a MAC of at least *mac_min* and is nearer to it than to any
    other mode of *selection* (pole distance |Δf|/f + 1 - MAC): a mode of the other
    estimate confirms one mode only, so the strong mode beside an estimator's second pole a
    per cent off (pLSCF's over-fitted orders) confirms itself, not that pole. *Near* is
    within *frequency_tol*, or *neighbour_share* of the mode's relative distance to the
    nearest other mode of *selection* where that is wider (at most :data:`NEAR_MODE`): a
    mode that moves inside the block (ice) reads differently in the halves, and a mode far
    from any other can be confirmed across that move. Stage-3 modes are kept as they
    are.

    The thresholds gain ``second_look_unconfirmed`` (modes left out); ``second_look`` and
    ``second_look_poles`` count the modes kept. With no other estimate (*others* empty)
    nothing is judged and *selection* is returned unchanged.
    """
    poles = selection.thresholds.get("second_look_poles", ())
    modes = selection.modes
    if not len(poles) or not others or "pole_index" not in modes.columns:
        return selection
    from .pole_clustering import _pole_distance

    second = modes["pole_index"].isin(poles).to_numpy()
    frequency = modes["frequency_hz"].to_numpy(dtype=float)
    separation = np.abs(frequency[:, None] / frequency[None, :] - 1.0)
    np.fill_diagonal(separation, np.inf)
    tolerance = np.clip(neighbour_share * separation.min(axis=1), frequency_tol, None)
    tolerance = np.minimum(tolerance, max(frequency_tol, NEAR_MODE))
    confirmed = np.zeros(len(modes), dtype=bool)
    for other in others:
        other_frequency = other.modes["frequency_hz"].to_numpy(dtype=float)
        if not other_frequency.size:
            continue
        # each mode of the other estimate speaks for the mode of this block nearest to it
        # (frequency and shape): the strong mode a half finds beside a column 1 % off
        # confirms that mode, not the column
        distance = _pole_distance(
            other_frequency, other.mode_shapes, frequency, selection.mode_shapes
        )
        nearest = np.argmin(distance, axis=1)
        shape_mac = np.atleast_2d(mac(other.mode_shapes, selection.mode_shapes))
        for j, k in enumerate(nearest):
            if (
                abs(other_frequency[j] / frequency[k] - 1.0) < tolerance[k]
                and shape_mac[j, k] >= mac_min
            ):
                confirmed[k] = True
    keep = ~second | confirmed
    if keep.all():
        return dataclasses.replace(
            selection, thresholds={**selection.thresholds, "second_look_unconfirmed": 0}
        )
    kept_poles = tuple(int(p) for p in modes["pole_index"].to_numpy()[keep & second])
    thresholds = {
        **selection.thresholds,
        "second_look": len(kept_poles),
        "second_look_poles": kept_poles,
        "second_look_unconfirmed": int((~keep).sum()),
    }
    return dataclasses.replace(
        selection,
        modes=modes[keep].reset_index(drop=True),
        mode_shapes=selection.mode_shapes[:, keep],
        thresholds=thresholds,
    )
