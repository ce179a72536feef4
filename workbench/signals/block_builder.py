"""Conditioned blocks of accelerations cut from consecutive acquisition files, streamed.

The files are planned into blocks by :func:`~workbench.signals.block_plan.plan_blocks`
(headers only); this module builds the blocks without loading a voyage:

* :func:`iter_blocks` streams the blocks in order, holding only the files of the current
  block in memory (a deque of at most ``ceil(length / file duration) + 1`` records).
* :func:`load_block` builds one block from just its files (for parallel workers).

Each block is conditioned in this order: faulty channels are found on the raw samples
(:func:`~workbench.signals.moments.faulty_channels`) and dropped for this block; NaN runs
in the kept channels (all shorter than ``max_nan_run_s``, else the channel was faulty)
are bridged linearly; then optional linear detrend, decimation and band-pass.


Blocks overlapping a gap between files are skipped or NaN-padded as described in
:mod:`workbench.signals.block_plan`. Skipped blocks are not left out silently:
:func:`iter_blocks` yields them as :class:`AccelerationBlock` with ``acceleration=None``
and ``skipped_reason`` set.
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

from ..blocks import BlockGrid
from ..errors import UnreadableInputError
from .block_plan import (
    CLOCK_JITTER_S,
    BlockPlan,
    FileInfo,
    PlannedBlock,
    _block_files_and_gap,
    _ns,
    align_channels,
    plan_blocks,
    plan_file_infos,
    read_file_info,
)
from .conditioning import bandpass, decimate, interpolate_nan_runs
from .conditioning import detrend as linear_detrend
from .moments import ChannelCheckOptions, _channel_groups, faulty_channels

__all__ = ["AccelerationBlock", "ConditioningOptions", "iter_blocks", "load_block"]


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
class ConditioningOptions:
    """How raw accelerations become a conditioned block (:func:`iter_blocks`,
    :func:`load_block`, :class:`~workbench.signals.file_conditioning.FileConditioner`).

    Attributes
    ----------
    target_rate_hz : float, optional
        Decimate to this rate (:func:`~workbench.signals.conditioning.decimate`); the
        file conditioner needs one that divides the files' rate by a whole number > 1. [Hz]
    band_hz : (float or None, float or None), optional
        Band-pass edges after decimation (:func:`~workbench.signals.conditioning.bandpass`).
        [Hz]
    detrend : bool
        Remove a straight line from each channel of each block (the file conditioner:
        without a lower band edge, the band-pass having removed it otherwise).
    channel_check : ChannelCheckOptions
        Thresholds of :func:`~workbench.signals.moments.faulty_channels`; its
        ``max_nan_run_s`` also sets the longest NaN run that is interpolated.
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded (see the module
        notes); blocks overlapping longer gaps are skipped. [s]
    read_options : mapping
        Keyword arguments for :func:`data_contracts.read_accelerations` (file layout).
    """

    target_rate_hz: float | None = None
    band_hz: tuple[float | None, float | None] | None = None
    detrend: bool = True
    channel_check: ChannelCheckOptions = field(default_factory=ChannelCheckOptions)
    max_gap_s: float = 0.0
    read_options: Mapping = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.band_hz is not None:
            band = tuple(self.band_hz)
            if len(band) != 2:
                raise ValueError(f"band_hz={self.band_hz!r} must be (low_hz, high_hz)")
            object.__setattr__(self, "band_hz", band)
        object.__setattr__(self, "detrend", bool(self.detrend))
        object.__setattr__(self, "read_options", dict(self.read_options or {}))

    @property
    def max_nan_run_s(self) -> float:
        return float(self.channel_check.max_nan_run_s)

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
    """The samples of the planned file *info*, channels in *channels* order, starting at
    the planned ``info.start_time`` (the file's stamp re-timed for clock jitter, if it was).

    Raises
    ------
    UnreadableInputError
        The file's samples cannot be read (cut short, a bad checksum, ...).
    ValueError
        The file is no longer what was planned.
    """
    try:
        record = read_accelerations(info.path, **dict(read_options))
    except (OSError, ValueError) as error:
        raise UnreadableInputError.of(info.path, error) from None
    if record.sampling_rate_hz != info.sampling_rate_hz or record.n_samples != info.n_samples:
        raise ValueError(f"{info.path}: file changed since it was planned")
    # placed where the plan put it (re-timed for clock jitter: FileInfo.clock_shift_s), as
    # the file conditioner places it, not at its own stamp
    values = align_channels(record.acceleration, record.channels, channels)
    return AccelerationRecord(
        values, record.sampling_rate_hz, info.start_time, channels, record.blanked
    )


def blanked_notes(path, blanked: Sequence[tuple[str, str]]) -> tuple[str, ...]:
    """The notes of a block holding the file *path* whose reader set the channels of
    *blanked* (``AccelerationRecord.blanked``) to NaN."""
    return tuple(
        f"{Path(path).name}: channel {channel} blanked ({why}){BLANKED_NOTE_END}"
        for channel, why in blanked
    )


#: How a note of :func:`blanked_notes` ends (the run's summary picks them out by it).
BLANKED_NOTE_END = ", dropped for the file"


def _assemble(
    records: Sequence[AccelerationRecord],
    start: pd.Timestamp,
    length_s: float,
    rate: float,
    *,
    on_lattice: bool = False,
) -> tuple[np.ndarray, list[str]]:
    """Samples of [start, start + length) from *records* on the first record's sample lattice;
    uncovered samples are NaN (gaps allowed by the plan). Returns the array and notes.
    *on_lattice*: *start* is a sample's time (a drifting record's block, to the ns), taken
    as the nearest lattice sample."""
    n_block = int(round(length_s * rate))
    n_channels = records[0].acceleration.shape[1]
    out = np.full((n_block, n_channels), np.nan)
    reference = records[0].start_time
    # first lattice sample at or after the block start
    b0 = math.ceil((start - reference).total_seconds() * rate - 1e-6)
    if on_lattice:
        b0 = round((start - reference).total_seconds() * rate)
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
        notes.append(f"gap of {_duration(np.count_nonzero(~filled) / rate)} NaN-padded")
    return out, notes


def _duration(seconds: float) -> str:
    """A padded stretch as a reader wants it: tenths of a second, or milliseconds below
    0.1 s (a record placed after a gap is known to within the clock jitter, 50 ms: its
    edge's pad is milliseconds, which tenths would show as 0.0 s)."""
    return f"{seconds:.1f} s" if seconds >= 0.1 else f"{1e3 * seconds:.0f} ms"


def _condition(
    raw: np.ndarray,
    rate: float,
    channels: tuple[str, ...],
    options: ConditioningOptions,
    planned: PlannedBlock,
    notes: list[str],
) -> AccelerationBlock:
    report = faulty_channels(raw, rate, channels, options=options.channel_check)
    faulty, dropped, names, notes = _verdicts(report, channels, notes)
    if not names:
        return _finished(planned, None, rate, (), dropped, notes, report, "all channels faulty")
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
    return _finished(planned, x, out_rate, names, dropped, notes, report)


def _verdicts(
    report: pd.DataFrame, channels: Sequence[str], notes: Sequence[str] = ()
) -> tuple[np.ndarray, tuple[tuple[str, str], ...], tuple[str, ...], tuple[str, ...]]:
    """From a channel report (:func:`~workbench.signals.moments.faulty_channels`): the
    faulty mask, the dropped (channel, reason) pairs, the kept channels and *notes* with a
    line per dropped channel."""
    faulty = report["faulty"].to_numpy()
    dropped = tuple(
        (str(c), str(r))
        for c, r in zip(report["channel"][faulty], report["reason"][faulty], strict=True)
    )
    notes = (*notes, *(f"{c} dropped: {r}" for c, r in dropped))
    names = tuple(c for c, bad in zip(channels, faulty, strict=True) if not bad)
    return faulty, dropped, names, notes


def _finished(
    planned: PlannedBlock,
    acceleration: np.ndarray | None,
    rate: float,
    channels: tuple[str, ...],
    dropped: tuple[tuple[str, str], ...],
    notes: Sequence[str],
    report: pd.DataFrame | None,
    skipped_reason: str = "",
) -> AccelerationBlock:
    """The block *planned*: built (*acceleration*), or skipped with *skipped_reason*."""
    return AccelerationBlock(
        planned.block,
        planned.block_start,
        planned.block_end,
        acceleration,
        rate,
        channels,
        dropped,
        tuple(Path(f).name for f in planned.files),
        skipped_reason,
        tuple(notes),
        report,
    )


def _skipped(planned: PlannedBlock, rate: float, reason: str) -> AccelerationBlock:
    return _finished(planned, None, rate, (), (), (f"skipped: {reason}",), None, reason)


def _build(
    plan: BlockPlan,
    planned: PlannedBlock,
    records: Sequence[AccelerationRecord],
    options: ConditioningOptions,
    blanked: Sequence[str] = (),
) -> AccelerationBlock:
    """Block *planned* from its files' *records*; *blanked*: notes of the channels their
    reader set to NaN (:func:`blanked_notes`)."""
    raw, notes = _assemble(
        records,
        planned.sample_start,
        plan.grid.length_s,
        plan.sampling_rate_hz,
        on_lattice=planned.drifting,
    )
    notes = [*blanked, *notes]
    return _condition(raw, plan.sampling_rate_hz, plan.channels, options, planned, notes)


def iter_blocks(
    files: Iterable[str | os.PathLike],
    *,
    grid: BlockGrid | None = None,
    length_s: float | None = None,
    step_s: float | None = None,
    blocks: Iterable[int] | None = None,
    options: ConditioningOptions | None = None,
    unreadable: dict[str, UnreadableInputError] | None = None,
) -> Iterator[AccelerationBlock]:
    """Stream conditioned blocks of accelerations from consecutive files.

    Parameters
    ----------
    files : iterable of path-like or FileInfo
        Acceleration files (any order, any format ``read_accelerations`` reads), or their
        headers as planned (:class:`~workbench.signals.block_plan.FileInfo`: not read again).
    grid : BlockGrid, optional
        Block grid; default: anchored at the first file's start floored to the step, with
        *length_s* / *step_s* (default 1200 s / 300 s).
    length_s, step_s : float, optional
        Block length and step when *grid* is not given. [s]
    blocks : iterable of int, optional
        Build only these blocks (e.g. those not yet done when resuming); files not needed by
        them are never read. Requested blocks outside the files' span are yielded as
        skipped.
    options : ConditioningOptions, optional
        Decimation, band-pass, detrend, channel check, gaps and file layout; default
        ``ConditioningOptions()``.
    unreadable : dict, optional
        Given: a file whose samples cannot be read does not end the stream; the blocks
        needing it are yielded skipped (its error as the reason) and the file is added here
        (its path as given -> the :class:`~workbench.errors.UnreadableInputError`).
        Without it such a file raises that error.

    Yields
    ------
    AccelerationBlock
        In ascending block order; skipped blocks have ``acceleration=None`` and a
        ``skipped_reason``.

    Raises
    ------
    ValueError
        Before the first block: files inconsistent in channels or sampling rate, or
        overlapping, or a *target_rate_hz* that does not divide their rate.

    Notes
    -----
    Memory: the loaded files sit in a deque; files ending before the current block starts
    are released before new ones are read, so at most ``ceil(length / file duration) + 1``
    files are held (5 for 20-min blocks of 5-min files) plus the block being built.
    """
    options = options or ConditioningOptions()
    plan = plan_blocks(
        files,
        grid,
        length_s=length_s,
        step_s=step_s,
        max_gap_s=options.max_gap_s,
        read_options=options.read_options,
    )
    options.check_rate(plan.sampling_rate_hz)
    return _stream(plan, options, blocks, unreadable)


def _stream(
    plan: BlockPlan,
    options: ConditioningOptions,
    blocks: Iterable[int] | None,
    unreadable: dict[str, UnreadableInputError] | None = None,
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
        failed = None
        for i in needed:
            path = str(plan.files[i].path)
            if unreadable is not None and path in unreadable:
                failed = unreadable[path]
                break
            if i not in loaded:
                try:
                    cache.append((i, _load(plan.files[i], plan.channels, options.read_options)))
                except UnreadableInputError as error:
                    if unreadable is None:
                        raise
                    unreadable[path] = failed = error
                    break
        if failed is not None:
            yield _skipped(planned, rate, str(failed))
            continue
        records = [r for i, r in cache if needed[0] <= i <= needed[-1]]
        blanked = [
            note
            for i, r in cache
            if needed[0] <= i <= needed[-1]
            for note in blanked_notes(plan.files[i].path, r.blanked)
        ]
        yield _build(plan, planned, records, options, blanked)
        del records


def load_block(
    files: Iterable[str | os.PathLike | FileInfo],
    block: int,
    grid: BlockGrid,
    *,
    options: ConditioningOptions | None = None,
    channels: Sequence[str] | None = None,
    sample_start: pd.Timestamp | None = None,
) -> AccelerationBlock:
    """Build one block from its files, e.g. in a parallel worker.

    Parameters
    ----------
    files : iterable of path-like or FileInfo
        The block's files (``PlannedBlock.files``) or any superset; only files overlapping
        the block are read. With the files beyond it, a block over a hole names the files
        on either side of the hole, as :func:`iter_blocks` does.
    block : int
        Block number on *grid*.
    grid : BlockGrid
        The voyage's grid (``BlockPlan.grid``).
    options : ConditioningOptions, optional
        As for :func:`iter_blocks`.
    channels : sequence of str, optional
        The voyage's channels (``BlockPlan.channels``); default: those of the block's files
        (:func:`~workbench.signals.block_plan.reference_channels`). A channel a file lacks
        is NaN in it, and dropped as faulty.
    sample_start : pandas.Timestamp, optional
        Placed time of the block's first sample, as the voyage's plan has it
        (``PlannedBlock.sample_start``: a drifting record's block is cut where the record's
        clock line puts its label, which the block's own files cannot fit); default: the
        block's start.

    Returns
    -------
    AccelerationBlock
        Identical to the one :func:`iter_blocks` yields for this block; skipped (with the
        reason) when the files do not cover it.
    """
    options = options or ConditioningOptions()
    infos = [
        f if isinstance(f, FileInfo) else read_file_info(f, read_options=options.read_options)
        for f in files
    ]
    k = int(block)
    start, end = grid.start(k), grid.end(k)
    if sample_start is not None:
        return _load_drifting(infos, k, grid, pd.Timestamp(sample_start), options, channels)
    if not infos:
        return _skipped(PlannedBlock(k, start, end, ()), float("nan"), "no acceleration files")
    # plan only the files touching the block (consistency checks included), with the
    # last file before it and the first after it (_span_infos)
    selected, rate = _span_infos(infos, start, end)
    if selected is None:
        return _skipped(
            PlannedBlock(k, start, end, ()), rate, "outside the span of the acceleration files"
        )
    plan = plan_file_infos(selected, grid, max_gap_s=options.max_gap_s, channels=channels)
    plan = dataclasses.replace(plan, blocks=tuple(b for b in plan.blocks if b.block == k))
    if all(b.block != k for b in plan.blocks):
        # The block reaches past the touching files into an allowed gap (the next file
        # starts after the block's end): plan it on its own, as the full plan does.
        paths, reason = _span_files(plan, start, end, options)
        single = PlannedBlock(k, start, end, paths, reason)
        plan = dataclasses.replace(plan, blocks=(single,))
    options.check_rate(plan.sampling_rate_hz)
    return next(_stream(plan, options, [k]))


def _span_infos(
    infos: Sequence[FileInfo], start: pd.Timestamp, end: pd.Timestamp
) -> tuple[list[FileInfo] | None, float]:
    """The files touching [*start*, *end*), with the last file before it and the first
    after it of the same rate (a gap at the span's edge, or a span inside a hole, is then
    named by the files on either side, as the full plan names it), and that rate; None
    for the files when the span lies outside them."""
    touching = [i for i in infos if i.start_time < end and i.end_time > start]
    rate = (touching or infos)[0].sampling_rate_hz
    before = [i for i in infos if i.end_time <= start and i.sampling_rate_hz == rate]
    after = [i for i in infos if i.start_time >= end and i.sampling_rate_hz == rate]
    if not touching and not (before and after):
        return None, rate
    neighbours = [max(before, key=lambda i: i.end_time)] if before else []
    neighbours += [min(after, key=lambda i: i.start_time)] if after else []
    return touching + neighbours, rate


def _span_files(
    plan: BlockPlan, start: pd.Timestamp, end: pd.Timestamp, options: ConditioningOptions
) -> tuple[tuple, str | None]:
    """The paths of *plan*'s files a block spanning [*start*, *end*) reads, and why it is
    skipped (None: it is not), judged as the full plan judges a block."""
    starts_ns = np.array([_ns(i.start_time) for i in plan.files], dtype=np.int64)
    ends_ns = np.array([_ns(i.end_time) for i in plan.files], dtype=np.int64)
    indices, reason = _block_files_and_gap(
        plan.files,
        starts_ns,
        ends_ns,
        _ns(start),
        _ns(end),
        plan.sampling_rate_hz,
        float(options.max_gap_s),
        CLOCK_JITTER_S,
    )
    return tuple(plan.files[i].path for i in indices), reason


def _load_drifting(
    infos: Sequence[FileInfo],
    k: int,
    grid: BlockGrid,
    sample_start: pd.Timestamp,
    options: ConditioningOptions,
    channels: Sequence[str] | None,
) -> AccelerationBlock:
    """:func:`load_block` of a block whose samples start at *sample_start* (placed time),
    not at its label: its files and gaps judged on its sample span."""
    start, end = grid.start(k), grid.end(k)
    sample_end = sample_start + (end - start)
    planned = PlannedBlock(k, start, end, (), sample_start=sample_start, drifting=True)
    if not infos:
        return _skipped(planned, float("nan"), "no acceleration files")
    selected, rate = _span_infos(infos, sample_start, sample_end)
    if selected is None:
        return _skipped(planned, rate, "outside the span of the acceleration files")
    plan = plan_file_infos(selected, grid, max_gap_s=options.max_gap_s, channels=channels)
    paths, reason = _span_files(plan, sample_start, sample_end, options)
    single = dataclasses.replace(planned, files=paths, skipped_reason=reason)
    plan = dataclasses.replace(plan, blocks=(single,))
    options.check_rate(plan.sampling_rate_hz)
    return next(_stream(plan, options, [k]))
