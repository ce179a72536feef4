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
result depends only on its own data and the options, which the store checks). The store
is locked while a run works on it, and every input file is fingerprinted (size,
modification time, SHA-256 of its content): a second run on a busy store, or a rerun on
changed files, is refused instead of mixing or reusing results of other data.

Every option is checked against the files' headers before the first block (rate, band,
reference channels, block rows against the samples of a block): an option that would make
every block fail raises :class:`~workbench.errors.OptionError` at once.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from data_contracts import POLES, atomic_path, shape_columns

from .blocks import BlockGrid
from .errors import OptionError, WorkbenchError
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
    target_rate_hz : float, optional
        Decimate to this rate first (e.g. 2048 Hz -> 64 Hz); ``None`` keeps the files' rate.
        [Hz]
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
    """

    method: Literal["cov", "data"] = "cov"
    block_rows: int = 20
    orders: tuple[int, ...] = tuple(range(4, 61, 2))
    weighting: Literal["pc", "upc", "cva"] = "pc"
    reference_channels: tuple[str, ...] | None = None
    length_s: float = 1200.0
    step_s: float = 300.0
    target_rate_hz: float | None = None
    band_hz: tuple[float, float] | None = (2.0, 12.0)
    max_gap_s: float = 0.0
    frequency_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.98
    max_damping: float = 0.10

    def __post_init__(self) -> None:
        if self.method not in ("cov", "data"):
            raise OptionError(f"method={self.method!r} must be 'cov' or 'data'")
        if self.weighting not in ("pc", "upc", "cva"):
            raise OptionError(f"weighting={self.weighting!r} must be 'pc', 'upc' or 'cva'")
        if int(self.block_rows) != self.block_rows or self.block_rows < 2:
            raise OptionError(f"block_rows={self.block_rows} must be an integer of at least 2")
        orders = tuple(int(o) for o in self.orders)
        if not orders or min(orders) < 1:
            raise OptionError(f"orders={self.orders!r} must be positive model orders")
        object.__setattr__(self, "orders", orders)
        for name in ("length_s", "step_s"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise OptionError(f"{name}={value:g} must be a positive number of seconds")
        if not (math.isfinite(float(self.max_gap_s)) and self.max_gap_s >= 0):
            raise OptionError(
                f"max_gap_s={float(self.max_gap_s):g} must be a non-negative number of seconds"
            )
        if self.target_rate_hz is not None:
            rate = float(self.target_rate_hz)
            if not (math.isfinite(rate) and rate > 0):
                raise OptionError(f"target_rate_hz={rate:g} must be a positive rate [Hz]")
        if self.band_hz is not None:
            try:
                low, high = (float(v) for v in self.band_hz)
            except (TypeError, ValueError):
                raise OptionError(f"band_hz={self.band_hz!r} must be (low, high) [Hz]") from None
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
                raise OptionError(
                    f"band_hz=({low:g}, {high:g}) must be (low, high) with 0 <= low < high"
                )
            object.__setattr__(self, "band_hz", (low, high))
        for name in ("frequency_tol", "damping_tol", "mac_min", "max_damping"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and 0 <= value <= 1):
                raise OptionError(f"{name}={value:g} must lie in [0, 1]")
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


def _identify_data(task: _Task, grid: BlockGrid, options: IdentifyOptions):
    """Conditioned block, SSI result (None if skipped) and mode selection of one block."""
    from .sid import select_modes, ssi_cov, ssi_data, stabilise
    from .signals import load_block

    band = options.band_hz
    if band is not None and band[0] == 0:  # (0, high): low-pass only
        band = (None, band[1])
    data = load_block(
        task.files,
        task.block,
        grid,
        target_rate_hz=options.target_rate_hz,
        band_hz=band,
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
    task: _Task, *, grid: BlockGrid, channels: Sequence[str], options: IdentifyOptions
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
        data, result, selection = _identify_data(task, grid, options)
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
            # hidden files (e.g. ``.name.tmp.npz`` of an interrupted write) are not data
            found += sorted(
                p
                for p in path.rglob("*")
                if p.suffix.lower() in ACCELERATION_SUFFIXES
                and not any(part.startswith(".") for part in p.relative_to(path).parts)
                and p.is_file()
            )
        elif path.is_file():
            found.append(path)
        else:
            raise WorkbenchError(f"{path}: no such file or folder")
    if not found:
        raise WorkbenchError("no acceleration files found in " + ", ".join(map(str, inputs)))
    return found


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
    from .signals import plan_blocks

    options = options or IdentifyOptions()
    _check_run_options(scheduler, n_workers, batch_blocks)
    out = Path(out_dir)
    store_path = Path(store_dir) if store_dir is not None else out / "store"
    for what, path in (("output folder", out), ("store", store_path)):
        if path.exists() and not path.is_dir():
            raise WorkbenchError(f"{path}: {what} is a file, not a folder")
    files = acceleration_files(inputs)
    try:
        plan = plan_blocks(
            files, length_s=options.length_s, step_s=options.step_s, max_gap_s=options.max_gap_s
        )
    except OptionError:
        raise
    except ValueError as error:
        raise WorkbenchError(str(error).splitlines()[0]) from None
    options.check_data(plan)
    grid = plan.grid
    channels = tuple(plan.channels)
    parameters = {
        **options.parameters(),
        "grid_t0": grid.t0.isoformat(),
        "channels": list(channels),
    }
    with BlockStore.open(store_path, parameters) as store:
        store.check_inputs(input_fingerprints(plan.files))
        wanted = None if blocks is None else {int(b) for b in blocks}
        tasks = [
            _Task(int(p.block), p.block_start, tuple(str(f) for f in p.files))
            for p in plan.blocks
            if wanted is None or int(p.block) in wanted
        ]
        func = functools.partial(identify_block, grid=grid, channels=channels, options=options)
        summary = run_blocks(
            tasks,
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
