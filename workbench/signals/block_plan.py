"""Which blocks a set of consecutive acquisition files gives, from their headers alone.

An acquisition system writes one file per interval (typically 5 minutes). Identification
works on blocks of the shared grid (:class:`~workbench.blocks.BlockGrid`; default 20 min
every 5 min). :func:`plan_blocks` reads only the file headers (:func:`read_file_info`; for
``.npz`` files: start time, rate, channel names and the array shape from the archive;
``.mat`` and ``.csv`` files are read whole once) and lists every block the files give, with
the files each needs and, for blocks that cannot be built, the reason. The orchestrator
plans parallel tasks with it; the blocks themselves are built by
:mod:`workbench.signals.block_builder`.

Gaps between files
------------------
Consecutive files normally abut (the next file starts one sample interval after the last
sample of the previous one). A recorder stamps each file from its PC clock (NTP steps,
write buffering), so a file's stamp may miss the previous file's end by a few milliseconds
while the samples run on without a break: a mismatch (gap or overlap) of at most
:data:`CLOCK_JITTER_S` is taken as such clock jitter and the later file is **re-timed** to
start at the previous file's end (:func:`place_files`; ``FileInfo.clock_shift_s`` keeps the
shift, and the plan's files carry the re-timed starts, which the block builder and the file
conditioner use alike). The recorder's sample clock may also run some ppm off its nominal
rate, so that its files last slightly less or more than their sample count says and the
stamps drift steadily from the sample count: the mismatch is then measured from the
least-squares line of the run's stamps on its sample count (:func:`place_files`,
:func:`clock_runs`, :func:`clock_drift_note`). The files keep the placed times (the
sample count); a drifting record's blocks are cut at the UTC of their labels: each takes
the grid's length of samples from where the record's clock line puts its label's time
(:func:`record_clocks`, ``PlannedBlock.sample_start``). A longer gap is a gap; a longer
overlap an error. A block that
overlaps a gap is **skipped** with the reason (``"gap of 42.0 s between acc_a.npz and
acc_b.npz"``), unless the gap's part inside the block is at most ``max_gap_s`` (or, at
the block's start or end, the clock jitter: a record after a gap is placed only to it): then the
gap is filled with NaN, which the NaN policy bridges by interpolation -- so ``max_gap_s``
should not exceed the faulty-channel ``max_nan_run_s`` (default 10 s), or every channel of
the block would be dropped. Files that overlap in time, differ in channel set or in
sampling rate are errors (:class:`ValueError` naming the file); identify and the monitor
first leave out a file at another rate than most files have, and an exact duplicate
(:func:`sort_out_files`). Channels in a different order are reordered to the first file's
order.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import read_accelerations
from data_contracts.npz import check_sample_header, read_checked_arrays, read_sample_header

from ..blocks import (
    DEFAULT_BLOCK_LENGTH_S,
    DEFAULT_BLOCK_STEP_S,
    MAX_BLOCKS,
    BlockGrid,
    utc_timestamp,
)
from ..errors import OptionError
from ..fingerprints import sha256

__all__ = [
    "CLOCK_JITTER_S",
    "EDGE_SHIFT_S",
    "BlockPlan",
    "ClockRun",
    "FileOverlapError",
    "FileInfo",
    "FilePlacement",
    "PlannedBlock",
    "RecordClock",
    "clock_runs",
    "cut_in_file",
    "cut_placed_ns",
    "cut_tolerance_s",
    "edge_cut_note",
    "line_placed_ns",
    "missed_blocks",
    "missed_blocks_line",
    "missed_blocks_note",
    "place_files",
    "placed_block_numbers",
    "placed_blocks",
    "sort_out_files",
    "plan_blocks",
    "read_file_info",
    "record_clocks",
]

_NS = 1_000_000_000

#: Largest mismatch between one file's end and the next file's start (a gap or an overlap)
#: taken as the recorder's clock jitter: the files are contiguous and the later one is
#: re-timed to the previous file's end. [s]
#:
#: A file's start is stamped from the recorder PC's clock, which NTP steps and slews and
#: which is read when a write buffer is flushed: consecutive stamps miss each other by
#: milliseconds to a few tens of milliseconds while the samples run on (half a sample,
#: the limit before, is 0.24 ms at 2048 Hz). Where the files really do have a gap or
#: overlap of d <= 50 ms, re-timing splices them with a phase jump 2 pi f d of each mode
#: (12 Hz, 10 ms: 0.75 rad; 50 ms: 3.8 rad) at one instant of a 20-minute block. SSI sees
#: that through the output covariances: only products across the splice change, a
#: fraction (lag / block length) of them, at most 40 lags of a 64-Hz block over 1200 s,
#: 5e-4, so the modes move far less than their block-to-block scatter; a lightly damped
#: mode (1 %, 12 Hz: decay time 1.3 s) forgets the jump within seconds, as it forgets any
#: gust. Bridging a NaN gap of d by interpolation (``--max-gap``) loses the same d of data
#: and costs the same; skipping the block (the default for gaps) loses 20 minutes. 50 ms
#: stays well below a recorder's lost write buffer (typically 0.25-1 s) and far below a
#: duplicate file's overlap (the file's whole length), which stay a gap and an error.
#:
#: A sample clock off its nominal rate by a fraction rho (crystals: 10-100 ppm) makes every
#: file last rho of its length less (or more) than its samples say, so the stamps drift
#: from the sample count steadily (20 ppm: 6 ms per 5-min file, 1.7 s a day) and would
#: pass this limit within the hour. The limit therefore bounds the stamps' distance from
#: the least-squares line of a run's stamps on its sample count (:func:`place_files`); the
#: blocks keep the recorder's consecutive samples, cut where that line puts the UTC of
#: their labels (:func:`record_clocks`). The modal
#: frequencies are those of the nominal rate, low by rho of themselves (20 ppm of 3 Hz:
#: 0.06 mHz; 100 ppm of 12 Hz: 1.2 mHz), far below their block-to-block scatter and the
#: same through a voyage; a rate fitted over a short run is uncertain by the jitter over
#: its span (25 ms over 5 min: 80 ppm), so a "correction" would add more than it removes.
CLOCK_JITTER_S = 0.05

#: A drifting record's block whose UTC span (where the record's clock line puts its
#: label) runs at most this far past the record's first or last sample is cut at that
#: sample: its samples begin up to this far off its label (said by
#: :func:`edge_cut_note`) instead of the block being lost. A clock *rho* fast records a
#: length of sample count T in T / (1 + rho) of UTC, so its last block, on the sample
#: count a whole block, misses its UTC span by rho x T (100 ppm: 0.36 s after 1 h). Such a
#: shift of up to 1 s moved the selected modes of 11 blocks of the 3-h demo voyage by at
#: most 6.2 mHz and 0.04 %-points of damping (median 0.7 mHz; their distance from the
#: simulation's truth: median 19 mHz), about what NaN-padding those seconds did (4.4 mHz,
#: 0.11 %-points, and 2 modes of one block changed); a 2-s shift moved the 1-s ship-log
#: means of 20-min blocks by at most 0.017 kn (benchmarks/results/clock_drift_utc_52.txt). [s]
EDGE_SHIFT_S = 1.0


def cut_tolerance_s(sampling_rate_hz: float, lattice: int = 1) -> float:
    """How far two cuts of one drifting block, each from the clock line of the files at
    hand then, may lie apart and be the same cut: the clock jitter, or one sample of the
    analysis lattice (*lattice* raw samples at *sampling_rate_hz*) when that is longer.

    Two lines of one record (the monitor's, of the files landed when it decided a block;
    identify's, of all of them) put a label a few ms apart; each cut is that point rounded
    to the nearest lattice sample, so where a rounding midpoint lies between the two
    points the cuts differ by one whole lattice sample however close the lines are (62.5
    ms at 16 Hz: -100 ppm, block 1 of the 3-h demo voyage,
    benchmarks/results/clock_drift_utc_53.txt). [s]"""
    return max(CLOCK_JITTER_S, lattice / sampling_rate_hz)


# ----------------------------------------------------------------------------------------
# file headers
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FileInfo:
    """What a file holds, without its samples.

    Parameters
    ----------
    path : Path
    start_time : pandas.Timestamp
        Time of the first sample. [UTC]
    sampling_rate_hz : float
        [Hz]
    n_samples : int
    channels : tuple of str
    clock_shift_s : float
        How far *start_time* lies after the file's own start stamp: the file re-timed to
        its predecessor's end (clock jitter, :func:`place_files`); 0 for a file as
        stamped. [s]
    """

    path: Path
    start_time: pd.Timestamp
    sampling_rate_hz: float
    n_samples: int
    channels: tuple[str, ...]
    clock_shift_s: float = 0.0

    @property
    def name(self) -> str:
        return self.path.name

    @functools.cached_property
    def end_time(self) -> pd.Timestamp:
        """Time just after the last sample. [UTC]"""
        return self.start_time + pd.Timedelta(seconds=self.n_samples / self.sampling_rate_hz)


def _npz_info(path: Path) -> FileInfo:
    header = read_sample_header(path)
    # The samples a header claims must be in the archive (a 1-KB file claiming 30 days
    # would plan thousands of blocks) and fit the memory budget: the readers' one guard,
    # also on the small arrays before they are read.
    check_sample_header(header, path, "array acceleration")
    shape = header.shape
    data = read_checked_arrays(path, ("sampling_rate_hz", "start_time", "channels"))
    rate = float(np.asarray(data["sampling_rate_hz"]).reshape(-1)[0])
    start = str(np.asarray(data["start_time"]).reshape(-1)[0])
    channels = tuple(str(c) for c in np.asarray(data["channels"]).ravel())
    if len(shape) != 2 or shape[1] != len(channels) or not (math.isfinite(rate) and rate > 0):
        raise ValueError("inconsistent header")
    if shape[0] < 2:  # no record (a recorder stopped at the start): the reader says so
        raise ValueError("too few samples")
    return FileInfo(path, utc_timestamp(start), rate, int(shape[0]), channels)


def read_file_info(path: str | os.PathLike, *, read_options: Mapping | None = None) -> FileInfo:
    """Header of an acceleration file: start time, rate, number of samples, channels.

    For ``.npz`` files only the small arrays and the header of the sample array are read.
    Other formats (and ``.npz`` files whose header looks wrong) are read whole with
    :func:`data_contracts.read_accelerations`, which also reports any problem.

    Parameters
    ----------
    path : path-like
    read_options : mapping, optional
        Keyword arguments for :func:`data_contracts.read_accelerations` (MATLAB variable
        names, CSV time column, ...).
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        try:
            return _npz_info(path)
        except Exception:  # anything odd: the full reader gives the proper ContractError
            pass
    record = read_accelerations(path, **dict(read_options or {}))
    return FileInfo(
        path, record.start_time, record.sampling_rate_hz, record.n_samples, record.channels
    )


# ----------------------------------------------------------------------------------------
# planning
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlannedBlock:
    """One block of a :class:`BlockPlan`: its span, its files, or why it cannot be built.

    Satisfies the ``BlockTask`` protocol of :func:`workbench.parallel.run_blocks`.

    Parameters
    ----------
    block : int
    block_start, block_end : pandas.Timestamp
        [UTC]
    files : tuple of Path
        Files overlapping the block, in time order (empty for some skipped blocks).
    skipped_reason : str
        Empty when the block can be built; else why not (e.g. a gap between files).
    sample_start : pandas.Timestamp, optional
        Placed time of the block's first sample (on the files' sample count, as
        ``FileInfo.start_time``): *block_start* unless the record's sample clock drifts
        from its stamps, where it is the sample count at which the record's clock line
        puts *block_start* (:class:`RecordClock`); the block holds the grid's length of
        samples from there. Default: *block_start*.
    drifting : bool
        Whether the block is cut on its record's clock line (*sample_start*, which may
        also equal *block_start* there): a builder then takes *sample_start* as it is,
        not a placement of the block's own files.
    """

    block: int
    block_start: pd.Timestamp
    block_end: pd.Timestamp
    files: tuple[Path, ...]
    skipped_reason: str = ""
    sample_start: pd.Timestamp | None = None
    drifting: bool = False

    def __post_init__(self) -> None:
        if self.sample_start is None:
            object.__setattr__(self, "sample_start", self.block_start)

    @property
    def sample_end(self) -> pd.Timestamp:
        """Placed time just after the block's last sample. [UTC]"""
        return self.sample_start + (self.block_end - self.block_start)


@dataclass(frozen=True, eq=False)
class BlockPlan:
    """The blocks a set of acceleration files gives.

    Parameters
    ----------
    grid : BlockGrid
    files : tuple of FileInfo
        The files, sorted by start time, as placed (:func:`place_files`: re-timed for clock
        jitter where ``clock_shift_s`` is not 0).
    channels : tuple of str
        Channel names (order of the first file).
    sampling_rate_hz : float
        [Hz]
    blocks : tuple of PlannedBlock
        Every block lying inside the span of the files, ascending; blocks overlapping a gap
        carry a ``skipped_reason``.
    max_gap_s : float
        Gaps up to this length inside a block are NaN-padded. [s]
    left_out : tuple of (Path, str)
        Files given that cannot belong to the record, with why (:func:`sort_out_files`):
        not among *files*, their spans are gaps.
    lattice : int
        The decimation factor on whose lattice a drifting record's blocks are cut
        (:func:`placed_blocks`); 1: the raw samples.
    """

    grid: BlockGrid
    files: tuple[FileInfo, ...]
    channels: tuple[str, ...]
    sampling_rate_hz: float
    blocks: tuple[PlannedBlock, ...]
    max_gap_s: float = 0.0
    left_out: tuple[tuple[Path, str], ...] = ()
    lattice: int = 1

    def frame(self) -> pd.DataFrame:
        """Table of the plan: block, block_start, block_end, n_files, skipped_reason."""
        return pd.DataFrame(
            {
                "block": np.array([b.block for b in self.blocks], dtype=np.int64),
                "block_start": pd.DatetimeIndex([b.block_start for b in self.blocks]),
                "block_end": pd.DatetimeIndex([b.block_end for b in self.blocks]),
                "n_files": np.array([len(b.files) for b in self.blocks], dtype=np.int64),
                "skipped_reason": pd.Series([b.skipped_reason for b in self.blocks], dtype=str),
            }
        )

    @property
    def max_files_per_block(self) -> int:
        return max((len(b.files) for b in self.blocks), default=0)


def majority_channels(infos: Sequence[FileInfo]) -> tuple[str, ...]:
    """The channel set most of *infos* carry (ties: the earliest), in the order of the
    first file carrying it (:func:`reference_channels` without its checks)."""
    counts: dict[frozenset, int] = {}
    order: dict[frozenset, tuple[str, ...]] = {}
    for info in infos:
        key = frozenset(info.channels)
        counts[key] = counts.get(key, 0) + 1
        order.setdefault(key, tuple(info.channels))
    return order[max(counts, key=lambda key: counts[key])]  # first maximum: earliest


def majority_rate(infos: Sequence[FileInfo]) -> tuple[float, int]:
    """The sampling rate most of *infos* have (ties: the earliest file's) and how many
    have it."""
    counts: dict[float, int] = {}
    for info in infos:
        counts[info.sampling_rate_hz] = counts.get(info.sampling_rate_hz, 0) + 1
    rate = max(counts, key=lambda r: counts[r])  # first maximum: the earliest file's
    return rate, counts[rate]


def _names(infos: Sequence[FileInfo]) -> str:
    """``a.npz``, ``a.npz, b.npz`` or ``5 files (a.npz .. e.npz)``."""
    if len(infos) <= 2:
        return ", ".join(i.name for i in infos)
    return f"{len(infos)} files ({infos[0].name} .. {infos[-1].name})"


def sort_out_files(
    infos: Sequence[FileInfo],
) -> tuple[list[FileInfo], tuple[tuple[Path, str], ...]]:
    """The files of *infos* (sorted by start time) that can be one record, and those that
    cannot with why: a file at another sampling rate than more than half of the files
    have (a recorder briefly set otherwise), and an exact duplicate of an earlier file
    (the same bytes, so the same stamp and samples: a file copied twice into the folder;
    the first by path is kept). Their spans are then gaps.

    Raises
    ------
    ValueError
        No sampling rate is shared by more than half of the files: which is the record's is
        not clear, naming the files of each rate. (Two different files for the same span
        are an error of :func:`place_files`.)
    """
    infos = sorted(infos, key=lambda i: (i.start_time, str(i.path)))
    if not infos:
        return [], ()
    rate, count = majority_rate(infos)
    if 2 * count <= len(infos):
        rates: dict[float, list[FileInfo]] = {}
        for info in infos:
            rates.setdefault(info.sampling_rate_hz, []).append(info)
        listed = "; ".join(f"{r:g} Hz: {_names(group)}" for r, group in rates.items())
        raise ValueError(
            f"{infos[0].path}: no sampling rate is shared by more than half of the "
            f"{len(infos)} files ({listed}); give the files of one recording"
        )
    left_out: list[tuple[Path, str]] = []
    kept = []
    for info in infos:
        if info.sampling_rate_hz != rate:
            left_out.append(
                (
                    info.path,
                    f"sampling rate {info.sampling_rate_hz:g} Hz, not {rate:g} Hz (that of "
                    f"{count} of the {len(infos)} files); its span is a gap",
                )
            )
        else:
            kept.append(info)
    same: dict[tuple, list[FileInfo]] = {}
    for info in kept:
        key = (info.start_time, info.n_samples, info.channels)
        same.setdefault(key, []).append(info)
    duplicates: set[Path] = set()
    for group in same.values():
        if len(group) < 2:
            continue
        first: dict[str, FileInfo] = {}
        for info in sorted(group, key=lambda i: str(i.path)):
            try:
                digest = sha256(info.path)
            except OSError:  # read later, where it is said
                continue
            if digest in first:
                duplicates.add(info.path)
                left_out.append((info.path, duplicate_reason(first[digest])))
            else:
                first[digest] = info
    kept = [info for info in kept if info.path not in duplicates]
    left_out.sort(key=lambda item: str(item[0]))
    return kept, tuple(left_out)


def duplicate_reason(original: FileInfo) -> str:
    """Why a file with the bytes of *original* is not used."""
    return f"the same data as {original.name} (a duplicate)"


def reference_channels(
    infos: Sequence[FileInfo], channels: Sequence[str] | None = None
) -> tuple[str, ...]:
    """The channels of a set of files: *channels* when given (a voyage's, for a few of its
    files), else the channel set most files carry (ties: the earliest), in the order of the
    first file carrying it.

    A recorder that drops a channel for a while writes files lacking it; those files are
    read with the channel all-NaN (:func:`align_channels`), and the blocks holding them drop
    it as faulty. Raises ValueError naming the file when a file differs from the sampling
    rate most files have (ties: the earliest file's; so the file named is the odd one, also
    when it is the first) or lacks more than half of the channels (then it is not the same
    recorder's file).
    """
    rates: dict[float, list[FileInfo]] = {}
    for info in infos:
        rates.setdefault(info.sampling_rate_hz, []).append(info)
    usual = max(rates.values(), key=len)  # first maximum: the earliest file's rate
    channels = tuple(majority_channels(infos) if channels is None else channels)
    for info in infos:
        if info.sampling_rate_hz != usual[0].sampling_rate_hz:
            others = usual[0].name if len(usual) == 1 else f"{len(usual)} of the {len(infos)} files"
            raise ValueError(
                f"{info.path}: sampling rate {info.sampling_rate_hz:g} Hz differs from "
                f"{usual[0].sampling_rate_hz:g} Hz of {others}"
            )
        if len(set(info.channels)) != len(info.channels):
            raise ValueError(f"{info.path}: a channel name appears twice")
        missing = [c for c in channels if c not in info.channels]
        if 2 * len(missing) > len(channels):
            extra = [c for c in info.channels if c not in channels]
            parts = [f"missing {', '.join(missing)}"] + (
                [f"extra {', '.join(extra)}"] * bool(extra)
            )
            raise ValueError(
                f"{info.path}: channels differ from those of the other files ({'; '.join(parts)})"
            )
    return channels


def lacking_channels(
    infos: Sequence[FileInfo], channels: Sequence[str]
) -> dict[tuple[str, ...], list[str]]:
    """Files lacking some of *channels*: the missing channels -> the names of the files."""
    out: dict[tuple[str, ...], list[str]] = {}
    for info in infos:
        missing = tuple(c for c in channels if c not in info.channels)
        if missing:
            out.setdefault(missing, []).append(info.name)
    return out


def align_channels(values: np.ndarray, names: Sequence[str], channels: Sequence[str]) -> np.ndarray:
    """*values*' columns (named *names*) in *channels* order; a channel not among *names* is
    all-NaN and a name not among *channels* is left out."""
    names = tuple(names)
    if names == tuple(channels):
        return values
    out = np.full((values.shape[0], len(channels)), np.nan)
    for j, channel in enumerate(channels):
        if channel in names:
            out[:, j] = values[:, names.index(channel)]
    return out


class _ClockRun:
    """The clock of one contiguous run of files: their stamps against the samples recorded
    before each (the sample count), for :func:`place_files`.

    Running sums of a least-squares line ``stamp - anchor - x = alpha + beta * x``, x the
    sample count in nominal seconds (so alpha, beta are small: milliseconds and ppm).
    """

    def __init__(self, first: FileInfo, rate: float) -> None:
        self.rate = rate
        # the first stamp, and how far the run's placed times lie after the stamps there
        self.anchor = first.start_time - pd.Timedelta(seconds=first.clock_shift_s)
        self.anchor_shift_s = first.clock_shift_s
        self.samples = 0
        self.n = 0
        self.sum_x = self.sum_y = self.sum_xx = self.sum_xy = self.sum_yy = 0.0
        self.last_n_samples = 0
        self.add(first)

    def _y(self, info: FileInfo, x: float) -> float:
        stamp = info.start_time - pd.Timedelta(seconds=info.clock_shift_s)
        return (stamp - self.anchor).total_seconds() - x

    def add(self, info: FileInfo) -> None:
        """*info*, placed as the run's next file."""
        x = self.samples / self.rate
        y = self._y(info, x)
        self.n += 1
        self.sum_x += x
        self.sum_y += y
        self.sum_xx += x * x
        self.sum_xy += x * y
        self.sum_yy += y * y
        self.samples += info.n_samples
        self.last_n_samples = info.n_samples

    def _moments(self) -> tuple[float, float, float, float, float]:
        mean_x, mean_y = self.sum_x / self.n, self.sum_y / self.n
        sxx = self.sum_xx - self.n * mean_x * mean_x
        sxy = self.sum_xy - self.n * mean_x * mean_y
        syy = self.sum_yy - self.n * mean_y * mean_y
        return mean_x, mean_y, sxx, sxy, syy

    def line(self) -> tuple[float, float]:
        """alpha [s] and beta (the stamps' seconds per nominal second, less 1) of the line."""
        if self.n < 2:
            return 0.0, 0.0
        mean_x, mean_y, sxx, sxy, _ = self._moments()
        beta = sxy / sxx if sxx > 0 else 0.0
        return mean_y - beta * mean_x, beta

    def walk_s(self) -> float:
        """How far the line moves from the sample count over the run's stamps, less twice
        its standard error (from the stamps' scatter about the line): a drift told apart
        from jitter. [s]"""
        if self.n < 3:
            return 0.0
        _, _, sxx, sxy, syy = self._moments()
        if sxx <= 0:
            return 0.0
        beta = sxy / sxx
        scatter = math.sqrt(max(syy - beta * sxy, 0.0) / (self.n - 2))
        last_x = (self.samples - self.last_n_samples) / self.rate
        return (abs(beta) - 2 * scatter / math.sqrt(sxx)) * last_x

    def drifting(self, clock_jitter_s: float) -> bool:
        """Whether the line drifts from the sample count by more than half the jitter over
        the run's stamps: they are then judged against the line alone."""
        return self.walk_s() > 0.5 * clock_jitter_s

    def sample_count_gap_s(self, offset_s: float, clock_jitter_s: float) -> float | None:
        """A gap of *offset_s* after the line's time at the run's end (a stamp that far
        after where the run's clock puts its next file) in the run's sample count: the
        samples the recorder would have counted in it, offset_s / (1 + beta) [s]; None
        when the line cannot carry the record's time over the gap: the run does not
        drift (its stamps are the time), or the line's time at the stamp is uncertain by
        more than half the clock jitter (twice its standard error from the stamps'
        scatter, which grows with the gap)."""
        if not self.drifting(clock_jitter_s):
            return None
        mean_x, _, sxx, sxy, syy = self._moments()
        beta = sxy / sxx
        scatter = math.sqrt(max(syy - beta * sxy, 0.0) / (self.n - 2))
        gap_x = offset_s / (1 + beta)
        x = self.samples / self.rate + gap_x
        error_s = scatter * math.sqrt(1 / self.n + (x - mean_x) ** 2 / sxx)
        return gap_x if 2 * error_s <= 0.5 * clock_jitter_s else None

    def offsets_s(self, info: FileInfo, previous: FileInfo, clock_jitter_s: float) -> list[float]:
        """How far *info*'s stamp lies after where the run's clock puts its next file [s]:
        after the line's time at the run's sample count, once the run drifts; before, after
        the previous file's placed end (the sample count), then (two stamps or more) after
        the line's time, whose drift a short run cannot yet tell from jitter."""
        stamp = info.start_time - pd.Timedelta(seconds=info.clock_shift_s)
        chain = (stamp - previous.end_time).total_seconds() + self.anchor_shift_s
        if self.n < 2:
            return [chain]
        alpha, beta = self.line()
        x = self.samples / self.rate
        line = self._y(info, x) - (alpha + beta * x)
        return [line] if self.drifting(clock_jitter_s) else [chain, line]


class FileOverlapError(ValueError):
    """A file starting more than the clock jitter before its predecessor's end.

    Attributes
    ----------
    info, previous : FileInfo
        The file and the one it overlaps.
    """

    def __init__(self, info: FileInfo, previous: FileInfo, seconds: float) -> None:
        super().__init__(
            f"{info.path}: starts {seconds:g} s before the end of {previous.name} "
            "(overlapping or duplicate files)"
        )
        self.info, self.previous = info, previous


def place_files(
    infos: Sequence[FileInfo], *, clock_jitter_s: float = CLOCK_JITTER_S
) -> tuple[FileInfo, ...]:
    """*infos* (sorted by start time, one sampling rate) placed in time: runs of contiguous
    files on the sample count, a file whose stamp misses the run's clock by at most
    *clock_jitter_s* (either way) re-timed to start at the previous file's end
    (:data:`CLOCK_JITTER_S` says why).

    Within a run the samples are one record: each file starts at its predecessor's placed
    end (also when its stamp misses that by less than half a sample), so the blocks cut
    from it hold the recorder's consecutive samples, on one sample lattice. The stamps are
    judged against the run's clock: the least-squares line of the run's stamps on its
    sample count, the jitter being the stamps' distance from that line. A sample clock
    some ppm off its nominal rate makes its files last slightly less or more than their
    sample count says, so that the sample count (the placed times) walks steadily away
    from the stamps; once that line drifts from the sample count by more than half of
    *clock_jitter_s* over the run, beyond twice its standard error (from the stamps'
    scatter about it), a stamp is judged against the line alone. Before, the run's few
    stamps cannot yet tell a drift from jitter: a stamp within *clock_jitter_s* of the
    sample count (the previous file's placed end) or of the line is contiguous.

    A stamp more than *clock_jitter_s* after the clock is a gap: the file starts a new run.
    After a drifting run, where the run's line puts the stamp on the sample count (the gap
    in the samples the recorder counted, offset / (1 + beta)), so that the runs share one
    time, while the line's time there is uncertain by at most half of *clock_jitter_s*;
    else at its stamp (or, when the run's placed end has walked past that stamp, the gap
    after the placed end). More than *clock_jitter_s* before the clock is an error. Files
    already placed (their start at the previous placed end, or a run's first file placed
    after a gap) come back unchanged; a file's stamp is its start less ``clock_shift_s``.

    Raises
    ------
    FileOverlapError
        A file starting more than *clock_jitter_s* before the end of its predecessor
        (overlapping or duplicate files), naming the file (a :class:`ValueError`).
    """
    placement = FilePlacement(clock_jitter_s=clock_jitter_s)
    for info in infos:
        placement.add(info)
    return tuple(placement.files)


class FilePlacement:
    """:func:`place_files` one file at a time: the files placed so far, the start of their
    last run and its clock. A file placed after them costs the same whatever their number
    (the monitor places each newly landed file so).

    Parameters
    ----------
    clock_jitter_s : float
        As :func:`place_files`'. [s]
    """

    def __init__(self, *, clock_jitter_s: float = CLOCK_JITTER_S) -> None:
        if not (math.isfinite(float(clock_jitter_s)) and clock_jitter_s >= 0):
            raise ValueError(
                f"clock_jitter_s={clock_jitter_s} must be a non-negative number of seconds"
            )
        self.clock_jitter_s = clock_jitter_s
        #: The files placed, in order.
        self.files: list[FileInfo] = []
        #: Index in :attr:`files` of the first file of the last run.
        self.run_start = 0
        self._run: _ClockRun | None = None

    @property
    def last_run_drifting(self) -> bool:
        """Whether the last run's clock drifts from its sample count by more than the
        clock jitter (:attr:`ClockRun.drifting`, as :func:`clock_runs` says it)."""
        return self._run is not None and self._run.walk_s() > self.clock_jitter_s

    def add(self, info: FileInfo) -> FileInfo:
        """*info* (starting no earlier than the last file placed, at its sampling rate)
        placed after the files so far, and kept; the placed header.

        Raises
        ------
        FileOverlapError
            *info* starts more than the clock jitter before the previous file's end; the
            placement is then unchanged.
        """
        placed, run = self._place(info, self._run)
        if run is not self._run:  # a new run (a gap, or the first file)
            self._run = run
            self.run_start = len(self.files)
        self.files.append(placed)
        return placed

    def place(self, info: FileInfo) -> FileInfo:
        """*info* as :meth:`add` would place it, without keeping it.

        Raises
        ------
        FileOverlapError
            As :meth:`add`.
        """
        return self._place(info, copy.copy(self._run))[0]

    def _place(self, info: FileInfo, run: _ClockRun | None) -> tuple[FileInfo, _ClockRun]:
        """*info* placed after the files so far with the last run's clock *run* (updated
        in place when *info* joins it), and the clock of *info*'s run."""
        if not self.files:
            return info, _ClockRun(info, info.sampling_rate_hz)
        clock_jitter_s = self.clock_jitter_s
        previous = self.files[-1]
        if info.start_time == previous.end_time:  # abutting (or placed before): as it is
            run.add(info)
            return info, run
        half_s = 0.5 / run.rate
        if info.clock_shift_s and (info.start_time - previous.end_time).total_seconds() > half_s:
            # placed before as a new run after a gap (a plan's header, some of a voyage's
            # files planned again): where it was placed, which these files' clock alone
            # may not carry over the gap
            return info, _ClockRun(info, run.rate)
        mismatch_s = (info.start_time - previous.end_time).total_seconds()
        offsets_s = run.offsets_s(info, previous, clock_jitter_s)
        offset_s = offsets_s[0]
        if abs(mismatch_s) <= half_s or min(map(abs, offsets_s)) <= clock_jitter_s:
            shift = previous.end_time - info.start_time
            info = dataclasses.replace(
                info,
                start_time=previous.end_time,
                clock_shift_s=info.clock_shift_s + shift.total_seconds(),
            )
            run.add(info)
            return info, run
        if offset_s < 0:
            raise FileOverlapError(info, previous, -offset_s)
        # a gap: a new run, on the record's sample count where the run's clock carries
        # it over the gap, else at the file's stamp unless that is not after the end
        stamp = info.start_time - pd.Timedelta(seconds=info.clock_shift_s)
        start = stamp
        gap_s = run.sample_count_gap_s(offset_s, clock_jitter_s)
        if gap_s is not None:
            # a drifting clock: the blocks after the gap stay on the time of those before
            # it (the samples the recorder counted through the gap), not a walk apart
            start = previous.end_time + pd.Timedelta(seconds=gap_s)
        elif (stamp - previous.end_time).total_seconds() < max(clock_jitter_s, half_s):
            # the run's sample count walked past the stamp: the gap after its end
            start = previous.end_time + pd.Timedelta(seconds=offset_s)
        if start != info.start_time:
            info = dataclasses.replace(
                info, start_time=start, clock_shift_s=(start - stamp).total_seconds()
            )
        if gap_s is None:
            return info, _ClockRun(info, run.rate)
        # the record goes on over the gap on its sample count: its clock too (a new run
        # for the notes), so that a second gap soon after is carried by the whole
        # record's line, not placed at its stamp by the few files between the gaps (a
        # late file filling the second gap would then move the files after it by the
        # clock's walk: 0.6 s after 1.75 h at 100 ppm)
        carried = copy.copy(run)
        carried.samples += gap_s * run.rate
        carried.add(info)
        return info, carried


@dataclass(frozen=True)
class ClockRun:
    """One contiguous run of placed files and its clock (:func:`clock_runs`).

    Parameters
    ----------
    files : tuple of FileInfo
        The run's files, as placed.
    rate_offset : float
        How much faster than nominal its sample clock runs, from the least-squares line of
        the stamps on the sample count (positive: the files last less than their sample
        count says); 0 for a single file. [-]
    jitter_s : float
        Largest distance of a stamp from that line. [s]
    drifting : bool
        Whether the line drifts from the sample count by more than the clock jitter over
        the run, beyond twice its standard error: a drift told apart from jitter, which
        the run's notes say. (Beyond half that, :func:`place_files` already judges the
        stamps against the line alone.)
    """

    files: tuple[FileInfo, ...]
    rate_offset: float
    jitter_s: float
    drifting: bool

    @property
    def largest_shift(self) -> FileInfo:
        """The file placed farthest from its stamp."""
        return max(self.files, key=lambda i: abs(i.clock_shift_s))


def clock_runs(
    infos: Sequence[FileInfo], *, clock_jitter_s: float = CLOCK_JITTER_S
) -> list[ClockRun]:
    """The contiguous runs of placed files *infos* (:func:`place_files`), with their clocks."""
    runs: list[list[FileInfo]] = []
    for info in infos:
        if runs:
            previous = runs[-1][-1]
            if abs((info.start_time - previous.end_time).total_seconds()) <= 0.5 / (
                info.sampling_rate_hz
            ):
                runs[-1].append(info)
                continue
        runs.append([info])
    out = []
    for files in runs:
        clock = _ClockRun(files[0], files[0].sampling_rate_hz)
        residuals = []
        for info in files[1:]:
            clock.add(info)
        alpha, beta = clock.line()
        x = 0.0
        for info in files:
            residuals.append(abs(clock._y(info, x) - (alpha + beta * x)))
            x += info.n_samples / info.sampling_rate_hz
        out.append(
            ClockRun(
                tuple(files),
                -beta / (1 + beta),
                max(residuals),
                clock.walk_s() > clock_jitter_s,
            )
        )
    return out


@dataclass(frozen=True)
class RecordClock:
    """The clock line of one record of placed files (:func:`record_clocks`): a run of
    contiguous files and the runs :func:`place_files` carried over gaps on its sample
    count.

    The line ``stamp - anchor - x = alpha + beta * x`` of the record's stamps on its
    sample count x (nominal seconds after its first file's placed start; the stamps are
    the placed starts less ``clock_shift_s``), as :func:`place_files` fits it. Where it
    drifts (by more than half the clock jitter over the record, beyond twice its standard
    error: the test :func:`place_files` judges the stamps by), a UTC *t* lies at sample
    count ``x = (t - anchor - alpha) / (1 + beta)``; elsewhere the placed times are UTC.

    Parameters
    ----------
    first, stop : int
        The record's files are ``infos[first:stop]``.
    start_ns : int
        Placed start of its first file. [ns since the epoch]
    first_shift_s : float
        That file's ``clock_shift_s`` (its stamp is ``start - first_shift_s``). [s]
    alpha_s, beta : float
        The line's offset [s] and slope (stamp seconds per nominal second, less 1). [-]
    drifting : bool
        Whether the blocks are cut at the UTC of their labels on the line.
    """

    first: int
    stop: int
    start_ns: int
    first_shift_s: float
    alpha_s: float
    beta: float
    drifting: bool

    def placed_ns(self, utc_ns: int) -> float:
        """Placed time (sample count) at which the line puts the UTC *utc_ns*. [ns]"""
        if not self.drifting:
            return float(utc_ns)
        t_s = (utc_ns - self.start_ns) / _NS + self.first_shift_s - self.alpha_s
        return self.start_ns + t_s / (1 + self.beta) * _NS

    def utc_ns(self, placed_ns: int) -> float:
        """UTC the line gives the placed time *placed_ns*. [ns]"""
        if not self.drifting:
            return float(placed_ns)
        x_s = (placed_ns - self.start_ns) / _NS
        return self.start_ns + (self.alpha_s - self.first_shift_s + (1 + self.beta) * x_s) * _NS


def cut_in_file(
    infos: Sequence[FileInfo], starts_ns: np.ndarray, sample_ns: int
) -> tuple[int, int]:
    """Where the placed time *sample_ns* (a block's cut) lies among the placed files
    *infos* (time order; *starts_ns* their placed starts [ns]): the position of the file
    it is counted from (the last starting at or before it, else the first) and the index
    of the sample there, from the file's first (beyond its ends in a gap). The samples
    stay where a later placement of the same files puts them (:func:`cut_placed_ns`)."""
    position = max(int(np.searchsorted(starts_ns, sample_ns, side="right")) - 1, 0)
    rate = infos[position].sampling_rate_hz
    return position, round((sample_ns - int(starts_ns[position])) / _NS * rate)


def cut_placed_ns(info: FileInfo, index: int) -> int:
    """Placed time of sample *index* of the placed file *info* (:func:`cut_in_file`). [ns]"""
    return _ns(info.start_time) + round(index / info.sampling_rate_hz * _NS)


def _line(x: np.ndarray, y: np.ndarray, clock_jitter_s: float) -> tuple[float, float, bool]:
    """alpha, beta and whether the line of *y* on *x* drifts (:meth:`_ClockRun.walk_s`
    beyond half *clock_jitter_s*, the test of :meth:`_ClockRun.drifting`)."""
    n = x.size
    if n < 2:
        return 0.0, 0.0, False
    mean_x, mean_y = x.mean(), y.mean()
    dx, dy = x - mean_x, y - mean_y
    sxx = float(dx @ dx)
    if sxx <= 0:
        return float(mean_y), 0.0, False
    sxy, syy = float(dx @ dy), float(dy @ dy)
    beta = sxy / sxx
    alpha = float(mean_y) - beta * float(mean_x)
    if n < 3:
        return alpha, beta, False
    scatter = math.sqrt(max(syy - beta * sxy, 0.0) / (n - 2))
    walk_s = (abs(beta) - 2 * scatter / math.sqrt(sxx)) * float(x[-1])
    return alpha, beta, walk_s > 0.5 * clock_jitter_s


def record_clocks(
    infos: Sequence[FileInfo],
    starts_ns: np.ndarray | None = None,
    *,
    clock_jitter_s: float = CLOCK_JITTER_S,
) -> list[RecordClock]:
    """The records of the placed files *infos* (:func:`place_files`, time order) and their
    clock lines, from the placed headers alone: a record is a run of contiguous files and
    the runs after gaps that :func:`place_files` carried on its sample count (a run whose
    first stamp lies on the record's line where it is placed). *starts_ns*: their placed
    starts [ns], when at hand."""
    if not infos:
        return []
    if starts_ns is None:
        starts_ns = np.array([_ns(i.start_time) for i in infos], dtype=np.int64)
    shifts = np.array([i.clock_shift_s for i in infos], dtype=float)
    rate = infos[0].sampling_rate_hz
    half_ns = 0.5 / rate * _NS
    ends_ns = starts_ns + np.array([round(i.n_samples / rate * _NS) for i in infos])
    gaps = np.flatnonzero(np.abs(starts_ns[1:] - ends_ns[:-1]) > half_ns) + 1
    bounds = [0]
    for j in gaps.tolist():
        r0 = bounds[-1]
        x = (starts_ns[r0:j] - starts_ns[r0]) / _NS
        y = shifts[r0] - shifts[r0:j]
        alpha, beta, drifting = _line(x, y, clock_jitter_s)
        x_j = (starts_ns[j] - starts_ns[r0]) / _NS
        carried = drifting and abs(shifts[r0] - shifts[j] - (alpha + beta * x_j)) <= 1e-4
        if not carried:
            bounds.append(j)
    bounds.append(len(infos))
    out = []
    for r0, stop in zip(bounds[:-1], bounds[1:], strict=True):
        x = (starts_ns[r0:stop] - starts_ns[r0]) / _NS
        alpha, beta, drifting = _line(x, shifts[r0] - shifts[r0:stop], clock_jitter_s)
        out.append(
            RecordClock(r0, stop, int(starts_ns[r0]), float(shifts[r0]), alpha, beta, drifting)
        )
    return out


def _record_of(
    clocks: Sequence[RecordClock], starts_ns: np.ndarray, utc_ns: int, edge_ns: float
) -> RecordClock:
    """The record whose line cuts the block labelled *utc_ns*: the last one starting
    (its first file's placed start) at most *edge_ns* after where its line puts *utc_ns*,
    else the first."""
    chosen = clocks[0]
    for clock in clocks[1:]:
        if clock.placed_ns(utc_ns) + edge_ns >= starts_ns[clock.first]:
            chosen = clock
        else:
            break
    return chosen


def line_placed_ns(
    clocks: Sequence[RecordClock], starts_ns: np.ndarray, labels_ns: np.ndarray, rate: float
) -> np.ndarray:
    """Placed time at which the clock line of the record cutting each block puts its label
    *labels_ns* (before any rounding to a lattice or cut at the data's edge: a block's cut
    lies within half a lattice sample of it unless cut at the edge; :func:`placed_blocks`)
    [ns]; *clocks* of the placed files starting at *starts_ns* (:func:`record_clocks`)."""
    edge_ns = max(0.5 / rate, CLOCK_JITTER_S) * _NS
    return np.array(
        [_record_of(clocks, starts_ns, int(t), edge_ns).placed_ns(int(t)) for t in labels_ns],
        dtype=float,
    )


def _sample_start_ns(
    clock: RecordClock,
    starts_ns: np.ndarray,
    rate: float,
    utc_ns: int,
    t0_ns: int,
    lattice: int = 1,
) -> int:
    """Placed time of the first sample of a block labelled *utc_ns* on the drifting
    record *clock*: where its line puts that UTC, rounded to the sample lattice of the
    file holding it (half a sample at most: 0.24 ms at 2048 Hz); to every *lattice*-th
    sample from the grid's origin *t0_ns* (the analysis lattice of a decimation by
    *lattice*: half an analysis sample at most, 31 ms at 16 Hz) where the file lies on
    the raw lattice from there. [ns]"""
    placed = clock.placed_ns(utc_ns)
    index = int(np.searchsorted(starts_ns[clock.first : clock.stop], placed, side="right"))
    index = clock.first + max(index - 1, 0)
    m = round((placed - starts_ns[index]) / _NS * rate)
    offset = (int(starts_ns[index]) - t0_ns) / _NS * rate  # the file's first raw sample
    if lattice > 1 and abs(offset - round(offset)) < 1e-3:
        m = lattice * round((round(offset) + (placed - starts_ns[index]) / _NS * rate) / lattice)
        m -= round(offset)
    return int(starts_ns[index]) + round(m / rate * _NS)


def _stretches(starts_ns: np.ndarray, ends_ns: np.ndarray, half_ns: float) -> np.ndarray:
    """Indices of the files starting a stretch of contiguous files (abutting to half a
    sample), and the number of files last."""
    gaps = np.flatnonzero(np.abs(starts_ns[1:] - ends_ns[:-1]) > half_ns) + 1
    return np.concatenate([[0], gaps, [len(starts_ns)]]).astype(np.int64)


def _stretch(bounds: np.ndarray, starts_ns: np.ndarray, time_ns: int) -> tuple[int, int]:
    """The files ``[first, stop)`` of the stretch (:func:`_stretches`' *bounds*) holding
    *time_ns*, or of the file starting last before it (the first file before all)."""
    index = max(int(np.searchsorted(starts_ns, time_ns, side="right")) - 1, 0)
    k = int(np.searchsorted(bounds, index, side="right")) - 1
    return int(bounds[k]), int(bounds[k + 1])


def _inward(time_ns: int, t0_ns: int, rate: float, lattice: int, *, up: bool) -> int:
    """*time_ns* (a record's sample) moved to the next sample of every *lattice*-th from
    *t0_ns* later (*up*) or earlier, where it lies on the raw lattice from there. [ns]"""
    x = (time_ns - t0_ns) / _NS * rate
    if lattice <= 1 or abs(x - round(x)) >= 1e-3:
        return time_ns
    m = round(x)
    m = -(-m // lattice) * lattice if up else (m // lattice) * lattice
    return t0_ns + round(m / rate * _NS)


def edge_cut_note(plan: BlockPlan) -> str:
    """One line on the blocks of *plan* cut at the first or last sample of a drifting
    record or of its data between gaps (:data:`EDGE_SHIFT_S`) and how far their samples lie off the UTC of their labels
    (negative: they begin before it), or "" when none is."""
    infos = plan.files
    clocks = record_clocks(infos)
    if not any(c.drifting for c in clocks):
        return ""
    starts_ns = np.array([_ns(i.start_time) for i in infos], dtype=np.int64)
    rate = plan.sampling_rate_hz
    edge_ns = max(0.5 / rate, CLOCK_JITTER_S) * _NS
    rounding_s = (0.5 * plan.lattice + 0.5) / rate  # the cut's rounding to the lattice
    said = []
    for planned in plan.blocks:
        if not planned.drifting or planned.skipped_reason:
            continue
        clock = _record_of(clocks, starts_ns, _ns(planned.block_start), edge_ns)
        off_s = (_ns(planned.sample_start) - clock.placed_ns(_ns(planned.block_start))) / _NS
        if abs(off_s) > rounding_s + 1e-6:
            said.append(f"block {planned.block} {off_s * (1 + clock.beta):+.2f} s")
    if not said:
        return ""
    return (
        "block(s) cut at the first or last sample of a drifting record (or of its data "
        f"between gaps), which misses their UTC span by at most {EDGE_SHIFT_S:g} s; their "
        f"first sample recorded this long after the UTC of their label: {', '.join(said)}"
    )


def missed_blocks_note(plan: BlockPlan) -> str:
    """One line naming the blocks whose span a drifting record's samples hold on their
    count but not in UTC by more than :data:`EDGE_SHIFT_S` (a fast clock records the
    nominal length of its samples in less UTC: the last block's UTC span may run past its
    last sample), and by how much; "" when there is none. Those blocks are not in *plan*
    (:func:`placed_block_numbers`): without this line they would be missing unsaid."""
    missed = missed_blocks(
        plan.files, plan.grid, plan.sampling_rate_hz, {int(b.block) for b in plan.blocks}
    )
    return missed_blocks_line(missed)


def missed_blocks(
    infos: Sequence[FileInfo],
    grid: BlockGrid,
    sampling_rate_hz: float,
    listed,
    starts_ns: np.ndarray | None = None,
) -> dict[int, str]:
    """The blocks of *grid* whose span the placed files *infos* (time order) hold on
    their samples' count but which a plan of them does not list (*listed*: the blocks it
    lists, :func:`placed_block_numbers`) because a drifting record's first or last sample
    falls inside their UTC span (:func:`missed_blocks_note`): block -> "by 1.08 s at its
    end". *starts_ns*: the files' placed starts [ns], when at hand."""
    if not infos:
        return {}
    clocks = record_clocks(infos, starts_ns)
    if not (clocks[0].drifting or clocks[-1].drifting):
        return {}
    edge = max(pd.Timedelta(seconds=0.5 / sampling_rate_hz), pd.Timedelta(seconds=CLOCK_JITTER_S))
    held = grid.complete_blocks(infos[0].start_time - edge, infos[-1].end_time + edge)
    listed = {int(k) for k in listed}
    first_ns = clocks[0].utc_ns(_ns(infos[0].start_time))
    last_ns = clocks[-1].utc_ns(_ns(infos[-1].end_time))
    missed = {}
    for block in (int(k) for k in held if int(k) not in listed):
        before_s = (first_ns - _ns(grid.start(block))) / _NS
        after_s = (_ns(grid.end(block)) - last_ns) / _NS
        where = "at its end" if after_s >= before_s else "at its start"
        missed[block] = f"by {max(before_s, after_s):.2f} s {where}"
    return missed


def missed_blocks_line(missed: Mapping[int, str]) -> str:
    """The line of :func:`missed_blocks_note` naming *missed* (:func:`missed_blocks`), ""
    when empty."""
    if not missed:
        return ""
    said = ", ".join(f"block {block} {how}" for block, how in sorted(missed.items()))
    return (
        "block(s) not identified, whose span a drifting record's samples hold on their "
        f"count but whose UTC span runs more than {EDGE_SHIFT_S:g} s past the record's first "
        f"or last sample: {said}"
    )


def _span(files: Sequence[FileInfo]) -> str:
    return files[0].name if len(files) == 1 else f"{files[0].name} .. {files[-1].name}"


def clock_jitter_note(infos: Sequence[FileInfo]) -> str:
    """One line on the files of a plan re-timed for clock jitter, or "" when none was:
    how many file starts, the largest shift and its file (runs placed against their clock
    drift are said by :func:`clock_drift_note`)."""
    # a run after a gap may start off its stamp (on the record's sample count, said by
    # clock_drift_note): its files are re-timed by their shift beyond its first file's
    moved = [
        (i.clock_shift_s - run.files[0].clock_shift_s, i)
        for run in clock_runs(infos)
        if not run.drifting
        for i in run.files
        if abs(i.clock_shift_s - run.files[0].clock_shift_s) > 0.5 / i.sampling_rate_hz
    ]
    if not moved:
        return ""
    shift_s, largest = max(moved, key=lambda m: abs(m[0]))
    return (
        f"clock jitter: {len(moved)} file start(s) re-timed to the previous file's end "
        f"(largest {shift_s * 1e3:+.1f} ms, {largest.name}; a stamp within "
        f"{CLOCK_JITTER_S * 1e3:g} ms of that end or of the line of the run's stamps on its "
        "sample count is taken as contiguous)"
    )


def clock_drift_note(infos: Sequence[FileInfo]) -> str:
    """One line on the runs of placed files whose sample clock drifts from their stamps
    (:func:`place_files`), or "" when none does: the runs, their clock rate offset [ppm],
    the stamps' jitter about their lines and how far the blocks' times (the sample count)
    lie from the stamps."""
    drifting = [run for run in clock_runs(infos) if run.drifting]
    if not drifting:
        return ""
    files = [i for run in drifting for i in run.files]
    ppm = [run.rate_offset * 1e6 for run in drifting]
    largest = max((run.largest_shift for run in drifting), key=lambda i: abs(i.clock_shift_s))
    rate = f"{min(ppm):+.1f} to {max(ppm):+.1f}" if len(drifting) > 1 else f"{ppm[0]:+.1f}"
    what = (
        f"{_span(files)} ({len(files)} files in {len(drifting)} records)"
        if len(drifting) > 1
        else f"{_span(files)} ({len(files)} files, one record)"
    )
    return (
        f"clock drift: {what}: the sample clock runs {rate} ppm from "
        f"{files[0].sampling_rate_hz:g} Hz (stamps regressed on the sample count; up to "
        f"{max(run.jitter_s for run in drifting) * 1e3:.1f} ms about that line); the files "
        f"follow the sample count, up to {largest.clock_shift_s * 1e3:+.1f} ms from their "
        f"stamps ({largest.name})"
    )


def _resolve_grid(
    grid: BlockGrid | None, length_s: float | None, step_s: float | None, first_time
) -> BlockGrid:
    if grid is None:
        return BlockGrid.from_first_time(
            first_time,
            DEFAULT_BLOCK_LENGTH_S if length_s is None else length_s,
            DEFAULT_BLOCK_STEP_S if step_s is None else step_s,
        )
    if not isinstance(grid, BlockGrid):
        raise TypeError(f"grid must be a BlockGrid, got {type(grid).__name__}")
    for name, value, own in (
        ("length_s", length_s, grid.length_s),
        ("step_s", step_s, grid.step_s),
    ):
        if value is not None and float(value) != own:
            raise ValueError(f"{name}={value:g} contradicts the grid's {name}={own:g}")
    return grid


def _ns(time: pd.Timestamp) -> int:
    return pd.Timestamp(time).as_unit("ns").value


def _block_files_and_gap(
    infos: Sequence[FileInfo],
    starts_ns: np.ndarray,
    ends_ns: np.ndarray,
    start: int,
    end: int,
    rate: float,
    max_gap_s: float,
    edge_s: float = 0.0,
) -> tuple[list[int], str]:
    """Indices of the files overlapping [start, end) ns, and a skip reason ("" if none).

    A stretch of the block before its first file or after its last of at most *edge_s*
    (the clock jitter, within which the stamps place a record after a gap) is covered
    (NaN-padded), as a gap of at most *max_gap_s* anywhere in the block."""
    half = int(0.5 / rate * _NS)
    first = int(np.searchsorted(ends_ns, start + half, side="right"))
    last = int(np.searchsorted(starts_ns, end - half, side="left"))
    indices = list(range(first, last))
    if not indices:
        before = infos[first - 1].name if first > 0 else "the first file"
        after = infos[first].name if first < len(infos) else "the last file"
        return indices, f"no data (gap between {before} and {after})"
    # uncovered stretches inside the block: before the first file, between files, after;
    # each named by the files on either side (also those just outside the block)
    first_i, last_i = indices[0], indices[-1]
    edges = [(start, starts_ns[first_i], first_i - 1, first_i)]
    edges += [(ends_ns[i], starts_ns[i + 1], i, i + 1) for i in indices[:-1]]
    edges += [(ends_ns[last_i], end, last_i, last_i + 1)]
    for k, (gap_start, gap_end, a, b) in enumerate(edges):
        inside = min(gap_end, end) - max(gap_start, start)
        if inside <= half:
            continue
        inside_s = inside / _NS
        allowed_s = max_gap_s + 0.5 / rate
        if k in (0, len(edges) - 1):  # at the block's start or end
            allowed_s = max(allowed_s, edge_s)
        if inside_s > allowed_s:
            left = infos[a].name if a >= 0 else "the start of the data"
            right = infos[b].name if b < len(infos) else "the end of the data"
            return indices, f"gap of {inside_s:.1f} s between {left} and {right}"
    return indices, ""


def plan_file_infos(
    infos: Sequence[FileInfo],
    grid: BlockGrid | None = None,
    *,
    length_s: float | None = None,
    step_s: float | None = None,
    max_gap_s: float = 0.0,
    channels: Sequence[str] | None = None,
    clock_jitter_s: float = CLOCK_JITTER_S,
    lattice: int = 1,
) -> BlockPlan:
    """:func:`plan_blocks` for files whose headers are already read (:class:`FileInfo`).

    Callers that keep the headers (the identify planner, the monitor re-planning as files
    arrive) plan from them without reading the files again. *channels*: the voyage's
    channels when these files are a few of its files (:func:`reference_channels`).
    The plan's files are placed by :func:`place_files` (re-timed for clock jitter up to
    *clock_jitter_s*). *lattice*: the decimation factor of the analysis, on whose lattice
    a drifting record's blocks are cut (:func:`placed_blocks`). Parameters and errors as
    in :func:`plan_blocks`.
    """
    if not infos:
        raise ValueError("no acceleration files given")
    if not (math.isfinite(float(max_gap_s)) and max_gap_s >= 0):
        raise ValueError(f"max_gap_s={max_gap_s} must be a non-negative number of seconds")
    infos = sorted(infos, key=lambda i: (i.start_time, str(i.path)))
    channels = reference_channels(infos, channels)
    infos = place_files(infos, clock_jitter_s=clock_jitter_s)
    rate = infos[0].sampling_rate_hz
    grid = _resolve_grid(grid, length_s, step_s, infos[0].start_time)
    starts_ns = np.array([_ns(i.start_time) for i in infos], dtype=np.int64)
    ends_ns = np.array([_ns(i.end_time) for i in infos], dtype=np.int64)
    numbers = placed_block_numbers(infos, grid, clock_jitter_s)
    planned = placed_blocks(
        infos,
        starts_ns,
        ends_ns,
        grid,
        numbers,
        max_gap_s=float(max_gap_s),
        clock_jitter_s=clock_jitter_s,
        lattice=lattice,
    )
    return BlockPlan(
        grid, tuple(infos), channels, rate, tuple(planned), float(max_gap_s), lattice=lattice
    )


def placed_block_numbers(
    infos: Sequence[FileInfo], grid: BlockGrid, clock_jitter_s: float = CLOCK_JITTER_S
) -> np.ndarray:
    """The numbers of the blocks of *grid* lying inside the span of the placed files
    *infos* (in time order), or missing at most *clock_jitter_s* of it at the span's start
    or end, ascending, as :func:`plan_file_infos` lists them.

    Raises
    ------
    OptionError
        The span holds more than :data:`~workbench.blocks.MAX_BLOCKS` steps of the grid.
    """
    half = pd.Timedelta(seconds=0.5 / infos[0].sampling_rate_hz)
    span_s = (infos[-1].end_time - infos[0].start_time).total_seconds()
    if span_s / grid.step_s > MAX_BLOCKS:  # counted before any block is listed
        raise OptionError(
            f"step_s={grid.step_s:g} gives about {span_s / grid.step_s:.3g} blocks over the "
            f"files' {span_s / 3600:.3g} h; at most {MAX_BLOCKS} blocks: give a step of at "
            f"least {span_s / MAX_BLOCKS:.3g} s or fewer files"
        )
    # a block the record misses by at most the clock jitter at its start or end is the
    # record's: its placement after a gap is only known to that (its stamp's jitter)
    edge = max(half, pd.Timedelta(seconds=clock_jitter_s))
    first, last = infos[0].start_time, infos[-1].end_time
    clocks = record_clocks(infos, clock_jitter_s=clock_jitter_s)
    before = after = edge
    # the blocks are cut at the UTC of their labels: its span's, less EDGE_SHIFT_S at
    # either end (such a block is cut at the record's first or last sample)
    shift = max(edge, pd.Timedelta(seconds=EDGE_SHIFT_S))
    if clocks[0].drifting:
        first = pd.Timestamp(round(clocks[0].utc_ns(_ns(first))), tz="UTC")
        before = shift
    if clocks[-1].drifting:
        last = pd.Timestamp(round(clocks[-1].utc_ns(_ns(last))), tz="UTC")
        after = shift
    return grid.complete_blocks(first - before, last + after)


def placed_blocks(
    infos: Sequence[FileInfo],
    starts_ns: np.ndarray,
    ends_ns: np.ndarray,
    grid: BlockGrid,
    blocks: Iterable[int],
    *,
    max_gap_s: float = 0.0,
    clock_jitter_s: float = CLOCK_JITTER_S,
    lattice: int = 1,
) -> list[PlannedBlock]:
    """The planned blocks *blocks* of *grid* over files already placed and checked, as
    :func:`plan_file_infos` plans them: each block's files and skip reason depend only on
    the files, so a caller keeping the placed files (the monitor) plans the few blocks it
    still has to decide at a cost that does not grow with the files' number.

    Parameters
    ----------
    infos : sequence of FileInfo
        The files as :func:`place_files` places them (in time order, one sampling rate).
    starts_ns, ends_ns : ndarray of int64
        Their start and end times. [ns since the epoch]
    grid : BlockGrid
    blocks : iterable of int
        Block numbers among :func:`placed_block_numbers`, ascending.
    max_gap_s, clock_jitter_s : float
        As :func:`plan_file_infos`'. [s]
    lattice : int
        A drifting record's blocks are cut on every *lattice*-th raw sample from the
        grid's origin: the decimation factor of the analysis (the file conditioner cuts its
        decimated files there); 1: on the raw samples. Other records' blocks are cut at
        their labels whatever it is.
    """
    rate = infos[0].sampling_rate_hz
    clocks = record_clocks(infos, starts_ns, clock_jitter_s=clock_jitter_s)
    drifting = any(clock.drifting for clock in clocks)
    edge_ns = max(0.5 / rate, clock_jitter_s) * _NS
    shift_ns = max(edge_ns, EDGE_SHIFT_S * _NS)
    bounds = _stretches(starts_ns, ends_ns, 0.5 / rate * _NS)
    t0_ns = _ns(grid.t0)

    def files_and_gap(start_ns: int, end_ns: int) -> tuple[list[int], str]:
        return _block_files_and_gap(
            infos,
            starts_ns,
            ends_ns,
            start_ns,
            end_ns,
            rate,
            float(max_gap_s),
            float(clock_jitter_s),
        )

    def cut(clock: RecordClock, start_ns: int, length_ns: int, on: int) -> int:
        """The block's samples: the grid's length of them from where the record's clock
        line puts the UTC of its label (on every *on*-th sample)."""
        sample_ns = _sample_start_ns(clock, starts_ns, rate, start_ns, t0_ns, on)
        # a span the data (the record, or a stretch of it between gaps) misses by at most
        # EDGE_SHIFT_S is its first or last samples (on the lattice inside), not lost
        first, stop = _stretch(bounds, starts_ns, sample_ns + length_ns // 2)
        first_ns, last_ns = int(starts_ns[first]), int(ends_ns[stop - 1])
        if last_ns - first_ns < length_ns:
            return sample_ns
        if first_ns - shift_ns <= sample_ns < first_ns:
            return _inward(first_ns, t0_ns, rate, on, up=True)
        if last_ns < sample_ns + length_ns <= last_ns + shift_ns:
            return _inward(last_ns - length_ns, t0_ns, rate, on, up=False)
        return sample_ns

    planned = []
    for k in blocks:
        start, end = grid.start(int(k)), grid.end(int(k))
        start_ns, end_ns = _ns(start), _ns(end)
        sample_start = start
        on_line = False
        clock = _record_of(clocks, starts_ns, start_ns, edge_ns) if drifting else None
        if clock is not None and clock.drifting:
            on_line = True
            length_ns = end_ns - start_ns
            sample_ns = cut(clock, start_ns, length_ns, int(lattice))
            indices, reason = files_and_gap(sample_ns, sample_ns + length_ns)
            if reason and lattice > 1:
                # the analysis lattice (half an analysis sample off the line) moved the
                # span across a record's edge or a gap that the nearest sample keeps
                # inside (the file conditioner then leaves the block to load_block)
                raw_ns = cut(clock, start_ns, length_ns, 1)
                raw = files_and_gap(raw_ns, raw_ns + length_ns)
                if not raw[1]:
                    sample_ns, (indices, reason) = raw_ns, raw
            sample_start = pd.Timestamp(sample_ns, tz="UTC")
        else:
            indices, reason = files_and_gap(start_ns, end_ns)
        planned.append(
            PlannedBlock(
                int(k),
                start,
                end,
                tuple(infos[i].path for i in indices),
                reason,
                sample_start,
                on_line,
            )
        )
    return planned


def plan_blocks(
    files: Iterable[str | os.PathLike],
    grid: BlockGrid | None = None,
    *,
    length_s: float | None = None,
    step_s: float | None = None,
    max_gap_s: float = 0.0,
    read_options: Mapping | None = None,
    clock_jitter_s: float = CLOCK_JITTER_S,
) -> BlockPlan:
    """List the blocks a set of acceleration files gives, reading only their headers.

    Parameters
    ----------
    files : iterable of path-like or FileInfo
        Acceleration files in any order (any format :func:`data_contracts.read_accelerations`
        reads), or their headers already read; they are sorted by start time.
    grid : BlockGrid, optional
        Block grid; default: anchored at the first file's start floored to the step.
    length_s, step_s : float, optional
        Block length and step when *grid* is not given (default 1200 s and 300 s). [s]
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded; blocks over
        longer gaps are listed as skipped. [s]
    read_options : mapping, optional
        Keyword arguments for :func:`data_contracts.read_accelerations`.
    clock_jitter_s : float
        A file starting at most this far before or after its predecessor's end is re-timed
        to that end (:func:`place_files`, :data:`CLOCK_JITTER_S`). [s]

    Returns
    -------
    BlockPlan
        Every block of the grid lying entirely inside the span of the files, or missing
        at most *clock_jitter_s* of it at the span's start or end (those samples
        NaN-padded: the stamps place a record only to the jitter).

    Raises
    ------
    ValueError
        No files; files differing in sampling rate or lacking more than half of the
        channels (:func:`reference_channels`); files overlapping by more than
        *clock_jitter_s*. The message names the file.
    """
    infos = [
        f if isinstance(f, FileInfo) else read_file_info(f, read_options=read_options)
        for f in files
    ]
    return plan_file_infos(
        infos,
        grid,
        length_s=length_s,
        step_s=step_s,
        max_gap_s=max_gap_s,
        clock_jitter_s=clock_jitter_s,
    )
