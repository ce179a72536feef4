"""Local worker processes for :func:`~workbench.parallel.run_blocks`: forked, each with a
contiguous range of the tasks, sharing inputs without recomputing them.

Why not a local Dask cluster: its scheduler, nannies and workers are fresh interpreters
that import numpy, scipy, pandas and workbench again (several CPU seconds per run), and
every task and result crosses the scheduler. A forked worker starts with this process's
modules already imported and gets its tasks without any serialisation; only the tables
of each finished block (and the few shared inputs two ranges both need) travel back.

Each worker runs its range in order, like the in-process scheduler, so the shared inputs of
consecutive tasks (an acquisition file conditioned once for the four overlapping blocks
holding it) are computed once in that worker and dropped once no later task of its range
names them. An input needed by two neighbouring ranges is computed once, by whichever of
the two has less work (its tasks, plus :data:`SHARED_INPUT_WEIGHT` tasks per input it
computes; e.g. a 1-h voyage's 9 blocks and 12 files: 5 blocks and 6 files against 4 and
6, where handing every shared file to the later worker gave 5 and 5 against 4 and 7), and
handed to the other through this process; workers compute what they hand over before
their own tasks, so the receiver does not wait. The tasks must be in time order, as
:func:`~workbench.parallel.run_blocks` documents for shared inputs.

Workers follow :mod:`workbench.processes`: they start with Ctrl-C blocked, end with this
process, and are stopped by it (``terminate``) when the run ends early.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import multiprocessing
import os
import pickle
import queue
import sys
import threading
import traceback
from collections.abc import Callable, Hashable, Sequence
from typing import Any

from .processes import end_with_parent, interrupts_deferred

__all__ = ["fork_available", "run_forked", "split_ranges"]

#: glibc ``mallopt`` parameters of the workers: arrays up to 256 MiB (a raw 5-min file of
#: 19 channels at 2048 Hz is 93 MB, read once per file) are reused from the heap instead of
#: being mapped and zeroed afresh, and up to 512 MiB of freed heap is kept for them. A
#: worker's peak memory is what it holds at once either way; the kernel's page faults and
#: zeroing of every file's fresh mapping were 0.25 s of system CPU per 1-h voyage.
#: (Dask workers, which hold no raw files, keep ``workbench.parallel._WORKER_MALLOC``.)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD_BYTES = 256 * 2**20
_TRIM_THRESHOLD_BYTES = 512 * 2**20


def fork_available() -> bool:
    """True where worker processes can be forked (Linux: the default local pool)."""
    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


def split_ranges(n_tasks: int, n_workers: int) -> list[range]:
    """*n_tasks* split into at most *n_workers* contiguous ranges of near-equal length
    (the first ones one longer), none empty."""
    if n_tasks < 0 or n_workers < 1:
        raise ValueError(f"n_tasks={n_tasks} must be >= 0 and n_workers={n_workers} >= 1")
    n_workers = min(n_workers, n_tasks)
    ranges, start = [], 0
    for k in range(n_workers):
        length = n_tasks // n_workers + (1 if k < n_tasks % n_workers else 0)
        ranges.append(range(start, start + length))
        start += length
    return ranges


def _allocate_like_a_plain_process() -> None:
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_BYTES)
        libc.mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD_BYTES)
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        pass


#: Work of computing a shared input, in tasks (the balance of :func:`_owners`): in
#: ``workbench identify`` a shared input is a raw file read, checked and decimated, about
#: twice a block's identification at 2048 Hz (0.37 s against 0.18 s of CPU). [-]
SHARED_INPUT_WEIGHT = 2.0


def _owners(
    needs: Sequence[Sequence[Hashable]],
    ranges: Sequence[range],
    weight: float = SHARED_INPUT_WEIGHT,
) -> dict:
    """Key -> the worker computing it.

    A key named by one worker's range is that worker's. A key named by several (the
    inputs at the join of two ranges) goes, in time order, to whichever of them has the
    least work so far: its tasks plus *weight* per key it computes; a tie goes to the later
    worker (it needs the key for its first tasks). Workers compute the keys they hand
    over before their own tasks (:func:`_worker`), so none waits long for a neighbour.
    """
    naming: dict = {}  # key -> workers whose range names it, in order
    for worker, span in enumerate(ranges):
        for i in span:
            for key in needs[i]:
                workers = naming.setdefault(key, [])
                if worker not in workers:
                    workers.append(worker)
    load = [float(len(span)) for span in ranges]
    owner: dict = {}
    for key, workers in naming.items():
        if len(workers) == 1:
            owner[key] = workers[0]
            load[workers[0]] += weight
    for key, workers in naming.items():
        if len(workers) > 1:
            chosen = min(reversed(workers), key=lambda w: load[w])
            owner[key] = chosen
            load[chosen] += weight
    return owner


def _worker(
    worker: int,
    tasks: Sequence[Any],
    run_task: Callable,
    compute_shared: Callable,
    owner: dict,
    exported: set,
    inbox,
    outbox,
    parent_pid: int,
    started_by_main_thread: bool,
) -> None:
    """Body of worker *worker*: its tasks in order; messages to the parent are
    ``("outcome", outcome)``, ``("shared", key, value)``, ``("error", exception or text)``
    and ``("done",)``."""
    end_with_parent(parent_pid, started_by_main_thread)
    _allocate_like_a_plain_process()
    received: dict = {}
    values: dict = {}
    needs = [tuple(getattr(task, "shared_inputs", None) or ()) for task in tasks]
    last_use: dict = {}  # key -> index of the last of this worker's tasks needing it
    for i, task_needs in enumerate(needs):
        for need in task_needs:
            last_use[need.key] = i
    try:
        # the inputs handed to other workers first: they may need them for their first
        # tasks; each is kept here only while a task of this range still needs it
        handed = {n.key: n for task_needs in needs for n in task_needs if n.key in exported}
        for key, need in handed.items():
            value = compute_shared(need.compute, need.argument)
            outbox.send(("shared", key, value))
            if key in last_use:
                values[key] = value
        for i, task in enumerate(tasks):
            if not needs[i]:
                outbox.send(("outcome", run_task(task, None)))
                continue
            for key in [k for k in values if last_use.get(k, -1) < i]:
                del values[key]  # no later task of this range needs it
            for need in needs[i]:
                if need.key in values:
                    continue
                if owner[need.key] == worker:
                    values[need.key] = compute_shared(need.compute, need.argument)
                    continue
                while need.key not in received:  # ends: the parent forwards or exits
                    key, value = inbox.recv()
                    received[key] = value
                values[need.key] = received.pop(need.key)
            outbox.send(("outcome", run_task(task, {n.key: values[n.key] for n in needs[i]})))
        outbox.send(("done",))
    except BaseException as error:  # noqa: BLE001 - handed to the parent, which raises it
        try:
            pickle.dumps(error)
            outbox.send(("error", error))
        except Exception:  # noqa: BLE001 - an exception that does not pickle: its text
            outbox.send(("error", "".join(traceback.format_exception(error))))
    finally:
        outbox.close()
        os._exit(0)


def _sender(connection, messages: queue.Queue) -> None:
    """Forward *messages* to a worker without blocking the parent's receiving loop."""
    while True:
        message = messages.get()
        if message is None:
            return
        try:
            connection.send(message)
        except (OSError, ValueError):  # the worker ended: nothing left to forward
            return


def run_forked(
    tasks: Sequence[Any],
    run_task: Callable[[Any, dict | None], Any],
    compute_shared: Callable[[Callable, Any], Any],
    n_workers: int,
    accept: Callable[[Any], None],
) -> None:
    """Run *tasks* (in time order) on *n_workers* forked processes, a contiguous range
    each; ``accept(outcome)`` is called here for each result as it arrives.

    ``run_task(task, inputs)`` gives a task's outcome (*inputs*: its shared inputs by key,
    or None without any); ``compute_shared(compute, argument)`` a shared input. Raises
    what a worker raised (its text as RuntimeError when it does not pickle), or
    RuntimeError when a worker died.
    """
    from multiprocessing.connection import wait

    tasks = list(tasks)
    if not tasks:
        return
    ranges = split_ranges(len(tasks), n_workers)
    needs = [
        tuple(need.key for need in (getattr(task, "shared_inputs", None) or ())) for task in tasks
    ]
    owner = _owners(needs, ranges)
    wanted_by: dict = {}  # key -> workers that receive it from its owner
    for worker, span in enumerate(ranges):
        for i in span:
            for key in needs[i]:
                if owner[key] != worker:
                    wanted_by.setdefault(key, set()).add(worker)
    context = multiprocessing.get_context("fork")
    main_thread = threading.current_thread() is threading.main_thread()
    processes, outboxes, senders, queues = [], [], [], []
    try:
        with interrupts_deferred():  # the workers start with Ctrl-C blocked
            for worker, span in enumerate(ranges):
                inbox_read, inbox_write = context.Pipe(duplex=False)
                outbox_read, outbox_write = context.Pipe(duplex=False)
                exported = {k for k in wanted_by if owner[k] == worker}
                process = context.Process(
                    target=_worker,
                    args=(
                        worker,
                        tasks[span.start : span.stop],
                        run_task,
                        compute_shared,
                        owner,
                        exported,
                        inbox_read,
                        outbox_write,
                        os.getpid(),
                        main_thread,
                    ),
                    name=f"workbench-worker-{worker}",
                    daemon=True,
                )
                process.start()
                inbox_read.close()
                outbox_write.close()
                processes.append(process)
                outboxes.append(outbox_read)
                messages: queue.Queue = queue.Queue()
                queues.append(messages)
                sender = threading.Thread(target=_sender, args=(inbox_write, messages), daemon=True)
                sender.start()
                senders.append((sender, inbox_write))
        running = dict(enumerate(outboxes))
        while running:  # ends: each worker sends "done" or an error, or its pipe closes
            for connection in wait(list(running.values())):
                worker = next(w for w, c in running.items() if c is connection)
                try:
                    message = connection.recv()
                except EOFError:
                    raise RuntimeError(
                        f"worker process {worker} ended without finishing its blocks "
                        f"(exit code {processes[worker].exitcode})"
                    ) from None
                kind = message[0]
                if kind == "outcome":
                    accept(message[1])
                elif kind == "shared":
                    for other in wanted_by.get(message[1], ()):
                        queues[other].put((message[1], message[2]))
                elif kind == "error":
                    error = message[1]
                    raise error if isinstance(error, BaseException) else RuntimeError(error)
                else:
                    del running[worker]
    finally:
        for messages in queues:
            messages.put(None)
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join()
        for connection in outboxes:
            connection.close()
        for sender, connection in senders:
            sender.join(timeout=5.0)
            connection.close()
