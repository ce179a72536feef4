"""Shaft and blade-pass harmonics: which selected modes and poles are orders of the shaft.

A ship's hull carries the shaft rate, its orders and the blade-pass rate (blades x shaft
rate). They are forced responses: their frequency follows the shaft speed exactly
(order x rpm / 60), they sweep with the ship's speed and cross the structural modes, and
SSI identifies them as lightly damped poles whose shape is the hull's forced deflection.
This module marks them, so that tracking keeps them out of the modal tables.

Two tests, by what the ship log offers:

* **Shaft speed logged** (:func:`mark_shaft_orders`): a selected mode is order k of the
  shaft when a large share of the order's energy in the block lies within a relative
  tolerance of the mode's frequency. The order's frequency is k x rpm(t) / 60 at every
  logged time of the block, and its energy is weighted by rpm⁴ (propeller and shaft-line
  forces grow as the square of the rate, their power as its fourth power). A harmonic's
  pole sits where its energy is; a structural mode that an order only sweeps past (a
  speed ramp) holds a small share and is kept.
* **Speed logged, shaft speed not** (:func:`mark_speed_following`): with a fixed-pitch
  propeller the shaft rate is proportional to the speed, so a harmonic's frequency over
  its energy-weighted block speed, f / v, is the same in every block, while its shape (the
  forced deflection) stays fixed. A selected mode is marked (order unknown, ``0``) when at
  least ``min_rows`` selected modes share its shape (MAC) and its ratio f / v and their
  frequencies spread over more than ``min_sweep``: a structural mode's frequency moves by a
  few per cent with speed, temperature and loading, never in proportion to the speed.

A logged shaft speed that stays put while the speed changes by a knot or more is either a
controllable-pitch propeller (the orders stay at the logged rate's orders) or a frozen log
(the harmonics follow the speed): :func:`shaft_log_against_speed` compares the two on the
selected modes and, where the lines following the speed win, the voyage is marked as
without a shaft speed (one warning naming the column).

Neither test touches a recording without a ship log (laboratory data): nothing is marked.

The marks are the ``harmonic`` column of the pole and selected tables: the order (1, 2,
..., the blade count for the blade pass), ``0`` for a harmonic found from the data whose
order is unknown, NaN for none. Tracking drops every tracked label most of whose rows are
marked (:class:`~workbench.sid.tracking.TrackingOptions` ``harmonic_share``), so a
harmonic is never a row of the tracked modal table; a mode crossed by an order keeps its
rows, since its shape is its own (the tracker gates on the shape).

A block-wise test of the data alone was measured and left out: the kurtosis of the
band-filtered modal response (1.5 for a pure sinusoid, 3 for a Gaussian random response;
Brincker et al. 2000, Jacobsen 2006) does not separate the demo voyage's harmonics from
its modes (``benchmarks/results/harmonics.txt``).

References
----------
.. [1] R. Brincker, P. Andersen, N. Møller, "An indicator for separation of structural and
   harmonic modes in output-only modal testing", Proceedings of IMAC XVIII, 2000.
.. [2] N.-J. Jacobsen, "Separating structural modes and harmonic components in operational
   modal analysis", Proceedings of IMAC XXIV, 2006.
.. [3] R. B. Randall, B. Peeters, J. Antoni, S. Manzato, "New cepstral methods of signal
   preprocessing for operational modal analysis", Proceedings of ISMA 2012, Leuven.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from data_contracts import shape_columns, shapes_from_frame

__all__ = [
    "HarmonicMarker",
    "HarmonicMarks",
    "HarmonicOptions",
    "block_shaft_table",
    "mark_harmonics",
    "shaft_rate_per_knot",
    "shaft_log_against_speed",
    "steady_shaft_log",
    "frozen_shaft_log",
    "usable_shaft_speed",
    "mark_poles",
    "mark_shaft_orders",
    "mark_speed_following",
    "nearest_order_frequency",
    "SpeedFollowing",
    "order_list",
]

#: Exponent of the harmonic's power in the shaft rate (force ∝ rate², power ∝ rate⁴). [-]
POWER_EXPONENT = 4.0
#: Smallest share of a block's duration that the usable readings (shaft speed, or speed)
#: must cover for the block to be tested from them. [-]
MIN_COVERAGE = 0.5
#: Shortest run of identical nonzero shaft-speed readings taken as a frozen sensor (in a
#: log whose median run lasts under a tenth of it). [s]
FROZEN_SECONDS = 300.0
#: Readings in the running median of a spike test (centred). [-]
SPIKE_WINDOW = 31
#: A shaft-speed reading is a spike when it lies further than this share of the running
#: median, plus :data:`SPIKE_FLOOR_RPM`, from it. [-]
SPIKE_TOL = 0.2
#: Absolute part of the spike test's tolerance (a shaft at rest reads a few rpm). [rpm]
SPIKE_FLOOR_RPM = 5.0
#: Largest relative scatter (10-90 % range over median) of shaft speed over speed for the
#: shaft speed to be estimated from the speed where it is not logged (a fixed-pitch
#: propeller; a controllable-pitch one turns at a set rate whatever the speed). [-]
PITCH_SCATTER = 0.2
#: Largest relative scatter (10-90 % range over median) of the blocks' logged shaft speed
#: taken as a shaft speed that does not change (:func:`shaft_log_against_speed`). [-]
STEADY_SHAFT_SCATTER = 0.02
#: Smallest 10-90 % range of the blocks' mean speed over which a steady logged shaft
#: speed is checked against the speed-following test. [kn]
SPEED_RANGE_KN = 1.0


@dataclass(frozen=True)
class HarmonicOptions:
    """Settings of the harmonic tests (:func:`mark_harmonics`).

    Attributes
    ----------
    orders : tuple of float
        Shaft orders checked (1 = the shaft rate). [-]
    blades : int
        Propeller blades: the blade-pass order (and its double) is checked too; 0 for none
        (or unknown). [-]
    frequency_tol : float
        Relative half-width around a selected mode's frequency within which an order's
        energy counts as on the mode. [-]
    min_share : float
        Smallest share of an order's energy in the block within *frequency_tol* of a
        selected mode for the mode to be that order. [-]
    mac_min : float
        Lowest MAC between the shapes of selected modes taken as one harmonic
        (speed-following test) and between a marked mode and the poles marked with it. [-]
    ratio_tol : float
        Largest relative difference of frequency over block speed within one harmonic
        (speed-following test). [-]
    min_sweep : float
        Smallest relative spread of frequency (max / min - 1) of a speed-following group. [-]
    min_rows : int
        Fewest selected modes in a speed-following group. [-]
    min_speed_kn : float
        Blocks slower than this are not used by the speed-following test. [kn]
    """

    orders: tuple[float, ...] = (1.0, 2.0, 3.0)
    blades: int = 0
    frequency_tol: float = 0.02
    min_share: float = 0.2
    mac_min: float = 0.9
    ratio_tol: float = 0.03
    min_sweep: float = 0.15
    min_rows: int = 5
    min_speed_kn: float = 2.0

    def __post_init__(self) -> None:
        orders = tuple(float(k) for k in self.orders)
        if not orders or not all(math.isfinite(k) and k > 0 for k in orders):
            raise ValueError(f"orders={self.orders!r} must be positive shaft orders")
        object.__setattr__(self, "orders", orders)
        if int(self.blades) != self.blades or self.blades < 0:
            raise ValueError(f"blades={self.blades} must be a whole number of at least 0")
        object.__setattr__(self, "blades", int(self.blades))
        for name in ("frequency_tol", "min_share", "mac_min", "ratio_tol"):
            value = float(getattr(self, name))
            if not (0.0 < value <= 1.0):
                raise ValueError(f"{name}={value:g} must lie in (0, 1]")
        if not (self.min_sweep > 0):
            raise ValueError(f"min_sweep={self.min_sweep:g} must be positive")
        if int(self.min_rows) != self.min_rows or self.min_rows < 2:
            raise ValueError(f"min_rows={self.min_rows} must be a whole number of at least 2")
        if not (self.min_speed_kn >= 0):
            raise ValueError(f"min_speed_kn={self.min_speed_kn:g} must be at least 0")


def order_list(options: HarmonicOptions) -> tuple[float, ...]:
    """The orders checked: the shaft orders, then the blade pass and its double."""
    orders = list(options.orders)
    if options.blades:
        orders += [float(options.blades), 2.0 * options.blades]
    return tuple(dict.fromkeys(orders))


@dataclass(frozen=True)
class HarmonicMarks:
    """What :func:`mark_harmonics` found.

    Attributes
    ----------
    selected, poles : DataFrame
        The tables with their ``harmonic`` column.
    method : {"shaft speed", "speed", "none"}
        The test used: the logged shaft speed, the speed-following test, or none (no
        usable ship log).
    shaft : DataFrame
        :func:`block_shaft_table` of the blocks: the Campbell view's abscissa.
    orders : tuple of float
        The orders checked (:func:`order_list`).
    lines : list of str
        Summary for the engineer.
    """

    selected: pd.DataFrame
    poles: pd.DataFrame
    method: str
    shaft: pd.DataFrame
    orders: tuple[float, ...] = ()
    lines: list[str] = field(default_factory=list)


def _block_slices(times: np.ndarray, blocks: pd.DataFrame):
    """(block, start index, stop index) of the log rows inside each block's window."""
    start = pd.to_datetime(blocks["block_start"], utc=True).to_numpy("datetime64[ns]")
    end = pd.to_datetime(blocks["block_end"], utc=True).to_numpy("datetime64[ns]")
    lo = np.searchsorted(times, start, side="left")
    hi = np.searchsorted(times, end, side="left")
    return zip(blocks["block"].to_numpy(dtype=int), lo, hi, strict=True)


def _log_times(log: pd.DataFrame) -> np.ndarray:
    return pd.to_datetime(log["time"], utc=True).dt.tz_convert(None).to_numpy("datetime64[ns]")


def _blocks_of(table: pd.DataFrame) -> pd.DataFrame:
    return (
        table[["block", "block_start", "block_end"]]
        .drop_duplicates("block")
        .sort_values("block")
        .reset_index(drop=True)
    )


def _naive(values: pd.Series) -> pd.Series:
    return pd.to_datetime(values, utc=True).dt.tz_convert(None)


def _log_step_seconds(times: np.ndarray) -> float:
    """The log's usual interval between rows [s] (1 s for a single row)."""
    if len(times) < 2:
        return 1.0
    step = np.median(np.diff(times).astype("timedelta64[ns]").astype(float)) / 1e9
    return float(step) if step > 0 else 1.0


def _step_of(log: pd.DataFrame, times: np.ndarray | None = None) -> float:
    """The log's usual interval between rows [s]: ``attrs["log_step_s"]`` when *log* is a
    window of a longer log (:meth:`LiveShaftLog.window`), else :func:`_log_step_seconds`."""
    step = log.attrs.get("log_step_s")
    if step is not None:
        return float(step)
    return _log_step_seconds(_log_times(log) if times is None else times)


def _runs(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of the runs of equal consecutive values."""
    change = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts = np.concatenate([[0], change])
    stops = np.concatenate([change, [len(values)]])
    return starts, stops


def usable_shaft_speed(log: pd.DataFrame) -> pd.DataFrame:
    """The ship log (sorted by time) with the shaft-speed readings that cannot be trusted
    set to NaN: spikes and a frozen sensor.

    * A spike is a reading further than ``SPIKE_TOL`` x m + ``SPIKE_FLOOR_RPM`` from m, the
      running median of :data:`SPIKE_WINDOW` readings around it: a shaft line cannot
      change its rate by a fifth within seconds.
    * A frozen sensor repeats its last reading: a run of identical nonzero readings lasting
      :data:`FROZEN_SECONDS` or longer, in a log whose readings change (its median run of
      equal readings lasts under a tenth of that: a noisy sensor; a log that repeats
      values, a coarse or hold-last-value export, is left alone). A stopped shaft (0 rpm)
      is not frozen.

    ``attrs["shaft_rpm_notes"]`` says what was left out (one line each kind).
    """
    if log.attrs.get("shaft_rpm_checked"):
        return log
    log = log.sort_values("time", kind="stable").reset_index(drop=True)
    notes: list[str] = []
    if "shaft_rpm" in log.columns and log["shaft_rpm"].notna().any():
        rpm = log["shaft_rpm"].to_numpy(float).copy()
        finite = np.flatnonzero(np.isfinite(rpm))
        values = np.abs(rpm[finite])
        median = (
            pd.Series(values).rolling(SPIKE_WINDOW, center=True, min_periods=1).median().to_numpy()
        )
        spike = np.abs(values - median) > SPIKE_TOL * median + SPIKE_FLOOR_RPM
        times = _log_times(log)
        if spike.any():
            first = pd.Timestamp(times[finite[spike][0]])
            notes.append(
                f"{int(spike.sum())} shaft-speed spike(s) left out (first at "
                f"{first:%Y-%m-%d %H:%M:%S})"
            )
            rpm[finite[spike]] = np.nan
        finite = np.flatnonzero(np.isfinite(rpm))
        values = rpm[finite]
        if len(values) > 1:
            step = _log_step_seconds(times[finite])
            starts, stops = _runs(values)
            lasting = (times[finite[stops - 1]] - times[finite[starts]]) / np.timedelta64(
                1, "s"
            ) + step
        # a sensor whose readings change (most runs of equal readings short) is checked
        if len(values) > 1 and np.median(lasting) < FROZEN_SECONDS / 10:
            for start, stop, seconds in zip(starts, stops, lasting, strict=True):
                if values[start] != 0 and seconds >= FROZEN_SECONDS:
                    rpm[finite[start:stop]] = np.nan
                    notes.append(
                        f"shaft speed frozen at {values[start]:g} rpm from "
                        f"{pd.Timestamp(times[finite[start]]):%Y-%m-%d %H:%M:%S} for "
                        f"{seconds / 60:.0f} min: readings left out"
                    )
        log["shaft_rpm"] = rpm
    log.attrs["shaft_rpm_checked"] = True
    log.attrs["shaft_rpm_notes"] = notes
    return log


def _covered(count: int, step: float, block_start, block_end) -> bool:
    """Whether *count* readings *step* seconds apart cover :data:`MIN_COVERAGE` of the
    block."""
    duration = (block_end - block_start) / np.timedelta64(1, "s")
    return count * step >= MIN_COVERAGE * duration


def block_shaft_table(log: pd.DataFrame, blocks: pd.DataFrame) -> pd.DataFrame:
    """Per block: the shaft speed weighted by its fourth power (where the harmonics' energy
    is: on a speed ramp, the harmonic's pole sits near the top speed), the mean speed and the
    speed weighted the same way.

    Parameters
    ----------
    log : DataFrame
        Canonical ship log (:func:`data_contracts.read_dship`): ``time`` and, when logged,
        ``shaft_rpm`` [rpm] and ``speed_kn`` [kn].
    blocks : DataFrame
        ``block``, ``block_start``, ``block_end``.

    Returns
    -------
    DataFrame
        ``block``, ``block_start``, ``shaft_rpm`` [rpm], ``speed_kn`` [kn],
        ``speed_energy_kn`` [kn]; NaN where not logged.
    """
    blocks = _blocks_of(blocks)
    log = usable_shaft_speed(log)
    times = _log_times(log)
    step = _step_of(log, times)
    blocks_naive = blocks.assign(
        block_start=_naive(blocks["block_start"]), block_end=_naive(blocks["block_end"])
    )
    bounds = dict(
        zip(
            blocks_naive["block"].astype(int),
            zip(blocks_naive["block_start"], blocks_naive["block_end"], strict=True),
            strict=True,
        )
    )
    rpm = log["shaft_rpm"].to_numpy(float) if "shaft_rpm" in log else None
    speed = log["speed_kn"].to_numpy(float) if "speed_kn" in log else None
    rows = []
    for block, lo, hi in _block_slices(times, blocks_naive):
        row = {"block": block, "shaft_rpm": np.nan, "speed_kn": np.nan, "speed_energy_kn": np.nan}
        start, end = (np.datetime64(t, "ns") for t in bounds[int(block)])
        if rpm is not None and hi > lo:
            values = np.abs(rpm[lo:hi])
            values = values[np.isfinite(values)]
            weight = values**POWER_EXPONENT
            if _covered(len(values), step, start, end) and weight.sum() > 0:
                row["shaft_rpm"] = float((weight * values).sum() / weight.sum())
        if speed is not None and hi > lo:
            values = np.abs(speed[lo:hi])
            values = values[np.isfinite(values)]
            if _covered(len(values), step, start, end):
                row["speed_kn"] = float(values.mean())
                weight = values**POWER_EXPONENT
                if weight.sum() > 0:
                    row["speed_energy_kn"] = float((weight * values).sum() / weight.sum())
        rows.append(row)
    table = pd.DataFrame(rows, columns=["block", "shaft_rpm", "speed_kn", "speed_energy_kn"])
    table.insert(1, "block_start", pd.to_datetime(blocks["block_start"], utc=True).to_numpy())
    table["block_start"] = pd.to_datetime(table["block_start"], utc=True)
    return table


def mark_shaft_orders(
    selected: pd.DataFrame, log: pd.DataFrame, options: HarmonicOptions | None = None
) -> pd.Series:
    """The shaft order of each selected mode, from the logged shaft speed.

    Parameters
    ----------
    selected : DataFrame
        Selected modes (SELECTED contract): ``block``, ``block_start``, ``block_end``,
        ``frequency_hz``.
    log : DataFrame
        Canonical ship log with ``time`` and ``shaft_rpm`` [rpm].
    options : HarmonicOptions, optional

    Returns
    -------
    Series
        Aligned with *selected*: the order (of :func:`order_list`) whose energy in the
        block lies on the mode, NaN for none (and for blocks whose usable shaft-speed
        readings, :func:`usable_shaft_speed`, cover less than :data:`MIN_COVERAGE` of them).

    Notes
    -----
    With n(t) the logged shaft speed [rpm] at the block's log times and w(t) = n(t)⁴ the
    order's relative energy, the share of order k on a mode at frequency f is

    .. math:: s_k(f) = \\frac{\\sum_t w(t)\\,[|k\\,n(t)/60 - f| \\le τ f]}{\\sum_t w(t)},

    τ = max(``frequency_tol``, ζ) with ζ the mode's damping ratio (a pole stands for the
    energy within its half-power bandwidth ±ζ f; a harmonic smeared by a speed ramp is a
    heavily damped pole); the mode is order k when s_k(f) >= ``min_share`` (the order with
    the largest share when several qualify).
    """
    options = options or HarmonicOptions()
    out = pd.Series(np.nan, index=selected.index, name="harmonic")
    if "shaft_rpm" not in log.columns or selected.empty:
        return out
    orders = np.array(order_list(options))
    log = usable_shaft_speed(log)
    step = _step_of(log)
    log = log[["time", "shaft_rpm"]].dropna()
    times = _log_times(log)
    rpm = np.abs(log["shaft_rpm"].to_numpy(float))
    blocks = _blocks_of(selected)
    blocks = blocks.assign(
        block_start=_naive(blocks["block_start"]), block_end=_naive(blocks["block_end"])
    )
    rows_of = selected.groupby("block").indices
    frequency = selected["frequency_hz"].to_numpy(float)
    # a pole stands for the energy within its half-power bandwidth, ±ζ f: a harmonic
    # smeared by a speed ramp is a heavily damped pole
    damping = (
        selected["damping_ratio"].to_numpy(float)
        if "damping_ratio" in selected
        else np.zeros(len(selected))
    )
    tol = np.fmax(options.frequency_tol, np.nan_to_num(np.abs(damping)))
    bounds = dict(
        zip(
            blocks["block"].astype(int),
            zip(blocks["block_start"], blocks["block_end"], strict=True),
            strict=True,
        )
    )
    for block, lo, hi in _block_slices(times, blocks):
        start, end = (np.datetime64(t, "ns") for t in bounds[int(block)])
        if hi <= lo or not _covered(hi - lo, step, start, end):
            continue
        rate_hz = rpm[lo:hi] / 60.0
        weight = rate_hz**POWER_EXPONENT
        total = weight.sum()
        if not total > 0:
            continue
        lines = orders[:, None] * rate_hz[None, :]  # (orders, times) [Hz]
        for row in rows_of[block]:
            f = frequency[row]
            share = ((np.abs(lines - f) <= tol[row] * f) * weight).sum(axis=1) / total
            best = int(np.argmax(share))
            if share[best] >= options.min_share:
                out.iat[row] = orders[best]
    return out


def _shapes(table: pd.DataFrame) -> np.ndarray:
    """Unit-norm complex shapes (rows), NaN channels as 0."""
    _, shapes = shapes_from_frame(table[[c for c in table.columns if c.startswith("shape_")]])
    shapes = np.nan_to_num(shapes)
    norm = np.linalg.norm(shapes, axis=1, keepdims=True)
    return shapes / np.where(norm > 0, norm, 1.0)


def _mac_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """MAC between the unit-norm rows of *a* and of *b*."""
    return np.abs(a @ b.conj().T) ** 2


#: Rows whose shapes are compared with a window's rows at once by the speed-following
#: test: a comparison holds this many rows times the window's rows. [-]
_CHUNK_ROWS = 256
#: Fewest shapes whose groups are found from balls of shapes (:func:`_components`); fewer
#: are compared pair by pair. [-]
_BALLS_FROM_ROWS = 32
#: Levels of balls within balls by which two balls' members are compared (then member by
#: member). [-]
_LINK_DEPTH = 6
#: Bins of the log ratio per ``ratio_tol`` by which the speed-following test decides its
#: rows together (see :class:`SpeedFollowing`): 1, 2 and 4 give the same marks, 1 the
#: fewest shape comparisons (``benchmarks/results/harmonics_speed_scale_51.txt``). [-]
_BINS_PER_TOL = 1
#: Margin of the bins' windows against rounding of the log ratios. [-]
_RATIO_EPS = 1e-9


#: Margin of the distance between shapes (the angle arccos sqrt(MAC)) by which two groups
#: of shapes are judged apart without comparing their shapes one by one: far above the
#: rounding of the MAC (1e-16 in the MAC, 1e-8 in the angle near MAC = 1). [rad]
_ANGLE_EPS = 1e-6


def _angle(mac: np.ndarray) -> np.ndarray:
    """The angle between shapes of MAC *mac*, arccos sqrt(MAC): a distance (it obeys the
    triangle inequality; the Fubini-Study metric of the shapes' directions). [rad]"""
    return np.arccos(np.sqrt(np.clip(mac, 0.0, 1.0)))


def _pairwise_components(shapes: np.ndarray, mac_min: float) -> np.ndarray:
    """:func:`_components` by comparing every pair of shapes, :data:`_CHUNK_ROWS` rows at a
    time against the rows after them, the labels merged after each chunk."""
    n = len(shapes)
    labels = np.arange(n)
    for start in range(0, n, _CHUNK_ROWS):
        stop = min(start + _CHUNK_ROWS, n)
        linked = _mac_matrix(shapes[start:stop], shapes[start:]) >= mac_min
        row, column = np.nonzero(linked)
        labels = _merged(labels, labels[start + row], labels[start + column])
    return labels


def _merged(labels: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """*labels* (of 0..n-1) with the labels linked by the pairs (*a*, *b*) merged."""
    keep = a != b
    if not keep.any():
        return labels
    n = len(labels)
    pairs = np.unique(a[keep].astype(np.int64) * n + b[keep])
    graph = csr_matrix((np.ones(len(pairs), dtype=bool), (pairs // n, pairs % n)), (n, n))
    return connected_components(graph, directed=False)[1][labels]


def _balls(shapes: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shapes gathered around leaders: the first shape not yet gathered leads every other
    within *radius* of it [rad]. Returns each shape's ball, each ball's leader and its
    reach (the largest angle of a member from its leader)."""
    ball = np.full(len(shapes), -1)
    leaders, reach = [], []
    free = np.arange(len(shapes))
    while free.size:  # each pass gathers at least its leader
        leader = free[0]
        angle = _angle(_mac_matrix(shapes[free], shapes[leader : leader + 1])[:, 0])
        inside = angle <= radius
        inside[0] = True
        ball[free[inside]] = len(leaders)
        leaders.append(leader)
        reach.append(float(angle[inside].max()))
        free = free[~inside]
    return ball, np.array(leaders), np.array(reach)


def _components(shapes: np.ndarray, mac_min: float) -> np.ndarray:
    """Connected components of the rows of *shapes* (unit norm) linked by MAC >= *mac_min*:
    a label per row, the same components as from the MAC of every pair.

    Notes
    -----
    With θ = arccos sqrt(*mac_min*) the angle of a link, the shapes are gathered in balls
    of radius θ / 2 around leaders (:func:`_balls`; each member linked to its leader, so a
    ball is connected). Two balls A and B, leaders a and b, reaches r_A and r_B, are linked
    when a and b are; they are not when d(a, b) > θ + r_A + r_B (every pair of members is
    then further apart than θ, by the triangle inequality); in between, their members are
    compared (those within θ + r_B of b with those within θ + r_A of a), unless the two
    balls are joined already. The shapes of a harmonic line or of a mode at one speed
    gather in a few balls, so a window of thousands of modes costs its modes times its
    balls, not its modes squared.
    """
    n = len(shapes)
    link = math.acos(math.sqrt(mac_min))
    if n <= _BALLS_FROM_ROWS or link < 100 * _ANGLE_EPS:
        return _pairwise_components(shapes, mac_min)
    ball, leaders, reach = _balls(shapes, link / 2)
    members = np.split(np.argsort(ball, kind="stable"), np.cumsum(np.bincount(ball))[:-1])
    n_balls = len(leaders)
    labels = np.arange(n_balls)
    for start in range(0, n_balls, _CHUNK_ROWS):
        stop = min(start + _CHUNK_ROWS, n_balls)
        mac = _mac_matrix(shapes[leaders[start:stop]], shapes[leaders[start:]])
        row, column = np.nonzero(mac >= mac_min)
        labels = _merged(labels, labels[start + row], labels[start + column])
        angle = _angle(mac)
        near = angle <= link + reach[start:stop, None] + reach[None, start:] + _ANGLE_EPS
        row, column = np.nonzero(near & (mac < mac_min))
        for k in np.argsort(angle[row, column], kind="stable"):  # the nearest first
            a, b = start + row[k], start + column[k]
            if labels[a] == labels[b] or not _balls_linked(
                shapes, members[a], members[b], leaders[a], leaders[b], reach[a], reach[b], link,
                mac_min,
            ):  # fmt: skip
                continue
            labels[labels == labels[b]] = labels[a]
    return labels[ball]


def _balls_linked(shapes, one, other, leader_one, leader_other, reach_one, reach_other, link,
                  mac_min, depth: int = 0) -> bool:  # fmt: skip
    """Whether a member of ball *one* and one of ball *other* have MAC >= *mac_min*.

    Only the members within θ + r_B of b and θ + r_A of a can link (θ = *link*, a and b
    the leaders, r the reaches). Many of them are gathered again in balls of half the
    reach, and those balls' pairs decided as in :func:`_components` (linked leaders: yes;
    too far apart: no; else their members, one level down); at most
    :data:`_LINK_DEPTH` levels, then or when few, member by member."""
    one = one[
        _angle(_mac_matrix(shapes[one], shapes[leader_other : leader_other + 1])[:, 0])
        <= link + reach_other + _ANGLE_EPS
    ]
    other = other[
        _angle(_mac_matrix(shapes[other], shapes[leader_one : leader_one + 1])[:, 0])
        <= link + reach_one + _ANGLE_EPS
    ]
    if not len(one) or not len(other):
        return False
    if len(one) * len(other) > _CHUNK_ROWS**2 and depth < _LINK_DEPTH:
        sides = []
        for rows, reach in ((one, reach_one), (other, reach_other)):
            ball, leaders, reaches = _balls(shapes[rows], reach / 2)
            members = np.split(
                rows[np.argsort(ball, kind="stable")], np.cumsum(np.bincount(ball))[:-1]
            )
            sides.append((members, rows[leaders], reaches))
        (members_one, leaders_one, reach_ones), (members_other, leaders_other, reach_others) = sides
        if len(leaders_one) * len(leaders_other) < len(one) * len(other) // 4:
            mac = _mac_matrix(shapes[leaders_one], shapes[leaders_other])
            if (mac >= mac_min).any():
                return True
            angle = _angle(mac)
            near = angle <= link + reach_ones[:, None] + reach_others[None, :] + _ANGLE_EPS
            row, column = np.nonzero(near)
            for k in np.argsort(angle[row, column], kind="stable"):  # the nearest first
                i, j = row[k], column[k]
                if _balls_linked(
                    shapes, members_one[i], members_other[j], leaders_one[i], leaders_other[j],
                    reach_ones[i], reach_others[j], link, mac_min, depth + 1,
                ):  # fmt: skip
                    return True
            return False
    for start in range(0, len(one), _CHUNK_ROWS):
        if (_mac_matrix(shapes[one[start : start + _CHUNK_ROWS]], shapes[other]) >= mac_min).any():
            return True
    return False


class SpeedFollowing:
    """The speed-following test (:func:`mark_speed_following`) over selected modes given
    a few at a time (the monitor's blocks) or all at once.

    A mode is *swept* when its group (see :func:`mark_speed_following`) holds at least
    ``min_rows`` modes whose frequencies spread over more than ``min_sweep``. Modes added
    later only enlarge the groups of the modes before them (a group is the modes of a
    ratio window linked by shape), so a swept mode stays swept and only the unswept modes
    within ``ratio_tol`` of an added mode are tested again: the result is the same
    whether the modes come in one table or block by block.

    The test of a mode needs the component of its shape graph within its own ratio
    window. Sorted by the log ratio, the modes are decided a bin of ``ratio_tol`` /
    :data:`_BINS_PER_TOL` at a time: the window of every mode of a bin contains the
    bin's inner window (the ratios within ``ratio_tol`` of the whole bin) and lies within
    its outer window (the ratios within ``ratio_tol`` of any of it). A mode whose group
    in the inner window is swept is swept; one whose group in the outer window is not, is
    not; only the few left between are tested on their own window (within their group
    of the outer window). The groups of a window are found from balls of similar shapes
    (:func:`_components`) and kept: a mode added later joins the groups of the windows it
    falls in (compared with their modes), so a block costs its modes times the modes of
    their windows. Memory: the modes, the kept windows' group labels (a few per mode), and
    a chunk of :data:`_CHUNK_ROWS` modes compared with a window's.

    Parameters
    ----------
    options : HarmonicOptions, optional
    """

    #: Added modes falling in a kept window above which its groups are found afresh
    #: rather than joined one mode at a time. [-]
    REBUILD_ROWS = 64

    def __init__(self, options: HarmonicOptions | None = None):
        self.options = options or HarmonicOptions()
        self.log_ratio = np.empty(0)
        self.frequency = np.empty(0)
        self.shapes: np.ndarray | None = None
        self.swept = np.empty(0, dtype=bool)
        self._order = np.empty(0, dtype=int)  # the modes by log ratio
        self._sorted = np.empty(0)
        # (bin, "inner" | "outer") -> [modes of the window (sorted), their group labels]
        self._windows: dict[tuple[int, str], list[np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self.log_ratio)

    def copy(self) -> SpeedFollowing:
        """An independent copy (to test modes without keeping them)."""
        other = SpeedFollowing(self.options)
        other.log_ratio, other.frequency = self.log_ratio.copy(), self.frequency.copy()
        other.shapes = None if self.shapes is None else self.shapes.copy()
        other.swept = self.swept.copy()
        other._order, other._sorted = self._order.copy(), self._sorted.copy()
        other._windows = {key: [rows.copy(), labels.copy()] for key, (rows, labels) in
                          self._windows.items()}  # fmt: skip
        return other

    def add(self, frequency_hz: np.ndarray, speed_kn: np.ndarray, shapes: np.ndarray) -> None:
        """Add modes (those of blocks at least ``min_speed_kn`` fast: the caller's choice)
        and test them and the unswept modes within ``ratio_tol`` of them.

        Parameters
        ----------
        frequency_hz : ndarray, shape (n,)
            [Hz]
        speed_kn : ndarray, shape (n,)
            Energy-weighted speed of each mode's block. [kn]
        shapes : ndarray, shape (n, n_channels)
            Unit-norm complex mode shapes (:func:`_shapes`).
        """
        frequency = np.asarray(frequency_hz, dtype=float)
        if not len(frequency):
            return
        log_ratio = np.log(frequency / np.asarray(speed_kn, dtype=float))
        tol = self.options.ratio_tol
        # the unswept modes whose window the new modes enter
        lo = np.searchsorted(self._sorted, log_ratio - tol - _RATIO_EPS, side="left")
        hi = np.searchsorted(self._sorted, log_ratio + tol + _RATIO_EPS, side="right")
        reached = np.zeros(len(self), dtype=bool)
        for a, b in zip(lo, hi, strict=True):
            reached[self._order[a:b]] = True
        n_before = len(self)
        self.log_ratio = np.concatenate([self.log_ratio, log_ratio])
        self.frequency = np.concatenate([self.frequency, frequency])
        self.shapes = shapes if self.shapes is None else np.concatenate([self.shapes, shapes])
        self.swept = np.concatenate([self.swept, np.zeros(len(frequency), dtype=bool)])
        self._order = np.argsort(self.log_ratio, kind="stable")
        self._sorted = self.log_ratio[self._order]
        self._join_windows(np.arange(n_before, len(self)))
        candidates = np.concatenate(
            [np.flatnonzero(reached & ~self.swept[:n_before]), np.arange(n_before, len(self))]
        )
        self.swept[candidates] = self._decide(candidates)

    def _bounds(self, k: int, which: str) -> tuple[float, float]:
        """The log ratios [low, high] of bin *k*'s inner or outer window."""
        tol = self.options.ratio_tol
        step = tol / _BINS_PER_TOL
        left, right = k * step, (k + 1) * step
        if which == "inner":  # within every mode's window of the bin
            return right - tol + _RATIO_EPS, left + tol - _RATIO_EPS
        return left - tol - _RATIO_EPS, right + tol + _RATIO_EPS  # holds every one

    def _join_windows(self, new: np.ndarray) -> None:
        """The added modes *new* join the kept windows they fall in (or the window's
        groups are dropped, found afresh when next needed, when many fall in it)."""
        options = self.options
        for key in list(self._windows):
            low, high = self._bounds(*key)
            inside = new[(self.log_ratio[new] >= low) & (self.log_ratio[new] <= high)]
            if not len(inside):
                continue
            if len(inside) > self.REBUILD_ROWS:
                del self._windows[key]
                continue
            rows, labels = self._windows[key]
            for row in inside:  # each joins the groups it links (MAC >= mac_min)
                linked = _mac_matrix(self.shapes[row : row + 1], self.shapes[rows])[0]
                joined = np.unique(labels[linked >= options.mac_min])
                label = int(joined[0]) if len(joined) else int(labels.max(initial=-1)) + 1
                labels = np.where(np.isin(labels, joined), label, labels)
                at = int(np.searchsorted(rows, row))
                rows, labels = np.insert(rows, at, row), np.insert(labels, at, label)
            self._windows[key] = [rows, labels]

    def _window(self, low: float, high: float) -> np.ndarray:
        """The modes whose log ratio lies in [low, high]."""
        a = np.searchsorted(self._sorted, low, side="left")
        b = np.searchsorted(self._sorted, high, side="right")
        return self._order[a:b]

    def _kept(self, k: int, which: str) -> tuple[np.ndarray, np.ndarray]:
        """The modes (sorted) of bin *k*'s inner or outer window and their group labels."""
        kept = self._windows.get((k, which))
        if kept is None:
            rows = np.sort(self._window(*self._bounds(k, which)))
            labels = (
                _components(self.shapes[rows], self.options.mac_min)
                if len(rows) >= self.options.min_rows
                else np.arange(len(rows))
            )
            kept = self._windows[(k, which)] = [rows, labels]
        return kept[0], kept[1]

    def _swept_labels(self, rows: np.ndarray, labels: np.ndarray) -> np.ndarray:
        """Per mode of *rows*, whether its group (same label) is swept: at least
        ``min_rows`` modes whose frequencies spread over more than ``min_sweep``."""
        options = self.options
        groups, inverse = np.unique(labels, return_inverse=True)
        frequency = self.frequency[rows]
        size = np.bincount(inverse, minlength=len(groups))
        low = np.full(len(groups), np.inf)
        high = np.full(len(groups), -np.inf)
        np.minimum.at(low, inverse, frequency)
        np.maximum.at(high, inverse, frequency)
        with np.errstate(invalid="ignore", divide="ignore"):
            swept = (size >= options.min_rows) & (high / low - 1.0 > options.min_sweep)
        return swept[inverse]

    def _decide(self, candidates: np.ndarray) -> np.ndarray:
        """Whether each candidate mode is swept."""
        options = self.options
        tol, step = options.ratio_tol, options.ratio_tol / _BINS_PER_TOL
        out = np.zeros(len(candidates), dtype=bool)
        bins = np.floor(self.log_ratio[candidates] / step).astype(np.int64)
        for k in np.unique(bins):  # one pass per occupied bin
            at = np.flatnonzero(bins == k)
            rows = candidates[at]
            # every mode of the bin has all of the inner window in its own, and its own
            # within the outer window
            inner, labels = self._kept(int(k), "inner")
            open_ = np.ones(len(rows), dtype=bool)
            if len(inner) >= options.min_rows:
                where = np.minimum(np.searchsorted(inner, rows), len(inner) - 1)
                hit = (inner[where] == rows) & self._swept_labels(inner, labels)[where]
                out[at[hit]] = True
                open_ &= ~hit
            if not open_.any():
                continue
            outer, labels = self._kept(int(k), "outer")
            if len(outer) < options.min_rows:
                continue
            where = np.searchsorted(outer, rows)
            swept = self._swept_labels(outer, labels)
            found: dict[bytes, np.ndarray] = {}  # own windows met already: swept per mode
            for j in np.flatnonzero(open_ & swept[where]):
                # between the two: the mode's own window, within its group of the outer one
                group = outer[labels == labels[where[j]]]
                own = group[np.abs(self.log_ratio[group] - self.log_ratio[rows[j]]) <= tol]
                if len(own) < options.min_rows:
                    continue
                key = own.tobytes()
                if key not in found:
                    own_labels = _components(self.shapes[own], options.mac_min)
                    found[key] = self._swept_labels(own, own_labels)
                out[at[j]] = found[key][np.searchsorted(own, rows[j])]
        return out

    def marked(self) -> tuple[np.ndarray, float]:
        """Per mode whether it is marked (swept, or at an order's ratio), and the shaft
        rate per knot found (NaN when none is swept). [Hz/kn]

        The lowest swept ratio r_1 is taken as the lowest order of ``orders``; every mode
        within ``ratio_tol`` of k r_1 / min(orders), k an order of :func:`order_list`
        (the blade pass included), is marked too."""
        options = self.options
        marked = self.swept.copy()
        if not marked.any():
            return marked, np.nan
        base = float(np.exp(np.min(self.log_ratio[marked])))
        lowest = min(options.orders)
        for order in order_list(options):
            ratio = np.log(base * order / lowest)
            marked |= np.abs(self.log_ratio - ratio) <= options.ratio_tol
        return marked, base / lowest


def mark_speed_following(
    selected: pd.DataFrame, shaft: pd.DataFrame, options: HarmonicOptions | None = None
) -> pd.Series:
    """Selected modes whose frequency follows the speed while their shape stays fixed.

    Parameters
    ----------
    selected : DataFrame
        Selected modes with shape columns.
    shaft : DataFrame
        :func:`block_shaft_table` of the blocks (``speed_energy_kn``).
    options : HarmonicOptions, optional

    Returns
    -------
    Series
        ``0.0`` (a harmonic of unknown order) for the marked modes, NaN for the others;
        ``attrs["shaft_hz_per_kn"]``: the shaft rate per knot found (when any). [Hz/kn]

    Notes
    -----
    Mode i of a block with energy-weighted speed v_i > ``min_speed_kn`` has the ratio
    r_i = f_i / v_i. Its group is every mode j with |ln r_j - ln r_i| <= ``ratio_tol``
    linked to mode i by a chain of shapes with MAC >= ``mac_min`` (a harmonic's forced
    shape changes gradually with its frequency, near a mode it takes on the mode's
    shape); mode i is marked when its group holds at least ``min_rows`` modes whose
    frequencies spread by more than ``min_sweep`` (max / min - 1). A structural mode's
    frequency does not scale with speed, so its group (same ratio, linked shapes) lies at
    one speed and one frequency.

    The lowest ratio marked this way, r_1, is taken as the lowest order of ``orders``; every
    mode whose ratio lies within ``ratio_tol`` of k r_1 / min(orders) for an order k of
    :func:`order_list` (the blade pass included) is marked too: an order the voyage shows
    at one speed only does not sweep. A structural mode is marked only in the blocks whose
    speed puts an order on it, a minority of its blocks, so tracking keeps it.

    The groups are found by :class:`SpeedFollowing` without comparing every pair of modes:
    memory grows with the modes, time with the modes times those of a ratio window.
    """
    options = options or HarmonicOptions()
    out = pd.Series(np.nan, index=selected.index, name="harmonic")
    if selected.empty or "speed_energy_kn" not in shaft:
        return out
    speed = selected["block"].map(shaft.set_index("block")["speed_energy_kn"]).to_numpy(float)
    rows = np.flatnonzero(np.isfinite(speed) & (speed > options.min_speed_kn))
    if len(rows) < options.min_rows:
        return out
    part = selected.iloc[rows]
    test = SpeedFollowing(options)
    test.add(part["frequency_hz"].to_numpy(float), speed[rows], _shapes(part))
    marked, per_kn = test.marked()
    if np.isfinite(per_kn):
        out.attrs["shaft_hz_per_kn"] = per_kn
    out.iloc[rows[marked]] = 0.0
    return out


def steady_shaft_log(shaft: pd.DataFrame) -> tuple[float, float, float] | None:
    """Whether the blocks' logged shaft speed (*shaft*, :func:`block_shaft_table`) stays
    within :data:`STEADY_SHAFT_SCATTER` (10-90 % range over median) while their mean speed
    spans :data:`SPEED_RANGE_KN` or more (10-90 % range): the median shaft speed [rpm] and
    the 10 and 90 % speeds [kn] when it does (the log is then checked against the speed,
    :func:`shaft_log_against_speed`), else None."""
    rpm = shaft["shaft_rpm"].to_numpy(float)
    speed = shaft["speed_kn"].to_numpy(float)
    rpm, speed = rpm[np.isfinite(rpm)], speed[np.isfinite(speed)]
    if len(rpm) < 2 or len(speed) < 2:
        return None
    low, middle, high = np.percentile(rpm, [10, 50, 90])
    speed_low, speed_high = np.percentile(speed, [10, 90])
    if not (middle > 0 and high - low <= STEADY_SHAFT_SCATTER * middle):
        return None
    if speed_high - speed_low < SPEED_RANGE_KN:
        return None
    return float(middle), float(speed_low), float(speed_high)


def shaft_log_against_speed(
    selected: pd.DataFrame,
    log: pd.DataFrame,
    shaft: pd.DataFrame,
    options: HarmonicOptions | None = None,
) -> str | None:
    """Whether a steady logged shaft speed is contradicted by the voyage's selected modes:
    a line naming the column when it is (the log is then unusable), else None.

    A controllable-pitch propeller turns at a set rate while the speed changes, so a
    steady shaft speed alone is no fault; a sensor (or an export) repeating one value
    while the shaft follows the speed is. They differ in the modes: with the shaft truly
    steady the orders stay at the logged rate's orders and no line follows the speed;
    with a frozen log the harmonics follow the speed (:func:`mark_speed_following`) and
    the logged orders hold only what happens to sit there.

    Checked when the blocks' logged shaft speed (*shaft*, :func:`block_shaft_table`)
    scatters by at most :data:`STEADY_SHAFT_SCATTER` (10-90 % range over median) while
    their mean speed spans :data:`SPEED_RANGE_KN` or more (10-90 % range,
    :func:`steady_shaft_log`). The two
    explanations are compared on the modes each marks and the other does not: n_log
    (at an order of the logged shaft speed, :func:`mark_shaft_orders`, not following the
    speed) and n_speed (following the speed, at no logged order). A line whose
    frequency sweeps with the speed by more than ``min_sweep`` cannot be an order of a
    shaft whose rate scatters by 2 %; the speed-following lines win, and the log is
    judged unusable, when n_speed >= ``min_rows`` and n_speed >= n_log.
    """
    options = options or HarmonicOptions()
    steady = steady_shaft_log(shaft)
    if steady is None:
        return None
    at_orders = mark_shaft_orders(selected, log, options).notna().to_numpy()
    following = mark_speed_following(selected, shaft, options).notna().to_numpy()
    return frozen_shaft_log(steady, at_orders, following, options)


def frozen_shaft_log(
    steady: tuple[float, float, float],
    at_orders: np.ndarray,
    following: np.ndarray,
    options: HarmonicOptions | None = None,
) -> str | None:
    """The verdict of :func:`shaft_log_against_speed` from its parts: *steady*
    (:func:`steady_shaft_log`), and per selected mode whether it sits at an order of the
    logged shaft speed (*at_orders*, :func:`mark_shaft_orders`) and whether it follows the
    speed (*following*, :func:`mark_speed_following`)."""
    options = options or HarmonicOptions()
    middle, speed_low, speed_high = steady
    at_orders, following = np.asarray(at_orders, bool), np.asarray(following, bool)
    n_log = int((at_orders & ~following).sum())
    n_speed = int((following & ~at_orders).sum())
    if n_speed < options.min_rows or n_speed < n_log:
        return None
    return (
        f"shaft_rpm: the logged shaft speed stays at {middle:.4g} rpm while the speed "
        f"spans {speed_low:.1f}-{speed_high:.1f} kn, and {n_speed} selected modes follow "
        f"the speed at none of its orders ({n_log} sit at its orders only): the column is "
        "not used, harmonics marked from the speed"
    )


def mark_poles(
    poles: pd.DataFrame, selected: pd.DataFrame, options: HarmonicOptions | None = None
) -> pd.Series:
    """The ``harmonic`` column of the pole table from the marked selected modes.

    A pole of a block is marked with the order of a marked selected mode of that block when
    its frequency lies within ``frequency_tol`` of the mode's and its shape has
    MAC >= ``mac_min`` with the mode's (the harmonic's poles over the model orders, not a
    structural mode's poles nearby).
    """
    options = options or HarmonicOptions()
    out = pd.Series(np.nan, index=poles.index, name="harmonic")
    if "harmonic" not in selected or poles.empty:
        return out
    marked = selected[selected["harmonic"].notna()]
    if marked.empty:
        return out
    channels = [c for c in shape_columns(_channels(selected)) if c in poles.columns]
    pole_rows = poles.groupby("block").indices
    pole_frequency = poles["frequency_hz"].to_numpy(float)
    for block, part in marked.groupby("block"):
        rows = pole_rows.get(block)
        if rows is None:
            continue
        block_shapes = _shapes(poles.iloc[rows][channels])
        for _, mode in part.iterrows():
            f = float(mode["frequency_hz"])
            near = np.abs(pole_frequency[rows] - f) <= options.frequency_tol * f
            if not near.any():
                continue
            shape = _shapes(mode.to_frame().T[channels])
            mac = _mac_matrix(block_shapes[near], shape)[:, 0]
            hit = rows[near][mac >= options.mac_min]
            out.iloc[hit] = float(mode["harmonic"])
    return out


def _channels(table: pd.DataFrame) -> list[str]:
    channels, _ = shapes_from_frame(table.iloc[:0])
    return list(channels)


def _running_median(values: pd.Series) -> np.ndarray:
    """Running median of :data:`SPIKE_WINDOW` readings (the log's noise and spikes out)."""
    return (
        values.astype(float)
        .rolling(SPIKE_WINDOW, center=True, min_periods=1)
        .median()
        .abs()
        .to_numpy()
    )


def shaft_rate_per_knot(log: pd.DataFrame, options: HarmonicOptions | None = None) -> float:
    """The shaft speed per knot of speed [rpm/kn] from the rows logging both, NaN when
    they do not show a fixed ratio (a controllable-pitch propeller) or are too few.

    The ratio of each row faster than ``min_speed_kn`` (running medians of both, the
    log's noise and spikes out); fixed when its 10-90 % range is within
    :data:`PITCH_SCATTER` of its median, over at least 10 minutes of rows.
    """
    options = options or HarmonicOptions()
    if "shaft_rpm" not in log.columns or "speed_kn" not in log.columns:
        return np.nan
    log = usable_shaft_speed(log)
    rpm = np.abs(log["shaft_rpm"].to_numpy(float))
    speed = _running_median(log["speed_kn"])
    both = np.isfinite(rpm) & np.isfinite(speed) & (speed > options.min_speed_kn)
    step = _log_step_seconds(_log_times(log))
    if both.sum() * step < 600:
        return np.nan
    ratio = rpm[both] / speed[both]
    low, middle, high = np.percentile(ratio, [10, 50, 90])
    return float(middle) if (high - low) <= PITCH_SCATTER * middle else np.nan


def nearest_order_frequency(
    frequency_hz: np.ndarray, shaft_hz: np.ndarray, orders: tuple[float, ...]
) -> np.ndarray:
    """Per mode, the frequency of the order (of *orders*) whose line k x *shaft_hz* is
    nearest the mode's frequency (on a log scale), NaN where the shaft rate is unknown:
    the order of a mode marked by the speed-following test (its ``harmonic`` is 0). [Hz]
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    rate = np.asarray(shaft_hz, dtype=float)
    if not np.isfinite(rate).any():
        return np.full(len(frequency), np.nan)
    lines = np.asarray(orders, dtype=float)
    nearest = lines[
        np.argmin(
            np.abs(
                np.log(frequency[:, None]) - np.log(np.fmax(lines[None, :] * rate[:, None], 1e-300))
            ),
            axis=1,
        )
    ]
    return nearest * rate


class HarmonicMarker:
    """Marks the harmonics of one voyage: its selected modes first (the whole table, small),
    then its poles chunk by chunk (:func:`mark_poles` against the marked modes).

    Parameters
    ----------
    log : DataFrame or None
        Canonical ship log (:func:`data_contracts.read_dship`); None: nothing is marked
        (the ``harmonic`` columns are added, all NaN).
    options : HarmonicOptions, optional
    """

    def __init__(self, log: pd.DataFrame | None, options: HarmonicOptions | None = None):
        self.log = log
        self.options = options or HarmonicOptions()
        self.orders = order_list(self.options)
        self.method = "none"
        self.shaft = pd.DataFrame(
            columns=["block", "block_start", "shaft_rpm", "speed_kn", "speed_energy_kn"]
        )
        self.marked = pd.DataFrame()
        self.rpm_per_kn = np.nan
        #: Shaft rate per knot the speed-following test found (a log without the shaft
        #: speed; NaN otherwise or when it found none). [Hz/kn]
        self.shaft_hz_per_kn = np.nan
        self.n_selected = 0
        self.n_poles = 0
        #: Why the logged shaft speed was not used (:func:`shaft_log_against_speed`), or
        #: None.
        self.shaft_log_note: str | None = None

    def mark_selected(
        self, selected: pd.DataFrame, *, shaft_logged: bool | None = None, judge_log: bool = True
    ) -> pd.DataFrame:
        """*selected* with its ``harmonic``, ``harmonic_frequency_hz`` and
        ``harmonic_checked`` columns.

        Blocks whose shaft speed is not usable (not logged, an outage, the log ending
        early, a frozen sensor) are tested from the shaft speed estimated from the logged
        speed, when the blocks with both show a fixed ratio (:func:`shaft_rate_per_knot`);
        blocks with neither are not checked (``harmonic_checked`` False): tracking judges a
        label by its checked rows and leaves out one seen (almost) only where the log fails.

        *shaft_logged*: whether the voyage's blocks have a usable shaft speed (None: those
        of *selected*, the voyage). True for a part of the voyage (the monitor's newest
        blocks) marks it from the shaft speed, estimated from the speed where the part has
        none, as the whole voyage would be, not by the speed-following test over the part.

        *judge_log*: whether a steady logged shaft speed is checked against the speed
        (:func:`shaft_log_against_speed`, with *shaft_logged* None). False where the caller
        judged the log over the voyage (the monitor, whose *selected* is its newest blocks:
        their speed rarely spans a knot).
        """
        selected = selected.copy()
        selected["harmonic"] = np.nan
        selected["harmonic_frequency_hz"] = np.nan
        self.n_selected = len(selected)
        if self.log is None or selected.empty:
            return selected
        self.log = usable_shaft_speed(self.log)
        self.shaft = block_shaft_table(self.log, selected)
        self.shaft["shaft_rpm_from"] = np.where(self.shaft["shaft_rpm"].notna(), "log", "")
        shaft = self.shaft.set_index("block")
        if shaft_logged is None:
            shaft_logged = bool(self.shaft["shaft_rpm"].notna().any())
            self.shaft_log_note = (
                shaft_log_against_speed(selected, self.log, self.shaft, self.options)
                if shaft_logged and judge_log
                else None
            )
            if self.shaft_log_note:
                # a frozen log: the voyage is marked as without a shaft speed
                attrs = dict(self.log.attrs)
                self.log = self.log.assign(shaft_rpm=np.nan)
                self.log.attrs.update(attrs)
                self.shaft["shaft_rpm"] = np.nan
                self.shaft["shaft_rpm_from"] = ""
                shaft = self.shaft.set_index("block")
                shaft_logged = False
        if shaft_logged:
            self.method = "shaft speed"
            selected["harmonic"] = mark_shaft_orders(selected, self.log, self.options)
            self.rpm_per_kn = shaft_rate_per_knot(self.log, self.options)
            missing = self.shaft["shaft_rpm"].isna() & self.shaft["speed_kn"].notna()
            if np.isfinite(self.rpm_per_kn) and missing.any():
                # the shaft speed from the speed where it is not logged (fixed pitch)
                estimated = self.log[["time"]].assign(
                    shaft_rpm=self.rpm_per_kn * _running_median(self.log["speed_kn"])
                )
                estimated.attrs["shaft_rpm_checked"] = True
                blocks = set(self.shaft.loc[missing, "block"].astype(int))
                rows = selected["block"].isin(blocks).to_numpy()
                selected.loc[rows, "harmonic"] = mark_shaft_orders(
                    selected[rows], estimated, self.options
                ).to_numpy()
                from_speed = block_shaft_table(estimated, selected[rows]).set_index("block")
                fill = self.shaft["block"].map(from_speed["shaft_rpm"])
                self.shaft.loc[missing, "shaft_rpm"] = fill[missing]
                self.shaft.loc[missing & fill.notna(), "shaft_rpm_from"] = "speed"
                shaft = self.shaft.set_index("block")
            rate_hz = selected["block"].map(shaft["shaft_rpm"]).to_numpy(float) / 60.0
            selected["harmonic_frequency_hz"] = selected["harmonic"].to_numpy(float) * rate_hz
            checked = shaft["shaft_rpm"].notna()
        elif self.shaft["speed_energy_kn"].notna().any():
            marks = mark_speed_following(selected, self.shaft, self.options)
            selected["harmonic"] = marks
            self.method = "speed"
            per_kn = marks.attrs.get("shaft_hz_per_kn", np.nan)
            self.shaft_hz_per_kn = float(per_kn)
            speed = selected["block"].map(shaft["speed_energy_kn"]).to_numpy(float)
            selected["harmonic_frequency_hz"] = np.where(
                marks.notna(),
                nearest_order_frequency(
                    selected["frequency_hz"].to_numpy(float), per_kn * speed, self.orders
                ),
                np.nan,
            )
            checked = shaft["speed_energy_kn"].notna()
        else:
            checked = None
        if checked is not None:
            selected["harmonic_checked"] = (
                selected["block"].map(checked).fillna(False).to_numpy(bool)
            )
        self.marked = selected[selected["harmonic"].notna()]
        return selected

    def mark_poles(self, poles: pd.DataFrame) -> pd.DataFrame:
        """A chunk of the pole table with its ``harmonic`` column."""
        poles = poles.copy()
        poles["harmonic"] = (
            mark_poles(poles, self.marked, self.options) if len(self.marked) else np.nan
        )
        self.n_poles += int(poles["harmonic"].notna().sum())
        return poles

    def unmarked(self) -> list[str]:
        """Warning lines when the ship log leaves blocks without a usable shaft speed (a
        log ending before the recordings, an outage, a frozen sensor): what was left out,
        the blocks marked from the speed instead, and those not checked at all."""
        notes = list(self.log.attrs.get("shaft_rpm_notes", [])) if self.log is not None else []
        lines = [f"ship log: {note}" for note in notes]
        if self.shaft_log_note:
            lines.append(f"ship log: {self.shaft_log_note}")
        if self.method == "none" or self.shaft.empty:
            return lines
        from ..store import block_ranges

        n = len(self.shaft)
        if self.method == "shaft speed":
            from_speed = self.shaft.loc[self.shaft["shaft_rpm_from"] == "speed", "block"]
            if len(from_speed):
                lines.append(
                    f"ship log: no usable shaft speed over block(s) "
                    f"{block_ranges(set(from_speed.astype(int)))} ({len(from_speed)} of {n} "
                    f"blocks): harmonics there marked from the speed x "
                    f"{self.rpm_per_kn:.2f} rpm/kn (the logged blocks' ratio)"
                )
            column = "shaft_rpm"
        else:
            column = "speed_energy_kn"
        missing = self.shaft.loc[self.shaft[column].isna(), "block"].astype(int)
        if len(missing):
            what = "shaft speed or speed" if self.method == "shaft speed" else "speed"
            lines.append(
                f"ship log: no usable {what} over block(s) {block_ranges(set(missing))} "
                f"({len(missing)} of {n} blocks): harmonics there cannot be told from modes; "
                "tracking leaves out a line seen (almost) only there"
            )
        return lines

    def lines(self) -> list[str]:
        """One line for the engineer: the test used and what it marked."""
        if self.log is None:
            return []
        what = {
            "shaft speed": "orders "
            + ", ".join(f"{k:g}" for k in self.orders)
            + " of the logged shaft speed",
            "speed": "frequency following the speed with a fixed shape; "
            + ("logged shaft speed not used" if self.shaft_log_note else "no shaft speed logged"),
            "none": "no shaft speed or speed in the ship log: none marked",
        }[self.method]
        if self.method == "speed" and np.isfinite(self.shaft_hz_per_kn):
            what += f"; shaft rate {self.shaft_hz_per_kn:.4f} Hz/kn"
        return [
            f"harmonics ({what}): {len(self.marked)} of {self.n_selected} selected modes and "
            f"{self.n_poles} poles marked, kept out of tracking"
        ]


def mark_harmonics(
    selected: pd.DataFrame,
    poles: pd.DataFrame,
    log: pd.DataFrame | None,
    options: HarmonicOptions | None = None,
) -> HarmonicMarks:
    """Mark the harmonics among the selected modes and poles of a voyage.

    Parameters
    ----------
    selected, poles : DataFrame
        The identification's tables (SELECTED and POLES contracts).
    log : DataFrame or None
        Canonical ship log (:func:`data_contracts.read_dship`); None: nothing is marked.
    options : HarmonicOptions, optional

    Returns
    -------
    HarmonicMarks
        The tables with a ``harmonic`` column, the test used and a per-block shaft table.
    """
    marker = HarmonicMarker(log, options)
    selected = marker.mark_selected(selected)
    poles = marker.mark_poles(poles)
    return HarmonicMarks(
        selected, poles, marker.method, marker.shaft, marker.orders, marker.lines()
    )


class _Growing:
    """A 1-D array appended to in place (its capacity doubled as needed)."""

    def __init__(self, dtype):
        self._data = np.empty(1024, dtype=dtype)
        self.size = 0

    def extend(self, values: np.ndarray) -> None:
        need = self.size + len(values)
        if need > len(self._data):
            grown = np.empty(max(need, 2 * len(self._data)), dtype=self._data.dtype)
            grown[: self.size] = self._data[: self.size]
            self._data = grown
        self._data[self.size : need] = values
        self.size = need

    @property
    def values(self) -> np.ndarray:
        return self._data[: self.size]


def _add_counts(counts: dict[int, int], values: np.ndarray) -> None:
    keys, n = np.unique(values, return_counts=True)
    for key, k in zip(keys.tolist(), n.tolist(), strict=True):
        counts[key] = counts.get(key, 0) + k


def _middle(counts: dict[int, int], extra: np.ndarray) -> np.ndarray:
    """The middle value (odd count) or two middle values (even) of the multiset *counts*
    (value -> count) with *extra* added, as ``np.median`` takes them."""
    merged = dict(counts)
    _add_counts(merged, extra)
    keys = np.array(sorted(merged), dtype=np.int64)
    cumulative = np.cumsum([merged[k] for k in keys.tolist()])
    total = int(cumulative[-1])
    ranks = [total // 2] if total % 2 else [total // 2 - 1, total // 2]
    return keys[np.searchsorted(cumulative, np.array(ranks) + 1, side="left")]


def _runs_after(open_run, times: np.ndarray, values: np.ndarray):
    """The runs of equal *values* (times *times*) continuing *open_run* ((value, first time,
    last time) or None): the closed runs' first times, last times and values, and the run
    left open."""
    if open_run is not None:
        firsts = np.concatenate([[open_run[1]], times])
        lasts = np.concatenate([[open_run[2]], times])
        values = np.concatenate([[open_run[0]], values])
    else:
        firsts = lasts = times
    if not len(values):
        return (np.empty(0, np.int64),) * 2 + (np.empty(0),), None
    starts, stops = _runs(values)
    first, last, value = firsts[starts], lasts[stops - 1], values[starts]
    return (first[:-1], last[:-1], value[:-1]), (float(value[-1]), int(first[-1]), int(last[-1]))


class LiveShaftLog:
    """:func:`usable_shaft_speed` and the log's interval between rows for a ship log that
    grows by rows appended at its end (the monitor's, read as it grows), at a cost that
    does not grow with the log: each :meth:`update` takes the new rows only, and
    :meth:`window` gives the rows of a few blocks as :func:`usable_shaft_speed` of the
    whole log gives them, with the whole log's interval (``attrs["log_step_s"]``), for
    :class:`HarmonicMarker` to mark those blocks.

    Kept: the count of each interval between rows; the finite shaft-speed readings (their
    spike test is final once :data:`SPIKE_WINDOW` // 2 readings follow: the running
    median is centred); the intervals between the readings left after the spike test and
    the runs of equal readings among them (first and last time, value), whose durations'
    median decides whether the frozen-sensor test applies. The newest readings, whose
    spike test may still change, are tested again at each update (with the readings the
    running median needs before them); the rows appended are never changed (a log read
    again whole is followed by a new instance: :meth:`update` refuses a shorter log).
    """

    def __init__(self):
        self.rows = 0
        self._last_time: int | None = None
        self._intervals: dict[int, int] = {}  # interval between rows [ns] -> count
        self._finite_row = _Growing(np.int64)
        self._finite_time = _Growing(np.int64)
        self._finite_value = _Growing(float)
        self._spike = _Growing(bool)  # final spike test of the first readings
        self._tail_spike = np.zeros(0, dtype=bool)  # the test of the others, for now
        self._kept_last: int | None = None  # time of the last settled reading kept
        self._kept_count = 0
        self._kept_intervals: dict[int, int] = {}
        self._open_run = None  # (value, first time, last time)
        self._run_first = _Growing(np.int64)
        self._run_last = _Growing(np.int64)
        self._run_value = _Growing(float)
        self._durations: dict[int, int] = {}  # closed runs' last - first time [ns] -> count

    @staticmethod
    def _ns(times: pd.Series) -> np.ndarray:
        return pd.DatetimeIndex(pd.to_datetime(times, utc=True)).as_unit("ns").asi8

    def update(self, log: pd.DataFrame) -> None:
        """Take the rows of *log* (sorted by time, unique times) after those taken."""
        n = len(log)
        if n < self.rows:
            raise ValueError(f"log of {n} rows is shorter than the {self.rows} rows taken")
        if n == self.rows:
            return
        times = self._ns(log["time"].iloc[self.rows :])
        before = [] if self._last_time is None else [self._last_time]
        _add_counts(self._intervals, np.diff(np.concatenate([before, times]).astype(np.int64)))
        self._last_time = int(times[-1])
        if "shaft_rpm" in log.columns:
            rpm = log["shaft_rpm"].iloc[self.rows :].to_numpy(float)
            finite = np.flatnonzero(np.isfinite(rpm))
            self._finite_row.extend(finite + self.rows)
            self._finite_time.extend(times[finite])
            self._finite_value.extend(rpm[finite])
        self.rows = n
        self._settle()

    def _spikes_from(self, first: int) -> np.ndarray:
        """The spike test of the finite readings from the *first* on, over the readings
        taken (the running median of each with the readings around it)."""
        start = max(0, first - SPIKE_WINDOW // 2)
        values = np.abs(self._finite_value.values[start:])
        median = (
            pd.Series(values).rolling(SPIKE_WINDOW, center=True, min_periods=1).median().to_numpy()
        )
        spike = np.abs(values - median) > SPIKE_TOL * median + SPIKE_FLOOR_RPM
        return spike[first - start :]

    def _settle(self) -> None:
        first = self._spike.size
        spike = self._spikes_from(first)
        settled = max(first, self._finite_value.size - SPIKE_WINDOW // 2)
        final = spike[: settled - first]
        self._spike.extend(final)
        self._tail_spike = spike[settled - first :]
        kept = np.flatnonzero(~final) + first
        times = self._finite_time.values[kept]
        before = [] if self._kept_last is None else [self._kept_last]
        _add_counts(self._kept_intervals, np.diff(np.concatenate([before, times]).astype(np.int64)))
        if len(times):
            self._kept_last = int(times[-1])
            self._kept_count += len(times)
        closed, self._open_run = _runs_after(self._open_run, times, self._finite_value.values[kept])
        self._add_runs(closed)

    def _add_runs(self, closed) -> None:
        first, last, value = closed
        self._run_first.extend(first)
        self._run_last.extend(last)
        self._run_value.extend(value)
        _add_counts(self._durations, last - first)

    def step_s(self) -> float:
        """:func:`_log_step_seconds` of the whole log's times. [s]"""
        if self.rows < 2:
            return 1.0
        middle = _middle(self._intervals, np.empty(0, np.int64)).astype(float)
        step = np.median(middle) / 1e9
        return float(step) if step > 0 else 1.0

    def _tail(self):
        """The newest readings kept by the spike test as it stands (indices), the runs
        among them continuing the settled ones, and the readings' interval and whether the
        frozen-sensor test applies (:func:`usable_shaft_speed` over the whole log)."""
        settled = self._spike.size
        tail = np.flatnonzero(~self._tail_spike) + settled
        times = self._finite_time.values[tail]
        closed, open_run = _runs_after(self._open_run, times, self._finite_value.values[tail])
        count = self._kept_count + len(tail)
        if count <= 1:
            return tail, closed, open_run, 1.0, False
        before = [] if self._kept_last is None else [self._kept_last]
        gaps = np.diff(np.concatenate([before, times]).astype(np.int64))
        middle = _middle(self._kept_intervals, gaps).astype(float)
        step = np.median(middle) / 1e9
        step = float(step) if step > 0 else 1.0
        durations = np.concatenate([closed[1] - closed[0], [open_run[2] - open_run[1]]])
        middle = _middle(self._durations, durations.astype(np.int64))
        lasting = middle.astype("timedelta64[ns]") / np.timedelta64(1, "s") + step
        return tail, closed, open_run, step, bool(np.median(lasting) < FROZEN_SECONDS / 10)

    def settled_until(self) -> pd.Timestamp | None:
        """The time before which the verdict of every shaft-speed reading taken (spike,
        frozen sensor) is final, as :func:`usable_shaft_speed` of the log however long it
        grows gives it (UTC; None: every reading's).

        A reading's spike test waits for the :data:`SPIKE_WINDOW` // 2 finite readings
        after it (the running median is centred: 15 s of a 1-s log, longer where the shaft
        speed is not logged); a run of equal readings still open, shorter than
        :data:`FROZEN_SECONDS` and not at 0 rpm, may still grow into a frozen one (when the
        frozen-sensor test applies: a property of the whole log, taken as it stands)."""
        found = []
        settled = self._spike.size
        if settled < self._finite_value.size:
            found.append(int(self._finite_time.values[settled]))
        if self._open_run is not None and self._open_run[0] != 0:
            *_, step, frozen_test = self._tail()
            value, first, last = self._open_run
            if frozen_test and (last - first) / 1e9 + step < FROZEN_SECONDS:
                found.append(int(first))
        return pd.Timestamp(min(found), tz="UTC") if found else None

    def settled(self, starts, ends) -> np.ndarray:
        """Per block (*starts*, *ends*): whether the verdicts of its shaft-speed readings
        (those in ``[start, end)``) are final (:meth:`settled_until`; a block without a
        reading after it, such as one in an outage, is)."""
        start = pd.DatetimeIndex(pd.to_datetime(pd.Series(starts), utc=True)).as_unit("ns").asi8
        end = pd.DatetimeIndex(pd.to_datetime(pd.Series(ends), utc=True)).as_unit("ns").asi8
        until = self.settled_until()
        if until is None:
            return np.ones(len(start), dtype=bool)
        times = self._finite_time.values
        first = np.searchsorted(times, np.maximum(start, until.value), side="left")
        return np.searchsorted(times, end, side="left") <= first

    def window(self, log: pd.DataFrame, starts, ends) -> pd.DataFrame:
        """The rows of *log* (the log taken by :meth:`update`) from the first at or after
        the earliest of *starts* to the last before the latest of *ends*, as
        :func:`usable_shaft_speed` of the whole log gives them (``attrs``:
        ``shaft_rpm_checked``, ``log_step_s`` the whole log's interval)."""
        if len(log) != self.rows:
            raise ValueError(f"log of {len(log)} rows, {self.rows} taken")
        start = pd.to_datetime(pd.Series(starts), utc=True).min()
        end = pd.to_datetime(pd.Series(ends), utc=True).max()
        times = log["time"]
        lo = int(times.searchsorted(start, side="left"))
        hi = int(times.searchsorted(end, side="left"))
        part = log.iloc[lo:hi].reset_index(drop=True).copy()
        if "shaft_rpm" in log.columns and self._finite_value.size:
            part["shaft_rpm"] = self._cleaned(lo, hi, part["shaft_rpm"].to_numpy(float).copy())
        part.attrs["shaft_rpm_checked"] = True
        part.attrs["log_step_s"] = self.step_s()
        return part

    def _cleaned(self, lo: int, hi: int, rpm: np.ndarray) -> np.ndarray:
        """*rpm*, the rows *lo* to *hi* of the log, with the spikes and the frozen readings
        of the whole log's test set to NaN."""
        rows = self._finite_row.values
        a, b = (int(k) for k in np.searchsorted(rows, [lo, hi], side="left"))
        settled = self._spike.size
        spike = np.concatenate(
            [self._spike.values[a : min(b, settled)], self._tail_spike[max(a, settled) - settled :
             max(b, settled) - settled]]
        )  # fmt: skip
        rpm[rows[a:b][spike] - lo] = np.nan
        _, closed, open_run, step, frozen_test = self._tail()
        if not frozen_test:
            return rpm
        kept = np.flatnonzero(~spike) + a
        times = self._finite_time.values[kept]
        # the runs: the settled ones closed before the open one, then those from it on
        tail_first = np.concatenate([closed[0], [open_run[1]]])
        tail_last = np.concatenate([closed[1], [open_run[2]]])
        tail_value = np.concatenate([closed[2], [open_run[0]]])
        late = times >= tail_first[0]
        first, last, value = (np.empty(len(times), d) for d in (np.int64, np.int64, float))
        run = np.searchsorted(self._run_first.values, times[~late], side="right") - 1
        first[~late] = self._run_first.values[run]
        last[~late] = self._run_last.values[run]
        value[~late] = self._run_value.values[run]
        run = np.searchsorted(tail_first, times[late], side="right") - 1
        first[late], last[late], value[late] = tail_first[run], tail_last[run], tail_value[run]
        lasting = (last - first).astype("timedelta64[ns]") / np.timedelta64(1, "s") + step
        frozen = (value != 0) & (lasting >= FROZEN_SECONDS)
        rpm[rows[kept[frozen]] - lo] = np.nan
        return rpm
