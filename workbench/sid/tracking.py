"""Mode tracking: give the modes identified block by block labels that stay the same.

A *library* of reference modes (pole and mode shape) is kept. The modes selected in each
block are assigned to library modes one-to-one by maximising the pole-weighted MAC (MACXP)
with the Hungarian algorithm; a pair counts only when its MACXP reaches a threshold and the
frequencies are close. Unmatched modes become *candidates*; a candidate is *born* as a new
library mode when a matching mode appears again within a few blocks. Library poles and
shapes follow slow drift by exponential smoothing, so temperature or speed trends do not
break the track, and a library mode that is not seen for a while keeps its label and is
picked up again when it returns. Because matching uses shapes as well as poles, two modes
whose frequencies cross keep their labels.

Labels are append-only: a library mode is labelled when it has been seen in ``min_blocks``
blocks (the table shows it from then on), with the next unused number; modes labelled at
the same block are numbered in order of frequency. A label keeps its mode for the rest of
the voyage (a mode that returns keeps it, a new or intermittent mode gets a new one, a
number is never reused, even when its mode is later dropped as a shaft harmonic), so the
table of the first blocks is never relabelled by later ones: ``workbench track`` over a
voyage and the live monitor block by block (:mod:`workbench.monitor.tracking`) give the
same labels.

Blocks may lack channels (faulty channels dropped for that block): shapes are compared on
the channels both have.

References
----------
.. [1] H. W. Kuhn, "The Hungarian method for the assignment problem", Naval Research
   Logistics Quarterly 2, 1955, 83-97. doi:10.1002/nav.3800020109
.. [2] P. Vacher, B. Jacquier, A. Bucharles, "Extensions of the MAC criterion to complex
   modes", Proceedings of ISMA 2010, Leuven, 2713-2725.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from data_contracts import MODAL, shape_columns, shapes_from_frame

from .assurance import continuous_pole, mac, macxp

__all__ = ["LibraryMode", "ModeTracker", "TrackingOptions", "label_agreement", "track_modes"]

_BLOCK_COLUMNS = ("block", "block_start", "block_end")


@dataclass(frozen=True)
class TrackingOptions:
    """Parameters of :class:`ModeTracker`.

    Attributes
    ----------
    mac_min : float
        Lowest value of the gate criterion for a block mode to join a library mode (or a
        candidate). [-]
    gate : {"mac", "macxp"}
        Criterion *mac_min* applies to. Among admissible pairs the assignment always
        maximises MACXP. The default gates on the shape alone (MAC) because MACXP's pole
        weighting makes it fall quickly with the scatter of SSI estimates: for two
        identical shapes with damping ζ and a relative frequency difference δ,
        MACXP ≈ 4ζ²/(4ζ² + δ²), i.e. 0.8 for ζ = δ = 0.5 %, which is within the
        block-to-block scatter of identified frequencies. Gating on MACXP at 0.9 splits
        such modes into several labels.
    frequency_tol : float
        Largest relative frequency difference between a block mode and the library mode it
        joins. [-]
    smoothing : float
        Weight of a new observation in the exponential update of the library pole and shape
        (0: frozen library, 1: the library is the last observation). [-]
    confirm_within : int
        A candidate is born as a library mode when a matching mode appears within this many
        blocks after it was first seen. [blocks]
    candidate_lifetime : int
        Candidates not confirmed within this many blocks are forgotten. [blocks]
    min_blocks : int
        A library mode is labelled (and shown in the table) once it has been seen in this
        many blocks; modes seen in fewer are dropped from the table (spurious). [blocks]
    min_channels : int
        Fewest channels shared by two shapes for them to be compared. [-]
    harmonic_share : float
        Tracked labels with at least this share of rows marked as shaft or blade-pass
        harmonics (the selected table's ``harmonic`` column, :mod:`workbench.sid.harmonics`)
        are harmonics, not modes, and are dropped, except a label unmarked in at least a
        quarter of its blocks (of its checked blocks, for a label seen in under half of the
        voyage's blocks) whose marked rows do not follow the order's frequency
        (``harmonic_frequency_hz``: slope of ln f on it below 0.5): a mode that an order
        sits on for hours. A mode that an order crosses keeps its rows (its own shape
        joined the label). Where the ship log could not check every row
        (``harmonic_checked``), the share is the marked share of all rows, or the larger of
        it and that of the checked rows where the label has at least 10 checked rows (or
        all its rows checked), is seen mostly where the log fails (checked in under a
        quarter of the voyage's share of checked blocks) or is seen in under half of the
        voyage's blocks (a line that comes and goes with the shaft speed; a structural mode
        is seen throughout). A label seen mostly where the log fails and checked in fewer
        than 10 blocks and a quarter of its blocks is dropped too, as unverified. [-]
    """

    mac_min: float = 0.9
    gate: Literal["mac", "macxp"] = "mac"
    frequency_tol: float = 0.05
    smoothing: float = 0.2
    confirm_within: int = 3
    candidate_lifetime: int = 3
    min_blocks: int = 3
    min_channels: int = 3
    harmonic_share: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.mac_min <= 1.0:
            raise ValueError(f"mac_min={self.mac_min} must be in (0, 1]")
        if self.gate not in ("mac", "macxp"):
            raise ValueError(f"gate={self.gate!r} must be 'mac' or 'macxp'")
        if not 0.0 < self.frequency_tol < 1.0:
            raise ValueError(f"frequency_tol={self.frequency_tol} must be in (0, 1)")
        if not 0.0 <= self.smoothing <= 1.0:
            raise ValueError(f"smoothing={self.smoothing} must be in [0, 1]")
        if not 0.0 < self.harmonic_share <= 1.0:
            raise ValueError(f"harmonic_share={self.harmonic_share} must be in (0, 1]")
        for name in ("confirm_within", "candidate_lifetime", "min_blocks", "min_channels"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}={getattr(self, name)} must be at least 1")


@dataclass
class LibraryMode:
    """A reference mode of the tracker (or a candidate not yet confirmed).

    ``serial`` numbers the library modes in order of birth (0 for a candidate); ``label``
    is the label shown, given once the mode has been seen in ``min_blocks`` blocks (None
    before), at block ``labelled_block`` (-1: a reference mode), when the mode's frequency
    was ``labelled_frequency_hz``.
    """

    serial: int
    frequency_hz: float
    damping_ratio: float
    shape: np.ndarray  # complex, n_channels; NaN where never observed
    first_block: int
    last_block: int
    n_blocks: int = 1
    frequencies: list[float] = field(default_factory=list)
    keys: list = field(default_factory=list)  # identifiers of a candidate's observations
    label: int | None = None
    labelled_block: int | None = None
    labelled_frequency_hz: float | None = None

    @property
    def pole(self) -> complex:
        return complex(continuous_pole(self.frequency_hz, min(max(self.damping_ratio, 1e-4), 0.99)))


def _align(shape: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """*shape* times the complex factor that best fits *reference* on their common channels.

    Least squares: ``c = φᴴ φ_ref / φᴴ φ`` over the common channels, so phase and scale match
    even when the two shapes were normalised over different channel sets.
    """
    both = np.isfinite(shape) & np.isfinite(reference)
    power = np.vdot(shape[both], shape[both]).real
    if power == 0:
        return shape
    return shape * (np.vdot(shape[both], reference[both]) / power)


def _normalise(shape: np.ndarray) -> np.ndarray:
    finite = np.isfinite(shape)
    norm = np.linalg.norm(shape[finite])
    if norm == 0:
        return shape
    shape = shape / norm
    largest = np.nanargmax(np.where(finite, np.abs(shape), -1.0))
    phase = shape[largest] / abs(shape[largest])
    return shape / phase


class ModeTracker:
    """Assign block modes to a library of reference modes, block after block.

    Parameters
    ----------
    n_channels : int
        Length of the mode shapes (the voyage's channel list; missing channels are NaN).
    options : TrackingOptions, optional
    reference : list of (frequency_hz, damping_ratio, shape), optional
        Initial library (e.g. modes of an earlier voyage). Without it, the library is born
        from the data.

    Notes
    -----
    Score of block mode *i* against library mode *j*: ``MACXP(φ_i, λ_i; φ_j, λ_j)`` on the
    channels both shapes have, set to 0 when below ``mac_min``, when
    ``|f_i - f_j| > frequency_tol * f_j`` or when fewer than ``min_channels`` are
    shared. The assignment maximises the summed score with the Hungarian algorithm [1]_,
    so two block modes never take the same label. A library mode that joins is updated as
    ``f ← (1 - α) f + α f_i`` (same for damping) and ``φ ← normalise((1 - α) φ + α φ_i)``
    with ``φ_i`` phase-aligned to ``φ`` first (α = ``smoothing``).
    """

    def __init__(
        self,
        n_channels: int,
        options: TrackingOptions | None = None,
        reference: Sequence[tuple[float, float, np.ndarray]] | None = None,
        *,
        reference_labels: Sequence[int] | None = None,
    ):
        self.n_channels = int(n_channels)
        self.options = options or TrackingOptions()
        self.library: list[LibraryMode] = []
        self.candidates: list[LibraryMode] = []
        #: (key, serial, score) of candidate observations from earlier blocks, assigned
        #: when the candidate was confirmed; drained by the caller.
        self.late_assignments: list[tuple[object, int, float]] = []
        reference = list(reference or ())
        if reference_labels is None:
            reference_labels = range(1, len(reference) + 1)
        reference_labels = [int(label) for label in reference_labels]
        if len(reference_labels) != len(reference) or len(set(reference_labels)) != len(
            reference_labels
        ):
            raise ValueError(
                f"reference_labels={reference_labels!r} must be {len(reference)} distinct labels"
            )
        # reference modes keep their labels; new modes are numbered after them
        self._next_serial = max(reference_labels, default=0) + 1
        self._next_label = self._next_serial
        for (frequency, damping, shape), label in zip(reference, reference_labels, strict=True):
            shape = np.asarray(shape, dtype=complex)
            if shape.shape != (self.n_channels,):
                raise ValueError(
                    f"reference shape has {shape.size} channels, expected {self.n_channels}"
                )
            mode = self._new_mode(frequency, damping, shape, block=-1, seen=0, serial=label)
            mode.label, mode.labelled_block = label, -1
            mode.labelled_frequency_hz = mode.frequency_hz
            self.library.append(mode)

    def labels(self) -> dict[int, int]:
        """Label shown of each labelled library mode, by serial."""
        return {m.serial: m.label for m in self.library if m.label is not None}

    def _new_mode(self, frequency, damping, shape, block, seen=1, serial=None) -> LibraryMode:
        if serial is None:
            serial = self._next_serial
            self._next_serial += 1
        return LibraryMode(
            serial=int(serial),
            frequency_hz=float(frequency),
            damping_ratio=float(damping),
            shape=_normalise(np.asarray(shape, dtype=complex).copy()),
            first_block=int(block),
            last_block=int(block),
            n_blocks=seen,
        )

    def _label_new_modes(self, block: int) -> None:
        """Label the library modes seen in ``min_blocks`` blocks by now (in order of
        frequency when several reach it in one block): the next unused numbers."""
        due = [m for m in self.library if m.label is None and m.n_blocks >= self.options.min_blocks]
        for mode in sorted(due, key=lambda m: (m.frequency_hz, m.serial)):
            mode.label, mode.labelled_block = self._next_label, int(block)
            mode.labelled_frequency_hz = mode.frequency_hz
            self._next_label += 1

    def _scores(
        self, frequency: np.ndarray, damping: np.ndarray, shapes: np.ndarray, modes
    ) -> np.ndarray:
        """Score matrix (n_block_modes x len(modes)), 0 where not admissible."""
        options = self.options
        scores = np.zeros((len(frequency), len(modes)))
        if not len(modes) or not len(frequency):
            return scores
        block_poles = continuous_pole(frequency, np.clip(damping, 1e-4, 0.99))
        block_finite = np.isfinite(shapes).all(axis=1)  # channels this block has, all modes
        for j, mode in enumerate(modes):
            common = block_finite & np.isfinite(mode.shape)
            if common.sum() < options.min_channels:
                continue
            close = np.abs(frequency - mode.frequency_hz) <= options.frequency_tol * (
                mode.frequency_hz
            )
            if not close.any():
                continue
            block_shapes = shapes[common][:, close]
            values = macxp(
                block_shapes,
                block_poles[close],
                mode.shape[common][:, None],
                np.array([mode.pole]),
            )[:, 0]
            gate = values if options.gate == "macxp" else mac(block_shapes, mode.shape[common])
            values = np.where(gate >= options.mac_min, np.maximum(values, 1e-9), 0.0)
            scores[np.flatnonzero(close), j] = values
        return scores

    @staticmethod
    def _assign(scores: np.ndarray) -> list[tuple[int, int, float]]:
        if scores.size == 0 or not (scores > 0).any():
            return []
        rows, cols = linear_sum_assignment(scores, maximize=True)
        return [
            (int(r), int(c), float(scores[r, c]))
            for r, c in zip(rows, cols, strict=True)
            if scores[r, c] > 0
        ]

    def _absorb(self, mode: LibraryMode, frequency, damping, shape, block) -> None:
        alpha = self.options.smoothing
        mode.frequency_hz = (1 - alpha) * mode.frequency_hz + alpha * float(frequency)
        mode.damping_ratio = (1 - alpha) * mode.damping_ratio + alpha * float(damping)
        aligned = _align(np.asarray(shape, dtype=complex), mode.shape)
        merged = np.where(
            np.isfinite(mode.shape) & np.isfinite(aligned),
            (1 - alpha) * mode.shape + alpha * aligned,
            np.where(np.isfinite(mode.shape), mode.shape, aligned),
        )
        mode.shape = _normalise(merged)
        mode.last_block = int(block)
        mode.n_blocks += 1
        mode.frequencies.append(float(frequency))

    def update(
        self, block: int, frequency_hz, damping_ratio, shapes, keys: Sequence | None = None
    ) -> list[tuple[int, int, float]]:
        """Track one block's modes.

        Parameters
        ----------
        block : int
            Block number (blocks must arrive in increasing order).
        frequency_hz, damping_ratio : array_like, shape (n_modes,)
        shapes : array_like, complex, shape (n_channels, n_modes)
            Mode shapes; NaN rows for channels the block does not have.

        Returns
        -------
        list of (index, serial, macxp)
            For each block mode that joined a library mode: its column index, the library
            mode's serial (:meth:`labels` maps serials to the labels shown) and the MACXP
            with the library mode before the update.
        """
        frequency = np.asarray(frequency_hz, dtype=float).ravel()
        keys = list(range(frequency.size)) if keys is None else list(keys)
        damping = np.asarray(damping_ratio, dtype=float).ravel()
        shapes = np.asarray(shapes, dtype=complex).reshape(self.n_channels, -1)
        if shapes.shape[1] != frequency.size or damping.size != frequency.size:
            raise ValueError(
                f"block {block}: {frequency.size} frequencies, {damping.size} damping ratios "
                f"and {shapes.shape[1]} shapes"
            )
        usable = np.isfinite(frequency) & np.isfinite(damping) & (frequency > 0)
        index = np.flatnonzero(usable)
        frequency, damping, shapes = frequency[usable], damping[usable], shapes[:, usable]

        matches = self._assign(self._scores(frequency, damping, shapes, self.library))
        assigned = []
        taken = set()
        for i, j, score in matches:
            mode = self.library[j]
            self._absorb(mode, frequency[i], damping[i], shapes[:, i], block)
            assigned.append((int(index[i]), mode.serial, score))
            taken.add(i)

        # Unmatched modes: confirm a waiting candidate or become one.
        rest = [i for i in range(frequency.size) if i not in taken]
        life = self.options.candidate_lifetime
        self.candidates = [c for c in self.candidates if block - c.last_block <= life]
        if rest:
            sub = np.array(rest)
            cand_matches = self._assign(
                self._scores(frequency[sub], damping[sub], shapes[:, sub], self.candidates)
            )
            confirmed = set()
            for r, c, score in cand_matches:
                candidate = self.candidates[c]
                if block - candidate.first_block > self.options.confirm_within:
                    continue
                i = int(sub[r])
                self._absorb(candidate, frequency[i], damping[i], shapes[:, i], block)
                candidate.serial = self._next_serial
                self._next_serial += 1
                self.library.append(candidate)
                assigned.append((int(index[i]), candidate.serial, score))
                self.late_assignments += [(key, candidate.serial, score) for key in candidate.keys]
                confirmed.add(c)
                taken.add(i)
            self.candidates = [c for k, c in enumerate(self.candidates) if k not in confirmed]
            for i in rest:
                if i in taken:
                    continue
                candidate = LibraryMode(
                    serial=0,
                    frequency_hz=float(frequency[i]),
                    damping_ratio=float(damping[i]),
                    shape=_normalise(shapes[:, i].copy()),
                    first_block=int(block),
                    last_block=int(block),
                    frequencies=[float(frequency[i])],
                    keys=[keys[int(index[i])]],
                )
                self.candidates.append(candidate)
        self._label_new_modes(block)
        return sorted(assigned)


def _selected_arrays(frame: pd.DataFrame, channels: Sequence[str]):
    """Frequencies, damping ratios and shapes (n_channels x n) of one block's rows."""
    _, shapes = shapes_from_frame(frame[[*shape_columns(channels)]])
    return (
        frame["frequency_hz"].to_numpy(dtype=float),
        frame["damping_ratio"].to_numpy(dtype=float),
        shapes.T,
    )


def track_modes(
    selected: pd.DataFrame,
    *,
    options: TrackingOptions | None = None,
    reference_modes: pd.DataFrame | None = None,
    progress: bool = False,
) -> pd.DataFrame:
    """Tracked modal table from the modes selected block by block.

    Parameters
    ----------
    selected : DataFrame
        One row per selected mode and block: ``block``, ``block_start``, ``block_end``,
        ``frequency_hz``, ``damping_ratio``, optional ``model_order`` and ``mpc``, and mode
        shape columns ``shape_re_<c>``/``shape_im_<c>`` (NaN for channels a block lacks).
    options : TrackingOptions, optional
    reference_modes : DataFrame, optional
        Initial library: a modal table (its ``mode`` labels are kept; the median of each
        mode's frequency and damping and the shape of its first row are used).
    progress : bool
        Progress bar (blocks done, rate, ETA) on stderr.

    Returns
    -------
    DataFrame
        The tracked modal table (MODAL contract): one row per block and tracked mode, with
        ``mac`` the MACXP against the library mode when it joined. Labels are numbered
        in the order the modes were confirmed (see the module notes), not by frequency,
        and the numbers of modes later dropped (harmonics) are not reused.
    """
    options = options or TrackingOptions()
    missing = [
        c
        for c in ("block", "block_start", "block_end", "frequency_hz", "damping_ratio")
        if c not in selected.columns
    ]
    if missing:
        raise ValueError(f"selected modes: missing column(s) {', '.join(missing)}")
    channels, _ = shapes_from_frame(selected.iloc[:0])
    if not channels:
        raise ValueError("selected modes: no mode-shape columns (shape_re_<channel>)")
    tracker = tracker_for(channels, options, reference_modes)

    frame = selected.sort_values("block", kind="stable").reset_index(drop=True)
    rows: list[tuple[int, int, float]] = []  # (row in frame, serial, macxp)
    from ..progress import progress_bar

    groups = frame.groupby("block", sort=True)
    bar = progress_bar(groups, total=groups.ngroups, description="track", enabled=progress)
    for _, part in bar:
        frequency, damping, shapes = _selected_arrays(part, channels)
        block = int(part["block"].iat[0])
        for i, serial, score in tracker.update(block, frequency, damping, shapes, part.index):
            rows.append((int(part.index[i]), serial, score))
        rows += tracker.late_assignments
        tracker.late_assignments = []
    return _tracked_table(frame, rows, tracker, channels, options)


def tracker_for(
    channels: Sequence[str],
    options: TrackingOptions,
    reference_modes: pd.DataFrame | None = None,
) -> ModeTracker:
    """A :class:`ModeTracker` for *channels*, its library started from *reference_modes*
    (a modal table; its labels kept) when given."""
    if reference_modes is None:
        return ModeTracker(len(channels), options)
    if "mode" not in reference_modes.columns:
        raise ValueError("reference modal table: missing column 'mode'")
    labels = sorted(int(m) for m in reference_modes["mode"].unique())
    return ModeTracker(
        len(channels),
        options,
        _reference_modes(reference_modes, channels),
        reference_labels=labels,
    )


def _reference_modes(reference: pd.DataFrame | None, channels: Sequence[str]):
    if reference is None:
        return None
    if "mode" not in reference.columns:
        raise ValueError("reference modal table: missing column 'mode'")
    ref_channels, shapes = shapes_from_frame(reference)
    lookup = {c: k for k, c in enumerate(ref_channels)}
    modes = []
    positions = np.arange(len(reference))
    for _, part in reference.assign(_row=positions).groupby("mode", sort=True):
        first = shapes[int(part["_row"].iat[0])]
        shape = np.full(len(channels), np.nan, dtype=complex)
        for k, channel in enumerate(channels):
            if channel in lookup:
                shape[k] = first[lookup[channel]]
        modes.append(
            (float(part["frequency_hz"].median()), float(part["damping_ratio"].median()), shape)
        )
    return modes


#: Spread of ln(order frequency) over a label's marked rows below which whether the label
#: follows the order cannot be told (a harmonic at one steady shaft speed). [-]
_FOLLOW_SPREAD = 0.005
#: Share of a label's blocks without a mark for it to be kept as a mode although most of
#: its rows are marked (then only if it does not follow its order).
_SEEN_AWAY = 0.25
#: Fewest marked rows of a label for the slope to be judged (a short fragment of a
#: harmonic on a speed ramp does not follow its order closely; the majority rule decides).
_FOLLOW_ROWS = 10


#: Share of the voyage's blocks under which a label is a line that comes and goes, judged
#: by its checked rows however few (a structural mode is seen throughout a voyage).
_PASSING = 0.5


def _follows_its_order(rows: pd.DataFrame) -> bool:
    """Whether a label's marked rows follow the order's frequency: the slope of ln f on
    ln f_order (``harmonic_frequency_hz``) is at least 0.5 (a harmonic's is 1, a structural
    mode's about 0: an order sitting on a mode for hours marks most of its blocks, but the
    mode stays where it is while the shaft speed wanders). True when the order's frequency
    hardly varies (the slope is not determined), is not known, or the label has fewer
    than ``_FOLLOW_ROWS`` marked rows."""
    if "harmonic_frequency_hz" not in rows.columns:
        return True
    known = rows[rows["harmonic_frequency_hz"].notna() & (rows["harmonic_frequency_hz"] > 0)]
    if len(known) < _FOLLOW_ROWS:
        return True
    x = np.log(known["harmonic_frequency_hz"].to_numpy(float))
    y = np.log(known["frequency_hz"].to_numpy(float))
    if np.std(x) < _FOLLOW_SPREAD:
        return True
    slope = np.cov(x, y)[0, 1] / np.var(x, ddof=1)
    return bool(slope >= 0.5)


def _tracked_table(frame, rows, tracker: ModeTracker, channels, options) -> pd.DataFrame:
    """The tracked table of *rows* ((row of *frame*, serial, macxp)): the labelled modes'
    rows under their labels, shaft harmonics left out."""
    labels = tracker.labels() if tracker is not None else {}
    rows = [(r, labels[serial], score) for r, serial, score in rows if serial in labels]
    if not rows:
        return _empty_tracked(frame)
    index = np.array([r[0] for r in rows])
    modes = np.array([r[1] for r in rows], dtype="int64")
    harmonic_labels: list[dict] = []
    keep = np.ones(len(rows), dtype=bool)
    if "harmonic" in frame.columns:
        marks = frame.loc[index]
        # the rows the ship log could check (all, without the column)
        checked = (
            marks["harmonic_checked"].fillna(True).astype(bool).to_numpy()
            if "harmonic_checked" in marks.columns
            else np.ones(len(marks), dtype=bool)
        )
        harmonic_labels = harmonic_verdict(
            modes,
            marks["block"].to_numpy(),
            marks["harmonic"].notna().to_numpy(),
            checked,
            marks["frequency_hz"].to_numpy(float),
            (
                marks["harmonic_frequency_hz"].to_numpy(float)
                if "harmonic_frequency_hz" in marks.columns
                else None
            ),
            options,
        )
        keep = ~np.isin(modes, [h["label"] for h in harmonic_labels])
    table = tracked_rows(
        frame, index[keep], modes[keep], np.array([r[2] for r in rows])[keep], channels
    )
    table.attrs["harmonic_labels"] = harmonic_labels
    return table


def _empty_tracked(frame: pd.DataFrame) -> pd.DataFrame:
    empty = frame.iloc[:0].copy()
    empty.insert(3, "mode", pd.Series([], dtype="int64"))
    empty["mac"] = pd.Series([], dtype=float)
    return MODAL.validate(
        empty.drop(
            columns=["harmonic", "harmonic_frequency_hz", "harmonic_checked"], errors="ignore"
        )
    )


def tracked_rows(frame, index, modes, scores, channels) -> pd.DataFrame:
    """The tracked table's rows *index* of *frame* (selected modes) under the labels
    *modes* with their MACXP *scores*, sorted by (block, mode) (stable in the order given),
    the harmonic marks left out."""
    table = frame.loc[np.asarray(index, dtype="int64")].copy()
    table["mode"] = np.asarray(modes, dtype="int64")
    table["mac"] = np.clip(np.asarray(scores, dtype=float), 0.0, 1.0)
    table = table.drop(
        columns=["harmonic", "harmonic_frequency_hz", "harmonic_checked"], errors="ignore"
    )
    front = ["block", "block_start", "block_end", "mode", "frequency_hz", "damping_ratio", "mac"]
    if "model_order" in table.columns:
        front.append("model_order")
    shape = shape_columns(channels)
    rest = [c for c in table.columns if c not in front and c not in shape]
    table = table[[*front, *rest, *shape]].sort_values(["block", "mode"], kind="stable")
    return MODAL.validate(table.reset_index(drop=True))


def harmonic_verdict(
    modes, blocks, marked, checked, frequency_hz, harmonic_frequency_hz, options
) -> list[dict]:
    """The labels tracking leaves out as shaft or blade-pass harmonics (and those seen
    mostly in a log outage, which cannot be told from one), from the labelled rows: per
    row its label *modes*, *blocks*, whether it is *marked* (``harmonic`` not NaN) and
    *checked* by the ship log, its ``frequency_hz`` and ``harmonic_frequency_hz`` (None:
    not known). Returns ``label``, ``blocks``, ``frequency_hz`` (median), ``share`` and
    ``unverified`` for each, harmonics first, each group by label."""
    modes = np.asarray(modes, dtype="int64")
    marked = np.asarray(marked, dtype=bool)
    checked = np.asarray(checked, dtype=bool)
    # labels are small whole numbers: counted by bincount, no sort of the rows
    offset = int(modes.min()) if len(modes) else 0
    present = np.bincount(modes - offset) > 0
    labels = np.flatnonzero(present) + offset
    position = (np.cumsum(present) - 1)[modes - offset]
    count = len(labels)
    n_rows = pd.Series(np.bincount(position, minlength=count), index=labels)
    n_checked = pd.Series(np.bincount(position, weights=checked, minlength=count), index=labels)
    n_marked = np.bincount(position, weights=marked, minlength=count)
    n_marked_checked = pd.Series(
        np.bincount(position, weights=marked & checked, minlength=count), index=labels
    )
    n_checked = n_checked.astype("int64")
    n_marked_checked = n_marked_checked.astype("int64")
    share_all = pd.Series(n_marked / n_rows.to_numpy(), index=labels)
    share_checked = n_marked_checked / n_checked.where(n_checked > 0)
    # a label seen mostly where the log fails: checked in less than a quarter of the
    # share of the voyage's blocks the log checked (a line that appears in an outage);
    # a mode seen throughout a voyage is checked as often as the voyage is
    blocks = np.asarray(blocks, dtype="int64")
    first_block = int(blocks.min()) if len(blocks) else 0
    rows_in = np.bincount(blocks - first_block)
    checked_in = np.bincount(blocks - first_block, weights=checked, minlength=len(rows_in))
    voyage_checked = float((checked_in > 0).sum() / (rows_in > 0).sum())
    in_outage = n_checked < _SEEN_AWAY * voyage_checked * n_rows
    # the share that judges a label: of all its rows (the unchecked counted unmarked:
    # without the shaft speed there, nothing shows the line keeps to its order); of its
    # checked rows where they are enough to judge (_FOLLOW_ROWS, or all its rows), where
    # the label is seen mostly in an outage, or where it is seen in under half of the
    # voyage's blocks: a line that comes and goes (a harmonic with the shaft speed) is
    # what its checked rows, however few, show (a line in the last 45 min, marked in its
    # 1-2 checked rows). A label seen throughout a voyage with fewer checked rows is
    # judged by all its rows: a harmonic would need the shaft at one rate all voyage, a
    # structural mode is what persists (an order sits on modes 1 and 7 in the last 45
    # min, the log's 8 blocks: 8 of 69 rows marked, modes).
    enough = n_checked >= np.minimum(_FOLLOW_ROWS, n_rows)
    passing = n_rows < _PASSING * (rows_in > 0).sum()
    share = np.maximum(share_all, share_checked.where(enough | in_outage | passing).fillna(0.0))

    def rows_of(label, only_marked=False):
        inside = modes == label
        if only_marked:
            inside &= marked
        part = pd.DataFrame({"frequency_hz": np.asarray(frequency_hz, float)[inside]})
        if harmonic_frequency_hz is not None:
            part["harmonic_frequency_hz"] = np.asarray(harmonic_frequency_hz, float)[inside]
        return part

    # most rows marked: a harmonic, unless the label is also seen away from the orders
    # in at least a quarter of its blocks and does not follow its order (a mode an
    # order sits on for hours). Seen away: in its unmarked rows, the unchecked included,
    # for a label seen throughout the voyage (a mode persists where the log fails); in
    # its checked unmarked rows for a line that comes and goes, whose checked rows stand
    # for it (a harmonic line through an outage of every column is unmarked there, not
    # away from its order). With every row checked both are the same.
    seen_away = pd.Series(
        np.where(
            passing,
            n_checked - n_marked_checked >= _SEEN_AWAY * n_checked,
            n_rows - n_marked >= _SEEN_AWAY * n_rows,
        ),
        index=labels,
    )
    harmonic = [
        label
        for label in share.index[share >= options.harmonic_share]
        if not seen_away[label] or _follows_its_order(rows_of(label, True))
    ]
    # a label seen mostly in an outage and checked in fewer than _FOLLOW_ROWS blocks
    # and a quarter of its blocks cannot be told from a harmonic: left out, unverified
    unverified = [
        label
        for label in share.index
        if label not in harmonic
        and in_outage[label]
        and n_checked[label] < min(_FOLLOW_ROWS, _SEEN_AWAY * n_rows[label])
    ]
    return [
        {
            "label": int(label),
            "blocks": int(n_rows[label]),
            "frequency_hz": float(rows_of(label)["frequency_hz"].median()),
            "share": float(np.nan_to_num(share[label])),
            "unverified": label in unverified,
        }
        for label in [*harmonic, *unverified]
    ]


def label_agreement(
    tracked: pd.DataFrame, truth: pd.DataFrame, *, tolerance: float = 0.03
) -> tuple[float, dict[int, int]]:
    """Share of tracked (block, mode) rows of true modes that carry the right label.

    Every tracked row is attributed to the true mode nearest in frequency in the same
    block; rows further than *tolerance* (relative) from every true mode are not modes of
    the structure (a shaft harmonic, a spurious pole) and are left out. Tracked labels and
    true modes are then paired one-to-one (Hungarian assignment on the counts of rows they
    share), so a true mode split over two labels, or two true modes merged under one label,
    counts the rows of the smaller part as wrong.

    Returns
    -------
    agreement : float
        In [0, 1]; NaN when no row is near a true mode.
    mapping : dict
        Tracked label -> true mode, for the paired labels.
    """
    if tracked.empty:
        return math.nan, {}
    truth_wide = truth.pivot(index="block", columns="mode", values="frequency_hz")
    merged = tracked[["block", "mode", "frequency_hz"]].merge(
        truth_wide, left_on="block", right_index=True, how="inner"
    )
    if merged.empty:
        return math.nan, {}
    true_modes = np.array(truth_wide.columns)
    true_frequency = merged[list(true_modes)].to_numpy(dtype=float)
    distances = np.abs(true_frequency - merged["frequency_hz"].to_numpy()[:, None])
    distances = np.where(np.isfinite(distances), distances, np.inf)
    position = np.argmin(distances, axis=1)
    rows = np.arange(len(merged))
    near = distances[rows, position] <= tolerance * true_frequency[rows, position]
    merged = merged[near]
    if merged.empty:
        return math.nan, {}
    nearest = true_modes[position[near]]
    counts = pd.crosstab(merged["mode"].to_numpy(), nearest)
    rows, cols = linear_sum_assignment(counts.to_numpy(), maximize=True)
    mapping = {
        int(counts.index[r]): int(counts.columns[c]) for r, c in zip(rows, cols, strict=True)
    }
    correct = sum(int(counts.iat[r, c]) for r, c in zip(rows, cols, strict=True))
    return correct / len(merged), mapping
