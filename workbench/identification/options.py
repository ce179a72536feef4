"""Options of block-wise identification: :class:`IdentifyOptions`, its error, and the
analysis rate they resolve to for a set of files."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Literal

from data_contracts.limits import MAX_LSCF_ORDER, MAX_MODEL_ORDER

from ..blocks import MAX_BLOCKS_PER_SAMPLE
from ..errors import OptionError
from ..signals.moments import ChannelCheckOptions


def _orders(name: str, values, highest: int) -> tuple[int, ...]:
    """*values* as a tuple of orders in [1, *highest*]; the count is checked before the
    tuple is built (a ``range(1, 10**12)`` would exhaust memory)."""
    try:
        count = len(values)
    except TypeError:
        count = None
    if count is not None and count > highest:
        raise OptionError(f"{name}: {count} orders given; orders lie in 1..{highest}")
    orders = tuple(int(o) for o in values)
    if not orders or min(orders) < 1 or max(orders) > highest:
        shown = f"{min(orders)}..{max(orders)}" if orders else "none"
        raise OptionError(f"{name}={shown} must be model orders in 1..{highest}")
    return orders


#: Lower damping limit of the automatic selection (harmonics have ζ ≈ 0). [-]
_LOWEST_DAMPING = 0.001


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
        and pair the selected modes of both (``crosscheck.csv``); the selected table then
        carries their combined estimate and its uncertainty (``combined_*`` columns,
        :func:`~workbench.sid.combined.combine_modes`).
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
        Thresholds of the channel check that differ from the defaults, fields of
        :class:`~workbench.signals.moments.ChannelCheckOptions`, e.g.
        ``(("kurtosis_limits", (1.3, 10.0)),)``.
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
        lscf_orders = _orders("lscf_orders", self.lscf_orders, MAX_LSCF_ORDER)
        object.__setattr__(self, "lscf_orders", lscf_orders)
        if int(self.block_rows) != self.block_rows or self.block_rows < 2:
            raise OptionError(f"block_rows={self.block_rows} must be an integer of at least 2")
        object.__setattr__(self, "orders", _orders("orders", self.orders, MAX_MODEL_ORDER))
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
        if self.length_s > MAX_BLOCKS_PER_SAMPLE * self.step_s:
            raise OptionError(
                f"step_s={self.step_s:g} puts every sample in "
                f"{self.length_s / self.step_s:.3g} blocks of {self.length_s:g} s; at most "
                f"{MAX_BLOCKS_PER_SAMPLE}: give a step of at least "
                f"{self.length_s / MAX_BLOCKS_PER_SAMPLE:g} s (block length / "
                f"{MAX_BLOCKS_PER_SAMPLE})"
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
        try:  # a mistyped threshold fails here, not in the middle of a voyage
            ChannelCheckOptions(**dict(self.fault_options))
        except TypeError as error:
            raise OptionError(f"fault_options: {error}") from None
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
            # a high-pass corner below one cycle per block removes nothing a block can hold
            # and is numerically degenerate (a corner 1e-9 of the rate: singular fits)
            lowest = 1.0 / float(self.length_s)
            if 0 < self.band_hz[0] < lowest:
                raise OptionError(
                    f"band_hz=({self.band_hz[0]:g}, {self.band_hz[1]:g}): the lower edge must "
                    f"be 0 (a low-pass) or at least one cycle per block, {lowest:.3g} Hz for "
                    f"{float(self.length_s) / 60:g}-min blocks"
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
        """Keyword arguments of :func:`data_contracts.read_accelerations`: the layout, and
        infinite or implausible values in some channels taken as those channels' faults
        in the file (set to NaN: dropped from the blocks holding it, said in their notes)."""
        layout = {"layout": dict(self.acceleration_layout)} if self.acceleration_layout else {}
        return {**layout, "glitches": "blank"}

    def decimation_factor(self, sampling_rate_hz: float) -> int:
        """Raw samples per analysis sample of resolved options at *sampling_rate_hz*
        (1 without decimation): the lattice a drifting record's blocks are cut on."""
        if self.target_rate_hz in (None, "auto"):
            return 1
        return max(1, round(float(sampling_rate_hz) / float(self.target_rate_hz)))

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


def analysis_rate(options: IdentifyOptions, sampling_rate_hz: float) -> float:
    """The rate blocks are identified at, for files at *sampling_rate_hz*. [Hz]

    ``target_rate_hz="auto"`` follows the band's upper edge
    (:func:`~workbench.signals.file_conditioning.default_decimation_rate`: the files' rate
    halved while it stays at or above 4 x the edge). With the band left to ``"auto"`` (then
    derived from the rate itself) or None, the edge is :data:`DEFAULT_MODE_CEILING_HZ`, so
    2048-Hz files are analysed at 128 Hz, 256 Hz at 128 Hz and 64 Hz at 64 Hz.
    """
    from ..signals.filter_cascade import default_decimation_rate

    if options.target_rate_hz is None:
        return float(sampling_rate_hz)
    if options.target_rate_hz == "auto":
        if isinstance(options.band_hz, tuple):
            band = options.band_hz
        else:
            band = (None, DEFAULT_MODE_CEILING_HZ)
        return default_decimation_rate(sampling_rate_hz, band)
    return float(options.target_rate_hz)
