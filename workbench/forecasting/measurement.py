"""What the Kalman blend measures in each block: the tracked pole (option A) or a consistent
pole cluster of the stabilisation diagram (option B), and how uncertain that block's
estimate is.

A physical mode shows up in a stabilisation diagram as a *column*: poles at many model
orders with nearly the same frequency and damping ratio. Noise poles scatter; a spurious
column (a lightly damped propeller harmonic, an ice-impact transient) is consistent too but
has a damping ratio unlike the mode's. Hence:

* :func:`cluster_around` - the poles of a block within a relative half-width of a
  frequency, summarised as a :class:`PoleCluster` (distinct orders, median frequency and
  damping, robust frequency scatter);
* :class:`ClusterChooser` - option B: inside the prediction gate, the candidate cluster
  with the best score

  .. math:: s = \\frac{n_{orders}}{n_{max}} - \\frac{|\\ln(ζ_c / ζ_{ref})|}{\\ln 3}
            - \\frac{|f_c - x^-|}{4 g},

  (n_max the most orders of any cluster in the block's diagram, ζ_ref the mode's damping
  ratio so far, g the gate), with at least :data:`MIN_ORDERS` orders and, once the mode
  has been chosen in 5 blocks, at least half the median orders of its last 36 clusters
  (a mode's column keeps its length; a short consistent column is a transient such as an
  ice impact, usually in a block where the mode is not excited) and a damping ratio within
  x3 of ζ_ref (a prediction that the model moved can put the gate on a propeller harmonic
  sweeping past, with ζ a fifth of the mode's, and the mode's own column outside it; the
  harmonic taken there pulled ζ_ref and the filter with it for 30 blocks:
  ``benchmarks/results/forecast_holdout_53.txt``); with mode shapes,
  only poles whose MAC with the mode's reference shape (the consensus of its recent
  tracked shapes, :mod:`workbench.forecasting.shape_reference`) is at least
  ``shape_mac_min`` count. The chosen cluster is grown to its whole column
  (:meth:`ClusterChooser._column`) and the measurement is the column's median frequency.
  When the gate holds no such cluster, the best one outside it within ``reacquire_band``
  (same tests) is the measurement, flagged
  ``outside_gate``: the Kalman update's Huber weight and its persistence rule, not a
  count of blocks here, tell an outlier stretch from a mode that moved;
* :func:`measurable_poles` - the poles option B may measure: not those marked as a shaft
  or blade-pass harmonic (``harmonic`` column), except in the column of a mode's tracked
  pole of their block (an order sitting on the mode: SSI finds one pole for both; option
  A, which reads the poles only for its scale, leaves every marked pole out);
* :func:`nearer_to_another_mode` - without shapes, the check of a pick against the other
  modes' tracked poles of the block (a close neighbour's column is not the mode);
* the per-block measurement scale: the cluster's frequency scatter across model orders,
  relative to the mode's typical scatter (:func:`scatter_scale`), which multiplies the
  measurement-noise variances of that block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = [
    "ClusterChooser",
    "PoleCluster",
    "PoleIndex",
    "cluster_around",
    "measurable_poles",
    "nearer_to_another_mode",
    "scatter_scale",
]

#: Fewest distinct model orders of a consistent cluster.
MIN_ORDERS = 3
#: A mode's cluster needs at least this fraction of the median orders of its recent ones.
_MIN_LENGTH_FRACTION = 0.5
#: Recent clusters remembered per mode, and how many before the rule applies.
_LENGTH_HISTORY = 36
_MIN_LENGTH_HISTORY = 5
#: Relative half-width of a cluster about its centre. [-]
CLUSTER_HALF_WIDTH = 2e-3
#: A chosen cluster grows to the poles within this many robust standard deviations. [-]
_COLUMN_SIGMA = 3.0
#: Bounds of the per-block measurement scale. [-]
SCALE_BOUNDS = (0.3, 6.0)
#: Scale of a block whose estimate has no cluster of MIN_ORDERS orders around it. [-]
NO_CLUSTER_SCALE = 3.0


@dataclass(frozen=True)
class PoleCluster:
    """Poles of one block around one frequency.

    Parameters
    ----------
    n_orders : int
        Distinct model orders.
    frequency_hz : float
        Median frequency. [Hz]
    damping_ratio : float
        Median damping ratio. [-]
    scatter_hz : float
        Robust standard deviation of the frequencies (1.4826 MAD; half the range for two
        poles). [Hz]
    min_order, max_order : int
        Lowest and highest model order.
    """

    n_orders: int
    frequency_hz: float
    damping_ratio: float
    scatter_hz: float
    min_order: int
    max_order: int


class PoleIndex:
    """The pole table sorted by block, with each grid row's slice (internal helper)."""

    def __init__(self, poles: pd.DataFrame, blocks: np.ndarray):
        needed = ("block", "model_order", "frequency_hz", "damping_ratio", "stable")
        missing = [c for c in needed if c not in poles.columns]
        if missing:
            raise ValueError(f"poles lacks column(s) {missing}")
        order = np.lexsort(
            (
                poles["frequency_hz"].to_numpy(dtype=float),
                poles["block"].to_numpy(dtype=np.int64),
            )
        )
        self.rows = order
        block = poles["block"].to_numpy(dtype=np.int64)[order]
        self.frequency = poles["frequency_hz"].to_numpy(dtype=float)[order]
        self.order = poles["model_order"].to_numpy(dtype=float)[order]
        self.damping = poles["damping_ratio"].to_numpy(dtype=float)[order]
        self.lo = np.searchsorted(block, blocks, side="left")
        self.hi = np.searchsorted(block, blocks, side="right")

    def block(self, i: int) -> slice:
        return slice(int(self.lo[i]), int(self.hi[i]))


def _summary(frequency, damping, order) -> PoleCluster:
    n_orders = int(np.unique(order).size)
    centre = float(np.median(frequency))
    if frequency.size >= 3:
        scatter = 1.4826 * float(np.median(np.abs(frequency - centre)))
    else:
        scatter = float(np.ptp(frequency)) / 2.0
    return PoleCluster(
        n_orders,
        centre,
        float(np.median(damping)),
        scatter,
        int(np.min(order)),
        int(np.max(order)),
    )


def cluster_around(
    index: PoleIndex, i: int, frequency_hz: float, half_width: float = CLUSTER_HALF_WIDTH
) -> PoleCluster | None:
    """The poles of grid row *i* within ±half_width x frequency of *frequency_hz*."""
    part = index.block(i)
    f = index.frequency[part]
    if f.size == 0 or not np.isfinite(frequency_hz):
        return None
    delta = half_width * abs(frequency_hz)
    a, b = np.searchsorted(f, [frequency_hz - delta, frequency_hz + delta + 1e-15])
    if b <= a:
        return None
    s = slice(part.start + a, part.start + b)
    return _summary(index.frequency[s], index.damping[s], index.order[s])


def measurable_poles(poles: pd.DataFrame, modal: pd.DataFrame, option: str = "B") -> pd.DataFrame:
    """The poles a measurement option reads: those not marked as a harmonic and, for option
    B, the marked ones within ±:data:`CLUSTER_HALF_WIDTH` of a tracked pole of their block.

    Parameters
    ----------
    poles : DataFrame
        Stabilisation diagrams (POLES contract); ``harmonic`` (the order, 0 when found from
        the data, NaN for a mode: :func:`workbench.sid.harmonics.mark_poles`) marks the
        poles of a shaft or blade-pass harmonic. Without that column every pole is kept.
    modal : DataFrame
        Tracked modal table: block, frequency_hz.
    option : {"B", "A"}
        ``"A"`` measures the tracked pole and reads the poles only for each block's
        measurement scale (:func:`cluster_around`): every marked pole is left out, so a
        block whose column is marked has no cluster and the larger
        :data:`NO_CLUSTER_SCALE` (less trust in an SSI estimate an order sits on).

    Returns
    -------
    DataFrame
        The rows of *poles* kept, in their order, with a fresh index.

    Notes
    -----
    A pole is marked when it lies within ``frequency_tol`` of a selected mode marked as an
    order and its shape matches that mode's. Where an order sits on a hull mode, SSI finds
    one pole for both: the selected mode is marked, tracking keeps it as the mode's row (its
    shape joins the mode's label) and option A measures it. The marked poles of that column
    are then the mode's own; leaving them out left option B nothing to measure in those
    blocks, and its blend ran on the model alone, worse than the raw SSI
    (``benchmarks/results/harmonics_option_b_52.txt``). A marked pole away from every
    tracked pole of its block is the harmonic's and is never measured.
    """
    if "harmonic" not in poles.columns:
        return poles
    marked = poles["harmonic"].notna().to_numpy()
    if not marked.any() or option != "B":
        return poles.loc[~marked].reset_index(drop=True)
    tracked = modal.loc[np.isfinite(modal["frequency_hz"].to_numpy(dtype=float))]
    tracked = tracked.sort_values(["block", "frequency_hz"], kind="stable")
    tracked_block = tracked["block"].to_numpy(dtype=np.int64)
    tracked_hz = tracked["frequency_hz"].to_numpy(dtype=float)
    block = poles["block"].to_numpy(dtype=np.int64)[marked]
    frequency = poles["frequency_hz"].to_numpy(dtype=float)[marked]
    lo = np.searchsorted(tracked_block, block, side="left")
    hi = np.searchsorted(tracked_block, block, side="right")
    near = np.zeros(block.size, dtype=bool)
    for k in range(block.size):  # a block's tracked poles: a handful
        if hi[k] > lo[k]:
            f = tracked_hz[lo[k] : hi[k]]
            near[k] = bool((np.abs(frequency[k] - f) <= CLUSTER_HALF_WIDTH * f).any())
    keep = ~marked
    keep[np.flatnonzero(marked)[near]] = True
    return poles.loc[keep].reset_index(drop=True)


def scatter_scale(scatter_hz: float, typical_scatter_hz: float) -> float:
    """Per-block measurement scale (scatter / typical scatter)², clipped to SCALE_BOUNDS."""
    if not (np.isfinite(scatter_hz) and np.isfinite(typical_scatter_hz)):
        return NO_CLUSTER_SCALE if not np.isfinite(scatter_hz) else 1.0
    if typical_scatter_hz <= 0:
        return 1.0
    return float(np.clip((max(scatter_hz, 0.0) / typical_scatter_hz) ** 2, *SCALE_BOUNDS))


def nearer_to_another_mode(pick_hz: float, j: int, anchors_hz: np.ndarray) -> bool:
    """Whether option B's pick for mode j lies nearer to another mode than to mode j.

    *anchors_hz* (n_modes,) holds each mode's frequency in the block: its tracked pole when
    the tracked table has one, else its a-priori estimate (NaN: unknown). Without mode
    shapes a consistent cluster in the gate of a mode may be the column of a close
    neighbour (5.2 and 5.5 Hz on the demo hull); a pick nearer (strictly) to another mode's
    anchor than to the mode's own is that neighbour, and a pick equal to another mode's
    tracked pole is the neighbour's measurement. NaN pick or own anchor: False (nothing to
    compare).
    """
    own = anchors_hz[j]
    if not (np.isfinite(pick_hz) and np.isfinite(own)):
        return False
    others = np.delete(anchors_hz, j)
    others = others[np.isfinite(others)]
    if others.size == 0:
        return False
    return bool(np.min(np.abs(others - pick_hz)) < abs(own - pick_hz))


@dataclass
class Choice:
    """Option B's choice for one mode in one block (internal).

    ``outside_gate``: the cluster is the mode's column seen only outside the gate (a
    measurement the Kalman update weights down, see :meth:`ClusterChooser.choose`; the
    forecast table's ``warning`` names such rows). The prior is never reset onto it.
    """

    cluster: PoleCluster
    mac: float
    outside_gate: bool = False


class ClusterChooser:
    """Option B: the consistent pole cluster inside the gate (module docstring).

    Parameters
    ----------
    index : PoleIndex
    shape_mac : callable or None
        ``shape_mac(i, j, rows)`` -> MAC of the poles *rows* (positions in *index*) with
        mode j's reference shape at grid row i (NaN: no reference); None without shapes.
    shape_mac_min : float
    reacquire_blocks : int
        Consecutive blocks with the mode's column only outside the gate (inside
        ±reacquire_band) before it is measured there; it stays the measurement while the
        column stays outside (1: at once).
    reacquire_band : float
        Relative half-width about the prediction searched when the gate holds no cluster
        of the mode. [-]
    """

    def __init__(self, index, shape_mac, *, shape_mac_min, reacquire_blocks, reacquire_band):
        self.index = index
        self.shape_mac = shape_mac
        self.mac_min = float(shape_mac_min)
        self.reacquire_blocks = int(reacquire_blocks)
        self.band = float(reacquire_band)
        self.misses: dict[int, int] = {}  # consecutive blocks seen only outside the gate
        self.lengths: dict[int, list[int]] = {}  # orders of each mode's recent clusters

    def _shortest(self, j: int) -> int:
        """Fewest orders a cluster of mode j needs: half its recent typical column.

        A mode's column in the stabilisation diagram keeps its length from block to block;
        a much shorter consistent column in the gate is a transient (an ice impact, a
        harmonic sweeping past) - most often while the mode itself is not excited, when
        taking it would pull the filter away for the whole gap.
        """
        recent = self.lengths.get(j, [])
        if len(recent) < _MIN_LENGTH_HISTORY:
            return MIN_ORDERS
        return max(MIN_ORDERS, int(math.ceil(_MIN_LENGTH_FRACTION * float(np.median(recent)))))

    def _accepted(self, j: int, cluster) -> None:
        recent = self.lengths.setdefault(j, [])
        recent.append(cluster.n_orders)
        del recent[:-_LENGTH_HISTORY]

    def _clusters(self, i, j, lo_hz, hi_hz):
        """Candidate clusters of row i between lo_hz and hi_hz (with MAC filter)."""
        part = self.index.block(i)
        f_all = self.index.frequency[part]
        a, b = np.searchsorted(f_all, [lo_hz, hi_hz])
        if b - a < 1:
            return [], 0
        pos = np.arange(part.start + a, part.start + b)
        macs = np.full(pos.size, np.nan)
        if self.shape_mac is not None:
            macs = self.shape_mac(i, j, pos)
            if np.isfinite(macs).any():
                with np.errstate(invalid="ignore"):
                    keep = macs >= self.mac_min
                pos, macs = pos[keep], macs[keep]
        if pos.size == 0:
            return [], 0
        f = self.index.frequency[pos]
        out = []
        used = np.zeros(pos.size, dtype=bool)
        # density peaks: the pole with the most distinct orders within ±half-width, greedy
        order = self.index.order[pos]
        width = CLUSTER_HALF_WIDTH * f
        counts = np.array(
            [np.unique(order[np.abs(f - f[p]) <= width[p]]).size for p in range(pos.size)]
        )
        for p in np.argsort(-counts, kind="stable"):
            if used[p]:
                continue
            member = (np.abs(f - f[p]) <= width[p]) & ~used
            used |= member
            cluster = _summary(f[member], self.index.damping[pos[member]], order[member])
            mac = float(np.nanmedian(macs[member])) if np.isfinite(macs[member]).any() else math.nan
            out.append((cluster, mac))
        return out, int(counts.max())

    def choose(
        self, i: int, j: int, prior_hz: float, gate_hz: float, damping_ref: float
    ) -> Choice | None:
        """The measurement of mode j in grid row i, or None (predict-only)."""
        if not (np.isfinite(prior_hz) and np.isfinite(gate_hz)):
            return None
        shortest = self._shortest(j)
        candidates, _ = self._clusters(i, j, prior_hz - gate_hz, prior_hz + gate_hz)
        candidates = [c for c in candidates if c[0].n_orders >= shortest]
        best = self._best(candidates, prior_hz, gate_hz, damping_ref)
        if best is not None:
            best = self._column(i, j, best, gate_hz)
            self.misses[j] = 0
            self._accepted(j, best[0])
            return Choice(best[0], best[1])
        # outside the gate (within the band): the column that passes the same tests and
        # has the mode's damping ratio (within x3) is the mode displaced, by an
        # identification error (an outlier stretch: the blocks sharing a corrupted stretch of
        # data all show it) or because the mode moved away from the model. It is the
        # block's measurement either way: the Kalman update's Huber weight bounds the pull of
        # an outlier, and a run of large innovations of one sign longer than the blocks
        # sharing data makes the filter follow a mode that moved (kalman_update).
        band = self.band * abs(prior_hz)
        outside, _ = self._clusters(i, j, prior_hz - band, prior_hz + band)
        outside = [
            c
            for c in outside
            if abs(c[0].frequency_hz - prior_hz) > gate_hz and c[0].n_orders >= shortest
        ]
        best = self._best(outside, prior_hz, band, damping_ref)
        if best is None:  # the mode is not seen in this block: no evidence either way
            return None
        self.misses[j] = self.misses.get(j, 0) + 1
        if self.misses[j] < self.reacquire_blocks:
            return None
        self._accepted(j, best[0])
        return Choice(best[0], best[1], outside_gate=True)

    def _column(self, i, j, chosen, gate_hz):
        """The whole column of the chosen cluster: its poles across the model orders.

        A cluster is the densest ±CLUSTER_HALF_WIDTH group; when the block's poles scatter
        across the orders by more than that (a poorly identified block, ice), the mode's
        column splits into several such groups, and the one kept is one end or the other
        of the column, partly chosen by its distance to the prediction. The column is
        re-centred instead: the poles (with shapes: those passing the MAC check) within
        ``_COLUMN_SIGMA`` robust standard deviations of the members' median, at least the
        half-width and at most the gate, repeated until the members no longer change. The
        measurement is then the median of the column, the estimate a stabilisation
        diagram's reader would take.
        """
        cluster, mac = chosen
        part = self.index.block(i)
        f_all = self.index.frequency[part]
        centre, members = cluster.frequency_hz, None
        for _ in range(8):
            width = min(
                max(CLUSTER_HALF_WIDTH * abs(centre), _COLUMN_SIGMA * cluster.scatter_hz),
                gate_hz,
            )
            a, b = np.searchsorted(f_all, [centre - width, centre + width + 1e-15])
            pos = np.arange(part.start + a, part.start + b)
            macs = np.full(pos.size, np.nan)
            if self.shape_mac is not None and pos.size:
                macs = self.shape_mac(i, j, pos)
                if np.isfinite(macs).any():
                    with np.errstate(invalid="ignore"):
                        mac_keep = macs >= self.mac_min
                    pos, macs = pos[mac_keep], macs[mac_keep]
            if pos.size == 0 or (members is not None and np.array_equal(pos, members)):
                break
            members = pos
            cluster = _summary(
                self.index.frequency[pos], self.index.damping[pos], self.index.order[pos]
            )
            mac = float(np.nanmedian(macs)) if np.isfinite(macs).any() else math.nan
            centre = cluster.frequency_hz
        return cluster, mac

    @staticmethod
    def _best(candidates, prior_hz, gate_hz, damping_ref):
        """The candidate with the best score (module docstring) among those with at least
        MIN_ORDERS orders and a damping ratio within x3 of *damping_ref*; None if none."""
        good = [c for c in candidates if c[0].n_orders >= MIN_ORDERS]
        if not good:
            return None
        n_max = max(c[0].n_orders for c in good)
        best, best_score = None, -math.inf
        for cluster, mac in good:
            damping_term = 0.0
            if np.isfinite(damping_ref) and damping_ref > 0 and cluster.damping_ratio > 0:
                damping_term = abs(math.log(cluster.damping_ratio / damping_ref)) / math.log(3.0)
                if damping_term > 1.0:  # not the mode's damping: a harmonic, a transient
                    continue
            score = (
                cluster.n_orders / n_max
                - damping_term
                - abs(cluster.frequency_hz - prior_hz) / (4 * gate_hz)
            )
            if score > best_score:
                best, best_score = (cluster, mac), score
        return best
