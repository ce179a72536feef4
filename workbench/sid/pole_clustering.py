"""Pole clustering primitives of the automatic mode selection (:mod:`workbench.sid.selection`,
``selection="cluster"``): the pole distance d = |Δf| / max(f_a, f_b) + 1 - MAC, every pole's
distance to its nearest pole of the neighbouring model orders, Otsu's threshold, the cut
between physical and spurious poles, and single-linkage clusters as connected components.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from .assurance import mac, mac_pairs

__all__ = ["DISTANCE_FLOOR", "MAX_CLUSTER_DISTANCE", "otsu_threshold"]

#: Largest pole distance d = Δf/f + 1 - MAC ever used to join poles into one cluster: the
#: fixed limit of Magalhães et al. (2009); the data-derived threshold is capped at it.
MAX_CLUSTER_DISTANCE = 0.02
#: Pole distances below this count as equal when the split into physical and spurious
#: poles is sought (a relative frequency change of 1e-5 is below any estimate's scatter).
DISTANCE_FLOOR = 1e-5


def otsu_threshold(values: np.ndarray) -> float:
    """Otsu's threshold of a sample: the split minimising the within-group variance.

    Parameters
    ----------
    values : ndarray
        Finite values (at least two distinct).

    Returns
    -------
    float
        Midpoint between the largest value of the lower group and the smallest of the upper
        group; NaN when the values do not have two distinct values.

    Notes
    -----
    For the sorted values x_1 <= ... <= x_n, split k minimises
    k·var(x_1..x_k) + (n-k)·var(x_k+1..x_n), equivalently maximises the between-group
    variance k(n-k)(μ_1 - μ_2)²/n [1]_; only splits between distinct values count.

    References
    ----------
    .. [1] N. Otsu, "A threshold selection method from gray-level histograms", IEEE
       Transactions on Systems, Man, and Cybernetics 9(1), 62-66, 1979.
       doi:10.1109/TSMC.1979.4310076
    """
    x = np.sort(np.asarray(values, dtype=float).ravel())
    n = x.size
    if n < 2 or x[0] == x[-1]:
        return float("nan")
    k = np.arange(1, n)
    cumulative = np.cumsum(x)[:-1]
    mean_low = cumulative / k
    mean_high = (x.sum() - cumulative) / (n - k)
    between = k * (n - k) * (mean_low - mean_high) ** 2
    between[x[1:] == x[:-1]] = -1.0  # no split between equal values
    best = int(np.argmax(between))
    return float(0.5 * (x[best] + x[best + 1]))


def _pole_distance(frequency_a, shapes_a, frequency_b, shapes_b) -> np.ndarray:
    """d = |Δf| / max(f_a, f_b) + 1 - MAC, every pair (matrix n_a x n_b)."""
    relative = np.abs(frequency_a[:, None] - frequency_b[None, :]) / np.maximum(
        frequency_a[:, None], frequency_b[None, :]
    )
    return relative + 1.0 - np.atleast_2d(mac(shapes_a, shapes_b))


def _neighbour_distance(
    order_rank: np.ndarray, frequency: np.ndarray, shapes: np.ndarray, n_ranks: int
) -> np.ndarray:
    """Distance of every pole to its nearest pole of the neighbouring orders (1 if none)."""
    nearest = np.ones(frequency.size)
    members = [np.flatnonzero(order_rank == r) for r in range(n_ranks)]
    for r in range(n_ranks - 1):
        a, b = members[r], members[r + 1]
        if a.size == 0 or b.size == 0:
            continue
        distance = _pole_distance(frequency[a], shapes[:, a], frequency[b], shapes[:, b])
        nearest[a] = np.minimum(nearest[a], distance.min(axis=1))
        nearest[b] = np.minimum(nearest[b], distance.min(axis=0))
    return np.clip(nearest, 0.0, 1.0)


def _distance_cut(log_distance: np.ndarray) -> float:
    """Cut between physical and spurious poles from the log10 nearest-neighbour distances:
    the least populated distance (minimum of a Gaussian kernel density estimate) between
    Otsu's split and the fixed limit :data:`MAX_CLUSTER_DISTANCE`.

    Otsu's split separates the two groups but, when many poles recur very tightly, falls
    inside the physical group and would cut off the more scattered (more damped) modes;
    the density minimum above it lies in the gap before the spurious poles.
    """
    from scipy.stats import gaussian_kde

    top = np.log10(MAX_CLUSTER_DISTANCE)
    split = otsu_threshold(log_distance)
    if not np.isfinite(split) or split >= top:
        return MAX_CLUSTER_DISTANCE
    try:
        density = gaussian_kde(log_distance)
    except (np.linalg.LinAlgError, ValueError):  # too few or identical values
        return float(10.0**split)
    grid = np.linspace(split, top, 101)
    return float(10.0 ** grid[np.argmin(density(grid))])


def _components(frequency: np.ndarray, shapes: np.ndarray, cut: float) -> np.ndarray:
    """Single-linkage clusters cut at *cut*: connected components of d < cut.

    d >= |Δf|/max(f) so only pairs with f_b within [f_a, f_a / (1 - cut)) can be joined;
    they are found in frequency order and their MACs computed pairwise.
    """
    n = frequency.size
    if n == 0:
        return np.zeros(0, dtype=int)
    order = np.argsort(frequency, kind="stable")
    f = frequency[order]
    upper = np.searchsorted(f, f / (1.0 - cut), side="left")
    counts = np.maximum(upper - np.arange(n) - 1, 0)
    a = np.repeat(np.arange(n), counts)
    b = a + 1 + (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts))
    if a.size:
        relative = (f[b] - f[a]) / np.maximum(f[a], f[b])
        close = relative < cut
        a, b, relative = a[close], b[close], relative[close]
    if a.size:
        distance = relative + 1.0 - mac_pairs(shapes[:, order[a]], shapes[:, order[b]])
        joined = distance < cut
        a, b = a[joined], b[joined]
    graph = sparse.coo_matrix((np.ones(a.size), (a, b)), shape=(n, n))
    _, labels_sorted = connected_components(graph, directed=False)
    labels = np.empty(n, dtype=int)
    labels[order] = labels_sorted
    return labels
