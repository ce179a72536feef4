"""Condition each acquisition file once and cut the blocks from the conditioned files.

With 20-minute blocks every 5 minutes, each 5-minute file lies in four blocks. The block
builder of :mod:`workbench.signals.block_builder` reads, checks and decimates every block from its
raw files, so every raw sample is read, checked and filtered four times. At a recorder's
rate (2048 Hz, about 20 channels) that repetition dominates the cost of identification.

:class:`FileConditioner` does the expensive work once per file:

* the file is read once (its neighbours' edges with a partial read),
* short NaN runs are bridged, the Chebyshev type I decimation
  (:func:`~workbench.signals.conditioning.decimate`) and the zero-phase band-pass
  (:func:`~workbench.signals.conditioning.bandpass`) run over the file **padded with the
  raw edges of the contiguous neighbouring files** (overlap and discard), and the padding is
  cut off again: the conditioned files join into the record that filtering the whole
  continuous record would give, to within the decay of the filters' transients over the
  padding (:func:`~workbench.signals.filter_cascade.padding_samples`). A gap between files
  (or the end of the data) breaks the chain: there the filters start as
  ``scipy.signal.sosfiltfilt`` starts at the ends of a record;
* the sums the faulty-channel check needs (NaN count and runs, power sums of the
  samples against time) are taken per grid step (:mod:`~workbench.signals.step_sums`),
  split further where a drifting record's blocks start and end (*cuts*: where the
  record's clock line puts their labels, on the analysis lattice), so
  the check of a block (:func:`~workbench.signals.moments.faulty_channels`: NaN fraction
  and runs, flatness, kurtosis and variance of the linearly detrended block) is assembled
  from them exactly, without the raw samples.

A block is then cut from the conditioned files (a few MB at the analysis rate) and its
faulty channels dropped. Blocks the conditioned files cannot give exactly as the per-block
builder would (a NaN-padded gap inside the block, a kept channel whose NaN run could not be
bridged elsewhere in its file, a block start off the decimated sample lattice, a block
edge among no piece's edges) are built by
:func:`~workbench.signals.block_builder.load_block` instead, so the result never silently differs.

Equality with the per-block builder
-----------------------------------
The per-block builder filters each block on its own, so its first and last samples carry
the filters' start-up transients; the conditioned files carry none (inside a chain). The
two agree in the block's interior: samples farther than
:func:`~workbench.signals.filter_cascade.padding_samples` from both block ends differ only
by the transients' remainder, in practice by rounding (``tests/signals/
test_file_conditioning.py`` checks 1e-10 of the signal RMS; the measured differences are
in ``benchmarks/results/throughput_33_identify.txt``). Near the block ends the per-block
builder's start-up transients remain, so the two paths' modes differ by those. The
faulty-channel statistics are equal up to rounding.

Memory: a :class:`FileConditioner` keeps the conditioned files of the blocks under way (at
the analysis rate) and one raw file; it does not grow with the voyage.

A file is conditioned channel by channel: each channel is gathered from the raw file and
its neighbours' edges into a buffer reused from channel to channel and filtered there in
place (:class:`~workbench.signals.filter_cascade._RowDecimator`), the same numbers as
decimating the padded file as one array (tested to the last bit).

In parallel runs each file is conditioned once by :func:`condition_file` (a
:class:`~workbench.parallel.SharedInput` of the blocks holding it) and the blocks take the
conditioned files with :meth:`FileConditioner.reuse`. Local workers are forked with a
contiguous range of blocks each (:mod:`workbench.local_workers`), so a file is read and
conditioned in the worker whose blocks hold it; only the small conditioned files at the
join of two ranges (a few MB at the analysis rate) travel between processes, never the
raw samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import read_accelerations

from ..blocks import BlockGrid
from ..errors import UnreadableInputError
from .block_builder import (
    AccelerationBlock,
    ConditioningOptions,
    _finished,
    _verdicts,
    blanked_notes,
    load_block,
)
from .block_plan import FileInfo, PlannedBlock, align_channels
from .conditioning import (
    bandpass,
    interpolate_nan_runs,
)
from .conditioning import detrend as linear_detrend
from .file_reads import _edge_rows, _read_whole
from .filter_cascade import (
    _RowDecimator,
    padding_samples,
)
from .moments import CoherenceNeeded, channel_verdicts
from .step_sums import _NS, _block_flat_runs, _block_statistics, _step_sums

__all__ = [
    "FileConditioner",
    "FileConditioning",
    "block_cuts",
    "condition_file",
    "cuts_within",
    "padding_samples",
]


#: Channels gathered from a raw file in one pass (their first-stage filter buffers, about
#: 5 MB each for a 5-min 2048-Hz file, are reused from file to file). [-]
_GATHER_CHANNELS = 4
#: Rows of a raw file copied at a time when gathering channels (cache-sized). [-]
_GATHER_ROWS = 4096


# ----------------------------------------------------------------------------------------
# the conditioner
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _ConditionedFile:
    first_out: int  # index of the first output sample on the analysis lattice
    samples: np.ndarray  # (n_out, n_channels), NaN columns where not bridgeable
    steps: dict  # grid step number -> list of _StepSums
    #: notes of the channels the reader set to NaN (block_builder.blanked_notes)
    blanked: tuple[str, ...] = ()


class FileConditioner:
    """Conditioned blocks of a voyage, each file conditioned once (see the module notes).

    Parameters
    ----------
    files : sequence of FileInfo
        The voyage's files (``BlockPlan.files``, time order) or a stretch of them that
        covers the blocks asked for and, where they exist, one file on either side.
    grid : BlockGrid
    channels : tuple of str
        Channel order of the blocks.
    options : ConditioningOptions
        Decimation (a *target_rate_hz* that divides the files' rate by a whole number > 1),
        band-pass, detrend (without a lower band edge: with one, the band-pass has already
        removed the line), channel check, gaps (blocks with a NaN-padded gap are built by
        :func:`~workbench.signals.block_builder.load_block`) and file layout.
    cuts : sequence of int
        Placed times [ns since the epoch] at which blocks start or end off the grid's
        steps: a drifting record's blocks (``PlannedBlock.sample_start`` and
        ``sample_end``), cut where the record's clock line puts their labels. The
        faulty-channel sums are split there too, so that such a block is assembled from
        them; a block whose edges are not among the pieces' is built by
        :func:`~workbench.signals.block_builder.load_block`.
    """

    def __init__(
        self,
        files: Sequence[FileInfo],
        grid: BlockGrid,
        channels: Sequence[str],
        *,
        options: ConditioningOptions,
        cuts: Sequence[int] = (),
    ) -> None:
        self.files = tuple(sorted(files, key=lambda i: i.start_time))
        self.grid = grid
        self.channels = tuple(channels)
        self.rate = float(self.files[0].sampling_rate_hz)
        self.options = options
        target_rate_hz = options.target_rate_hz
        self.target_rate_hz = float(target_rate_hz)
        self.factor = int(round(self.rate / self.target_rate_hz))
        if self.factor < 2 or abs(self.rate / self.target_rate_hz - self.factor) > 1e-9:
            raise ValueError(
                f"target_rate_hz={target_rate_hz:g} must divide {self.rate:g} Hz by a whole "
                "number above 1"
            )
        self.band_hz = options.band_hz
        self.max_gap_s = float(options.max_gap_s)
        self.read_options = options.read_options
        self.detrend = options.detrend
        self.channel_check = options.channel_check
        self.max_nan_run_s = float(self.channel_check.max_nan_run_s)
        self.padding = padding_samples(self.rate, self.target_rate_hz, self.band_hz)
        self._decimator = _RowDecimator(self.factor, rows=_GATHER_CHANNELS)
        self._t0_ns = pd.Timestamp(grid.t0).as_unit("ns").value
        self._starts_ns = np.array([_start_ns(i) for i in self.files], dtype=np.int64)
        # the cuts as raw lattice indices from the grid origin
        self._cuts = np.unique(
            np.round((np.asarray(cuts, dtype=np.int64) - self._t0_ns) / _NS * self.rate)
        ).astype(np.int64)
        self._cache: dict[int, _ConditionedFile] = {}
        self.fallbacks = 0  # blocks built by load_block

    def reuse(self, conditioned: Mapping[str | Path, _ConditionedFile | None]) -> None:
        """Take files conditioned elsewhere (by :func:`condition_file`, e.g. in another
        worker) for the files of this conditioner with those paths; ``None`` values and
        paths not among its files are ignored (those files are conditioned here)."""
        index = {str(info.path): i for i, info in enumerate(self.files)}
        for path, value in conditioned.items():
            if value is not None and str(path) in index:
                self._cache[index[str(path)]] = value

    def conditioned_file(self, index: int) -> _ConditionedFile:
        """File *index* of :attr:`files` conditioned (padded with its contiguous
        neighbours' edges), with its faulty-channel step sums; cached."""
        return self._conditioned(index)

    # -- lattice helpers ------------------------------------------------------------------
    def _offset(self, index: int) -> float:
        """Raw samples from the grid origin to the file's first sample (may be fractional)."""
        return (self._starts_ns[index] - self._t0_ns) / _NS * self.rate

    def _contiguous(self, a: int, b: int) -> bool:
        """Files *a* and *b* (b = a + 1) abut on one sample lattice."""
        if a < 0 or b >= len(self.files):
            return False
        gap = self._offset(b) - (self._offset(a) + self.files[a].n_samples)
        return abs(gap) <= 1e-6 * self.rate or abs(gap) < 1e-3

    def _on_lattice(self, index: int) -> bool:
        offset = self._offset(index)
        return abs(offset - round(offset)) < 1e-3

    # -- conditioning of one file -----------------------------------------------------------
    def _raw_file(self, index: int) -> tuple[np.ndarray, tuple[str, ...]]:
        """File *index*'s samples in the blocks' channel order, and the notes of the
        channels its reader set to NaN."""
        info = self.files[index]
        try:
            if info.path.suffix.lower() == ".npz":
                record = read_accelerations(info.path, **self.read_options)
            else:  # parsed whole: the neighbours' conditioning reads it again
                record = _read_whole(info.path, self.read_options)
        except (OSError, ValueError) as error:
            raise UnreadableInputError.of(info.path, error) from None
        if record.sampling_rate_hz != info.sampling_rate_hz or record.n_samples != info.n_samples:
            raise ValueError(f"{info.path}: file changed since it was planned")
        values = align_channels(record.acceleration, record.channels, self.channels)
        return values, blanked_notes(info.path, record.blanked)

    def _conditioned(self, index: int) -> _ConditionedFile:
        cached = self._cache.get(index)
        if cached is not None:
            return cached
        info = self.files[index]
        raw, blanked = self._raw_file(index)
        n = info.n_samples
        start = int(round(self._offset(index)))  # raw lattice index of the first sample
        f = self.factor
        parts = []
        before = 0
        if self._contiguous(index - 1, index):
            previous = self.files[index - 1]
            want = self.padding + start % f  # padded record starts on the analysis lattice
            tail = _edge_rows(
                previous, self.channels, previous.n_samples - want, None, self.read_options
            )
            if tail is not None:
                parts.append(tail)
                before = tail.shape[0]
        parts.append(raw)
        if self._contiguous(index, index + 1):
            head = _edge_rows(
                self.files[index + 1], self.channels, 0, self.padding + f, self.read_options
            )
            if head is not None:
                parts.append(head)
        steps = self._step_sums(index, raw, start)
        origin = start - before  # raw lattice index of the first padded sample
        lead = (-origin) % f  # samples before the first one on the analysis lattice
        parts[0] = parts[0][lead:]
        y, bad = self._decimated(parts)
        if self.band_hz is not None and not bad.all():  # column by column: bad ones stay NaN
            y[:, ~bad] = bandpass(y[:, ~bad], self.target_rate_hz, *self.band_hz)
        # analysis samples m * f with start <= m * f < start + n belong to this file
        first_out = -(-start // f)
        skip = first_out - (origin + lead) // f
        n_out = -(-(start + n) // f) - first_out
        samples = np.ascontiguousarray(y[skip : skip + n_out])
        samples[:, bad] = np.nan
        conditioned = _ConditionedFile(first_out, samples, steps, blanked)
        self._cache[index] = conditioned
        return conditioned

    def _decimated(self, parts: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The padded record made of *parts* ((n, n_channels) pieces in time order),
        decimated one channel at a time: (n_out, n_channels) and the channels whose NaN
        runs could not be bridged (NaN throughout, not filtered: the file's conditioned
        samples of such a channel are NaN whatever the filters give).

        Each channel's samples are gathered from the pieces straight into the decimator's
        buffer (no copy of the whole record); short NaN runs are bridged on the whole
        padded channel, as :func:`~workbench.signals.conditioning.interpolate_nan_runs`
        does column by column.
        """
        decimator = self._decimator
        n = sum(p.shape[0] for p in parts)
        edge = decimator.edge
        n_channels = len(self.channels)
        bad = np.zeros(n_channels, dtype=bool)
        out = None
        stack = decimator.buffers(n)
        for first in range(0, n_channels, decimator.rows):
            group = min(decimator.rows, n_channels - first)
            # the group's channels copied in row chunks that stay in the CPU cache: one
            # pass over the file per group instead of one per channel
            position = edge
            for part in parts:
                for lo in range(0, part.shape[0], _GATHER_ROWS):
                    chunk = part[lo : lo + _GATHER_ROWS, first : first + group]
                    stack[:group, position : position + chunk.shape[0]] = chunk.T
                    position += chunk.shape[0]
            for j in range(group):
                channel = first + j
                row = stack[j, edge : edge + n]
                if np.isnan(row).any():
                    bridged = interpolate_nan_runs(row, self.rate, max_run_s=self.max_nan_run_s)
                    bad[channel] = np.isnan(bridged).any()
                    if bad[channel]:
                        continue  # a run left unbridged: the whole channel of this file is NaN
                    row[:] = bridged
                decimated = decimator.decimate(n, row=j)
                if out is None:
                    out = np.full((n_channels, decimated.shape[0]), np.nan)
                out[channel] = decimated
        if out is None:  # every channel unbridgeable
            n_out = len(range(0, n, self.factor))
            out = np.full((n_channels, n_out), np.nan)
        return out.T, bad

    def _step_sums(self, index: int, raw: np.ndarray, start: int) -> dict:
        """Faulty-channel sums of the file's pieces, one per grid step it touches, split
        further at the cuts inside it (:class:`FileConditioner`)."""
        step_samples = self.grid.step_s * self.rate
        n = raw.shape[0]
        inside = self._cuts[(self._cuts > start) & (self._cuts < start + n)] - start
        steps: dict[int, list] = {}
        position = 0
        while position < n:
            number = math.floor((start + position) / step_samples + 1e-9)
            end = min(n, math.ceil((number + 1) * step_samples - 1e-9) - start)
            end = max(end, position + 1)
            cut = int(np.searchsorted(inside, position, side="right"))
            if cut < inside.size and inside[cut] < end:
                end = int(inside[cut])
            first_ns = self._t0_ns + int(round((start + position) / self.rate * _NS))
            steps.setdefault(number, []).append(_step_sums(raw[position:end], first_ns, self.rate))
            position = end
        return steps

    def _pieces(self, files: Sequence[_ConditionedFile], first: int, stop: int) -> list | None:
        """The step sums of *files* that tile the raw samples [first, stop) (lattice
        indices from the grid origin) in time order, or None where their edges are not
        among the pieces' (a cut the files were not split at)."""
        pieces = []
        for f in files:
            for step in f.steps.values():
                for piece in step:
                    at = self._raw_index(piece.first_ns)
                    if first <= at < stop:
                        pieces.append((at, piece))
        pieces.sort(key=lambda item: item[0])
        position = first
        for at, piece in pieces:
            if at != position:
                return None
            position += piece.n_samples
        if position != stop:
            return None
        return [piece for _, piece in pieces]

    def _raw_index(self, time_ns: int) -> int:
        return round((time_ns - self._t0_ns) / _NS * self.rate)

    def release_before(self, index: int) -> None:
        """Forget conditioned files before file *index* (blocks are taken in time order)."""
        for key in [k for k in self._cache if k < index]:
            del self._cache[key]

    # -- blocks -------------------------------------------------------------------------------
    def block(self, planned: PlannedBlock) -> AccelerationBlock:
        """The conditioned block *planned* (a block of this conditioner's voyage plan)."""
        built = None if planned.skipped_reason else self._from_files(planned)
        if built is None:
            self.fallbacks += 1
            return load_block(
                self.files,
                planned.block,
                self.grid,
                options=self.options,
                channels=self.channels,
                sample_start=planned.sample_start if planned.drifting else None,
            )
        return built

    def _from_files(self, planned: PlannedBlock) -> AccelerationBlock | None:
        index = {info.path: i for i, info in enumerate(self.files)}
        try:
            needed = [index[Path(p)] for p in planned.files]
        except KeyError:
            return None
        if not needed or not all(self._on_lattice(i) for i in needed):
            return None
        if any(not self._contiguous(a, a + 1) for a in needed[:-1]):
            return None
        # its samples' start: the label, or a drifting record's cut (PlannedBlock.sample_start)
        block_start = (pd.Timestamp(planned.sample_start).as_unit("ns").value - self._t0_ns) / _NS
        start_raw = block_start * self.rate
        n_raw = int(round(self.grid.length_s * self.rate))
        if abs(start_raw - round(start_raw)) > 1e-3 or round(start_raw) % self.factor:
            return None
        if n_raw % self.factor:
            return None
        start_raw = int(round(start_raw))
        first_index = needed[0]
        if self._offset(first_index) > start_raw + 0.5 or (
            self._offset(needed[-1]) + self.files[needed[-1]].n_samples < start_raw + n_raw - 0.5
        ):
            return None
        self.release_before(first_index)
        files = [self._conditioned(i) for i in needed]
        # faulty-channel check from the step sums: the pieces that tile the block
        pieces = self._pieces(files, start_raw, start_raw + n_raw)
        if pieces is None:
            return None
        nan_fraction, longest, variance, kurtosis = _block_statistics(pieces, n_raw, self.rate)
        try:
            report = channel_verdicts(
                self.channels,
                nan_fraction,
                longest,
                variance,
                kurtosis,
                options=self.channel_check,
                longest_flat_s=_block_flat_runs(pieces, self.rate),
            )
        except CoherenceNeeded:
            return None  # a variance outlier's coherence needs the raw block: load_block

        blanked = [note for f in files for note in f.blanked]
        faulty, dropped, names, notes = _verdicts(report, self.channels, blanked)
        if not names:
            return _finished(
                planned, None, self.rate, (), dropped, notes, report, "all channels faulty"
            )
        kept = np.flatnonzero(~faulty)
        first_out = start_raw // self.factor
        n_out = n_raw // self.factor
        out = np.empty((n_out, kept.size))
        filled = 0
        for f in files:
            lo = max(first_out, f.first_out)
            hi = min(first_out + n_out, f.first_out + f.samples.shape[0])
            if hi <= lo:
                continue
            if lo - first_out != filled:
                return None
            out[lo - first_out : hi - first_out] = f.samples[lo - f.first_out : hi - f.first_out][
                :, kept
            ]
            filled = hi - first_out
        if filled != n_out or np.isnan(out).any():
            return None
        if self.detrend and (self.band_hz is None or self.band_hz[0] is None):
            out = linear_detrend(out)
        return _finished(planned, out, self.target_rate_hz, names, dropped, notes, report)


@dataclass(frozen=True)
class FileConditioning:
    """What :func:`condition_file` needs to condition one file on its own (picklable).

    Parameters
    ----------
    files : tuple of FileInfo
        The file and its neighbours in the voyage plan (one on either side where they
        exist): their edges pad the filters.
    index : int
        Position of the file in *files*.
    grid : BlockGrid
    channels : tuple of str
    options : ConditioningOptions
    cuts : tuple of int
        As for :class:`FileConditioner` (those inside the file at least).
    """

    files: tuple
    index: int
    grid: BlockGrid
    channels: tuple
    options: ConditioningOptions
    cuts: tuple = ()


def condition_file(job: FileConditioning) -> _ConditionedFile:
    """One file conditioned once, for every block holding it: the value a
    :class:`FileConditioner` of those blocks takes with :meth:`FileConditioner.reuse`."""
    conditioner = FileConditioner(
        job.files, job.grid, job.channels, options=job.options, cuts=job.cuts
    )
    return conditioner.conditioned_file(conditioner.files.index(job.files[job.index]))


def _start_ns(info: FileInfo) -> int:
    return pd.Timestamp(info.start_time).as_unit("ns").value


def block_cuts(blocks: Sequence[PlannedBlock]) -> tuple[int, ...]:
    """The cuts [ns since the epoch] of the blocks cut on a drifting record's clock line
    (``sample_start`` and ``sample_end``), ascending: :class:`FileConditioner`'s
    *cuts*."""
    cuts = set()
    for planned in blocks:
        if planned.drifting:
            cuts.add(pd.Timestamp(planned.sample_start).as_unit("ns").value)
            cuts.add(pd.Timestamp(planned.sample_end).as_unit("ns").value)
    return tuple(sorted(cuts))


def cuts_within(cuts: Sequence[int], files: Sequence[FileInfo]) -> tuple[int, ...]:
    """The *cuts* (ascending) inside the span of *files* (time order)."""
    if not cuts or not files:
        return ()
    lo, hi = _start_ns(files[0]), pd.Timestamp(files[-1].end_time).as_unit("ns").value
    a = int(np.searchsorted(cuts, lo, side="left"))
    b = int(np.searchsorted(cuts, hi, side="right"))
    return tuple(int(c) for c in cuts[a:b])
