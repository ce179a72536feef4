"""The per-block engine: one block's data conditioned and identified (per block, or cut
from files conditioned once), and the rows it adds to the store."""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from data_contracts import shape_columns

from ..blocks import BlockGrid
from ..parallel import BlockOutcome
from ..signals.block_builder import BLANKED_NOTE_END, ConditioningOptions
from ..signals.moments import ChannelCheckOptions
from .options import IdentifyOptions


@dataclass(frozen=True)
class BlockTask:
    """One block to identify (picklable: sent to the workers and to
    :func:`identify_block`; the live monitor builds one per ready block).

    ``infos`` are the planned headers of ``files`` (:class:`~workbench.signals.FileInfo`),
    so a worker does not read every file once more to plan the block (for a CSV file that
    is a whole parse per block holding it).
    """

    block: int
    block_start: pd.Timestamp
    files: tuple
    infos: tuple = ()
    #: Why the voyage's plan skips the block (a gap between two files it names), or "".
    skipped: str = ""
    #: Placed time of the block's first sample where it is cut on a drifting record's
    #: clock line (``PlannedBlock.sample_start``, ``drifting``), else None.
    sample_start: pd.Timestamp | None = None


def _block_tasks(plan, planned) -> list[BlockTask]:
    """Tasks of the *planned* blocks of *plan*, with their files' headers."""
    header = {info.path: info for info in plan.files}
    return [
        BlockTask(
            int(p.block),
            p.block_start,
            tuple(str(f) for f in p.files),
            tuple(header[Path(f)] for f in p.files if Path(f) in header),
            p.skipped_reason,
            p.sample_start if p.drifting else None,
        )
        for p in planned
    ]


def _identify_data(
    task: BlockTask,
    grid: BlockGrid,
    options: IdentifyOptions,
    cross=False,
    conditioner=None,
    channels: Sequence[str] | None = None,
):
    """Conditioned block, SSI or LSCF result (None if skipped) and mode selection of one
    block; with *cross*, also the result and selection of the other method (or None).

    *conditioner* (a :class:`~workbench.signals.file_conditioning.FileConditioner`) gives
    the block from files conditioned once; without it the block is built from its files.
    """
    from ..signals import PlannedBlock, load_block

    if conditioner is not None:
        planned = PlannedBlock(
            task.block,
            task.block_start,
            grid.end(task.block),
            tuple(map(Path, task.files)),
            sample_start=task.sample_start,
            drifting=task.sample_start is not None,
        )
        data = conditioner.block(planned)
    else:
        infos = getattr(task, "infos", ())  # planned headers: no file read to plan again
        data = load_block(
            infos if len(infos) == len(task.files) else task.files,
            task.block,
            grid,
            options=conditioning_options(options),
            channels=channels,
            sample_start=task.sample_start,
        )
    if data.acceleration is None:
        return _with_planned_reason(data, getattr(task, "skipped", "")), None, None
    kept = list(data.channels)
    if len(kept) < 2:
        raise ValueError(f"block {task.block}: only {len(kept)} good channel(s) left")
    reference = _reference_columns(options, kept, task.block)
    result, selection = _identify_method(options.method, data, reference, options)
    if not cross:
        return data, result, selection
    other = "cov" if options.method == "lscf" else "lscf"
    try:
        checked = _identify_method(other, data, reference, options)
    except (ValueError, np.linalg.LinAlgError):
        checked = None  # the block's own result stands; it just has no cross-check
    return data, result, selection, checked


#: How the reason of a block skipped for data missing begins: the block builder, which
#: sees the block's own files only, names the data's start or end where the voyage's plan
#: names the files on either side of the gap.
_MISSING_DATA = (
    "gap of ",
    "no data (gap ",
    "no acceleration files",
    "outside the span of the acceleration files",
)


def _with_planned_reason(data, planned: str):
    """*data* (a skipped block) with the reason of the voyage's plan when both say data is
    missing (the plan knows the files beyond the block, the builder only the block's)."""
    if not (planned and data.skipped_reason.startswith(_MISSING_DATA)):
        return data
    if not planned.startswith(_MISSING_DATA) or planned == data.skipped_reason:
        return data
    notes = tuple(
        f"skipped: {planned}" if note == f"skipped: {data.skipped_reason}" else note
        for note in data.notes
    )
    return dataclasses.replace(data, skipped_reason=planned, notes=notes)


def _reference_columns(options: IdentifyOptions, kept: Sequence[str], block: int):
    """Columns of the reference channels among the block's *kept* channels (None: all)."""
    if not options.reference_channels:
        return None
    reference = [kept.index(c) for c in options.reference_channels if c in kept]
    if not reference:
        raise ValueError(f"block {block}: no reference channel left")
    return reference


#: Each half of a block is identified at every HALF_ORDER_STEP-th order of the upper half
#: of the block's model orders (a physical mode's column is longest there), enough to find
#: the modes the block already selected without a stabilisation diagram of its own. [-]
HALF_ORDER_STEP = 2
#: A half's pole belongs to a selected mode when within this relative frequency of it ... [-]
HALF_FREQUENCY_TOL = 0.02
#: ... with a MAC of at least this with its shape (the pairing of the combined model). [-]
HALF_MAC = 0.8
#: Fewest model orders at which a half shows the mode. [-]
HALF_MIN_ORDERS = 2


def half_differences(method: str, data, reference, options: IdentifyOptions, selection, whole=None):
    """f₁ - f₂ of every selected mode: its frequency in the first and in the second half of
    the block [Hz] (NaN where a half does not show it, and for LSCF).

    The two halves are independent records of the same structure, each with twice the
    block's variance of the frequency estimate (that variance goes as 1 / length), so
    E[(f₁ - f₂)²] / 4 is the variance of the block's own estimate, measured from the block
    itself and not from a model of how the modes move: the forecast's yardstick for how far
    its estimate may lie from SSI (:mod:`workbench.forecasting.ssi_guard`). A mode that
    moves inside the block adds its move between the halves, so the yardstick errs on the
    large side there. Each half's frequency is the median, over the orders that show it, of
    the pole nearest the mode within :data:`HALF_FREQUENCY_TOL` with a MAC of at least
    :data:`HALF_MAC` and a damping ratio within the selection's limits.

    *whole*, the block's SSI-cov result (with its ``output_correlations``), lets the halves
    start from the block's lagged products
    (:func:`~workbench.sid.ssi.covariance_driven.ssi_cov_halves`: one FFT pass instead of
    two, no system matrices or stability flags): the same poles up to rounding
    (``benchmarks/results/halves_cost_40.txt``). Without it each half runs
    :func:`~workbench.sid.ssi_cov` (or :func:`~workbench.sid.ssi_data`) on its own.
    """
    from ..sid import ssi_cov, ssi_data
    from ..sid.ssi.covariance_driven import ssi_cov_halves

    modes = selection.modes
    out = np.full(len(modes), np.nan)
    if method not in ("cov", "data") or not len(modes):
        return out
    n = data.acceleration.shape[0]
    orders = _reachable_orders(options, len(data.channels), len(reference or data.channels))
    orders = orders[len(orders) // 2 :: HALF_ORDER_STEP]
    if not orders:
        return out
    ssi = {"block_rows": options.block_rows, "orders": orders, "reference_channels": reference}
    correlations = getattr(whole, "output_correlations", None)
    try:
        if method == "cov" and correlations is not None:
            halves = ssi_cov_halves(data.acceleration, data.sampling_rate_hz, correlations, **ssi)
        else:
            halves = []
            for part in (slice(0, n // 2), slice(n // 2, None)):
                if method == "cov":
                    result = ssi_cov(data.acceleration[part], data.sampling_rate_hz, **ssi)
                else:
                    result = ssi_data(
                        data.acceleration[part],
                        data.sampling_rate_hz,
                        **ssi,
                        weighting=options.weighting,
                    )
                halves.append(_half_poles(result))
    except (ValueError, np.linalg.LinAlgError):
        return out
    f_mode = modes["frequency_hz"].to_numpy(dtype=float)
    found = [
        _half_frequencies(f_mode, selection.mode_shapes, half, options.damping_limits)
        for half in halves
    ]
    return found[0] - found[1]


def _half_poles(result):
    """The pole columns :func:`_half_frequencies` reads, from an :class:`SSIResult`."""
    from types import SimpleNamespace

    poles = result.poles
    return SimpleNamespace(
        model_order=poles["model_order"].to_numpy(),
        frequency_hz=poles["frequency_hz"].to_numpy(dtype=float),
        damping_ratio=poles["damping_ratio"].to_numpy(dtype=float),
        mode_shapes=result.mode_shapes,
    )


def _half_frequencies(f_mode, mode_shapes, poles, damping_limits) -> np.ndarray:
    """Frequency of each mode (*f_mode*, shapes *mode_shapes*) in one half's *poles*
    (``model_order``, ``frequency_hz``, ``damping_ratio``, ``mode_shapes``): the median over
    orders of the nearest pole within :data:`HALF_FREQUENCY_TOL`, of usable damping and
    MAC >= :data:`HALF_MAC`; NaN with fewer than :data:`HALF_MIN_ORDERS` orders."""
    from ..sid.assurance import mac

    f = poles.frequency_hz
    zeta = poles.damping_ratio
    order = poles.model_order
    low, high = damping_limits
    found = np.full(len(f_mode), np.nan)
    usable = np.flatnonzero((zeta >= low) & (zeta <= high))
    # (pole, mode) pairs within the frequency tolerance; MAC only for those
    pole, mode = np.nonzero(np.abs(f[usable, None] / f_mode[None, :] - 1.0) < HALF_FREQUENCY_TOL)
    if not pole.size:
        return found
    pole = usable[pole]
    cross = mac(mode_shapes, poles.mode_shapes[:, np.unique(pole)])
    column = np.searchsorted(np.unique(pole), pole)
    keep = cross[mode, column] >= HALF_MAC
    pole, mode = pole[keep], mode[keep]
    # per (mode, order) the pole nearest the mode (the first of equals, in pole order)
    rank = np.lexsort((pole, np.abs(f[pole] - f_mode[mode]), order[pole], mode))
    pole, mode = pole[rank], mode[rank]
    first = np.ones(pole.size, dtype=bool)
    first[1:] = (mode[1:] != mode[:-1]) | (order[pole[1:]] != order[pole[:-1]])
    pole, mode = pole[first], mode[first]
    for i in np.unique(mode):
        picks = f[pole[mode == i]]
        if picks.size >= HALF_MIN_ORDERS:
            found[i] = float(np.median(picks))
    return found


def _identify_method(
    method: str, data, reference, options: IdentifyOptions, *, confirm: bool = True
):
    """Result of *method* on a conditioned block, stabilised, and its mode selection.

    The modes the selection's second look added are kept only when the same method on
    either half of the block confirms them (*confirm*, :func:`_confirmed_by_halves`): SSI
    (``cov``, ``data``) and LSCF alike.
    """
    from ..sid import select_modes, ssi_cov, ssi_data, stabilise
    from ..sid.plscf import lscf

    n_channels = len(data.channels)
    orders = _reachable_orders(options, n_channels, len(reference or range(n_channels)))
    ssi = {"block_rows": options.block_rows, "orders": orders, "reference_channels": reference}
    if method == "cov":
        result = ssi_cov(data.acceleration, data.sampling_rate_hz, **ssi)
    elif method == "data":
        result = ssi_data(
            data.acceleration, data.sampling_rate_hz, **ssi, weighting=options.weighting
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
        # pLSCF's over-fitted orders pull its poles: its modes are read from the orders
        # where the column agrees with itself
        frequency_from="consistent_orders" if method == "lscf" else "all_orders",
    )
    if confirm and selection.thresholds.get("second_look"):
        selection = _confirmed_by_halves(method, data, reference, options, selection)
    return result, selection


def _confirmed_by_halves(method: str, data, reference, options: IdentifyOptions, selection):
    """*selection* without the second-look modes that neither half of the block confirms.

    Each half of the block is an independent record of the same structure: a mode the
    second look found (a close or weakly excited mode) shows in at least one of them, a
    column of the estimator's own on this record does not
    (:func:`~workbench.sid.selection.confirmed_second_look`: a mode of a half nearer to it
    than to any other mode of the block, within 1 % - or half the distance to its nearest
    neighbour, at most 3 %, for a mode that moves inside the block - and MAC >= 0.8). SSI
    and LSCF alike (the spurious modes before and after, on the simulated close and weak
    modes of ``benchmarks/bench_close_weak.py``: ``benchmarks/results/identification_32e.txt``).
    The halves cannot judge a column the estimator puts into every record of the block's
    length (pLSCF's second pole of a strong resonance): the second look leaves those out by
    their shape (:func:`~workbench.sid.selection._shape_of_its_own`;
    ``identification_32f.txt``). Only blocks whose second look added a mode pay for the two
    half-length identifications. A half that cannot be identified (too short for the block
    rows) confirms nothing; with neither half the selection stands.
    """
    from types import SimpleNamespace

    from ..sid.selection import confirmed_second_look

    n = data.acceleration.shape[0]
    halves = []
    for part in (slice(0, n // 2), slice(n // 2, None)):
        half = SimpleNamespace(
            acceleration=data.acceleration[part],
            sampling_rate_hz=data.sampling_rate_hz,
            channels=data.channels,
        )
        try:
            halves.append(_identify_method(method, half, reference, options, confirm=False)[1])
        except (ValueError, np.linalg.LinAlgError):
            continue
    return confirmed_second_look(selection, halves)


def conditioning_band(options: IdentifyOptions):
    """Band-pass edges ``(low, high)`` [Hz] for the file conditioning of *options*, or
    None without a band: a lower edge of 0 means no high-pass (``low`` None)."""
    if not isinstance(options.band_hz, tuple):
        return None
    low, high = options.band_hz
    return (low if low > 0 else None, high)


def channel_check_options(options: IdentifyOptions) -> ChannelCheckOptions:
    """The channel check of *options* (every check off when ``channel_check`` is
    disabled)."""
    if not options.channel_check:
        return ChannelCheckOptions(
            max_nan_fraction=1.0,
            max_nan_run_s=math.inf,
            kurtosis_limits=(0.0, math.inf),
            flat_variance=-1.0,
            max_variance_z=math.inf,
        )
    return ChannelCheckOptions(**dict(options.fault_options))


def conditioning_options(options: IdentifyOptions) -> ConditioningOptions:
    """How *options* condition a block's accelerations, one object for every path that
    builds blocks (from their files, each file conditioned once, the adaptive block
    length's half-steps, the monitor)."""
    return ConditioningOptions(
        target_rate_hz=options.target_rate_hz,
        band_hz=conditioning_band(options),
        channel_check=channel_check_options(options),
        max_gap_s=options.max_gap_s,
        read_options=options.read_options,
    )


def _reachable_orders(options: IdentifyOptions, n_channels: int, n_reference: int):
    """The model orders a block with these channels can give: max order <= min(r·i,
    l·(i-1)) (r reference channels, l channels, i block rows). Channels dropped by the
    check must not make every block fail for orders chosen for the full set."""
    top = min(n_reference * options.block_rows, n_channels * (options.block_rows - 1))
    orders = tuple(o for o in options.orders if o <= top)
    return orders if len(orders) >= 2 else options.orders


def identify_block(
    task: BlockTask,
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
    from ..sid.threads import single_threaded

    # One BLAS thread per block, in workers and in-process alike: the parallelism is over
    # blocks, and the same arithmetic everywhere makes results bit-identical whatever the
    # scheduler (a resumed job may mix blocks computed either way).
    with single_threaded():
        data, result, selection, *other = _identify_data(
            task,
            grid,
            options,
            cross=options.cross_check,
            conditioner=conditioner,
            channels=channels,
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
    # a file's channels its reader set to NaN (infinite or implausible values), said once
    # a run with the file and why, then the channels' drops
    notes = tuple(n for n in data.notes if n.endswith(BLANKED_NOTE_END))
    notes += tuple(f"channel {c} dropped ({_reason_kind(r)})" for c, r in data.dropped)
    if result is None:
        return BlockOutcome(
            task.block, start, {"faults": faults}, skipped=data.skipped_reason, notes=notes
        )
    kept = list(data.channels)
    poles = _full_channels(result.poles_frame(kept, block=task.block), kept, channels)
    modes = selection.modes_frame(kept)
    with single_threaded():
        modes["half_difference_hz"] = half_differences(
            options.method,
            data,
            _reference_columns(options, kept, task.block),
            options,
            selection,
            whole=result,
        )
    if other and other[0] is not None:
        modes = _with_combined(modes, selection, other[0][1], options.method)
    selected_frame = _selected_frame(modes, kept, channels, task.block, start, end)
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


#: Columns the combined modal model adds to the selected table (see
#: :func:`~workbench.sid.combined.combine_modes`).
COMBINED_SELECTED_COLUMNS = {
    "frequency_hz": "combined_frequency_hz",
    "frequency_std_hz": "combined_frequency_std_hz",
    "damping_ratio": "combined_damping_ratio",
    "damping_std": "combined_damping_std",
    "n_methods": "combined_methods",
}


def _with_combined(modes: pd.DataFrame, selection, other_selection, method) -> pd.DataFrame:
    """The block's selected *modes* with the combined estimate of this method and the other
    family (:func:`~workbench.sid.combined.combine_modes`): ``combined_frequency_hz``,
    ``combined_frequency_std_hz``, ``combined_damping_ratio``, ``combined_damping_std`` and
    ``combined_methods`` (1 where the other method has no such mode; all five missing
    where the combined model leaves the mode out: a second-look mode of this method that
    the other does not confirm)."""
    from ..sid.combined import combine_modes

    own = "lscf" if method == "lscf" else "ssi"
    other = "ssi" if own == "lscf" else "lscf"
    combined = combine_modes({own: selection, other: other_selection})
    combined = combined[combined[f"{own}_mode"] >= 0].set_index(f"{own}_mode")
    modes = modes.copy()
    for source, column in COMBINED_SELECTED_COLUMNS.items():
        values = combined[source].reindex(range(len(modes)))
        if source == "n_methods":
            modes[column] = pd.array(values.to_numpy(dtype=float), dtype="Int64")
        else:
            modes[column] = values.to_numpy(dtype=float)
    return modes


def _cross_check_frame(selection, other_selection, method, block, start) -> pd.DataFrame:
    """The SSI and LSCF modes of one block paired (:func:`~workbench.sid.crosscheck.
    cross_check`), with ``block_start``."""
    from ..sid.crosscheck import cross_check

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
    #: As :attr:`BlockTask.sample_start`.
    sample_start: pd.Timestamp | None = None
    #: Cuts of drifting blocks inside ``window`` (``FileConditioner``'s *cuts*). [ns]
    cuts: tuple = ()


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
    from ..signals.file_conditioning import FileConditioner

    if not task.window:  # a planned block without files: the per-block path says why
        return identify_block(task, grid=grid, channels=channels, options=options)
    conditioner = FileConditioner(
        task.window, grid, channels, options=conditioning_options(options), cuts=task.cuts
    )
    conditioner.reuse(conditioned or {})
    return identify_block(
        task, grid=grid, channels=channels, options=options, conditioner=conditioner
    )


def _file_tasks(tasks: Sequence[BlockTask], plan, options: IdentifyOptions) -> list[_FileTask]:
    """*tasks* as blocks cut from files conditioned once, each file's conditioning shared
    by the blocks holding it."""
    from ..parallel import SharedInput
    from ..signals.file_conditioning import (
        FileConditioning,
        block_cuts,
        condition_file,
        cuts_within,
    )

    position = {info.path: i for i, info in enumerate(plan.files)}
    # a drifting record's blocks start and end off the grid's steps: the files' step
    # sums are split there too (the same cuts for a file wherever it is conditioned)
    cuts = block_cuts(plan.blocks)
    conditioning = conditioning_options(options)
    channels = tuple(plan.channels)
    jobs: dict[int, SharedInput] = {}
    out = []
    for task in tasks:
        used = sorted(position[Path(f)] for f in task.files)
        if not used:
            out.append(
                _FileTask(task.block, task.block_start, task.files, sample_start=task.sample_start)
            )
            continue
        for i in used:
            if i not in jobs:
                lo = max(i - 1, 0)
                job = FileConditioning(
                    tuple(plan.files[lo : i + 2]),
                    i - lo,
                    plan.grid,
                    channels,
                    conditioning,
                    cuts_within(cuts, plan.files[i : i + 1]),
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
                task.sample_start,
                cuts_within(cuts, plan.files[lo:hi]),
            )
        )
    return out


def _reason_kind(reason: str) -> str:
    """The kind of a fault reason without its numbers (for summary counts), e.g.
    ``"nan fraction 1.00 > 0.05"`` -> ``"nan fraction"``, ``"flat (variance 0)"`` ->
    ``"flat (variance)"`` (a parenthesis the cut opened is closed)."""
    words = []
    for word in reason.split():
        if any(ch.isdigit() for ch in word) or word in (">", "<", "=", "%"):
            break
        words.append(word)
    kind = " ".join(words)
    return kind + ")" * (kind.count("(") - kind.count(")")) or "faulty"


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
    if np.isnan(acceleration).any():
        rms = np.sqrt(np.nanmean(acceleration**2, axis=0))
        kurtosis = scipy_stats.kurtosis(acceleration, axis=0, fisher=False, nan_policy="omit")
    else:
        rms, kurtosis = _rms_and_kurtosis(acceleration)
    return pd.DataFrame(
        {
            "block": np.int64(block),
            "block_start": pd.to_datetime([start] * len(kept), utc=True),
            "channel": list(kept),
            "rms": rms,
            "kurtosis": kurtosis,
        }
    )


def _rms_and_kurtosis(acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RMS and kurtosis (Pearson's) of each column of a block without NaN: the numbers of
    ``np.sqrt(np.nanmean(x**2, axis=0))`` and ``scipy.stats.kurtosis(x, axis=0,
    fisher=False)``, the same operations in the same order (to the last bit; tested), with
    the deviations from the mean and their squares computed once for both moments
    instead of once per moment."""
    square = acceleration**2
    rms = np.sqrt(np.mean(square, axis=0))
    mean = np.mean(acceleration, axis=0, keepdims=True)
    deviation = np.subtract(acceleration, mean, out=square)  # the squares are done with
    with np.errstate(divide="ignore", invalid="ignore"):
        precision = np.max(np.abs(deviation), axis=0, keepdims=True) / np.abs(mean)
    if acceleration.shape[0] > 1 and np.any(precision < np.finfo(float).eps * 10):
        warnings.warn(
            "Precision loss occurred in moment calculation due to catastrophic cancellation. "
            "This occurs when the data are nearly identical. Results may be unreliable.",
            RuntimeWarning,
            stacklevel=2,
        )
    np.square(deviation, out=deviation)
    m2 = np.mean(deviation, axis=0)
    np.square(deviation, out=deviation)
    m4 = np.mean(deviation, axis=0)
    mean = mean[0]
    with np.errstate(all="ignore"):
        zero = m2 <= (np.finfo(m2.dtype).eps * mean) ** 2
        kurtosis = np.where(zero, np.nan, m4 / m2**2.0)
    return rms, kurtosis
