"""Block length by conditions (``identify --block-minutes auto``).

A fixed block length trades two errors: a long block averages the estimation scatter
down (SSI's frequency variance falls roughly as 1/length) but smears what changes inside
it, and SSI does not even read the block's mean then: it reads the block weighted toward
its strongly excited part (a block in which the ship speeds up from 0 to 10 kn reads the
faster, lower-frequency end). :func:`plan_block_lengths` picks, for every block, the
longest length at which the block looks stationary, from what is known before any
identification:

* the excitation: the conditioned channels' power (median over channels of the variance)
  in every half-step; the block's *excitation range* is the ratio of its largest to its
  smallest half-step power in dB (ice breaking: strong and intermittent, a range of
  several dB within minutes; calm open water: a fraction of a dB);
* the ship's speed from the log (frequencies follow it through the added water mass):
  the range of the half-step means over the block;
* the log's state where known (``cases``: ice, transit, station, ...): a block does not
  straddle a change of state.

Every block ``k`` is centred at ``t0 + step / 2 + k step`` and is an odd number of steps
long: 5, 15, 25 or 35 min with the default 5-min step. The step stays the file period
of a typical recorder (5 min): with the centres in the middle of a step and odd lengths,
every block is a whole number of steps (of whole files, when the files are a step long),
so no block cuts a file in two and the shortest block is exactly the fixed 5-min grid's
block. A step tied to the length would put blocks at irregular times, which the
tracking's and the forecast's block indexing does not take: with one step, block numbers
are regular times whatever each block's length, only the spans (``block_start`` /
``block_end``) differ. The lengths grow by two steps (x3, x5, x7 the shortest): each
longer block adds the same time on either side, and SSI's frequency scatter falls
roughly as one over the square root of the length, so the longest steady length is taken.

:func:`identify_adaptive` runs the identification once per length on the blocks that
chose it (each length a grid of its own, shifted so the centres agree, and a store of its
own so a rerun resumes) and merges the tables. The merged tables record the grid with
``"varying_length": true`` (:mod:`data_contracts.grid`) and carry ``block_length_s``,
``excitation_range_db`` and ``speed_range_kn``; ``excitation.csv`` keeps the half-steps'
excitation power (and speed), from which the predictors can be averaged as SSI reads a
block (``--excitation`` of the commands taking ``--dship``;
:func:`~workbench.predictors.averaging.excitation_weighted_predictors`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import OptionError, WorkbenchError
from ..store import block_ranges

__all__ = [
    "AdaptiveBlockOptions",
    "block_conditions",
    "decision_span",
    "half_step_grid",
    "half_step_power",
    "half_step_speeds",
    "identify_adaptive",
    "last_block",
    "length_grid",
    "plan_block_lengths",
]

_NS = 1_000_000_000


@dataclass(frozen=True)
class AdaptiveBlockOptions:
    """Limits and thresholds of the adaptive block length.

    Attributes
    ----------
    min_length_s, max_length_s : float
        Shortest and longest block. [s]
    step_s : float
        Step between block centres (block ``k`` is centred at ``t0 + step_s / 2 + k *
        step_s``); the lengths are the odd multiples of ``step_s`` within the limits. [s]
    max_excitation_range_db : float
        Largest excitation range of a stationary block (ratio of its largest to its
        smallest half-step power). [dB]
    max_speed_range_kn : float
        Largest range of the half-step mean speeds of a stationary block. [kn]
    """

    min_length_s: float = 300.0
    max_length_s: float = 2400.0
    step_s: float = 300.0
    max_excitation_range_db: float = 3.0
    max_speed_range_kn: float = 1.0

    def __post_init__(self) -> None:
        for name in ("min_length_s", "max_length_s", "step_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise OptionError(f"{name}={value!r} must be a positive number of seconds")
        if self.min_length_s < self.step_s:
            raise OptionError(
                f"min_length_s={self.min_length_s:g} must be at least step_s={self.step_s:g}"
            )
        if self.max_length_s < self.min_length_s:
            raise OptionError(
                f"max_length_s={self.max_length_s:g} must be at least "
                f"min_length_s={self.min_length_s:g}"
            )
        if self.max_length_s > 15 * self.step_s:
            raise OptionError(
                f"max_length_s={self.max_length_s:g} must be at most 15 x step_s "
                f"({15 * self.step_s:g}; at most 8 lengths)"
            )
        if not any(
            self.min_length_s * (1 - 1e-9) <= n * self.step_s <= self.max_length_s * (1 + 1e-9)
            for n in range(1, 16, 2)
        ):
            raise OptionError(
                f"min_length_s={self.min_length_s:g} .. max_length_s={self.max_length_s:g} "
                f"holds no odd multiple of step_s={self.step_s:g}"
            )
        for name in ("max_excitation_range_db", "max_speed_range_kn"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise OptionError(f"{name}={value!r} must be a positive number")

    def lengths(self) -> tuple[float, ...]:
        """The candidate lengths (odd multiples of the step), longest first. [s]"""
        return tuple(
            float(n * self.step_s)
            for n in range(15, 0, -2)
            if self.min_length_s * (1 - 1e-9) <= n * self.step_s <= self.max_length_s * (1 + 1e-9)
        )


def block_conditions(plan, options, *, dship=None, unreadable=None) -> pd.DataFrame:
    """Excitation (and speed) of every half-step of a planned voyage.

    Parameters
    ----------
    plan : BlockPlan
        The voyage's plan (:func:`~workbench.identification.planning.plan_identification`);
        its grid's ``t0`` is the first sample.
    options : IdentifyOptions
        Resolved options: the half-steps are conditioned as the blocks are (decimation,
        band-pass, channel check).
    dship : DataFrame, optional
        Canonical ship log (:func:`data_contracts.read_dship`); gives ``speed_kn``.
    unreadable : dict, optional
        Given: a file whose samples cannot be read leaves the half-steps that need it
        unbuilt (NaN power: no block spans them) and is added here (path as given ->
        :class:`~workbench.errors.UnreadableInputError`); without it, such a file raises.

    Returns
    -------
    DataFrame
        ``start``, ``end`` (UTC), ``power`` (median over the kept channels of the
        variance, [(m/s²)²]; NaN for a half-step that could not be built) and
        ``speed_kn`` (NaN without a log).
    """
    from ..signals import iter_blocks
    from .engine import conditioning_options

    rows = []
    for block in iter_blocks(
        plan.files,  # the headers as planned: not read again
        grid=half_step_grid(plan.files[0].start_time, plan.grid.step_s),
        options=conditioning_options(options),
        unreadable=unreadable,
    ):
        rows.append(
            {"start": block.block_start, "end": block.block_end, "power": half_step_power(block)}
        )
    table = pd.DataFrame(rows, columns=["start", "end", "power"])
    table["speed_kn"] = half_step_speeds(table, dship)
    return table


def half_step_grid(t0, step_s: float):
    """The grid of the half-steps whose conditions decide the lengths: half-step ``j``
    covers ``[t0 + j step_s / 2, t0 + (j + 1) step_s / 2)``."""
    from ..blocks import BlockGrid

    return BlockGrid(pd.Timestamp(t0), step_s / 2.0, step_s / 2.0)


def length_grid(t0, length_s: float, step_s: float):
    """The grid of the blocks *length_s* long: block ``k`` centred at ``t0 + step_s / 2 +
    k step_s`` as on every length's grid (its ``t0`` shifted by ``(step_s - length_s) /
    2``), so a block's number does not depend on its length."""
    from ..blocks import BlockGrid

    start = pd.Timestamp(t0) + pd.Timedelta(seconds=(step_s - length_s) / 2)
    return BlockGrid(start, float(length_s), float(step_s))


def half_step_power(block) -> float:
    """Excitation power of one conditioned half-step (an ``AccelerationBlock``): the
    median over the kept channels of the variance, NaN when it could not be built.
    [(m/s²)²]"""
    if block.acceleration is None or not block.acceleration.size:
        return math.nan
    with np.errstate(invalid="ignore"):
        return float(np.nanmedian(np.nanvar(block.acceleration, axis=0)))


def half_step_speeds(table: pd.DataFrame, dship=None) -> np.ndarray:
    """The log's mean speed over each half-step of *table* (``start``, ``end``), as
    :func:`~workbench.predictors.block_predictors` averages it (half the span covered at
    least); NaN without a log or a ``speed_kn`` column. [kn]"""
    speed = np.full(len(table), np.nan)
    if dship is None or not len(table) or "speed_kn" not in dship.columns:
        return speed
    from ..predictors import PredictorWarning, block_predictors

    spans = pd.DataFrame(
        {
            "block": np.arange(len(table)),
            "block_start": pd.to_datetime(table["start"], utc=True),
            "block_end": pd.to_datetime(table["end"], utc=True),
        }
    )
    log = dship[["time", "speed_kn"]]
    with warnings.catch_warnings():  # the speed is all it needs of the log
        warnings.simplefilter("ignore", PredictorWarning)
        averaged = block_predictors(log, blocks=spans, min_coverage=0.5)
    return averaged["speed_kn"].to_numpy(dtype=float)


def decision_span(block: int, options: AdaptiveBlockOptions) -> tuple[int, int]:
    """Half-steps (from ``t0``) that decide block *block*'s length: ``first`` to ``end``
    (excluded), its longest candidate span, clipped at the start of the data (a live run
    decides the block once they are known, :mod:`workbench.monitor.adaptive`). ``first``
    is even: the blocks from ``first // 2`` on keep their numbers on a plan that starts at
    half-step ``first``."""
    centre_half = 1 + 2 * int(block)  # (step / 2 + k step) / (step / 2)
    half_width = int(round(max(options.lengths()) / options.step_s))  # odd: 2L/step / 2
    return max(0, centre_half - half_width), centre_half + half_width


def last_block(n_half: int, options: AdaptiveBlockOptions) -> int:
    """The last block whose shortest span ends inside *n_half* half-steps of data (-1:
    none)."""
    # block k's centre in half-steps from t0: (step / 2 + k step) / half
    return math.floor(
        (n_half * options.step_s / 2 - min(options.lengths()) / 2 - options.step_s / 2)
        / options.step_s
        + 1e-9
    )


def plan_block_lengths(
    conditions: pd.DataFrame,
    t0,
    options: AdaptiveBlockOptions | None = None,
    *,
    cases: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """The length of every block from the conditions of its half-steps.

    Parameters
    ----------
    conditions : DataFrame
        Half-steps of :func:`block_conditions` (``start``, ``end``, ``power``,
        ``speed_kn``), consecutive from *t0*.
    t0 : time-like
        Start of the data (block ``k`` is centred at ``t0 + step / 2 + k step``).
    options : AdaptiveBlockOptions, optional
    cases : DataFrame, optional
        The log's states: ``case``, ``start``, ``end`` (UTC); a block does not straddle a
        change of state.

    Returns
    -------
    DataFrame
        ``block``, ``block_start``, ``block_end``, ``block_length_s``,
        ``excitation_range_db``, ``speed_range_kn`` (NaN without speeds): per block the
        longest candidate length inside the data whose span is stationary (excitation
        range and speed range within the limits, one state), else the shortest; blocks
        where not even the shortest fits in the data, or with a half-step that could not
        be built in every candidate span, are left out.
    """
    options = options or AdaptiveBlockOptions()
    start0 = pd.Timestamp(t0)
    start0 = start0.tz_localize("UTC") if start0.tzinfo is None else start0.tz_convert("UTC")
    half_ns = int(round(options.step_s / 2 * _NS))
    n_half = len(conditions)
    if n_half == 0:
        return _empty_plan()
    power = conditions["power"].to_numpy(dtype=float)
    speed = conditions["speed_kn"].to_numpy(dtype=float)
    state = np.zeros(n_half, dtype=np.int64)
    if cases is not None and len(cases):
        mid = pd.to_datetime(conditions["start"], utc=True) + pd.Timedelta(
            seconds=options.step_s / 4
        )
        starts = pd.to_datetime(cases["start"], utc=True)
        ends = pd.to_datetime(cases["end"], utc=True)
        for number, (a, b) in enumerate(zip(starts, ends, strict=True), start=1):
            state[((mid >= a) & (mid < b)).to_numpy()] = number
    lengths = options.lengths()
    centre_offset = options.step_s / 2
    last = last_block(n_half, options)
    rows = []
    for k in range(max(last + 1, 0)):
        centre_half = (centre_offset + k * options.step_s) / (options.step_s / 2)
        chosen = None
        for length in lengths:
            width = length / (options.step_s / 2)
            lo, hi = centre_half - width / 2, centre_half + width / 2
            if abs(lo - round(lo)) > 1e-9 or lo < 0 or hi > n_half + 1e-9:
                continue
            lo, hi = int(round(lo)), int(round(hi))
            span_power = power[lo:hi]
            if not np.all(np.isfinite(span_power)) or np.any(span_power <= 0):
                continue
            excitation = 10.0 * math.log10(span_power.max() / span_power.min())
            span_speed = speed[lo:hi]
            speed_range = (
                float(np.nanmax(span_speed) - np.nanmin(span_speed))
                if np.isfinite(span_speed).any()
                else math.nan
            )
            candidate = (length, lo, hi, excitation, speed_range)
            steady = (
                excitation <= options.max_excitation_range_db
                and not (speed_range > options.max_speed_range_kn)
                and np.unique(state[lo:hi]).size == 1
            )
            if steady or length == min(lengths):
                # a longer span holds the shorter ones (same centre): if the shortest
                # does not fit (a gap), none does and the block is left out
                chosen = candidate
                break
        if chosen is not None:
            length, lo, hi, excitation, speed_range = chosen
            rows.append(
                {
                    "block": k,
                    "block_start": start0 + pd.Timedelta(lo * half_ns, unit="ns"),
                    "block_end": start0 + pd.Timedelta(hi * half_ns, unit="ns"),
                    "block_length_s": float(length),
                    "excitation_range_db": float(excitation),
                    "speed_range_kn": speed_range,
                }
            )
    if not rows:
        return _empty_plan()
    return pd.DataFrame(rows)


def _empty_plan() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "block": pd.Series([], dtype="int64"),
            "block_start": pd.Series([], dtype="datetime64[ns, UTC]"),
            "block_end": pd.Series([], dtype="datetime64[ns, UTC]"),
            "block_length_s": pd.Series([], dtype=float),
            "excitation_range_db": pd.Series([], dtype=float),
            "speed_range_kn": pd.Series([], dtype=float),
        }
    )


def _read_cases(cases) -> pd.DataFrame | None:
    if cases is None or isinstance(cases, pd.DataFrame):
        return cases
    path = Path(cases)
    try:
        table = pd.read_csv(path)
    except (OSError, ValueError) as error:
        raise WorkbenchError(f"{path}: cannot read the cases table ({error})") from None
    missing = [c for c in ("case", "start", "end") if c not in table.columns]
    if missing:
        raise WorkbenchError(f"{path}: cases table lacks column(s) {', '.join(missing)}")
    try:
        table["start"] = pd.to_datetime(table["start"], utc=True)
        table["end"] = pd.to_datetime(table["end"], utc=True)
    except (TypeError, ValueError) as error:
        raise WorkbenchError(f"{path}: start/end are not times ({error})") from None
    return table


def _missed_line(plan, first: pd.Timestamp, adaptive: AdaptiveBlockOptions) -> str:
    """The line naming the blocks whose span a drifting record's samples hold on their
    count but whose shortest span runs past its first or last sample in UTC (no length
    of theirs is planned: :func:`~workbench.signals.block_plan.missed_blocks`); ""
    when none. Each length's run names only its own blocks, which it identifies."""
    from ..signals.block_plan import missed_blocks, missed_blocks_line, placed_block_numbers

    grid = length_grid(first, adaptive.lengths()[-1], adaptive.step_s)
    listed = placed_block_numbers(plan.files, grid).tolist()
    return missed_blocks_line(missed_blocks(plan.files, grid, plan.sampling_rate_hz, listed))


def identify_adaptive(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options,
    adaptive: AdaptiveBlockOptions | None = None,
    store_dir: str | os.PathLike | None = None,
    dship=None,
    dship_mapping=None,
    cases=None,
    **run,
):
    """Identify every block of a voyage with its own length (see the module notes).

    Parameters
    ----------
    inputs, out_dir, options, store_dir, dship, dship_mapping
        As :func:`~workbench.identification.voyage.identify_voyage` takes them
        (*options*' ``length_s`` / ``step_s`` are replaced by each length and
        ``adaptive.step_s``).
    adaptive : AdaptiveBlockOptions, optional
    cases : path or DataFrame, optional
        The log's states (``case``, ``start``, ``end``).
    **run
        Passed on to :func:`~workbench.identification.voyage.identify_voyage`
        (scheduler, n_workers, progress, batch_blocks, keep_removed_inputs, harmonics).

    Returns
    -------
    IdentifyResult
        Summed over the lengths; ``files`` are the merged tables in *out_dir*.
    """
    from ..parallel import RunSummary
    from .planning import _file_list, acceleration_files, follow_on_starts, plan_identification
    from .voyage import IdentifyResult, _ship_log, identify_voyage

    adaptive = adaptive or AdaptiveBlockOptions()
    out = Path(out_dir)
    store_root = Path(store_dir) if store_dir is not None else out / "store"
    files = acceleration_files(inputs)
    options = follow_on_starts(files, options)
    reference = dataclasses.replace(options, length_s=adaptive.step_s, step_s=adaptive.step_s)
    # files that cannot be read are left out: their headers fail here, their samples when
    # the half-steps are conditioned (no block then spans them)
    unreadable: dict[str, str] = {}
    plan, resolved = plan_identification(files, reference, unreadable=unreadable)
    first = plan.files[0].start_time
    log = _ship_log(dship, dship_mapping)
    failed: dict = {}
    conditions = block_conditions(plan, resolved, dship=log, unreadable=failed)
    unreadable.update({name: error.detail for name, error in failed.items()})
    lengths = plan_block_lengths(conditions, first, adaptive, cases=_read_cases(cases))
    if lengths.empty:
        names = list(unreadable)
        damaged = (
            f"{_file_list(names)}: unreadable ({unreadable[names[0]]}), left out; then "
            if names
            else ""
        )
        raise WorkbenchError(
            f"{damaged}{plan.files[0].name}: no block of {adaptive.min_length_s / 60:g} min "
            "or more could be built from the data"
        )
    left_out = _unreadable_left_out(files, plan, unreadable, failed, lengths, adaptive)
    parts = []
    groups = []
    for length, group in lengths.groupby("block_length_s", sort=True):
        label = f"{length / 60:g}min"
        grid_t0 = length_grid(first, length, adaptive.step_s).t0
        part = identify_voyage(
            files,
            out / "by_length" / label,
            options=dataclasses.replace(options, length_s=float(length), step_s=adaptive.step_s),
            store_dir=store_root / label,
            blocks=group["block"].tolist(),
            dship=log,
            dship_mapping=dship_mapping,
            grid_t0=grid_t0,
            unreadable=unreadable,
            warn_unreadable=False,
            **run,
        )
        parts.append(part)
        groups.append(set(group["block"].tolist()))
    grid = {
        "t0": first,
        "length_s": adaptive.step_s,
        "step_s": adaptive.step_s,
        "varying_length": True,
    }
    merged = _merge_tables([p.files for p in parts], out, lengths, grid, groups, left_out)
    from .export import _write_csv

    merged["excitation"] = _write_csv(conditions, out / "excitation.csv")
    summary = RunSummary(
        processed=sum(p.run.processed for p in parts),
        skipped=sum(p.run.skipped for p in parts),
        already_done=sum(p.run.already_done for p in parts),
        skip_reasons=_summed(p.run.skip_reasons for p in parts),
        notes=_summed(p.run.notes for p in parts),
        seconds=sum(p.run.seconds for p in parts),
    )
    result = IdentifyResult(summary, files=merged, n_blocks=sum(p.n_blocks for p in parts))
    result.warnings = list(dict.fromkeys(n for p in parts for n in p.warnings))
    for name in dict.fromkeys(str(f) for f in files):
        if name in unreadable:
            blocks = left_out.loc[left_out["reason"].str.startswith(f"{name}: "), "block"]
            result.warnings.append(
                f"{name}: unreadable ({unreadable[name]}); left out"
                + (f": block(s) {block_ranges(blocks)} not identified" if len(blocks) else "")
            )
    result.notes = list(dict.fromkeys(n for p in parts for n in p.notes))
    missed = _missed_line(plan, first, adaptive)
    if missed:
        result.notes.append(missed)
    counts = lengths["block_length_s"].value_counts().sort_index()
    result.notes.insert(
        0,
        "block lengths (auto): "
        + ", ".join(f"{n} x {length / 60:g} min" for length, n in counts.items()),
    )
    selected = merged.get("selected")
    if selected is not None:
        result.n_selected = len(pd.read_parquet(selected, columns=["block"]))
    return result


def _unreadable_left_out(files, plan, unreadable, failed, lengths, adaptive) -> pd.DataFrame:
    """The blocks left out of *lengths* because a file of *unreadable* lies in their
    shortest span, as rows of ``blocks.csv`` (``block``, ``block_start`` of that span,
    ``status`` skipped, ``reason`` naming the file).

    A file whose samples fail (*failed*) spans what its header says; one whose header
    fails lies in its place among the files
    (:func:`~workbench.identification.voyage.unreadable_places`).
    """
    from .voyage import unreadable_places

    spans = {
        str(info.path): (info.start_time, info.end_time)
        for info in plan.files
        if str(info.path) in failed
    }
    spans.update(unreadable_places(files, plan, unreadable))
    shortest = min(adaptive.lengths())
    centre0 = plan.files[0].start_time + pd.Timedelta(seconds=adaptive.step_s / 2)
    end = plan.files[-1].end_time + pd.Timedelta(seconds=0.5 / plan.sampling_rate_hz)
    chosen = set(lengths["block"].tolist())
    rows = []
    k = 0
    while spans:
        centre = centre0 + pd.Timedelta(seconds=k * adaptive.step_s)
        low = centre - pd.Timedelta(seconds=shortest / 2)
        high = centre + pd.Timedelta(seconds=shortest / 2)
        if high > end:
            break
        if k not in chosen:
            name = next((n for n, (a, b) in spans.items() if low < b and high > a), None)
            if name is not None:
                rows.append(
                    {
                        "block": k,
                        "block_start": low,
                        "status": "skipped",
                        "reason": f"{name}: unreadable ({unreadable[name]})",
                    }
                )
        k += 1
    return pd.DataFrame(rows, columns=["block", "block_start", "status", "reason"])


def _summed(mappings) -> dict:
    total: dict = {}
    for mapping in mappings:
        for key, value in mapping.items():
            total[key] = total.get(key, 0) + value
    return total


_ADAPTIVE_COLUMNS = ("block_length_s", "excitation_range_db", "speed_range_kn")


def _merge_tables(
    parts: list[dict],
    out: Path,
    lengths: pd.DataFrame,
    grid: dict,
    groups: list[set] | None = None,
    left_out: pd.DataFrame | None = None,
) -> dict:
    """The tables of every length merged into *out* (rows in block order), with the
    blocks' length and stationarity, recorded with the *grid* of varying length.

    *groups* (one per part): the blocks that chose that part's length now; a part's rows
    of other blocks (stored by an earlier run that gave them that length) are left out.
    *left_out*: rows added to ``blocks.csv`` (blocks no length was given, and why)."""
    from data_contracts import POLES, SELECTED
    from data_contracts.tables import write_grid_sidecar

    from .export import _write_csv, _write_parquet_chunks

    measures = lengths.set_index("block")[list(_ADAPTIVE_COLUMNS)]
    files: dict[str, Path] = {}
    kinds = sorted({kind for part in parts for kind in part})
    for kind in kinds:
        if kind == "harmonics":
            continue
        frames = []
        for k, part in enumerate(parts):
            path = part.get(kind)
            if path is None or path.stat().st_size <= 1:
                continue
            frame = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
            if groups is not None and "block" in frame.columns:
                frame = frame[frame["block"].isin(groups[k])]
            frames.append(frame)
        if kind == "blocks" and left_out is not None and len(left_out):
            rows = left_out.copy()
            rows["block_start"] = rows["block_start"].dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
            frames.append(rows)
        if not frames:
            continue
        frame = pd.concat(frames, ignore_index=True)
        if "block" in frame.columns:
            frame = frame.sort_values(
                [c for c in ("block", "model_order", "frequency_hz") if c in frame.columns],
                kind="stable",
            ).reset_index(drop=True)
            if kind in ("selected", "blocks"):
                for column in _ADAPTIVE_COLUMNS:
                    frame[column] = measures[column].reindex(frame["block"]).to_numpy()
        if kind == "selected" and "harmonic_checked" in frame.columns:
            # a length none of whose blocks the log covers has no marks checked (and no
            # column): its blocks are not checked
            frame["harmonic_checked"] = frame["harmonic_checked"].fillna(False).astype(bool)
        if kind in ("selected", "poles"):
            contract = SELECTED if kind == "selected" else POLES
            path = _write_parquet_chunks([frame], out / f"{kind}.parquet", contract, grid=grid)
            if path is not None:
                files[kind] = path
        else:
            files[kind] = _write_csv(frame, out / f"{kind}.csv")
            write_grid_sidecar(files[kind], grid)
    return files
