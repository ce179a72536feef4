"""File discovery and planning: acceleration files of a voyage, their blocks, the
fingerprints of the inputs and the resolved options and store parameters of a run."""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..blocks import BlockGrid
from ..errors import OptionError, WorkbenchError
from .engine import _block_tasks
from .options import IdentifyOptions, analysis_rate

log = logging.getLogger("workbench")


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


def acceleration_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """:func:`data_contracts.formats.acceleration_files`, a missing input or an empty
    search reported as a :class:`~workbench.errors.WorkbenchError` (one line, exit 1)."""
    from data_contracts.formats import acceleration_files as find_files

    try:
        return find_files(inputs)
    except FileNotFoundError as error:
        raise WorkbenchError(str(error)) from None


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


def follow_on_starts(files: Sequence[Path], options: IdentifyOptions) -> IdentifyOptions:
    """*options* with one start time given for several files resolved per file.

    A start time (``--start-time``) stands for the first sample of the first file, in the
    order the files are found (names sorted). A file whose times are relative (or that has
    no time column) and restart at 0 follows the previous file without a gap; one whose
    relative times continue (a second file starting at 300 s) keeps its offset from the
    start when that lies after the previous file's end. Files with absolute times of their
    own (ISO-8601 column, ``.npz``, a MATLAB ``t0``) keep them. Each file is read once
    more for this (only when one start time is given for several files). A file that
    cannot be read is passed over: the next follows the one before it, as without it.
    """
    from data_contracts import ContractError, read_accelerations

    layout = dict(options.acceleration_layout or {})
    given = layout.get("start_time")
    if len(files) < 2 or given in (None, "filename") or layout.get("file_starts"):
        return options
    zero = pd.Timestamp(given)
    zero = zero.tz_localize("UTC") if zero.tzinfo is None else zero.tz_convert("UTC")
    own = {k: v for k, v in layout.items() if k != "start_time"}
    starts: dict[str, str] = {}
    previous_end = None
    first_error = ""
    for path in files:
        try:
            record = read_accelerations(path, layout=own)
        except ContractError:
            record = None  # needs the given start: relative times or no time column
        if record is None:
            try:
                record = read_accelerations(path, layout=layout)
            except ContractError as error:
                first_error = first_error or error.lines()[0]
                continue  # unreadable: the planner leaves it out and names it
            first = record.start_time
            if previous_end is not None and first < previous_end:
                first = previous_end  # restarted relative times: follow on
            starts[str(Path(path).resolve())] = (zero + (first - record.start_time)).isoformat()
            record_end = first + record.duration
        else:
            record_end = record.end_time
        previous_end = record_end if previous_end is None else max(previous_end, record_end)
    if previous_end is None and first_error:  # no file read: the layout, not one file
        raise WorkbenchError(first_error)
    if not starts:
        return options
    layout["file_starts"] = starts
    return replace(options, acceleration_layout=layout)


def _file_list(paths: Sequence[str]) -> str:
    """``a.npz`` or ``3 files (a.npz .. c.npz)``."""
    return paths[0] if len(paths) == 1 else f"{len(paths)} files ({paths[0]} .. {paths[-1]})"


def readable_file_infos(
    files: Sequence[Path], read_options, unreadable: dict[str, str] | None
) -> list:
    """Headers of *files* (:func:`~workbench.signals.block_plan.read_file_info`).

    With *unreadable* (a dict), a file whose header cannot be read is left out and added
    there (its path as given -> why, one line without the file's name); without it, such
    a file raises. When no file can be read the error names them (exit 1).
    """
    from ..errors import UnreadableInputError
    from ..signals.block_plan import read_file_info

    if unreadable is None:
        return [read_file_info(f, read_options=read_options) for f in files]
    infos = []
    for path in files:
        try:
            infos.append(read_file_info(path, read_options=read_options))
        except (OSError, ValueError, KeyError, EOFError) as error:
            if isinstance(error, OptionError):
                raise
            unreadable[str(path)] = UnreadableInputError.of(path, error).detail
    if files and not infos:
        names = list(unreadable)
        raise WorkbenchError(
            f"{_file_list(names)}: unreadable ({unreadable[names[0]]}); no acceleration "
            "file can be read, nothing identified"
        )
    return infos


def plan_identification(
    files: Sequence[Path],
    options: IdentifyOptions,
    *,
    grid_t0=None,
    unreadable: dict[str, str] | None = None,
):
    """The block plan of *files* and the options resolved for their sampling rate.

    The grid starts at the first sample (blocks lie inside the record from its start), or
    at *grid_t0* when given (the grids of :mod:`~workbench.identification.adaptive`).
    Data without a single complete block is an error naming the record, unless
    ``options.short_record == "one-block"``: then a single continuous record shorter than
    a block is identified as one block of its own length.

    *unreadable* (a dict) leaves out the files whose header cannot be read, adding them
    there (path as given -> why): the plan is that of the other files, as if those were
    not there (:func:`readable_file_infos`). Without it such a file is an error.

    A file at another sampling rate than most files have, and an exact duplicate, are
    left out too (:func:`~workbench.signals.block_plan.sort_out_files`), named with why in
    the plan's ``left_out`` (:func:`left_out_notes`); files split between rates with no
    majority are an error.

    Raises
    ------
    WorkbenchError
        Inconsistent files; no complete block (exit 1); no file readable.
    IdentifyOptionsError
        Options that do not fit the files (band, rate; exit 2).
    """
    try:
        return _plan_identification(files, options, grid_t0=grid_t0, unreadable=unreadable)
    except WorkbenchError as error:
        left_out = list(unreadable or ())
        if not left_out or str(error).startswith(_file_list(left_out)):
            raise
        # what is left without the unreadable files gives no block: name them first
        raise WorkbenchError(
            f"{_file_list(left_out)}: unreadable ({unreadable[left_out[0]]}), left out; "
            f"then {error}"
        ) from None


def _plan_identification(files, options, *, grid_t0, unreadable):
    from ..signals.block_plan import sort_out_files

    try:
        infos = readable_file_infos(files, options.read_options, unreadable)
        infos, left_out = sort_out_files(infos)
    except OptionError:
        raise
    except ValueError as error:
        raise WorkbenchError(str(error).splitlines()[0]) from None
    try:
        plan, options = _plan_files(infos, options, grid_t0=grid_t0)
    except WorkbenchError as error:
        if not left_out:
            raise
        # what is left without those files gives no block: name them first
        path, why = left_out[0]
        more = f" (and {len(left_out) - 1} more)" if len(left_out) > 1 else ""
        raise WorkbenchError(f"{path}: not used ({why}){more}; then {error}") from None
    return dataclasses.replace(plan, left_out=left_out), options


def left_out_notes(plan) -> list[str]:
    """One line per file of *plan* that could not belong to the record (another sampling
    rate, a duplicate: :func:`~workbench.signals.block_plan.sort_out_files`), as the
    monitor says it."""
    return [f"{Path(path).name}: not used: {why}" for path, why in plan.left_out]


def _plan_files(infos, options, *, grid_t0):
    from ..signals.block_plan import lacking_channels, plan_file_infos

    try:
        plan = plan_file_infos(
            infos,
            length_s=options.length_s,
            step_s=options.step_s,
            max_gap_s=options.max_gap_s,
        )
        first = plan.files[0].start_time if grid_t0 is None else pd.Timestamp(grid_t0)
        if plan.grid.t0 != first:  # anchor the grid at the first sample, not a round time
            grid = BlockGrid(first, options.length_s, options.step_s)
            plan = plan_file_infos(plan.files, grid, max_gap_s=options.max_gap_s)
    except OptionError:
        raise
    except ValueError as error:
        raise WorkbenchError(str(error).splitlines()[0]) from None
    options = options.resolved(plan.sampling_rate_hz)
    lattice = options.decimation_factor(plan.sampling_rate_hz)
    if lattice > 1 and any(b.drifting for b in plan.blocks):
        # a drifting record's blocks cut on the analysis lattice (the file conditioner
        # cuts its decimated files there)
        plan = plan_file_infos(plan.files, plan.grid, max_gap_s=options.max_gap_s, lattice=lattice)
    for missing, names in lacking_channels(plan.files, plan.channels).items():
        what = names[0] if len(names) == 1 else f"{len(names)} files ({names[0]} .. {names[-1]})"
        log.warning(
            "%s: channel(s) %s missing; NaN there, dropped as faulty in the blocks holding it",
            what,
            ", ".join(missing),
        )
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
                plan = plan_file_infos(plan.files, BlockGrid(start, length, length))
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
    if short and len(short) == len(records) and all(b.skipped_reason for b in plan.blocks):
        start, end, names = max(records, key=lambda r: r[1] - r[0])
        gaps = [
            ((later[0] - earlier[1]).total_seconds(), earlier[2][-1], later[2][0])
            for earlier, later in zip(records, records[1:], strict=False)
        ]
        gap = (
            f", split by gaps longer than the allowed {options.max_gap_s:g} s (the first: "
            f"{gaps[0][0]:.1f} s between {gaps[0][1]} and {gaps[0][2]})"
            if gaps
            else ""
        )
        raise WorkbenchError(
            f"{records[0][2][0]} .. {records[-1][2][-1]}: each of the {len(records)} records"
            f"{gap} is shorter than one block ({options.length_s / 60:g} min; the longest "
            f"{(end - start).total_seconds() / 60:.2f} min): no block to identify; give a "
            "shorter --block-minutes (and --step-minutes) or a larger --max-gap"
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

    *files* are :class:`~workbench.signals.block_plan.FileInfo` of a plan. The content hash
    covers every byte (header and samples), so data changed in place with its size and
    modification time kept is still told apart. The files are hashed on one thread per
    core (hashlib releases the GIL while it hashes), in the order given; a file hashed
    ahead by the entry point and unchanged since keeps that digest
    (:mod:`workbench.fingerprints`).
    """
    from ..fingerprints import stop_prefetch

    stop_prefetch()  # its digests so far are kept; no thread may outlive this into a fork
    files = list(files)
    if len(files) < 2:
        return [_fingerprint(info) for info in files]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=min(len(files), os.cpu_count() or 1)) as pool:
        return list(pool.map(_fingerprint, files))


def _fingerprint(info) -> dict:
    from ..fingerprints import sha256

    path = Path(info.path)
    try:
        stat = path.stat()
        digest = sha256(path)
    except OSError as error:
        raise WorkbenchError(f"{path}: cannot read ({error.strerror or error})") from None
    return {
        "path": str(path.resolve()),
        "start": info.start_time.isoformat(),
        "end": info.end_time.isoformat(),
        "size": int(stat.st_size),
        "mtime_ns": int(stat.st_mtime_ns),
        "sha256": digest,
    }


def _pick_tasks(inputs, options: IdentifyOptions, n_blocks: int, blocks):
    """Plan, resolved options and the tasks of *blocks*, or of *n_blocks* identifiable
    blocks spread evenly (files that cannot be read left out, as identify leaves them)."""
    plan, options = plan_identification(acceleration_files(inputs), options, unreadable={})
    planned = [p for p in plan.blocks if not p.skipped_reason]
    if blocks is None:
        picks = np.unique(np.linspace(0, len(planned) - 1, max(n_blocks, 1)).round().astype(int))
        chosen = [planned[k] for k in picks] if planned else []
    else:
        wanted = {int(b) for b in blocks}
        chosen = [p for p in planned if int(p.block) in wanted]
    tasks = _block_tasks(plan, chosen)
    return plan, tasks, options
