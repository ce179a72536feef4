"""Block-wise system identification of a voyage: files -> poles and selected modes per block.

:func:`identify_voyage` plans the blocks of a set of acceleration files (reading only file
headers), runs :func:`identify_block` on every block not yet done - in parallel with Dask,
on all local cores or on an existing cluster - into a resumable :class:`~workbench.store.
BlockStore`, and exports the store as contract tables:

* ``poles.parquet`` - stabilisation diagrams (POLES contract), one row per pole, block and
  model order, with mode shapes;
* ``selected.parquet`` - the automatically selected modes of each block (input of
  ``workbench track``), with the scatter of each mode's pole cluster
  (``frequency_std_hz``, ``damping_std``, ``n_poles``; see
  :mod:`workbench.sid.selection`);
* ``faults.csv`` - channels dropped per block and why;
* ``channels.csv`` - per block and channel: RMS and kurtosis of the conditioned signal;
* ``blocks.csv`` - every block: ``ok`` or ``skipped`` and the reason;
* ``crosscheck.csv`` - with ``cross_check``: the SSI and LSCF modes of every block paired
  (:func:`workbench.sid.crosscheck.cross_check`), summarised in the run's summary.

Killing the job at any moment and running it again finishes it without recomputing the
blocks already stored, and gives the same tables as an uninterrupted run (every block's
result depends only on its own data and the options, which the store checks). The store
is locked while a run works on it, and every input file is fingerprinted (size,
modification time, SHA-256 of its content): a second run on a busy store, or a rerun on
changed files, is refused instead of mixing or reusing results of other data.

Every option is checked against the files' headers before the first block (rate, band,
reference channels, block rows against the samples of a block): an option that would make
every block fail raises :class:`~workbench.errors.OptionError` at once.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import logging
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from data_contracts import POLES, SELECTED, atomic_path, shape_columns
from data_contracts.formats import ACCELERATION_SUFFIXES as _FORMAT_SUFFIXES
from data_contracts.tables import metadata_with_grid, write_grid_sidecar

from ._deprecation import renamed_fields
from .blocks import BlockGrid
from .errors import OptionError, WorkbenchError
from .parallel import BlockOutcome, RunSummary, run_blocks
from .store import BlockStore

log = logging.getLogger("workbench")

__all__ = [
    "IdentifyOptions",
    "IdentifyOptionsError",
    "IdentifyResult",
    "cross_check_blocks",
    "identify_block",
    "identify_voyage",
    "write_block_figures",
    "write_tpe_figures",
]

#: Acceleration file suffixes picked up from a folder. Text files (.csv, .tsv, .txt) are
#: taken only when their header looks like an acceleration record: a voyage folder also
#: holds ship logs and tables (see data_contracts.formats.text.looks_like_acceleration_table).
ACCELERATION_SUFFIXES = _FORMAT_SUFFIXES


#: Lower damping limit of the automatic selection (harmonics have ζ ≈ 0). [-]
_LOWEST_DAMPING = 0.001


@renamed_fields(
    max_damping=("damping_limits", lambda high: (_LOWEST_DAMPING, high), lambda lim: lim[1])
)
@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of block-wise identification (all stored with the results).

    Attributes
    ----------
    method : {"cov", "data", "lscf"}
        Covariance-driven or data-driven SSI, or poly-reference LSCF
        (:func:`workbench.sid.plscf.lscf`, fitted in *band_hz*).
    block_rows : int
        Block rows i of the Hankel/Toeplitz matrix (lags 1..2i). [-]
    orders : tuple of int
        Model orders of the stabilisation diagram. [-]
    weighting : {"pc", "upc", "cva"}
        Weighting of SSI-data.
    reference_channels : tuple of str, optional
        Reference channels (default: all).
    length_s, step_s : float
        Block length and step (default 20 min, 75 % overlap). [s]
    target_rate_hz : float or "auto", optional
        Decimate to this rate first (e.g. 2048 Hz -> 64 Hz); ``None`` keeps the files' rate;
        ``"auto"`` (default) derives it from the band
        (:func:`~workbench.signals.file_conditioning.default_decimation_rate`: the files'
        rate halved while it stays at or above 4 x the band's upper edge, so 2048 Hz files
        and a 2-12 Hz band are identified at 64 Hz, 64 Hz files at 64 Hz). When decimating,
        each file is conditioned once for all blocks sharing it
        (:class:`~workbench.signals.file_conditioning.FileConditioner`). [Hz]
    band_hz : (float, float) or "auto" or None
        Zero-phase band-pass after decimation; also the band of the automatic selection.
        ``"auto"`` (default) derives it from the analysis rate r (after decimation):
        (0, 0.8·r/2), the pass band of the decimation's anti-aliasing filter (also used
        without decimation: poles near Nyquist are poorly resolved). A lower edge of 0
        means no high-pass: a high-pass adds its own poles, which bias a mode within a few
        times its edge; the linear detrend removes offsets and drift. ``None``: no
        band-pass, selection up to 0.8·r/2. The upper edge may not exceed 0.8·r/2 when
        decimating (above it the filter's own poles would be selected as modes). [Hz]
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded. [s]
    frequency_tol, damping_tol, mac_min : float
        Stability criteria between consecutive orders (relative frequency change, relative
        damping change, lowest MAC).
    damping_limits : (float, float)
        Poles with damping ratios outside these limits are not selected (harmonics have
        ζ ≈ 0, noise poles large ζ). [-]
    lscf_orders : tuple of int
        Polynomial orders p of LSCF (p·r poles with r references). [-]
    lscf_lags : int, optional
        Correlation lags of the LSCF half-spectra (default: see :func:`~workbench.sid.plscf.
        lscf`).
    cross_check : bool
        Also identify every block with the other family (LSCF for SSI, SSI-cov for LSCF)
        and pair the selected modes of both (``crosscheck.csv``).
    acceleration_layout : mapping, optional
        How to read the acceleration files (fields of
        :class:`data_contracts.formats.AccelerationLayout`: time column and format, units,
        MATLAB/HDF5 names, ...); default: from the files themselves.
    selection : {"cluster", "library"}
        Automatic pole selection (:func:`~workbench.sid.selection.select_modes`).
    short_record : {"error", "one-block"}
        Data with no complete block: an error naming the record (default), or one block
        of the record's length (a single continuous record).
    channel_check : bool
        Drop faulty channels per block (:func:`~workbench.signals.moments.faulty_channels`).
    fault_options : tuple of (str, value)
        Thresholds of the channel check, e.g. ``(("kurtosis_limits", (1.3, 10.0)),)``.
    conditioning : {"per-file", "per-block"}
        When decimating: condition each file once and cut the blocks from the conditioned
        files (default), or build every block from its raw files (the reference path, four
        times the work for 75 % overlap; equal in the blocks' interior, see
        :mod:`workbench.signals.file_conditioning`).
    """

    method: Literal["cov", "data", "lscf"] = "cov"
    block_rows: int = 20
    orders: tuple[int, ...] = tuple(range(4, 61, 2))
    weighting: Literal["pc", "upc", "cva"] = "pc"
    reference_channels: tuple[str, ...] | None = None
    length_s: float = 1200.0
    step_s: float = 300.0
    target_rate_hz: float | Literal["auto"] | None = "auto"
    band_hz: tuple[float, float] | Literal["auto"] | None = "auto"
    max_gap_s: float = 0.0
    frequency_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.98
    damping_limits: tuple[float, float] = (_LOWEST_DAMPING, 0.10)
    lscf_orders: tuple[int, ...] = tuple(range(1, 16))
    lscf_lags: int | None = None
    cross_check: bool = False
    acceleration_layout: Mapping | None = None
    selection: Literal["cluster", "library"] = "cluster"
    short_record: Literal["error", "one-block"] = "error"
    channel_check: bool = True
    fault_options: tuple[tuple[str, object], ...] = ()
    conditioning: Literal["per-file", "per-block"] = "per-file"

    def __post_init__(self) -> None:
        if self.conditioning not in ("per-file", "per-block"):
            raise OptionError(
                f"conditioning={self.conditioning!r} must be 'per-file' or 'per-block'"
            )
        if self.method not in ("cov", "data", "lscf"):
            raise OptionError(f"method={self.method!r} must be 'cov', 'data' or 'lscf'")
        if self.weighting not in ("pc", "upc", "cva"):
            raise OptionError(f"weighting={self.weighting!r} must be 'pc', 'upc' or 'cva'")
        lscf_orders = tuple(int(o) for o in self.lscf_orders)
        if not lscf_orders or min(lscf_orders) < 1:
            raise OptionError(f"lscf_orders={self.lscf_orders!r} must be positive orders")
        object.__setattr__(self, "lscf_orders", lscf_orders)
        if int(self.block_rows) != self.block_rows or self.block_rows < 2:
            raise OptionError(f"block_rows={self.block_rows} must be an integer of at least 2")
        orders = tuple(int(o) for o in self.orders)
        if not orders or min(orders) < 1:
            raise OptionError(f"orders={self.orders!r} must be positive model orders")
        object.__setattr__(self, "orders", orders)
        if self.selection not in ("cluster", "library"):
            raise OptionError(f"selection={self.selection!r} must be 'cluster' or 'library'")
        if self.short_record not in ("error", "one-block"):
            raise OptionError(f"short_record={self.short_record!r} must be 'error' or 'one-block'")
        for name in ("length_s", "step_s"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise OptionError(f"{name}={value:g} must be a positive number of seconds")
        if self.step_s > self.length_s:
            raise OptionError(
                f"block step {self.step_s / 60:g} min is longer than the block length "
                f"{self.length_s / 60:g} min (blocks would leave gaps); give a step at most "
                "the length (e.g. --step-minutes)"
            )
        if not (math.isfinite(float(self.max_gap_s)) and self.max_gap_s >= 0):
            raise OptionError(
                f"max_gap_s={float(self.max_gap_s):g} must be a non-negative number of seconds"
            )
        if self.target_rate_hz is not None and self.target_rate_hz != "auto":
            try:
                rate = float(self.target_rate_hz)
            except (TypeError, ValueError):
                rate = math.nan
            if not (math.isfinite(rate) and rate > 0):
                raise OptionError(
                    f"target_rate_hz={self.target_rate_hz!r} must be a positive rate [Hz], "
                    "'auto' or None"
                )
            object.__setattr__(self, "target_rate_hz", rate)
        object.__setattr__(
            self, "fault_options", tuple((str(k), v) for k, v in dict(self.fault_options).items())
        )
        if isinstance(self.band_hz, str):
            if self.band_hz != "auto":
                raise OptionError(f"band_hz={self.band_hz!r} must be (low, high), 'auto' or None")
        elif self.band_hz is not None:
            try:
                low, high = (float(v) for v in self.band_hz)
            except (TypeError, ValueError):
                raise OptionError(f"band_hz={self.band_hz!r} must be (low, high) [Hz]") from None
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
                raise OptionError(
                    f"band_hz=({low:g}, {high:g}) must be (low, high) with 0 <= low < high"
                )
            object.__setattr__(self, "band_hz", (low, high))
        for name in ("frequency_tol", "damping_tol", "mac_min"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and 0 <= value <= 1):
                raise OptionError(f"{name}={value:g} must lie in [0, 1]")
        try:
            low, high = (float(v) for v in self.damping_limits)
        except (TypeError, ValueError):
            raise OptionError(
                f"damping_limits={self.damping_limits!r} must be (low, high)"
            ) from None
        if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high <= 1):
            raise OptionError(
                f"damping_limits=({low:g}, {high:g}) must be (low, high) with 0 <= low < high <= 1"
            )
        object.__setattr__(self, "damping_limits", (low, high))
        if self.reference_channels is not None and not self.reference_channels:
            object.__setattr__(self, "reference_channels", None)

    def check_data(self, plan) -> None:
        """Raise :class:`OptionError` now if the options cannot work on *plan*'s files.

        Checked against the headers: decimation to ``target_rate_hz`` (a whole-number
        factor), the band (below the Nyquist frequency of the decimated blocks), the
        reference channels (names of the files' channels), and block rows and model orders
        against the samples and channels of one block.
        """
        rate = float(plan.sampling_rate_hz)
        out_rate = rate
        if self.target_rate_hz is not None:
            ratio = rate / float(self.target_rate_hz)
            if not (ratio >= 1 and abs(ratio - round(ratio)) <= 1e-9 * ratio):
                raise OptionError(
                    f"target_rate_hz={float(self.target_rate_hz):g} must divide the files' "
                    f"sampling rate {rate:g} Hz by a whole number"
                )
            out_rate = float(self.target_rate_hz)
        if self.band_hz is not None:
            nyquist = out_rate / 2
            if self.band_hz[1] >= nyquist:
                raise OptionError(
                    f"band_hz=({self.band_hz[0]:g}, {self.band_hz[1]:g}): the upper edge must "
                    f"lie below the Nyquist frequency {nyquist:g} Hz of the {out_rate:g} Hz "
                    "blocks"
                )
        channels = list(plan.channels)
        if self.reference_channels:
            unknown = [c for c in self.reference_channels if c not in channels]
            if unknown:
                raise OptionError(
                    f"reference_channels: {', '.join(unknown)} not among the files' channels "
                    f"({', '.join(channels)})"
                )
        if self.method not in ("cov", "data"):
            return  # block rows and model orders are SSI settings
        n_refs = len(self.reference_channels or channels)
        n_channels = len(channels)
        capacity = min(n_refs * self.block_rows, n_channels * (self.block_rows - 1))
        if max(self.orders) > capacity:
            raise OptionError(
                f"orders up to {max(self.orders)} need more block_rows than {self.block_rows} "
                f"with {n_refs} reference and {n_channels} channels (largest order {capacity})"
            )
        n_samples = int(math.floor(self.length_s * out_rate + 1e-9))
        needed = (n_channels + n_refs + 2) * self.block_rows
        if n_samples < needed:
            raise OptionError(
                f"block_rows={self.block_rows} needs at least {needed} samples per block with "
                f"{n_channels} channels, a block has {n_samples} ({self.length_s:g} s at "
                f"{out_rate:g} Hz)"
            )

    def parameters(self) -> dict:
        """JSON-able form (what the store records and checks on resume)."""
        values = asdict(self)
        values["orders"] = list(self.orders)
        values["band_hz"] = list(self.band_hz) if isinstance(self.band_hz, tuple) else self.band_hz
        values["fault_options"] = {
            k: list(v) if isinstance(v, tuple) else v for k, v in self.fault_options
        }
        values["reference_channels"] = (
            list(self.reference_channels) if self.reference_channels else None
        )
        values["lscf_orders"] = list(self.lscf_orders)
        # recorded as the former max_damping while the lower limit is the former fixed one,
        # so stores written before the rename still resume
        del values["damping_limits"]
        if self.damping_limits[0] == _LOWEST_DAMPING:
            values["max_damping"] = self.damping_limits[1]
        else:
            values["damping_limits"] = list(self.damping_limits)
        # options added with LSCF are recorded only when used, so stores written before
        # them still resume
        if not self.cross_check:
            del values["cross_check"]
            if self.method != "lscf":
                del values["lscf_orders"], values["lscf_lags"]
        if self.acceleration_layout is None:  # stores made before the option resume
            del values["acceleration_layout"]
        else:
            values["acceleration_layout"] = dict(self.acceleration_layout)
        return values

    @property
    def read_options(self) -> dict:
        """Keyword arguments of :func:`data_contracts.read_accelerations`."""
        return {"layout": dict(self.acceleration_layout)} if self.acceleration_layout else {}

    def resolved(self, sampling_rate_hz: float) -> IdentifyOptions:
        """These options for files at *sampling_rate_hz*: the analysis rate (``"auto"``:
        :func:`analysis_rate`) and the band made concrete, the band checked against the
        anti-aliasing filter of the decimation.

        Raises
        ------
        IdentifyOptionsError
            Band above the filter's edge or Nyquist; a rate that does not divide the files'.
        """
        rate = float(sampling_rate_hz)
        out_rate = analysis_rate(self, rate)
        target = None if out_rate == rate else out_rate
        if self.target_rate_hz not in (None, "auto"):
            ratio = rate / out_rate
            if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
                raise IdentifyOptionsError(
                    f"--rate {out_rate:g} must divide the files' sampling rate {rate:g} Hz by "
                    f"a whole number (e.g. {rate / max(1, math.floor(ratio)):g})"
                )
        decimating = out_rate < rate
        edge = ANTI_ALIAS_EDGE * out_rate / 2
        if self.band_hz == "auto":
            band: tuple[float, float] | None = (0.0, edge)
        else:
            band = self.band_hz
        if band is not None:
            low, high = band
            if decimating and high > edge * (1 + 1e-9):
                raise IdentifyOptionsError(
                    f"--band upper edge {high:g} Hz lies above {edge:g} Hz, the edge of the "
                    f"anti-aliasing filter of the decimation to {out_rate:g} Hz (its poles "
                    "would be selected as modes); lower the band or raise --rate"
                )
            if high >= out_rate / 2:
                raise IdentifyOptionsError(
                    f"--band upper edge {high:g} Hz must lie below the Nyquist frequency "
                    f"{out_rate / 2:g} Hz of the {out_rate:g}-Hz analysis rate"
                )
        return dataclasses.replace(self, band_hz=band, target_rate_hz=target)

    def selection_band(self, sampling_rate_hz: float) -> tuple[float, float]:
        """The band of the automatic selection for an analysis rate. [Hz]"""
        if isinstance(self.band_hz, tuple):
            return self.band_hz
        return (0.0, ANTI_ALIAS_EDGE * float(sampling_rate_hz) / 2)


class IdentifyOptionsError(OptionError):
    """Options that do not fit the data (a usage error: the CLI exits 2)."""


#: Highest natural frequency the default analysis rate keeps in reach when no band is
#: given [Hz]: global modes of ship hulls (vertical and horizontal bending, torsion) and of
#: most civil structures lie well below it; give --band or --rate for anything higher.
DEFAULT_MODE_CEILING_HZ = 25.0

#: Edge of the decimation's anti-aliasing filter as a fraction of the new Nyquist frequency
#: (Chebyshev type I, as MATLAB's and SciPy's ``decimate``).
ANTI_ALIAS_EDGE = 0.8


@dataclass(frozen=True)
class _Task:
    """One block to identify (picklable: sent to the workers).

    ``infos`` are the planned headers of ``files`` (:class:`~workbench.signals.FileInfo`),
    so a worker does not read every file once more to plan the block (for a CSV file that
    is a whole parse per block holding it).
    """

    block: int
    block_start: pd.Timestamp
    files: tuple
    infos: tuple = ()


def _block_tasks(plan, planned) -> list[_Task]:
    """Tasks of the *planned* blocks of *plan*, with their files' headers."""
    header = {info.path: info for info in plan.files}
    return [
        _Task(
            int(p.block),
            p.block_start,
            tuple(str(f) for f in p.files),
            tuple(header[Path(f)] for f in p.files if Path(f) in header),
        )
        for p in planned
    ]


def _identify_data(
    task: _Task, grid: BlockGrid, options: IdentifyOptions, cross=False, conditioner=None
):
    """Conditioned block, SSI or LSCF result (None if skipped) and mode selection of one
    block; with *cross*, also the result and selection of the other method (or None).

    *conditioner* (a :class:`~workbench.signals.file_conditioning.FileConditioner`) gives
    the block from files conditioned once; without it the block is built from its files.
    """
    from .signals import PlannedBlock, load_block

    if conditioner is not None:
        planned = PlannedBlock(
            task.block, task.block_start, grid.end(task.block), tuple(map(Path, task.files))
        )
        data = conditioner.block(planned)
    else:
        infos = getattr(task, "infos", ())  # planned headers: no file read to plan again
        data = load_block(
            infos if len(infos) == len(task.files) else task.files,
            task.block,
            grid,
            target_rate_hz=options.target_rate_hz,
            band_hz=_filter_band(options),
            max_gap_s=options.max_gap_s,
            read_options=options.read_options,
            fault_options=_fault_options(options),
        )
    if data.acceleration is None:
        return data, None, None
    kept = list(data.channels)
    if len(kept) < 2:
        raise ValueError(f"block {task.block}: only {len(kept)} good channel(s) left")
    reference = None
    if options.reference_channels:
        reference = [kept.index(c) for c in options.reference_channels if c in kept]
        if not reference:
            raise ValueError(f"block {task.block}: no reference channel left")
    result, selection = _identify_method(options.method, data, reference, options)
    if not cross:
        return data, result, selection
    other = "cov" if options.method == "lscf" else "lscf"
    try:
        checked = _identify_method(other, data, reference, options)
    except (ValueError, np.linalg.LinAlgError):
        checked = None  # the block's own result stands; it just has no cross-check
    return data, result, selection, checked


def _identify_method(method: str, data, reference, options: IdentifyOptions):
    """Result of *method* on a conditioned block, stabilised, and its mode selection."""
    from .sid import select_modes, ssi_cov, ssi_data, stabilise
    from .sid.plscf import lscf

    n_channels = len(data.channels)
    orders = _reachable_orders(options, n_channels, len(reference or range(n_channels)))
    if method == "cov":
        result = ssi_cov(
            data.acceleration,
            data.sampling_rate_hz,
            block_rows=options.block_rows,
            orders=orders,
            reference_channels=reference,
        )
    elif method == "data":
        result = ssi_data(
            data.acceleration,
            data.sampling_rate_hz,
            block_rows=options.block_rows,
            orders=orders,
            reference_channels=reference,
            weighting=options.weighting,
        )
    else:
        nyquist = 0.5 * data.sampling_rate_hz
        low, high = options.selection_band(data.sampling_rate_hz)
        band = (min(low, nyquist), min(high, nyquist))
        result = lscf(
            data.acceleration,
            data.sampling_rate_hz,
            orders=options.lscf_orders,
            band_hz=band,
            n_lags=options.lscf_lags,
            reference_channels=reference,
        )
    result = stabilise(
        result,
        frequency_tol=options.frequency_tol,
        damping_tol=options.damping_tol,
        mac_min=options.mac_min,
    )
    selection = select_modes(
        result,
        selection=options.selection,
        band_hz=options.selection_band(data.sampling_rate_hz),
        damping_limits=options.damping_limits,
    )
    return result, selection


def _filter_band(options: IdentifyOptions):
    """Band-pass edges for the conditioning: a lower edge of 0 means no high-pass."""
    if not isinstance(options.band_hz, tuple):
        return None
    low, high = options.band_hz
    return (low if low > 0 else None, high)


def _fault_options(options: IdentifyOptions) -> dict:
    """Keyword arguments of the channel check (every check off when disabled)."""
    if not options.channel_check:
        return {
            "max_nan_fraction": 1.0,
            "max_nan_run_s": math.inf,
            "kurtosis_limits": (0.0, math.inf),
            "flat_variance": -1.0,
            "max_variance_z": math.inf,
        }
    return dict(options.fault_options)


def _reachable_orders(options: IdentifyOptions, n_channels: int, n_reference: int):
    """The model orders a block with these channels can give: max order <= min(r·i,
    l·(i-1)) (r reference channels, l channels, i block rows). Channels dropped by the
    check must not make every block fail for orders chosen for the full set."""
    top = min(n_reference * options.block_rows, n_channels * (options.block_rows - 1))
    orders = tuple(o for o in options.orders if o <= top)
    return orders if len(orders) >= 2 else options.orders


def identify_block(
    task: _Task,
    *,
    grid: BlockGrid,
    channels: Sequence[str],
    options: IdentifyOptions,
    conditioner=None,
) -> BlockOutcome:
    """Identify one block: load and condition, SSI over all orders, stabilise, select.

    Returns
    -------
    BlockOutcome
        Tables ``poles``, ``selected``, ``faults``, ``channels``; or skipped with the
        reason (gap, too few good channels, ...). Raises ValueError for data problems,
        which :func:`~workbench.parallel.run_blocks` records as a skipped block.
    """
    from threadpoolctl import threadpool_limits

    # One BLAS thread per block, in workers and in-process alike: the parallelism is over
    # blocks, and the same arithmetic everywhere makes results bit-identical whatever the
    # scheduler (a resumed job may mix blocks computed either way).
    with threadpool_limits(limits=1):
        data, result, selection, *other = _identify_data(
            task, grid, options, cross=options.cross_check, conditioner=conditioner
        )
    start = pd.Timestamp(task.block_start)
    end = grid.end(task.block)
    faults = pd.DataFrame(
        {
            "block": np.full(len(data.dropped), task.block, dtype="int64"),
            "block_start": pd.to_datetime([start] * len(data.dropped), utc=True),
            "channel": [c for c, _ in data.dropped],
            "reason": [r for _, r in data.dropped],
        }
    )
    notes = tuple(f"channel {c} dropped ({_reason_kind(r)})" for c, r in data.dropped)
    if result is None:
        return BlockOutcome(
            task.block, start, {"faults": faults}, skipped=data.skipped_reason, notes=notes
        )
    kept = list(data.channels)
    poles = _full_channels(result.poles_frame(kept, block=task.block), kept, channels)
    selected_frame = _selected_frame(
        selection.modes_frame(kept), kept, channels, task.block, start, end
    )
    channel_stats = _channel_statistics(data.acceleration, kept, task.block, start)
    tables = {
        "poles": poles,
        "selected": selected_frame,
        "faults": faults,
        "channels": channel_stats,
    }
    if other and other[0] is not None:
        tables["crosscheck"] = _cross_check_frame(
            selection, other[0][1], options.method, task.block, start
        )
    return BlockOutcome(task.block, start, tables, notes=notes)


def _cross_check_frame(selection, other_selection, method, block, start) -> pd.DataFrame:
    """The SSI and LSCF modes of one block paired (:func:`~workbench.sid.crosscheck.
    cross_check`), with ``block_start``."""
    from .sid.crosscheck import cross_check

    ssi, lscf = (other_selection, selection) if method == "lscf" else (selection, other_selection)
    frame = cross_check(
        ssi.modes["frequency_hz"],
        ssi.modes["damping_ratio"],
        ssi.mode_shapes,
        lscf.modes["frequency_hz"],
        lscf.modes["damping_ratio"],
        lscf.mode_shapes,
        block=block,
    )
    frame.insert(1, "block_start", pd.to_datetime([start] * len(frame), utc=True))
    return frame


@dataclass(frozen=True)
class _FileTask:
    """One block cut from files conditioned once (picklable: sent to the workers).

    ``window`` are the headers of the block's files plus one contiguous file on either
    side (their edges pad the filters); ``shared_inputs`` condition each of the block's
    files once for all the blocks holding it
    (:class:`~workbench.parallel.SharedInput` of
    :func:`~workbench.signals.file_conditioning.condition_file`).
    """

    block: int
    block_start: pd.Timestamp
    files: tuple
    window: tuple = ()
    shared_inputs: tuple = ()


def _conditioner_settings(options: IdentifyOptions) -> dict:
    return {
        "target_rate_hz": float(options.target_rate_hz),
        "band_hz": _filter_band(options),
        "max_gap_s": options.max_gap_s,
        "fault_options": _fault_options(options),
        "read_options": options.read_options,
    }


def identify_from_files(
    task: _FileTask,
    conditioned: Mapping | None = None,
    *,
    grid: BlockGrid,
    channels: Sequence[str],
    options: IdentifyOptions,
) -> BlockOutcome:
    """Identify one block from its files conditioned once.

    *conditioned* maps file paths to the files conditioned by
    :func:`~workbench.signals.file_conditioning.condition_file` (shared by the blocks
    holding them; :func:`~workbench.parallel.run_blocks` passes them); files missing there
    are conditioned here. Returns what :func:`identify_block` returns.
    """
    from .signals.file_conditioning import FileConditioner

    if not task.window:  # a planned block without files: the per-block path says why
        return identify_block(task, grid=grid, channels=channels, options=options)
    conditioner = FileConditioner(task.window, grid, channels, **_conditioner_settings(options))
    conditioner.reuse(conditioned or {})
    return identify_block(
        task, grid=grid, channels=channels, options=options, conditioner=conditioner
    )


def _file_tasks(tasks: Sequence[_Task], plan, options: IdentifyOptions) -> list[_FileTask]:
    """*tasks* as blocks cut from files conditioned once, each file's conditioning shared
    by the blocks holding it."""
    from .parallel import SharedInput
    from .signals.file_conditioning import FileConditioning, condition_file

    position = {info.path: i for i, info in enumerate(plan.files)}
    settings = _conditioner_settings(options)
    channels = tuple(plan.channels)
    jobs: dict[int, SharedInput] = {}
    out = []
    for task in tasks:
        used = sorted(position[Path(f)] for f in task.files)
        if not used:
            out.append(_FileTask(task.block, task.block_start, task.files))
            continue
        for i in used:
            if i not in jobs:
                lo = max(i - 1, 0)
                job = FileConditioning(
                    tuple(plan.files[lo : i + 2]), i - lo, plan.grid, channels, settings
                )
                jobs[i] = SharedInput(str(plan.files[i].path), condition_file, job)
        lo, hi = max(used[0] - 1, 0), min(used[-1] + 2, len(plan.files))
        out.append(
            _FileTask(
                task.block,
                task.block_start,
                task.files,
                tuple(plan.files[lo:hi]),
                tuple(jobs[i] for i in used),
            )
        )
    return out


def resolved_run(
    options: IdentifyOptions, sampling_rate_hz: float, grid, channels: Sequence[str]
) -> tuple[IdentifyOptions, bool, dict]:
    """The options of a run on files at *sampling_rate_hz*, whether its files are
    conditioned once each (per-file decimation by an integer factor), and the parameters
    its store is opened with (``identify`` and ``monitor`` share them, so their stores
    agree).
    """
    rate = analysis_rate(options, sampling_rate_hz)
    ratio = sampling_rate_hz / rate
    per_file = (
        options.conditioning == "per-file"
        and round(ratio) >= 2
        and abs(ratio - round(ratio)) <= 1e-9 * ratio
    )
    options = replace(options, target_rate_hz=None if rate == sampling_rate_hz else rate)
    parameters = {
        **options.parameters(),
        "grid_t0": grid.t0.isoformat(),
        "channels": list(channels),
    }
    return options, per_file, parameters


def analysis_rate(options: IdentifyOptions, sampling_rate_hz: float) -> float:
    """The rate blocks are identified at, for files at *sampling_rate_hz*. [Hz]

    ``target_rate_hz="auto"`` follows the band's upper edge
    (:func:`~workbench.signals.file_conditioning.default_decimation_rate`: the files' rate
    halved while it stays at or above 4 x the edge). With the band left to ``"auto"`` (then
    derived from the rate itself) or None, the edge is :data:`DEFAULT_MODE_CEILING_HZ`, so
    2048-Hz files are analysed at 128 Hz, 256 Hz at 128 Hz and 64 Hz at 64 Hz.
    """
    from .signals.file_conditioning import default_decimation_rate

    if options.target_rate_hz is None:
        return float(sampling_rate_hz)
    if options.target_rate_hz == "auto":
        if isinstance(options.band_hz, tuple):
            band = options.band_hz
        else:
            band = (None, DEFAULT_MODE_CEILING_HZ)
        return default_decimation_rate(sampling_rate_hz, band)
    return float(options.target_rate_hz)


def _reason_kind(reason: str) -> str:
    """The kind of a fault reason without its numbers (for summary counts), e.g.
    ``"nan fraction 1.00 > 0.05"`` -> ``"nan fraction"``."""
    words = []
    for word in reason.split():
        if any(ch.isdigit() for ch in word) or word in (">", "<", "=", "%"):
            break
        words.append(word)
    return " ".join(words) or "faulty"


def _full_channels(frame: pd.DataFrame, kept: Sequence[str], channels: Sequence[str]):
    """*frame* with shape columns for every voyage channel (NaN for dropped ones)."""
    frame = frame.copy()
    for column in shape_columns([c for c in channels if c not in kept]):
        frame[column] = np.nan
    front = [c for c in frame.columns if not str(c).startswith("shape_")]
    return frame[[*front, *shape_columns(channels)]]


def _selected_frame(selected, kept, channels, block, start, end) -> pd.DataFrame:
    frame = selected.reset_index(drop=True).copy()
    frame.insert(0, "block", np.int64(block))
    frame.insert(1, "block_start", start)
    frame.insert(2, "block_end", end)
    frame["block_start"] = pd.to_datetime(frame["block_start"], utc=True)
    frame["block_end"] = pd.to_datetime(frame["block_end"], utc=True)
    return _full_channels(frame, kept, channels)


def _channel_statistics(acceleration: np.ndarray, kept, block, start) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "block": np.int64(block),
            "block_start": pd.to_datetime([start] * len(kept), utc=True),
            "channel": list(kept),
            "rms": np.sqrt(np.nanmean(acceleration**2, axis=0)),
            "kurtosis": scipy_stats.kurtosis(acceleration, axis=0, fisher=False, nan_policy="omit"),
        }
    )


@dataclass
class IdentifyResult:
    """What :func:`identify_voyage` did and wrote."""

    summary: RunSummary
    files: dict[str, Path] = field(default_factory=dict)
    n_blocks: int = 0
    n_selected: int = 0

    def lines(self) -> list[str]:
        out = [str(self.summary)]
        crosscheck = self.files.get("crosscheck")
        if crosscheck is not None:
            from .sid.crosscheck import agreement_lines

            out += agreement_lines(pd.read_csv(crosscheck))
        out += [f"{kind}: {path}" for kind, path in self.files.items()]
        return out


def acceleration_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """Files named by *inputs*: files as given, folders searched (with their subfolders)
    for acceleration files of every supported format (:data:`ACCELERATION_SUFFIXES`)."""
    from data_contracts.formats.text import TEXT_SUFFIXES, looks_like_acceleration_table

    found: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            # hidden files (e.g. ``.name.tmp.npz`` of an interrupted write) are not data
            candidates = sorted(
                p
                for p in path.rglob("*")
                if p.suffix.lower() in ACCELERATION_SUFFIXES
                and not any(part.startswith(".") for part in p.relative_to(path).parts)
                and p.is_file()
            )
            other = [
                p
                for p in candidates
                if p.suffix.lower() in TEXT_SUFFIXES and not looks_like_acceleration_table(p)
            ]
            if other:
                log.info(
                    "%s: %d text file(s) without an acceleration header left out (%s)",
                    path,
                    len(other),
                    ", ".join(p.name for p in other[:5]) + (", ..." if len(other) > 5 else ""),
                )
            found += [p for p in candidates if p not in set(other)]
        elif path.is_file():
            found.append(path)
        else:
            raise WorkbenchError(f"{path}: no such file or folder")
    if not found:
        raise WorkbenchError("no acceleration files found in " + ", ".join(map(str, inputs)))
    return found


def _records(plan) -> list[tuple[pd.Timestamp, pd.Timestamp, list[str]]]:
    """Continuous records of a plan's files: (start, end, file names), split at gaps longer
    than half a sample plus the allowed ``max_gap_s``."""
    rate = plan.sampling_rate_hz
    records: list[tuple[pd.Timestamp, pd.Timestamp, list[str]]] = []
    for info in plan.files:
        if records:
            gap = (info.start_time - records[-1][1]).total_seconds()
            if gap <= plan.max_gap_s + 0.5 / rate:
                records[-1] = (records[-1][0], info.end_time, [*records[-1][2], info.name])
                continue
        records.append((info.start_time, info.end_time, [info.name]))
    return records


def plan_identification(files: Sequence[Path], options: IdentifyOptions):
    """The block plan of *files* and the options resolved for their sampling rate.

    The grid starts at the first sample (blocks lie inside the record from its start).
    Data without a single complete block is an error naming the record, unless
    ``options.short_record == "one-block"``: then a single continuous record shorter than
    a block is identified as one block of its own length.

    Raises
    ------
    WorkbenchError
        Inconsistent files; no complete block (exit 1).
    IdentifyOptionsError
        Options that do not fit the files (band, rate; exit 2).
    """
    from .signals import plan_blocks
    from .signals.stream import _plan

    try:
        plan = plan_blocks(
            files,
            length_s=options.length_s,
            step_s=options.step_s,
            max_gap_s=options.max_gap_s,
            read_options=options.read_options,
        )
        first = plan.files[0].start_time
        if plan.grid.t0 != first:  # anchor the grid at the first sample, not a round time
            grid = BlockGrid(first, options.length_s, options.step_s)
            plan = _plan(plan.files, grid, None, None, options.max_gap_s)
    except OptionError:
        raise
    except ValueError as error:
        raise WorkbenchError(str(error).splitlines()[0]) from None
    options = options.resolved(plan.sampling_rate_hz)
    records = _records(plan)
    short = [r for r in records if (r[1] - r[0]).total_seconds() < options.length_s - 1e-6]
    if not plan.blocks:
        if options.short_record == "one-block" and len(records) == 1:
            start, end, _ = records[0]
            n_samples = sum(info.n_samples for info in plan.files)
            length = n_samples / plan.sampling_rate_hz
            length = math.floor(length * 1e6) / 1e6  # whole microseconds
            options = dataclasses.replace(options, length_s=length, step_s=length)
            try:
                plan = _plan(plan.files, BlockGrid(start, length, length), None, None, 0.0)
            except ValueError as error:
                raise WorkbenchError(str(error)) from None
            return plan, options
        start, end, names = max(records, key=lambda r: r[1] - r[0])
        what = names[0] if len(names) == 1 else f"{names[0]} .. {names[-1]}"
        raise WorkbenchError(
            f"{what}: record of {(end - start).total_seconds() / 60:.2f} min is shorter than "
            f"one block ({options.length_s / 60:g} min): no block to identify; give a shorter "
            "--block-minutes (and --step-minutes), or --short-record one-block"
        )
    for start, end, names in short:
        log.warning(
            "%s: record of %.2f min is shorter than one block (%g min) and is not identified",
            names[0],
            (end - start).total_seconds() / 60,
            options.length_s / 60,
        )
    return plan, options


def input_fingerprints(files) -> list[dict]:
    """Fingerprint of each planned file: path, span, size, mtime and SHA-256 of the content.

    *files* are :class:`~workbench.signals.stream.FileInfo` of a plan. The content hash
    covers every byte (header and samples), so data changed in place with its size and
    modification time kept is still told apart.
    """
    out = []
    for info in files:
        path = Path(info.path)
        try:
            stat = path.stat()
            with open(path, "rb") as handle:
                digest = hashlib.file_digest(handle, "sha256").hexdigest()
        except OSError as error:
            raise WorkbenchError(f"{path}: cannot read ({error.strerror or error})") from None
        out.append(
            {
                "path": str(path.resolve()),
                "start": info.start_time.isoformat(),
                "end": info.end_time.isoformat(),
                "size": int(stat.st_size),
                "mtime_ns": int(stat.st_mtime_ns),
                "sha256": digest,
            }
        )
    return out


def _check_run_options(scheduler, n_workers, batch_blocks) -> None:
    if int(batch_blocks) != batch_blocks or batch_blocks < 1:
        raise OptionError(f"batch_blocks={batch_blocks} must be a whole number of at least 1")
    if n_workers is not None and (int(n_workers) != n_workers or n_workers < 1):
        raise OptionError(f"n_workers={n_workers} must be a whole number of at least 1")
    if scheduler is None or scheduler == "synchronous":
        return
    from urllib.parse import urlsplit

    text = str(scheduler)
    parsed = urlsplit(text if "://" in text else f"tcp://{text}")
    try:
        port = parsed.port
    except ValueError:
        port = None
    if parsed.scheme not in ("tcp", "tls", "inproc", "ucx", "ws", "wss") or not (
        parsed.hostname and port
    ):
        raise OptionError(
            f"scheduler={text!r} must be 'synchronous' or a dask.distributed scheduler "
            "address such as tcp://host:8786"
        )


def identify_voyage(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    store_dir: str | os.PathLike | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: bool = False,
    blocks: Sequence[int] | None = None,
    batch_blocks: int = 16,
) -> IdentifyResult:
    """Identify every block of a voyage's acceleration files; resumable and parallel.

    Parameters
    ----------
    inputs : iterable of path-like
        Acceleration files and/or folders holding them.
    out_dir : path-like
        Where the exported tables go.
    options : IdentifyOptions, optional
    store_dir : path-like, optional
        The per-block store (default ``out_dir / "store"``). Running again with the same
        store resumes; other options than the store's raise :class:`WorkbenchError`.
    scheduler : str, optional
        ``None``: local Dask cluster with *n_workers* processes (default all cores);
        ``"synchronous"``: this process; else a ``dask.distributed`` scheduler address.
    progress : bool
        Progress bar on stderr.
    blocks : sequence of int, optional
        Only these blocks.
    batch_blocks : int
        Blocks written to the store together (also every 30 s); an interruption loses at
        most the blocks of the batch under way.
    """
    options = options or IdentifyOptions()
    _check_run_options(scheduler, n_workers, batch_blocks)
    out = Path(out_dir)
    store_path = Path(store_dir) if store_dir is not None else out / "store"
    for what, path in (("output folder", out), ("store", store_path)):
        if path.exists() and not path.is_dir():
            raise WorkbenchError(f"{path}: {what} is a file, not a folder")
    files = acceleration_files(inputs)
    plan, options = plan_identification(files, options)
    options.check_data(plan)
    grid = plan.grid
    channels = tuple(plan.channels)
    # the analysis rate; decimating blocks are cut from files conditioned once
    options, per_file, parameters = resolved_run(options, plan.sampling_rate_hz, grid, channels)
    with BlockStore.open(store_path, parameters) as store:
        store.check_inputs(input_fingerprints(plan.files))
        wanted = None if blocks is None else {int(b) for b in blocks}
        tasks = _block_tasks(
            plan, [p for p in plan.blocks if wanted is None or int(p.block) in wanted]
        )
        if per_file:
            # each file conditioned once, on any worker, for the blocks holding it
            units = _file_tasks(tasks, plan, options)
            func = functools.partial(
                identify_from_files, grid=grid, channels=channels, options=options
            )
        else:
            units = tasks
            func = functools.partial(identify_block, grid=grid, channels=channels, options=options)
        summary = run_blocks(
            units,
            func,
            store=store,
            scheduler=scheduler,
            n_workers=n_workers,
            total=len(tasks),
            batch_blocks=batch_blocks,
            progress=progress,
            description="identify",
        )
        result = IdentifyResult(summary, n_blocks=len(tasks))
        result.files = export_store(store, out, channels, grid=grid)
    selected = result.files.get("selected")
    if selected is not None:
        result.n_selected = len(pd.read_parquet(selected, columns=["block"]))
    return result


def write_block_figures(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 3,
    blocks: Sequence[int] | None = None,
) -> list[Path]:
    """Stabilisation diagrams (over the CMIF of the block) of a few blocks, as PNG files.

    The blocks are identified again from their files with *options* (the same settings as
    the stored results give the same diagrams); by default *n_blocks* spread evenly over
    the voyage, skipping blocks that cannot be identified.
    """
    from .reporting.stabilisation_plot import write_stabilisation_figure

    plan, tasks, options = _pick_tasks(inputs, options or IdentifyOptions(), n_blocks, blocks)
    paths = []
    for task in tasks:
        try:
            data, result, selection = _identify_data(task, plan.grid, options)
        except ValueError:
            continue
        if result is None:
            continue
        path = Path(out_dir) / f"stabilisation_block{task.block:06d}.png"
        paths.append(
            write_stabilisation_figure(
                result,
                path,
                data.acceleration,
                selection=selection,
                band_hz=options.selection_band(data.sampling_rate_hz),
                title=f"Block {task.block} ({pd.Timestamp(task.block_start):%Y-%m-%d %H:%M} "
                f"UTC), {'LSCF' if options.method == 'lscf' else 'SSI-' + options.method}",
            )
        )
    return paths


def _pick_tasks(inputs, options: IdentifyOptions, n_blocks: int, blocks):
    """Plan, resolved options and the tasks of *blocks*, or of *n_blocks* identifiable
    blocks spread evenly."""
    plan, options = plan_identification(acceleration_files(inputs), options)
    planned = [p for p in plan.blocks if not p.skipped_reason]
    if blocks is None:
        picks = np.unique(np.linspace(0, len(planned) - 1, max(n_blocks, 1)).round().astype(int))
        chosen = [planned[k] for k in picks] if planned else []
    else:
        wanted = {int(b) for b in blocks}
        chosen = [p for p in planned if int(p.block) in wanted]
    tasks = _block_tasks(plan, chosen)
    return plan, tasks, options


def cross_check_blocks(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 6,
    blocks: Sequence[int] | None = None,
) -> pd.DataFrame:
    """SSI/LSCF cross-check of a few blocks, written to ``out_dir/crosscheck.csv``.

    Each block is identified with *options* (its method) and with the other family (LSCF
    for SSI, SSI-cov for LSCF) and the selected modes are paired
    (:func:`workbench.sid.crosscheck.cross_check`). For every block of a voyage, run
    :func:`identify_voyage` with ``cross_check=True`` instead. Returns the table (empty if
    no block could be identified); :func:`workbench.sid.crosscheck.agreement_lines` and
    :func:`~workbench.sid.crosscheck.agreement_by_block` summarise it.
    """
    from threadpoolctl import threadpool_limits

    from .sid.crosscheck import CROSS_CHECK_COLUMNS

    options = options or IdentifyOptions()
    plan, tasks, options = _pick_tasks(inputs, options, n_blocks, blocks)
    frames = []
    for task in tasks:
        try:
            with threadpool_limits(limits=1):
                _, result, selection, *other = _identify_data(task, plan.grid, options, cross=True)
        except ValueError:
            continue
        if result is None or other[0] is None:
            continue
        frames.append(
            _cross_check_frame(selection, other[0][1], options.method, task.block, task.block_start)
        )
    columns = ["block", "block_start", *CROSS_CHECK_COLUMNS[1:]]
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_grid_sidecar(_write_csv(table, out / "crosscheck.csv"), plan.grid)
    return table


def write_tpe_figures(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 3,
    blocks: Sequence[int] | None = None,
) -> list[Path]:
    """Stabilisation diagram of SSI-data with the total prediction error of every model
    order beside it (:func:`workbench.sid.tpe.total_prediction_error`), for a few blocks.

    SSI-data is used whatever *options.method* says (the TPE needs its Kalman gain), with
    the block rows, orders, weighting and references of *options*.
    """
    import dataclasses

    from .reporting.tpe_plot import write_stabilisation_tpe_figure
    from .sid.tpe import total_prediction_error

    options = dataclasses.replace(options or IdentifyOptions(), method="data", cross_check=False)
    plan, tasks, options = _pick_tasks(inputs, options, n_blocks, blocks)
    paths = []
    for task in tasks:
        try:
            data, result, selection = _identify_data(task, plan.grid, options)
            if result is None:
                continue
            errors = total_prediction_error(
                data.acceleration,
                data.sampling_rate_hz,
                block_rows=options.block_rows,
                orders=options.orders,
                reference_channels=result.reference_channels,
                weighting=options.weighting,
            )
        except ValueError:
            continue
        path = Path(out_dir) / f"tpe_block{task.block:06d}.png"
        paths.append(
            write_stabilisation_tpe_figure(
                result,
                errors,
                path,
                data.acceleration,
                selection=selection,
                band_hz=options.selection_band(data.sampling_rate_hz),
                title=f"Block {task.block} ({pd.Timestamp(task.block_start):%Y-%m-%d %H:%M} "
                f"UTC), SSI-data/{options.weighting}",
            )
        )
    return paths


def export_store(
    store: BlockStore,
    out_dir: str | os.PathLike,
    channels: Sequence[str],
    *,
    grid: BlockGrid | None = None,
):
    """Write the store's results as tables in *out_dir*; return them by kind.

    Poles and selected modes are streamed chunk by chunk into one Parquet file each (rows in
    block order), so exporting a voyage of any length needs the memory of one chunk. Every
    table records the block *grid* (Parquet metadata, or a ``<name>.grid.json`` sidecar
    beside the CSV files; see :mod:`data_contracts.grid`).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for kind, sort, name, contract in (
        ("poles", ["block", "model_order", "frequency_hz"], "poles.parquet", POLES),
        ("selected", ["block", "frequency_hz"], "selected.parquet", SELECTED),
    ):
        chunks = (
            chunk.sort_values(sort, kind="stable").reset_index(drop=True)
            for chunk in store.read_chunks(kind, blocks_per_chunk=64)
        )
        path = _write_parquet_chunks(chunks, out / name, contract, grid=grid)
        if path is not None:
            files[kind] = path
    for kind in ("faults", "channels", "crosscheck", "blocks"):
        table = store.read(kind)
        if kind == "blocks" and not table.empty:
            table = table.sort_values("block", kind="stable")
        if not table.empty or kind == "blocks":
            files[kind] = _write_csv(table.reset_index(drop=True), out / f"{kind}.csv")
            write_grid_sidecar(files[kind], grid)
    return files


def _write_parquet_chunks(chunks, path: Path, contract=None, *, grid=None) -> Path | None:
    """Stream DataFrame chunks into one Parquet file (validated per chunk), atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    writer = None
    schema = None
    try:
        with atomic_path(path) as tmp:
            try:
                for chunk in chunks:
                    if contract is not None:
                        chunk = contract.validate(chunk)
                    table = pa.Table.from_pandas(chunk, preserve_index=False, schema=schema)
                    if writer is None:
                        schema = table.schema
                        if grid is not None:
                            schema = schema.with_metadata(metadata_with_grid(schema.metadata, grid))
                        writer = pq.ParquetWriter(tmp, schema)
                    writer.write_table(table)
            finally:
                if writer is not None:
                    writer.close()
            if writer is None:
                raise _NothingWritten
    except _NothingWritten:
        return None
    return path


class _NothingWritten(Exception):
    pass


def _write_csv(frame: pd.DataFrame, path: Path) -> Path:
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, date_format="%Y-%m-%dT%H:%M:%S.%fZ")
    return path
