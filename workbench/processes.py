"""Child processes that end with their parent and leave Ctrl-C to it.

Two rules for every process a workbench command starts (the monitor's background
forecast worker, the forked identify workers of :mod:`workbench.local_workers`, a local
Dask cluster's workers):

1. **A child ends when its parent ends**, however the parent ended (``kill -9``, an
   out-of-memory kill, a crash). A worker of :class:`~concurrent.futures.ProcessPoolExecutor`
   otherwise waits for its next task for ever: it holds the write end of its own task
   queue, so it never reads end-of-file, and multiprocessing's resource tracker, whose
   pipe the worker holds too, stays with it. :func:`end_with_parent`, run as the pool's
   initializer, asks Linux to send the child ``SIGKILL`` when its parent dies
   (``prctl(PR_SET_PDEATHSIG)``) and starts a watchdog thread that ends the child when
   its parent process id changes (every platform; also when the parent died before the
   ``prctl`` call, or when the thread that started the child ended, which
   ``PR_SET_PDEATHSIG`` takes for the parent's death and the watchdog does not). Dask's
   own workers already end with their nanny's process (a pipe that closes with it).
2. **Ctrl-C reaches only the parent**, which stops its children in order. The terminal
   sends ``SIGINT`` to every process of the foreground group: a child starting up (importing
   numpy, scipy, dask) would print a ``KeyboardInterrupt`` traceback of its own, and a
   Dask cluster interrupted while it starts is left half-made for Dask's exit handler to
   trip over (``AssertionError: Status.init``). :func:`interrupts_deferred` starts
   children with ``SIGINT`` blocked (a signal mask is inherited through ``fork`` and
   ``exec``; a pending ``SIGINT`` is never delivered to them), and holds the parent's
   own ``SIGINT`` until the children are up, so that an interrupted start ends in one
   orderly shutdown.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = [
    "end_with_parent",
    "interrupts_deferred",
    "parent_watchdog_seconds",
    "worker_initializer",
]

#: How often the watchdog thread looks at the parent process id. [s]
parent_watchdog_seconds = 0.5
#: ``PR_SET_PDEATHSIG`` of ``<linux/prctl.h>``.
_PR_SET_PDEATHSIG = 1


def _death_signal(signum: int) -> bool:
    """Ask Linux to send *signum* to this process when its parent dies; False when the
    platform has no ``prctl``."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signum), 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
        return False


def _watch_parent(parent_pid: int, interval_s: float) -> None:
    while True:
        time.sleep(interval_s)
        if os.getppid() != parent_pid:  # re-parented: the parent is gone
            os._exit(1)


def end_with_parent(
    parent_pid: int, started_by_main_thread: bool = True, ignore_interrupts: bool = True
) -> None:
    """End this process when *parent_pid* ends (a pool initializer; see the module notes).

    Parameters
    ----------
    parent_pid : int
        Process id of the parent, taken in the parent (``os.getpid()`` there): a child
        whose parent died before this runs sees another parent and ends at once.
    started_by_main_thread : bool
        The parent starts this child from its main thread. Only then is
        ``PR_SET_PDEATHSIG`` asked for: Linux sends it when the *thread* that started the
        child ends, which for another thread is not the parent's death. The watchdog
        thread runs either way.
    ignore_interrupts : bool
        Also ignore ``SIGINT`` from here on (the parent stops its children on Ctrl-C).
    """
    if ignore_interrupts and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if started_by_main_thread:
        _death_signal(signal.SIGKILL)
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(
        target=_watch_parent,
        args=(parent_pid, parent_watchdog_seconds),
        name="workbench-parent-watchdog",
        daemon=True,
    ).start()


def worker_initializer(
    parent_pid: int, started_by_main_thread: bool = True, niceness: int = 0
) -> None:
    """Initializer of a pool's worker: :func:`end_with_parent`, then lower the worker's
    priority by *niceness* (0: unchanged).

    It lives in this light module so that a worker unpickles it, and so watches its
    parent, before importing the heavy modules of its tasks.
    """
    end_with_parent(parent_pid, started_by_main_thread)
    if niceness:
        try:
            os.nice(niceness)
        except (AttributeError, OSError):  # pragma: no cover - platforms without nice
            pass


@contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold Ctrl-C back while the block runs, and start children deaf to it.

    Inside the block, ``SIGINT`` is blocked in this thread, so processes (and threads)
    started inside begin with it blocked: the terminal's Ctrl-C never reaches them and
    their parent stops them. In the main thread, a Ctrl-C pressed meanwhile is recorded
    and handed to the previous handler when the block ends (the default one raises
    :class:`KeyboardInterrupt` there); a second Ctrl-C is handed over at once, so that a
    start that hangs can still be interrupted. Without ``pthread_sigmask`` (Windows) it
    does nothing.
    """
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - Windows
        yield
        return
    # multiprocessing's resource tracker, when it starts, unblocks SIGINT in the thread
    # starting it (CPython's resource_tracker.ensure_running): start it first
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    main = threading.current_thread() is threading.main_thread()
    pressed: list[object] = []  # frames of the Ctrl-C held back (at most one)
    handler = None

    def deliver(frame) -> None:
        if callable(handler):
            handler(signal.SIGINT, frame)
        elif handler == signal.SIG_DFL:
            raise KeyboardInterrupt

    def hold(signum, frame) -> None:  # noqa: ARG001 - signal handler signature
        if pressed:  # pressed again: the start may hang, act now
            pressed.clear()
            deliver(frame)
        else:
            pressed.append(frame)

    done = threading.Event()
    if main:
        handler = signal.signal(signal.SIGINT, hold)
        # a thread with SIGINT unblocked (started before the mask below): the system
        # delivers Ctrl-C to it, and the main thread runs `hold` when it next runs Python
        # code, instead of the signal waiting, blocked, for the end of the block
        threading.Thread(target=done.wait, name="workbench-ctrl-c", daemon=True).start()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
        done.set()
        if main:
            signal.signal(signal.SIGINT, handler)
            if pressed:
                deliver(pressed.pop())
