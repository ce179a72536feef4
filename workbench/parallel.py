"""Run independent per-block work in parallel with Dask, into a resumable :class:`BlockStore`.

The same code runs on local worker processes (all cores by default; forked, a contiguous
range of the tasks each: :mod:`workbench.local_workers`), on an existing
``dask.distributed`` cluster (``scheduler="tcp://host:8786"``) or in-process
(``scheduler="synchronous"``, for debugging and tiny jobs). Memory stays bounded: tasks are
streamed from an iterator with at most ``max_in_flight`` submitted at a time, and finished
results are flushed to the store in batches.

Tasks may share inputs (:class:`SharedInput`), e.g. an acquisition file conditioned once
for the four overlapping blocks that hold it: each shared input is computed once, on any
worker, and handed to every task naming it, instead of each task (or each worker)
computing it again.
"""

from __future__ import annotations

import functools
import logging
import os
import time
import warnings
from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from .errors import UnreadableInputError, WorkbenchError
from .local_workers import fork_available, run_forked
from .processes import interrupts_deferred, worker_initializer
from .store import CUT_COLUMNS, UNREADABLE_COLUMN, BlockStore

__all__ = [
    "BlockOutcome",
    "BlockTask",
    "RunSummary",
    "SharedInput",
    "UnreadableBlock",
    "process_map",
    "run_blocks",
]

log = logging.getLogger(__name__)


class BlockTask(Protocol):
    """What :func:`run_blocks` needs of a task: its block number and start time."""

    block: int
    block_start: pd.Timestamp


@dataclass(frozen=True)
class SharedInput:
    """A value several tasks need, computed once per run: ``compute(argument)``.

    A task lists the shared inputs it needs in a ``shared_inputs`` attribute; it is then
    called as ``func(task, inputs)`` with ``inputs`` mapping each :attr:`key` to its value.
    Inputs are computed in task order and forgotten once a task no longer names them (the
    tasks that share an input should be consecutive, as the blocks holding one file are).
    A computation failing with a data error (``ValueError``, ``OSError``, ...) gives
    ``None``: the task is expected to redo the work itself and report the error as its own.

    Parameters
    ----------
    key : hashable
        Names the value within a run (e.g. the file's path as text).
    compute : callable
        Picklable (module-level function or ``functools.partial`` of one).
    argument
        Passed to *compute*; picklable.
    """

    key: Hashable
    compute: Callable[[Any], Any]
    argument: Any


def _compute_shared(compute: Callable[[Any], Any], argument: Any) -> Any:
    try:
        return compute(argument)
    except (ValueError, OSError, WorkbenchError, ArithmeticError, np.linalg.LinAlgError):
        return None  # the task needing it redoes the work and reports the error


def _needs(task: Any) -> tuple[SharedInput, ...]:
    return tuple(getattr(task, "shared_inputs", None) or ())


@dataclass(frozen=True)
class BlockOutcome:
    """Result of one block: tables by kind, or a reason why the block was skipped.

    ``unreadable`` names (resolved paths) the input files the block was skipped for
    because they cannot be read (:class:`~workbench.errors.UnreadableInputError`); the
    store keeps them with the block, so a later run can tell when such a file has changed.
    """

    block: int
    block_start: pd.Timestamp
    tables: Mapping[str, pd.DataFrame] = field(default_factory=dict)
    skipped: str = ""
    notes: tuple[str, ...] = ()
    unreadable: tuple[str, ...] = ()


@dataclass(frozen=True)
class UnreadableBlock:
    """A task for a block known before the run to need input files that cannot be read
    (their headers already fail): :func:`run_blocks` records it as skipped with *reason*
    without calling the block function.

    Parameters
    ----------
    block : int
    block_start : pandas.Timestamp
    reason : str
        ``"<path>: unreadable (<why>)"``.
    paths : tuple of str
        The files (resolved paths).
    """

    block: int
    block_start: pd.Timestamp
    reason: str
    paths: tuple[str, ...]


@dataclass(frozen=True)
class RunSummary:
    """What a run did: counts, skip reasons, notes (e.g. faulty channels), timing."""

    processed: int
    skipped: int
    already_done: int
    skip_reasons: Mapping[str, int]
    notes: Mapping[str, int]
    seconds: float

    def __str__(self) -> str:
        lines = [
            f"{self.processed} block(s) processed, {self.skipped} skipped, "
            f"{self.already_done} already done, in {self.seconds:.1f} s"
        ]
        lines += [f"  skipped ({n}): {reason}" for reason, n in sorted(self.skip_reasons.items())]
        lines += [f"  note ({n}): {note}" for note, n in sorted(self.notes.items())]
        return "\n".join(lines)


def _guarded(func: Callable[..., BlockOutcome], task: Any, inputs=None) -> BlockOutcome:
    """Run *func* (with the task's shared *inputs*, if it has any); a failure of one block
    becomes a skipped block with the reason (an :class:`UnreadableBlock` is one without
    running)."""
    if isinstance(task, UnreadableBlock):
        return BlockOutcome(
            int(task.block),
            pd.Timestamp(task.block_start),
            skipped=task.reason,
            unreadable=task.paths,
        )
    try:
        return func(task) if inputs is None else func(task, inputs)
    except (ValueError, WorkbenchError, ArithmeticError, np.linalg.LinAlgError) as error:
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        unreadable = ()
        if isinstance(error, UnreadableInputError):
            unreadable = (str(Path(error.path).resolve()),)
        return BlockOutcome(
            int(task.block), pd.Timestamp(task.block_start), skipped=reason, unreadable=unreadable
        )


def _progress(total: int | None, enabled: bool, description: str):
    from .progress import progress_bar

    return progress_bar(
        total=total, description=description, unit="block", enabled=enabled, smoothing=0.1
    )


def process_map(
    func: Callable[..., Any],
    calls: list[tuple],
    *,
    n_workers: int = 1,
    progress: bool = False,
    description: str = "",
    unit: str = "task",
    sizes: list[int] | None = None,
) -> list[Any]:
    """``[func(*args) for args in calls]``, spread over *n_workers* local processes.

    For work that needs no store and no cluster (e.g. independent modes of a forecast):
    *func* must be picklable (module level) when *n_workers* > 1. *sizes* weighs each call in
    the progress bar (default 1 each). Results come back in the order of *calls*.
    """
    from .progress import progress_bar

    sizes = [1] * len(calls) if sizes is None else list(sizes)
    bar = progress_bar(total=sum(sizes), description=description, unit=unit, enabled=progress)
    with bar:
        if n_workers <= 1 or len(calls) <= 1:
            results = []
            for args, size in zip(calls, sizes, strict=True):
                results.append(func(*args))
                bar.update(size)
            return results
        import threading
        from concurrent.futures import ProcessPoolExecutor, as_completed

        # the workers end with this process and leave Ctrl-C to it (workbench.processes)
        main_thread = threading.current_thread() is threading.main_thread()
        with ProcessPoolExecutor(
            max_workers=n_workers,
            initializer=worker_initializer,
            initargs=(os.getpid(), main_thread),
        ) as pool:
            with interrupts_deferred():  # the workers are started by the first submits
                futures = {
                    pool.submit(func, *args): size for args, size in zip(calls, sizes, strict=True)
                }
            for done in as_completed(futures):
                bar.update(futures[done])
            return [future.result() for future in futures]


def run_blocks(
    tasks: Iterable[Any],
    func: Callable[[Any], BlockOutcome],
    *,
    store: BlockStore,
    scheduler: str | None = None,
    n_workers: int | None = None,
    batch_blocks: int = 64,
    flush_seconds: float = 30.0,
    max_in_flight: int | None = None,
    total: int | None = None,
    progress: bool = False,
    description: str = "blocks",
    cuts: Mapping[int, tuple[str, int]] | None = None,
) -> RunSummary:
    """Apply *func* to every task not yet in *store*, in parallel, and store the results.

    Parameters
    ----------
    tasks : iterable
        Objects with ``block`` and ``block_start`` (e.g. the blocks of the block builder),
        produced lazily; tasks whose block is already in the store are not submitted.
    func : callable
        ``func(task) -> BlockOutcome``; must be picklable (a module-level function or a
        ``functools.partial`` of one). ``ValueError`` and ``LinAlgError`` raised by it mark
        the block as skipped with the message as reason. A task of several consecutive
        blocks (with a ``blocks`` attribute) returns a list of outcomes, one per block.
        A task with ``shared_inputs`` (:class:`SharedInput`) is run as
        ``func(task, inputs)``; an :class:`UnreadableBlock` is recorded skipped without
        calling *func*. The files a skipped block could not read (``BlockOutcome.
        unreadable``) are kept with it in the store's ``blocks``
        (:data:`~workbench.store.UNREADABLE_COLUMN`).
    store : BlockStore
        Where results go; also tells which blocks are done (resume).
    scheduler : str, optional
        ``None``: *n_workers* local processes (default: all cores), forked with a
        contiguous range of the tasks each (:mod:`workbench.local_workers`; a local Dask
        cluster where processes cannot be forked); ``"synchronous"``: in this process;
        otherwise the address of a running ``dask.distributed`` scheduler.
    n_workers : int, optional
        Local worker processes (default ``os.cpu_count()``).
    batch_blocks : int
        Blocks per store batch (files written together).
    flush_seconds : float
        A batch is also written when this much time has passed since the last one, so an
        interrupted slow job loses at most this much work. [s]
    max_in_flight : int, optional
        Tasks submitted but not finished, at most (default 4 per worker). Bounds memory.
    total : int, optional
        Number of tasks, for the progress bar.
    progress : bool
        Show a progress bar (blocks done, rate, ETA) on stderr.
    cuts : mapping of int -> (str, int), optional
        Where a drifting record's blocks are cut (``PlannedBlock.sample_start`` of those
        ``drifting``, as :func:`~workbench.signals.block_plan.cut_in_file` gives it),
        kept with them in the store's ``blocks`` (:data:`~workbench.store.CUT_COLUMNS`).

    Returns
    -------
    RunSummary
    """
    if batch_blocks < 1:
        raise ValueError(f"batch_blocks={batch_blocks} must be at least 1")
    started = time.perf_counter()
    done = store.completed_blocks()
    counts: Counter = Counter()
    skip_reasons: Counter = Counter()
    notes: Counter = Counter()
    pending: list[BlockOutcome] = []
    last_flush = [time.monotonic()]

    def flush() -> None:
        last_flush[0] = time.monotonic()
        if not pending:
            return
        blocks = pd.DataFrame(
            {
                "block": [o.block for o in pending],
                "block_start": pd.to_datetime([o.block_start for o in pending], utc=True),
                "status": ["skipped" if o.skipped else "ok" for o in pending],
                "reason": [o.skipped for o in pending],
            }
        )
        if any(o.unreadable for o in pending):  # the files, for the next run to look at
            blocks[UNREADABLE_COLUMN] = ["\n".join(o.unreadable) for o in pending]
        cut = [cuts.get(int(o.block), ("", -1)) for o in pending] if cuts else []
        if any(path for path, _ in cut):  # where the clock line cut them, for the next run
            blocks[CUT_COLUMNS[0]] = [path for path, _ in cut]
            blocks[CUT_COLUMNS[1]] = np.array([index for _, index in cut], dtype=np.int64)
        kinds = sorted({k for o in pending for k in o.tables})
        results = {}
        for kind in kinds:
            frames = [o.tables[kind] for o in pending if kind in o.tables and len(o.tables[kind])]
            if frames:
                results[kind] = pd.concat(frames, ignore_index=True)
        store.write_batch(blocks, results)
        pending.clear()

    def accept(outcome: BlockOutcome | list[BlockOutcome], bar) -> None:
        if isinstance(outcome, list):  # a task of several blocks
            for one in outcome:
                accept(one, bar)
            return
        if outcome.skipped:
            counts["skipped"] += 1
            skip_reasons[outcome.skipped] += 1
        else:
            counts["processed"] += 1
        notes.update(outcome.notes)
        pending.append(outcome)
        bar.update(1)
        if len(pending) >= batch_blocks or time.monotonic() - last_flush[0] >= flush_seconds:
            flush()

    def remaining() -> Iterable[Any]:
        for task in tasks:
            numbers = [int(b) for b in getattr(task, "blocks", (task.block,))]
            if all(b in done for b in numbers):
                counts["already_done"] += len(numbers)
                continue
            yield task

    todo_total = None if total is None else max(total - len(done), 0)
    with ExitStack() as stack:
        bar = stack.enter_context(_progress(todo_total, progress, description))
        try:
            if scheduler == "synchronous":
                values: dict = {}
                for task in remaining():
                    needs = _needs(task)
                    if not needs:
                        accept(_guarded(func, task), bar)
                        continue
                    keys = {need.key for need in needs}
                    for key in [k for k in values if k not in keys]:
                        del values[key]  # consecutive tasks share; older inputs are done
                    for need in needs:
                        if need.key not in values:
                            values[need.key] = _compute_shared(need.compute, need.argument)
                    accept(_guarded(func, task, {n.key: values[n.key] for n in needs}), bar)
                values.clear()
            elif scheduler is None and fork_available():
                # local: forked workers, a contiguous range of the tasks each
                run_forked(
                    list(remaining()),
                    functools.partial(_guarded, func),
                    _compute_shared,
                    n_workers or os.cpu_count() or 1,
                    lambda o: accept(o, bar),
                )
            else:
                client = stack.enter_context(_client(scheduler, n_workers))
                workers = max(len(client.scheduler_info().get("workers", {})), 1)
                limit = max_in_flight or 4 * workers
                _run_distributed(client, remaining(), func, limit, lambda o: accept(o, bar))
        finally:
            flush()  # whatever finished is kept, even when interrupted
    return RunSummary(
        counts["processed"],
        counts["skipped"],
        counts["already_done"],
        dict(skip_reasons),
        dict(notes),
        time.perf_counter() - started,
    )


#: glibc allocator settings of the local cluster's worker processes. dask starts them with
#: ``MALLOC_TRIM_THRESHOLD_=65536``, which also fixes glibc's mmap threshold at 128 KiB, so
#: that every temporary array of a block (channel rows, filter passes, Hankel matrices) is
#: mapped afresh and its pages faulted in and zeroed again: with 2048-Hz files that kernel
#: time was a large share of the work (benchmarks/results/docstring_numbers.txt). Arrays up to 32 MiB are reused from the
#: heap instead (as in a plain process) and free memory beyond 64 MiB is still returned.
_WORKER_MALLOC = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 64 * 2**20,
    "distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 32 * 2**20,
}


def _client(scheduler: str | None, n_workers: int | None):
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError as error:  # pragma: no cover - dask is a dependency
        raise WorkbenchError("parallel processing needs dask[distributed]") from error
    if scheduler:
        return Client(scheduler, set_as_default=False)
    quiet = [
        logging.getLogger(name)
        for name in list(logging.root.manager.loggerDict)
        if name.startswith("distributed")
    ]
    levels = [logger.level for logger in quiet]
    for logger in quiet:  # no cluster start/stop chatter on the user's terminal
        logger.setLevel(logging.ERROR)
    # Ctrl-C is held back while the cluster starts: its workers begin with SIGINT blocked
    # (the terminal's Ctrl-C reaches this process only) and an interrupted start is closed
    # in order below instead of being left half-made (workbench.processes)
    cluster = client = None
    try:
        with interrupts_deferred(), warnings.catch_warnings():
            # the scheduler's HTTP server takes another port when 8787 is busy (another
            # cluster, another user): not the user's concern, no dashboard is opened
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            with dask.config.set(_WORKER_MALLOC):
                cluster = LocalCluster(
                    n_workers=n_workers or os.cpu_count() or 1,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            client = Client(cluster, set_as_default=False)
    except BaseException:  # a Ctrl-C held back until the cluster was up, or a failed start
        for part in (client, cluster):
            if part is not None:
                part.close()
        for logger, level in zip(quiet, levels, strict=True):
            logger.setLevel(level)
        raise

    class _Both:
        def __enter__(self):
            return client

        def __exit__(self, *exc):
            try:
                client.close()
                cluster.close()
            finally:
                for logger, level in zip(quiet, levels, strict=True):
                    logger.setLevel(level)
            return False

    return _Both()


def _run_distributed(client, tasks: Iterable[Any], func, limit: int, accept) -> None:
    from dask.distributed import as_completed

    shared: dict = {}  # key -> future of a shared input still named by the newest task

    def submit(task):
        needs = _needs(task)
        if not needs:
            return client.submit(_guarded, func, task, pure=False)
        keys = {need.key for need in needs}
        for key in [k for k in shared if k not in keys]:
            shared.pop(key).release()  # the cluster keeps it while a queued task needs it
        for need in needs:
            if need.key not in shared:
                shared[need.key] = client.submit(
                    _compute_shared, need.compute, need.argument, pure=False
                )
        inputs = {need.key: shared[need.key] for need in needs}
        return client.submit(_guarded, func, task, inputs, pure=False)

    iterator = iter(tasks)
    first = []
    for task in iterator:
        first.append(submit(task))
        if len(first) >= limit:
            break
    if not first:
        return
    in_flight = as_completed(first, loop=client.loop)
    for future in in_flight:
        accept(future.result())
        future.release()
        for task in iterator:  # keep at most `limit` tasks in flight
            in_flight.add(submit(task))
            break
    for future in shared.values():
        future.release()
    shared.clear()
