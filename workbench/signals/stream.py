"""Blocks of accelerations from consecutive acquisition files, streamed.

An acquisition system writes one file per interval (typically 5 minutes). Identification
works on blocks of the shared grid (:class:`~workbench.blocks.BlockGrid`; default 20 min
every 5 min). This module cuts the files into blocks without loading a voyage:

* :func:`plan_blocks` reads only the file headers (for ``.npz`` files: start time, rate,
  channel names and the array shape from the archive; ``.mat`` and ``.csv`` files are read
  whole once) and lists every block the files give, with the files each needs and, for
  blocks that cannot be built, the reason. The orchestrator plans parallel tasks with it.
* :func:`iter_blocks` streams the blocks in order, holding only the files of the current
  block in memory (a deque of at most ``ceil(length / file duration) + 1`` records).
* :func:`load_block` builds one block from just its files (for parallel workers).

Each block is conditioned in this order: faulty channels are found on the raw samples
(:func:`~workbench.signals.moments.faulty_channels`) and dropped for this block; NaN runs
in the kept channels (all shorter than ``max_nan_run_s``, else the channel was faulty)
are bridged linearly; then optional linear detrend, decimation and band-pass.

Gaps between files
------------------
Consecutive files normally abut (the next file starts one sample interval after the last
sample of the previous one; offsets below half a sample are ignored). A block that
overlaps a gap is **skipped** with the reason (``"gap of 42.0 s between acc_a.npz and
acc_b.npz"``), unless the gap's part inside the block is at most ``max_gap_s``: then the
gap is filled with NaN, which the NaN policy bridges by interpolation -- so ``max_gap_s``
should not exceed the faulty-channel ``max_nan_run_s`` (default 10 s), or every channel of
the block would be dropped. Files that overlap in time, differ in channel set or in
sampling rate are errors (:class:`ValueError` naming the file). Channels in a different
order are reordered to the first file's order.

Skipped blocks are not left out silently: :func:`iter_blocks` yields them as
:class:`AccelerationBlock` with ``acceleration=None`` and ``skipped_reason`` set.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import deque
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import AccelerationRecord, read_accelerations
from data_contracts.npz import read_sample_header

from ..blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S, BlockGrid, utc_timestamp
from .conditioning import MAX_INTERPOLATED_NAN_RUN_S, bandpass, decimate, interpolate_nan_runs
from .conditioning import detrend as linear_detrend
from .moments import _channel_groups, faulty_channels

__all__ = [
    "AccelerationBlock",
    "BlockPlan",
    "FileInfo",
    "PlannedBlock",
    "iter_blocks",
    "load_block",
    "plan_blocks",
    "read_file_info",
]

_NS = 1_000_000_000


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
    """

    path: Path
    start_time: pd.Timestamp
    sampling_rate_hz: float
    n_samples: int
    channels: tuple[str, ...]

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def end_time(self) -> pd.Timestamp:
        """Time just after the last sample. [UTC]"""
        return self.start_time + pd.Timedelta(seconds=self.n_samples / self.sampling_rate_hz)


def _npz_info(path: Path) -> FileInfo:
    header = read_sample_header(path)
    shape = header.shape
    # The samples the header claims must be in the archive (a 1-KB file claiming 30 days
    # would plan thousands of blocks): stored bytes lie within the file, and deflate
    # compresses by at most about 1032:1.
    if (
        header.member_size < header.claimed_bytes
        or header.compressed_size > path.stat().st_size
        or header.member_size > 1100 * max(header.compressed_size, 1)
    ):
        raise ValueError("the array header claims more samples than the file holds")
    with np.load(path, allow_pickle=False) as data:
        rate = float(np.asarray(data["sampling_rate_hz"]).reshape(-1)[0])
        start = str(np.asarray(data["start_time"]).reshape(-1)[0])
        channels = tuple(str(c) for c in np.asarray(data["channels"]).ravel())
    if len(shape) != 2 or shape[1] != len(channels) or not (math.isfinite(rate) and rate > 0):
        raise ValueError("inconsistent header")
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
    """

    block: int
    block_start: pd.Timestamp
    block_end: pd.Timestamp
    files: tuple[Path, ...]
    skipped_reason: str = ""


@dataclass(frozen=True, eq=False)
class BlockPlan:
    """The blocks a set of acceleration files gives.

    Parameters
    ----------
    grid : BlockGrid
    files : tuple of FileInfo
        The files, sorted by start time.
    channels : tuple of str
        Channel names (order of the first file).
    sampling_rate_hz : float
        [Hz]
    blocks : tuple of PlannedBlock
        Every block lying inside the span of the files, ascending; blocks overlapping a gap
        carry a ``skipped_reason``.
    max_gap_s : float
        Gaps up to this length inside a block are NaN-padded. [s]
    """

    grid: BlockGrid
    files: tuple[FileInfo, ...]
    channels: tuple[str, ...]
    sampling_rate_hz: float
    blocks: tuple[PlannedBlock, ...]
    max_gap_s: float = 0.0

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


def _check_consistent(infos: Sequence[FileInfo]) -> None:
    first = infos[0]
    for info in infos[1:]:
        if info.sampling_rate_hz != first.sampling_rate_hz:
            raise ValueError(
                f"{info.path}: sampling rate {info.sampling_rate_hz:g} Hz differs from "
                f"{first.sampling_rate_hz:g} Hz of {first.name}"
            )
        if set(info.channels) != set(first.channels) or len(info.channels) != len(first.channels):
            missing = [c for c in first.channels if c not in info.channels]
            extra = [c for c in info.channels if c not in first.channels]
            parts = []
            if missing:
                parts.append(f"missing {', '.join(missing)}")
            if extra:
                parts.append(f"extra {', '.join(extra)}")
            raise ValueError(
                f"{info.path}: channels differ from those of {first.name} ({'; '.join(parts)})"
            )
    rate = first.sampling_rate_hz
    for previous, info in zip(infos[:-1], infos[1:], strict=True):
        overlap_s = (previous.end_time - info.start_time).total_seconds()
        if overlap_s > 0.5 / rate:
            raise ValueError(
                f"{info.path}: starts {overlap_s:g} s before the end of {previous.name} "
                "(overlapping or duplicate files)"
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
) -> tuple[list[int], str]:
    """Indices of the files overlapping [start, end) ns, and a skip reason ("" if none)."""
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
    for gap_start, gap_end, a, b in edges:
        inside = min(gap_end, end) - max(gap_start, start)
        if inside <= half:
            continue
        inside_s = inside / _NS
        if inside_s > max_gap_s + 0.5 / rate:
            left = infos[a].name if a >= 0 else "the start of the data"
            right = infos[b].name if b < len(infos) else "the end of the data"
            return indices, f"gap of {inside_s:.1f} s between {left} and {right}"
    return indices, ""


def _plan(
    infos: Sequence[FileInfo],
    grid: BlockGrid | None,
    length_s: float | None,
    step_s: float | None,
    max_gap_s: float,
) -> BlockPlan:
    if not infos:
        raise ValueError("no acceleration files given")
    if not (math.isfinite(float(max_gap_s)) and max_gap_s >= 0):
        raise ValueError(f"max_gap_s={max_gap_s} must be a non-negative number of seconds")
    infos = sorted(infos, key=lambda i: (i.start_time, str(i.path)))
    _check_consistent(infos)
    rate = infos[0].sampling_rate_hz
    grid = _resolve_grid(grid, length_s, step_s, infos[0].start_time)
    starts_ns = np.array([_ns(i.start_time) for i in infos], dtype=np.int64)
    ends_ns = np.array([_ns(i.end_time) for i in infos], dtype=np.int64)
    half = pd.Timedelta(seconds=0.5 / rate)
    numbers = grid.complete_blocks(infos[0].start_time - half, infos[-1].end_time + half)
    planned = []
    for k in numbers:
        start, end = grid.start(int(k)), grid.end(int(k))
        indices, reason = _block_files_and_gap(
            infos, starts_ns, ends_ns, _ns(start), _ns(end), rate, float(max_gap_s)
        )
        planned.append(
            PlannedBlock(int(k), start, end, tuple(infos[i].path for i in indices), reason)
        )
    return BlockPlan(grid, tuple(infos), infos[0].channels, rate, tuple(planned), float(max_gap_s))


def plan_blocks(
    files: Iterable[str | os.PathLike],
    grid: BlockGrid | None = None,
    *,
    length_s: float | None = None,
    step_s: float | None = None,
    max_gap_s: float = 0.0,
    read_options: Mapping | None = None,
) -> BlockPlan:
    """List the blocks a set of acceleration files gives, reading only their headers.

    Parameters
    ----------
    files : iterable of path-like
        Acceleration files in any order (any format :func:`data_contracts.read_accelerations`
        reads); they are sorted by start time.
    grid : BlockGrid, optional
        Block grid; default: anchored at the first file's start floored to the step.
    length_s, step_s : float, optional
        Block length and step when *grid* is not given (default 1200 s and 300 s). [s]
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded; blocks over
        longer gaps are listed as skipped. [s]
    read_options : mapping, optional
        Keyword arguments for :func:`data_contracts.read_accelerations`.

    Returns
    -------
    BlockPlan
        Every block of the grid lying entirely inside the span of the files.

    Raises
    ------
    ValueError
        No files; files differing in channel set or sampling rate; overlapping files. The
        message names the file.
    """
    infos = [read_file_info(f, read_options=read_options) for f in files]
    return _plan(infos, grid, length_s, step_s, max_gap_s)


# ----------------------------------------------------------------------------------------
# blocks
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class AccelerationBlock:
    """One conditioned block of accelerations, or a skipped block and why.

    Parameters
    ----------
    block : int
        Block number on the grid.
    block_start, block_end : pandas.Timestamp
        Span of the block. [UTC]
    acceleration : ndarray, shape (n_samples, n_channels) or None
        Conditioned accelerations of the kept channels [m/s²]; None for a skipped block.
    sampling_rate_hz : float
        Rate of *acceleration* (after decimation). [Hz]
    channels : tuple of str
        Names of the kept channels, one per column.
    dropped : tuple of (str, str)
        Channels dropped for this block and the reason, e.g. ``("acc12", "nan run 300.0 s")``.
    files : tuple of str
        Names of the files the block was cut from.
    skipped_reason : str
        Empty for a built block; else why it was skipped (gap, all channels faulty, ...).
    notes : tuple of str
        Things worth recording (dropped channels, NaN-padded gaps).
    channel_report : DataFrame or None
        The per-channel checks of :func:`~workbench.signals.moments.faulty_channels`.
    """

    block: int
    block_start: pd.Timestamp
    block_end: pd.Timestamp
    acceleration: np.ndarray | None
    sampling_rate_hz: float
    channels: tuple[str, ...]
    dropped: tuple[tuple[str, str], ...] = ()
    files: tuple[str, ...] = ()
    skipped_reason: str = ""
    notes: tuple[str, ...] = ()
    channel_report: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def skipped(self) -> bool:
        """True when the block could not be built (see *skipped_reason*)."""
        return self.acceleration is None


@dataclass(frozen=True)
class _Conditioning:
    target_rate_hz: float | None
    band_hz: tuple[float | None, float | None] | None
    detrend: bool
    fault_options: Mapping
    read_options: Mapping

    @classmethod
    def make(cls, target_rate_hz, band_hz, detrend, fault_options, read_options) -> _Conditioning:
        options = dict(fault_options or {})
        # fail early on a mistyped option, not in the middle of a voyage
        faulty_channels(np.zeros((4, 1)) + np.arange(4)[:, None], 1.0, **options)
        if band_hz is not None:
            band = tuple(band_hz)
            if len(band) != 2:
                raise ValueError(f"band_hz={band_hz!r} must be (low_hz, high_hz)")
        else:
            band = None
        return cls(target_rate_hz, band, bool(detrend), options, dict(read_options or {}))

    @property
    def max_nan_run_s(self) -> float:
        return float(self.fault_options.get("max_nan_run_s", MAX_INTERPOLATED_NAN_RUN_S))

    def check_rate(self, rate: float) -> None:
        """Raise now (not at the first block) if decimation or band-pass cannot work."""
        out_rate = rate
        if self.target_rate_hz is not None:
            ratio = rate / float(self.target_rate_hz)
            if not (ratio >= 1 and abs(ratio - round(ratio)) <= 1e-9 * ratio):
                raise ValueError(
                    f"target_rate_hz={self.target_rate_hz:g} must divide the files' sampling "
                    f"rate {rate:g} Hz by a whole number"
                )
            out_rate = float(self.target_rate_hz)
        if self.band_hz is not None:
            bandpass(np.zeros((256, 1)), out_rate, *self.band_hz)


def _load(info: FileInfo, channels: tuple[str, ...], read_options: Mapping) -> AccelerationRecord:
    record = read_accelerations(info.path, **dict(read_options))
    if record.sampling_rate_hz != info.sampling_rate_hz or record.n_samples != info.n_samples:
        raise ValueError(f"{info.path}: file changed since it was planned")
    if record.channels != channels:
        order = [record.channels.index(c) for c in channels]
        record = AccelerationRecord(
            record.acceleration[:, order], record.sampling_rate_hz, record.start_time, channels
        )
    return record


def _assemble(
    records: Sequence[AccelerationRecord], start: pd.Timestamp, length_s: float, rate: float
) -> tuple[np.ndarray, list[str]]:
    """Samples of [start, start + length) from *records* on the first record's sample lattice;
    uncovered samples are NaN (gaps allowed by the plan). Returns the array and notes."""
    n_block = int(round(length_s * rate))
    n_channels = records[0].acceleration.shape[1]
    out = np.full((n_block, n_channels), np.nan)
    reference = records[0].start_time
    # first lattice sample at or after the block start
    b0 = math.ceil((start - reference).total_seconds() * rate - 1e-6)
    filled = np.zeros(n_block, dtype=bool)
    for record in records:
        offset = int(round((record.start_time - reference).total_seconds() * rate))
        lo = max(offset, b0)
        hi = min(offset + record.n_samples, b0 + n_block)
        if hi > lo:
            out[lo - b0 : hi - b0] = record.acceleration[lo - offset : hi - offset]
            filled[lo - b0 : hi - b0] = True
    notes = []
    if not filled.all():
        notes.append(f"gap of {np.count_nonzero(~filled) / rate:.1f} s NaN-padded")
    return out, notes


def _condition(
    raw: np.ndarray,
    rate: float,
    channels: tuple[str, ...],
    options: _Conditioning,
    planned: PlannedBlock,
    notes: list[str],
) -> AccelerationBlock:
    report = faulty_channels(raw, rate, channels, **options.fault_options)
    faulty = report["faulty"].to_numpy()
    dropped = tuple(
        (str(c), str(r))
        for c, r in zip(report["channel"][faulty], report["reason"][faulty], strict=True)
    )
    notes = notes + [f"{c} dropped: {r}" for c, r in dropped]
    names = tuple(c for c, bad in zip(channels, faulty, strict=True) if not bad)
    files = tuple(Path(f).name for f in planned.files)
    if not names:
        return AccelerationBlock(
            planned.block,
            planned.block_start,
            planned.block_end,
            None,
            rate,
            (),
            dropped,
            files,
            "all channels faulty",
            tuple(notes),
            report,
        )
    kept = np.flatnonzero(~faulty)
    decimating = options.target_rate_hz is not None and float(options.target_rate_hz) != rate
    out_rate = float(options.target_rate_hz) if decimating else rate
    parts = []
    # channel by channel group: the temporaries of a 2048-Hz block stay small
    for group in _channel_groups(raw.shape[0], len(kept)):
        x = interpolate_nan_runs(raw[:, kept[group]], rate, max_run_s=options.max_nan_run_s)
        if options.detrend:
            x = linear_detrend(x)
        if decimating:
            x = decimate(x, rate, out_rate, max_nan_run_s=options.max_nan_run_s)
        if options.band_hz is not None:
            x = bandpass(x, out_rate, *options.band_hz, max_nan_run_s=options.max_nan_run_s)
        parts.append(x)
    x = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
    return AccelerationBlock(
        planned.block,
        planned.block_start,
        planned.block_end,
        x,
        out_rate,
        names,
        dropped,
        files,
        "",
        tuple(notes),
        report,
    )


def _skipped(planned: PlannedBlock, rate: float, reason: str) -> AccelerationBlock:
    return AccelerationBlock(
        planned.block,
        planned.block_start,
        planned.block_end,
        None,
        rate,
        (),
        files=tuple(Path(f).name for f in planned.files),
        skipped_reason=reason,
        notes=(f"skipped: {reason}",),
    )


def _build(
    plan: BlockPlan,
    planned: PlannedBlock,
    records: Sequence[AccelerationRecord],
    options: _Conditioning,
) -> AccelerationBlock:
    raw, notes = _assemble(records, planned.block_start, plan.grid.length_s, plan.sampling_rate_hz)
    return _condition(raw, plan.sampling_rate_hz, plan.channels, options, planned, notes)


def iter_blocks(
    files: Iterable[str | os.PathLike],
    *,
    grid: BlockGrid | None = None,
    length_s: float | None = None,
    step_s: float | None = None,
    target_rate_hz: float | None = None,
    band_hz: tuple[float | None, float | None] | None = None,
    detrend: bool = True,
    fault_options: Mapping | None = None,
    blocks: Iterable[int] | None = None,
    max_gap_s: float = 0.0,
    read_options: Mapping | None = None,
) -> Iterator[AccelerationBlock]:
    """Stream conditioned blocks of accelerations from consecutive files.

    Parameters
    ----------
    files : iterable of path-like
        Acceleration files (any order, any format ``read_accelerations`` reads).
    grid : BlockGrid, optional
        Block grid; default: anchored at the first file's start floored to the step, with
        *length_s* / *step_s* (default 1200 s / 300 s).
    length_s, step_s : float, optional
        Block length and step when *grid* is not given. [s]
    target_rate_hz : float, optional
        Decimate to this rate (:func:`~workbench.signals.conditioning.decimate`). [Hz]
    band_hz : (float or None, float or None), optional
        Band-pass edges after decimation (:func:`~workbench.signals.conditioning.bandpass`).
        [Hz]
    detrend : bool
        Remove a straight line from each channel of each block.
    fault_options : mapping, optional
        Keyword arguments for :func:`~workbench.signals.moments.faulty_channels`;
        ``max_nan_run_s`` also sets the longest NaN run that is interpolated.
    blocks : iterable of int, optional
        Build only these blocks (e.g. those not yet done when resuming); files not needed by
        them are never read. Requested blocks outside the files' span are yielded as
        skipped.
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded (see the module
        notes); blocks overlapping longer gaps are skipped. [s]
    read_options : mapping, optional
        Keyword arguments for :func:`data_contracts.read_accelerations`.

    Yields
    ------
    AccelerationBlock
        In ascending block order; skipped blocks have ``acceleration=None`` and a
        ``skipped_reason``.

    Raises
    ------
    ValueError
        Before the first block: files inconsistent in channels or sampling rate, or
        overlapping; an unknown fault option raises TypeError.

    Notes
    -----
    Memory: the loaded files sit in a deque; files ending before the current block starts
    are released before new ones are read, so at most ``ceil(length / file duration) + 1``
    files are held (5 for 20-min blocks of 5-min files) plus the block being built.
    """
    options = _Conditioning.make(target_rate_hz, band_hz, detrend, fault_options, read_options)
    plan = plan_blocks(
        files,
        grid,
        length_s=length_s,
        step_s=step_s,
        max_gap_s=max_gap_s,
        read_options=read_options,
    )
    options.check_rate(plan.sampling_rate_hz)
    return _stream(plan, options, blocks)


def _stream(
    plan: BlockPlan, options: _Conditioning, blocks: Iterable[int] | None
) -> Iterator[AccelerationBlock]:
    index = {info.path: i for i, info in enumerate(plan.files)}
    by_number = {b.block: b for b in plan.blocks}
    if blocks is None:
        wanted = [b.block for b in plan.blocks]
    else:
        wanted = sorted({int(k) for k in blocks})
    cache: deque[tuple[int, AccelerationRecord]] = deque()
    rate = plan.sampling_rate_hz
    for k in wanted:
        planned = by_number.get(k)
        if planned is None:
            outside = PlannedBlock(k, plan.grid.start(k), plan.grid.end(k), ())
            yield _skipped(outside, rate, "outside the span of the acceleration files")
            continue
        if planned.skipped_reason:
            yield _skipped(planned, rate, planned.skipped_reason)
            continue
        needed = [index[p] for p in planned.files]
        while cache and cache[0][0] < needed[0]:
            cache.popleft()
        if cache and cache[-1][0] > needed[-1]:  # cannot happen for ascending blocks
            cache.clear()
        loaded = {i for i, _ in cache}
        for i in needed:
            if i not in loaded:
                cache.append((i, _load(plan.files[i], plan.channels, options.read_options)))
        records = [r for i, r in cache if needed[0] <= i <= needed[-1]]
        yield _build(plan, planned, records, options)
        del records


def load_block(
    files: Iterable[str | os.PathLike | FileInfo],
    block: int,
    grid: BlockGrid,
    *,
    target_rate_hz: float | None = None,
    band_hz: tuple[float | None, float | None] | None = None,
    detrend: bool = True,
    fault_options: Mapping | None = None,
    max_gap_s: float = 0.0,
    read_options: Mapping | None = None,
) -> AccelerationBlock:
    """Build one block from its files, e.g. in a parallel worker.

    Parameters
    ----------
    files : iterable of path-like or FileInfo
        The block's files (``PlannedBlock.files``) or any superset; only files overlapping
        the block are read.
    block : int
        Block number on *grid*.
    grid : BlockGrid
        The voyage's grid (``BlockPlan.grid``).
    target_rate_hz, band_hz, detrend, fault_options, max_gap_s, read_options
        As for :func:`iter_blocks`.

    Returns
    -------
    AccelerationBlock
        Identical to the one :func:`iter_blocks` yields for this block; skipped (with the
        reason) when the files do not cover it.
    """
    options = _Conditioning.make(target_rate_hz, band_hz, detrend, fault_options, read_options)
    infos = [
        f if isinstance(f, FileInfo) else read_file_info(f, read_options=read_options)
        for f in files
    ]
    k = int(block)
    start, end = grid.start(k), grid.end(k)
    if not infos:
        return _skipped(PlannedBlock(k, start, end, ()), float("nan"), "no acceleration files")
    # plan only the files touching the block (consistency checks included)
    touching = [i for i in infos if i.start_time < end and i.end_time > start]
    if not touching:
        return _skipped(
            PlannedBlock(k, start, end, ()),
            infos[0].sampling_rate_hz,
            "outside the span of the acceleration files",
        )
    plan = _plan(touching, grid, None, None, max_gap_s)
    if all(b.block != k for b in plan.blocks):
        # The block reaches past the touching files into an allowed gap (the next file
        # starts after the block's end): plan it on its own, as the full plan does.
        starts_ns = np.array([_ns(i.start_time) for i in plan.files], dtype=np.int64)
        ends_ns = np.array([_ns(i.end_time) for i in plan.files], dtype=np.int64)
        indices, reason = _block_files_and_gap(
            plan.files,
            starts_ns,
            ends_ns,
            _ns(start),
            _ns(end),
            plan.sampling_rate_hz,
            float(max_gap_s),
        )
        single = PlannedBlock(k, start, end, tuple(plan.files[i].path for i in indices), reason)
        plan = dataclasses.replace(plan, blocks=(single,))
    options.check_rate(plan.sampling_rate_hz)
    return next(_stream(plan, options, [k]))
