"""Block-wise system identification of a voyage: files -> poles and selected modes per block.

:func:`identify_voyage` plans the blocks of a set of acceleration files (reading only file
headers), runs :func:`identify_block` on every block not yet done - in parallel with Dask,
on all local cores or on an existing cluster - into a resumable :class:`~workbench.store.
BlockStore`, and exports the store as contract tables:

* ``poles.parquet`` - stabilisation diagrams (POLES contract), one row per pole, block and
  model order, with mode shapes;
* ``selected.parquet`` - the automatically selected modes of each block (input of
  ``workbench track``);
* ``faults.csv`` - channels dropped per block and why;
* ``channels.csv`` - per block and channel: RMS and kurtosis of the conditioned signal;
* ``blocks.csv`` - every block: ``ok`` or ``skipped`` and the reason.

Killing the job at any moment and running it again finishes it without recomputing the
blocks already stored, and gives the same tables as an uninterrupted run (every block's
result depends only on its own data and the options, which the store checks).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from data_contracts import POLES, atomic_path, shape_columns

from .blocks import BlockGrid
from .errors import WorkbenchError
from .parallel import BlockOutcome, RunSummary, run_blocks
from .store import BlockStore

__all__ = [
    "IdentifyOptions",
    "IdentifyResult",
    "identify_block",
    "identify_voyage",
    "write_block_figures",
]

#: Acceleration file suffixes picked up from a folder (CSV acceleration files must be named
#: one by one: a voyage folder also holds CSV tables that are not accelerations).
ACCELERATION_SUFFIXES = (".npz", ".mat")


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of block-wise identification (all stored with the results).

    Attributes
    ----------
    method : {"cov", "data"}
        Covariance-driven or data-driven SSI.
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
    band_hz : (float, float), optional
        Zero-phase band-pass after decimation; also the band of the automatic selection.
        [Hz]
    max_gap_s : float
        Gaps between files up to this length inside a block are NaN-padded. [s]
    frequency_tol, damping_tol, mac_min : float
        Stability criteria between consecutive orders (relative frequency change, relative
        damping change, lowest MAC).
    max_damping : float
        Poles with larger damping ratios are not selected. [-]
    conditioning : {"per-file", "per-block"}
        When decimating: condition each file once and cut the blocks from the conditioned
        files (default), or build every block from its raw files (the reference path, four
        times the work for 75 % overlap; equal in the blocks' interior, see
        :mod:`workbench.signals.file_conditioning`).
    """

    method: Literal["cov", "data"] = "cov"
    block_rows: int = 20
    orders: tuple[int, ...] = tuple(range(4, 61, 2))
    weighting: Literal["pc", "upc", "cva"] = "pc"
    reference_channels: tuple[str, ...] | None = None
    length_s: float = 1200.0
    step_s: float = 300.0
    target_rate_hz: float | Literal["auto"] | None = "auto"
    band_hz: tuple[float, float] | None = (2.0, 12.0)
    max_gap_s: float = 0.0
    frequency_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.98
    max_damping: float = 0.10
    conditioning: Literal["per-file", "per-block"] = "per-file"

    def __post_init__(self) -> None:
        if self.conditioning not in ("per-file", "per-block"):
            raise ValueError(
                f"conditioning={self.conditioning!r} must be 'per-file' or 'per-block'"
            )
        if self.method not in ("cov", "data"):
            raise ValueError(f"method={self.method!r} must be 'cov' or 'data'")
        if self.block_rows < 2:
            raise ValueError(f"block_rows={self.block_rows} must be at least 2")
        orders = tuple(int(o) for o in self.orders)
        if not orders or min(orders) < 1:
            raise ValueError(f"orders={self.orders!r} must be positive model orders")
        object.__setattr__(self, "orders", orders)
        if self.target_rate_hz is not None and self.target_rate_hz != "auto":
            rate = float(self.target_rate_hz)
            if not rate > 0:
                raise ValueError(
                    f"target_rate_hz={self.target_rate_hz!r} must be a positive rate, "
                    "'auto' or None"
                )
            object.__setattr__(self, "target_rate_hz", rate)
        if self.band_hz is not None:
            low, high = (float(v) for v in self.band_hz)
            if not 0 <= low < high:
                raise ValueError(f"band_hz={self.band_hz!r} must be (low, high) with low < high")
            object.__setattr__(self, "band_hz", (low, high))

    def parameters(self) -> dict:
        """JSON-able form (what the store records and checks on resume)."""
        values = asdict(self)
        values["orders"] = list(self.orders)
        values["band_hz"] = list(self.band_hz) if self.band_hz else None
        values["reference_channels"] = (
            list(self.reference_channels) if self.reference_channels else None
        )
        return values


@dataclass(frozen=True)
class _Task:
    """One block to identify (picklable: sent to the workers)."""

    block: int
    block_start: pd.Timestamp
    files: tuple


def _identify_data(task: _Task, grid: BlockGrid, options: IdentifyOptions, conditioner=None):
    """Conditioned block, SSI result (None if skipped) and mode selection of one block.

    *conditioner* (a :class:`~workbench.signals.file_conditioning.FileConditioner`) gives
    the block from files conditioned once; without it the block is built from its files.
    """
    from .sid import select_modes, ssi_cov, ssi_data, stabilise
    from .signals import PlannedBlock, load_block

    if conditioner is not None:
        planned = PlannedBlock(
            task.block, task.block_start, grid.end(task.block), tuple(map(Path, task.files))
        )
        data = conditioner.block(planned)
    else:
        rate = options.target_rate_hz
        data = load_block(
            task.files,
            task.block,
            grid,
            target_rate_hz=None if rate == "auto" else rate,
            band_hz=options.band_hz,
            max_gap_s=options.max_gap_s,
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
    if options.method == "cov":
        result = ssi_cov(
            data.acceleration,
            data.sampling_rate_hz,
            block_rows=options.block_rows,
            orders=options.orders,
            reference_channels=reference,
        )
    else:
        result = ssi_data(
            data.acceleration,
            data.sampling_rate_hz,
            block_rows=options.block_rows,
            orders=options.orders,
            reference_channels=reference,
            weighting=options.weighting,
        )
    result = stabilise(
        result,
        frequency_tol=options.frequency_tol,
        damping_tol=options.damping_tol,
        mac_min=options.mac_min,
    )
    selection = select_modes(
        result,
        frequency_band=options.band_hz,
        damping_limits=(0.001, options.max_damping),
    )
    return data, result, selection


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
        data, result, selection = _identify_data(task, grid, options, conditioner)
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
    return BlockOutcome(task.block, start, tables, notes=notes)


@dataclass(frozen=True)
class _Run:
    """Consecutive blocks identified in one worker from files conditioned once (picklable).

    ``files`` are the headers of the files the blocks need plus one contiguous file on
    either side (their edges pad the filters).
    """

    block: int
    block_start: pd.Timestamp
    tasks: tuple[_Task, ...]
    files: tuple

    @property
    def blocks(self) -> tuple[int, ...]:
        return tuple(t.block for t in self.tasks)


def identify_run(
    run: _Run, *, grid: BlockGrid, channels: Sequence[str], options: IdentifyOptions
) -> list[BlockOutcome]:
    """Identify the consecutive blocks of *run*, conditioning each of their files once.

    Returns one :class:`~workbench.parallel.BlockOutcome` per block, as
    :func:`identify_block` gives it (a block failing with a data error is skipped with the
    reason; the other blocks go on).
    """
    from .parallel import _guarded
    from .signals.file_conditioning import FileConditioner

    conditioner = FileConditioner(
        run.files,
        grid,
        channels,
        target_rate_hz=float(options.target_rate_hz),
        band_hz=options.band_hz,
        max_gap_s=options.max_gap_s,
    )
    func = functools.partial(
        identify_block, grid=grid, channels=channels, options=options, conditioner=conditioner
    )
    return [_guarded(func, task) for task in run.tasks]


def _runs(tasks: Sequence[_Task], plan, size: int) -> list[_Run]:
    """*tasks* (ascending) in runs of at most *size* consecutive blocks."""
    position = {info.path: i for i, info in enumerate(plan.files)}
    runs: list[_Run] = []
    for first in range(0, len(tasks), size):
        chunk = tuple(tasks[first : first + size])
        used = [position[Path(f)] for t in chunk for f in t.files]
        if used:
            lo, hi = max(min(used) - 1, 0), min(max(used) + 2, len(plan.files))
        else:
            lo = hi = 0
        runs.append(_Run(chunk[0].block, chunk[0].block_start, chunk, plan.files[lo:hi]))
    return runs


def analysis_rate(options: IdentifyOptions, sampling_rate_hz: float) -> float:
    """The rate blocks are identified at, for files at *sampling_rate_hz*. [Hz]"""
    from .signals.file_conditioning import default_decimation_rate

    if options.target_rate_hz is None:
        return float(sampling_rate_hz)
    if options.target_rate_hz == "auto":
        return default_decimation_rate(sampling_rate_hz, options.band_hz)
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
        out += [f"{kind}: {path}" for kind, path in self.files.items()]
        return out


def acceleration_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """Files named by *inputs*: files as given, folders searched (with their subfolders)
    for ``.npz`` and ``.mat`` acceleration files."""
    found: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found += sorted(
                p
                for p in path.rglob("*")
                if p.suffix.lower() in ACCELERATION_SUFFIXES and p.is_file()
            )
        elif path.is_file():
            found.append(path)
        else:
            raise WorkbenchError(f"{path}: no such file or folder")
    if not found:
        raise WorkbenchError("no acceleration files found in " + ", ".join(map(str, inputs)))
    return found


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
    from .signals import plan_blocks

    options = options or IdentifyOptions()
    out = Path(out_dir)
    files = acceleration_files(inputs)
    try:
        plan = plan_blocks(
            files, length_s=options.length_s, step_s=options.step_s, max_gap_s=options.max_gap_s
        )
    except ValueError as error:
        raise WorkbenchError(str(error)) from None
    grid = plan.grid
    channels = tuple(plan.channels)
    # the analysis rate; decimating blocks are cut from files conditioned once
    rate = analysis_rate(options, plan.sampling_rate_hz)
    ratio = plan.sampling_rate_hz / rate
    per_file = (
        options.conditioning == "per-file"
        and round(ratio) >= 2
        and abs(ratio - round(ratio)) <= 1e-9 * ratio
    )
    options = replace(options, target_rate_hz=None if rate == plan.sampling_rate_hz else rate)
    parameters = {
        **options.parameters(),
        "grid_t0": grid.t0.isoformat(),
        "channels": list(channels),
    }
    store = BlockStore.open(store_dir or out / "store", parameters)
    wanted = None if blocks is None else {int(b) for b in blocks}
    tasks = [
        _Task(int(p.block), p.block_start, tuple(str(f) for f in p.files))
        for p in plan.blocks
        if wanted is None or int(p.block) in wanted
    ]
    if per_file:
        done = store.completed_blocks()
        todo = [t for t in tasks if t.block not in done]
        # runs of up to 24 blocks (2 h), a whole number per worker: files at the ends of
        # a run are conditioned by both runs sharing them
        workers = 1 if scheduler == "synchronous" else n_workers or os.cpu_count() or 1
        n_runs = workers * max(1, -(-len(todo) // (24 * workers)))
        size = max(1, -(-len(todo) // n_runs))
        units = [t for t in tasks if t.block in done] + _runs(todo, plan, size)
        func = functools.partial(identify_run, grid=grid, channels=channels, options=options)
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
    result.files = export_store(store, out, channels)
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
    from .signals import plan_blocks

    options = options or IdentifyOptions()
    plan = plan_blocks(
        acceleration_files(inputs),
        length_s=options.length_s,
        step_s=options.step_s,
        max_gap_s=options.max_gap_s,
    )
    rate = analysis_rate(options, plan.sampling_rate_hz)
    options = replace(options, target_rate_hz=None if rate == plan.sampling_rate_hz else rate)
    planned = [p for p in plan.blocks if not p.skipped_reason]
    if blocks is None:
        picks = np.unique(np.linspace(0, len(planned) - 1, max(n_blocks, 1)).round().astype(int))
        chosen = [planned[k] for k in picks] if planned else []
    else:
        wanted = {int(b) for b in blocks}
        chosen = [p for p in planned if int(p.block) in wanted]
    paths = []
    for planned_block in chosen:
        task = _Task(
            int(planned_block.block),
            planned_block.block_start,
            tuple(str(f) for f in planned_block.files),
        )
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
                frequency_band=options.band_hz,
                title=f"Block {task.block} ({pd.Timestamp(task.block_start):%Y-%m-%d %H:%M} "
                f"UTC), SSI-{options.method}",
            )
        )
    return paths


def export_store(store: BlockStore, out_dir: str | os.PathLike, channels: Sequence[str]):
    """Write the store's results as tables in *out_dir*; return them by kind.

    Poles and selected modes are streamed chunk by chunk into one Parquet file each (rows in
    block order), so exporting a voyage of any length needs the memory of one chunk.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for kind, sort, name, contract in (
        ("poles", ["block", "model_order", "frequency_hz"], "poles.parquet", POLES),
        ("selected", ["block", "frequency_hz"], "selected.parquet", None),
    ):
        chunks = (
            chunk.sort_values(sort, kind="stable").reset_index(drop=True)
            for chunk in store.read_chunks(kind, blocks_per_chunk=64)
        )
        path = _write_parquet_chunks(chunks, out / name, contract)
        if path is not None:
            files[kind] = path
    for kind in ("faults", "channels", "blocks"):
        table = store.read(kind)
        if kind == "blocks" and not table.empty:
            table = table.sort_values("block", kind="stable")
        if not table.empty or kind == "blocks":
            files[kind] = _write_csv(table.reset_index(drop=True), out / f"{kind}.csv")
    return files


def _write_parquet_chunks(chunks, path: Path, contract=None) -> Path | None:
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
