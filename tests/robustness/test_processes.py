"""Child processes end with their parent, and Ctrl-C is one line (issue 34, item 5).

Before: ``kill -9`` of ``workbench monitor`` left its background forecast worker (blocked
on its own task pipe) and multiprocessing's resource tracker alive for minutes; Ctrl-C on
``identify --workers 2`` while the Dask workers started printed 28 lines ending in
``AssertionError: Status.init``. The descendants of each command are listed with psutil
(a dependency of dask.distributed) before the kill.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest

from .voyage import write_voyage

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="process groups and signals as on Linux"
)

#: The monitor on the tiny voyage: 2-minute blocks, small SSI, fast polls.
MONITOR_ARGS = [
    "--block-minutes", "2", "--step-minutes", "1", "--block-rows", "10",
    "--min-order", "4", "--max-order", "16", "--poll", "0.05", "--settle", "0.1",
]  # fmt: skip


def _start(argv: list[str], **kwargs) -> subprocess.Popen:
    """``workbench ARGV`` in a new session (its own process group, as a terminal job),
    with the default Ctrl-C handling even when pytest runs in the background."""
    return subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", *map(str, argv)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
        **kwargs,
    )


def _descendants_when(process: subprocess.Popen, condition, timeout_s: float = 120.0):
    """The descendants of *process* once ``condition(descendants)`` holds."""
    deadline = time.monotonic() + timeout_s
    parent = psutil.Process(process.pid)
    while True:
        assert process.poll() is None, process.communicate()
        try:
            found = parent.children(recursive=True)
            if condition(found):
                return found
        except psutil.Error:
            pass
        assert time.monotonic() < deadline, "the command never started its workers"
        time.sleep(0.05)


def _workers(found) -> list:
    return [p for p in found if "--multiprocessing-fork" in " ".join(_cmdline(p))]


def _cmdline(process) -> list[str]:
    try:
        return process.cmdline()
    except psutil.Error:
        return []


def _stop_all(process: subprocess.Popen, found) -> None:
    for one in [*found, process]:
        try:
            os.kill(one.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    process.communicate(timeout=30)


def test_kill_9_of_the_monitor_leaves_no_process(tmp_path):
    watch = tmp_path / "watch"
    write_voyage(watch, n_files=6)
    state = tmp_path / "state"
    process = _start(["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS])
    found = []
    try:
        # the background forecast worker is started once the first block is decided;
        # it has answered once (forecast.parquet) and waits for its next task
        found = _descendants_when(
            process, lambda f: len(_workers(f)) == 1 and (state / "forecast.parquet").exists()
        )
        assert any("resource_tracker" in " ".join(_cmdline(p)) for p in found)
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
        gone, alive = psutil.wait_procs(found, timeout=10)
        assert alive == [], [(p.pid, _cmdline(p)) for p in alive]
        assert len(gone) == len(found) >= 2
    finally:
        _stop_all(process, found)


#: A pool whose worker is started by another thread than the main one (the thread then
#: ends): the worker must keep serving its parent, and still end when the parent is killed.
_POOL_FROM_A_THREAD = textwrap.dedent(
    """
    import multiprocessing, os, sys, threading, time
    from concurrent.futures import ProcessPoolExecutor
    from workbench.processes import worker_initializer

    if __name__ == "__main__":
        pools = []

        def start():
            pool = ProcessPoolExecutor(
                1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=worker_initializer,
                initargs=(os.getpid(), False),
            )
            pool.submit(os.getpid).result()
            pools.append(pool)

        thread = threading.Thread(target=start)
        thread.start()
        thread.join()  # the thread that started the worker has ended
        time.sleep(1.0)
        print(pools[0].submit(os.getpid).result(), flush=True)
        time.sleep(300)
    """
)


def test_worker_started_by_a_thread_outlives_the_thread_not_the_parent(tmp_path):
    script = tmp_path / "pool.py"
    script.write_text(_POOL_FROM_A_THREAD, encoding="utf-8")
    process = subprocess.Popen(
        [sys.executable, str(script)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )
    found = []
    try:
        worker_pid = int(process.stdout.readline())  # answered after its thread ended
        found = psutil.Process(process.pid).children(recursive=True)
        assert worker_pid in [p.pid for p in found]
        process.kill()
        process.wait(timeout=30)
        gone, alive = psutil.wait_procs(found, timeout=10)
        assert alive == [] and len(gone) == len(found)
    finally:
        _stop_all(process, found)


def _forked_workers(found) -> list:
    """The forked identify workers (a fork keeps its parent's command line)."""
    return [p for p in found if "workbench.cli" in " ".join(_cmdline(p))]


def test_ctrl_c_while_local_workers_run_is_one_line(tmp_path):
    """SIGINT to the whole process group (what a terminal's Ctrl-C does) while the forked
    local workers identify blocks: one line, exit 130, no process left."""
    inputs = tmp_path / "inputs"
    write_voyage(inputs, n_files=60)
    argv = ["identify", inputs, "--out", tmp_path / "out", "--workers", "2"]
    argv += ["--block-minutes", "2", "--step-minutes", "1", "--block-rows", "10"]
    argv += ["--max-order", "16", "--quiet"]
    process = _start(argv)
    found = []
    try:
        found = _descendants_when(process, lambda f: len(_forked_workers(f)) >= 2)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=120)
        gone, alive = psutil.wait_procs(found, timeout=10)
    finally:
        _stop_all(process, found)
    assert process.returncode == 130, err
    assert err.splitlines() == ["interrupted"]
    assert alive == []


def _sigint_blocked_in_a_child() -> bool:
    status = subprocess.run(
        [sys.executable, "-c", "print(open('/proc/self/status').read())"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    mask = next(line for line in status.splitlines() if line.startswith("SigBlk:"))
    return bool(int(mask.split()[1], 16) & (1 << (signal.SIGINT - 1)))


def test_ctrl_c_is_held_until_the_start_ends_and_children_never_see_it():
    from workbench.processes import interrupts_deferred

    reached = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts_deferred():
            assert _sigint_blocked_in_a_child()
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.1)  # the default handler would have raised by now
            reached.append("end of the start")
    assert reached == ["end of the start"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert not _sigint_blocked_in_a_child()


def test_a_second_ctrl_c_acts_at_once():
    from workbench.processes import interrupts_deferred

    reached = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.1)
            reached.append("held")
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.1)
            reached.append("not reached")
    assert reached == ["held"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


_INTERRUPTED_IMPORT = """
import os, signal, sys
class CtrlCOnPandas:  # the user's Ctrl-C arrives while the CLI imports pandas
    def find_spec(self, name, path=None, target=None):
        if name == "pandas":
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, CtrlCOnPandas())
from {module} import main
sys.exit(main(["--help"]))
"""


def test_ctrl_c_while_the_command_line_imports_is_one_line():
    """The ``workbench`` entry point: Ctrl-C during the second of imports before any
    command runs is ``interrupted``, exit 130, no traceback (importing workbench.cli
    directly, the old entry point, printed a KeyboardInterrupt traceback)."""
    process = subprocess.run(
        [sys.executable, "-c", _INTERRUPTED_IMPORT.format(module="workbench.launch")],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )
    assert process.returncode == 130, process.stderr
    assert process.stderr.splitlines() == ["interrupted"]
    assert process.stdout == ""


def test_the_entry_point_is_the_launcher():
    """pyproject's console script is the light launcher, not the CLI module itself."""
    text = (Path(__file__).resolve().parents[2] / "pyproject.toml").read_text()
    assert 'workbench = "workbench.launch:main"' in text
