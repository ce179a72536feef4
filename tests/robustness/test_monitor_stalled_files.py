"""Files that never settle do not stall the monitor.

Before: an empty acceleration file (a recorder that stopped right after creating it) was
"still being written" forever. The monitor fixes its block grid only once no file is
pending, so one empty file among complete ones kept it from identifying anything: live,
for good ("waiting for the first complete files"); with ``--once`` it waited
``--flush-after`` (15 min by default) and then ended with exit 1, "no complete
acceleration file to monitor", over six good files. ``workbench identify`` over the same
folder names the file unreadable and identifies the rest; now the monitor does too. A file
stamped by a clock ahead of this machine's (a file server's) was likewise pending until
this machine's clock passed its time; now it is taken once the polls have seen it
unchanged for ``--settle`` seconds.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pandas as pd

from workbench.cli import main
from workbench.monitor import FolderWatcher

from .voyage import IDENTIFY_ARGS, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground"]


def test_once_over_good_files_and_an_empty_one_identifies_the_good_ones(tmp_path, capsys):
    watch = tmp_path / "watch"
    write_voyage(watch, n_files=6)
    (watch / "acc_006.npz").write_bytes(b"")
    argv = ["monitor", "--watch", watch, "--state", tmp_path / "state", *MONITOR_ARGS]
    started = time.monotonic()
    # --flush-after 30: the old behaviour ends after 30 s (not 15 min) with exit 1
    status = main([str(a) for a in [*argv, "--flush-after", "30", "--once"]])
    elapsed = time.monotonic() - started
    out, err = capsys.readouterr()
    assert status == 0, err
    assert elapsed < 20
    assert "note: acc_006.npz: unreadable (not a valid .npz acceleration file" in out
    assert "5 block(s) decided, tracked up to block 4" in out
    health = pd.read_parquet(tmp_path / "state" / "data_health.parquet")
    assert health["block"].tolist() == [0, 1, 2, 3, 4]
    assert (health["status"] == "ok").all()


def test_an_empty_file_is_reported_once_and_taken_when_written(tmp_path):
    source = write_voyage(tmp_path / "source", n_files=1)[0]
    watch = tmp_path / "watch"
    watch.mkdir()
    empty = watch / source.name
    empty.write_bytes(b"")
    old = time.time() - 5
    os.utime(empty, (old, old))  # created, then nothing for longer than settle_s
    watcher = FolderWatcher(watch, settle_s=0.5)
    landed, messages = watcher.poll()
    assert landed == [] and watcher.pending == set()
    assert len(messages) == 1 and messages[0].startswith(f"{source.name}: unreadable")
    assert watcher.poll() == ([], [])  # reported once
    shutil.copyfile(source, empty)
    os.utime(empty, (old, old))
    landed, messages = watcher.poll()
    assert [f.path for f in landed] == [empty] and messages == []


def test_a_named_pipe_under_a_data_files_name_is_left_out_not_waited_on(tmp_path):
    """A named pipe (or socket, device) named like an acceleration file is left out with one
    message; the good files beside it are taken (main: opening it to read its header waited
    for a writer, the monitor stuck in "looking for new files" for good, deaf to SIGTERM)."""
    import threading

    good = write_voyage(tmp_path / "watch", n_files=2)
    pipe = tmp_path / "watch" / "acc_002.npz"
    os.mkfifo(pipe)
    old = time.time() - 5
    for path in [*good, pipe]:
        os.utime(path, (old, old))
    watcher = FolderWatcher(tmp_path / "watch", settle_s=0.5)
    found = []
    polling = threading.Thread(target=lambda: found.append(watcher.poll()), daemon=True)
    polling.start()
    polling.join(timeout=20)
    if polling.is_alive():  # main: waiting in open(); a writer's open and close ends it
        os.close(os.open(pipe, os.O_WRONLY | os.O_NONBLOCK))
        polling.join(timeout=20)
    assert found, "the poll did not return"
    ((landed, messages),) = found
    assert [f.path for f in landed] == good
    assert messages == ["acc_002.npz: not a regular file (a pipe, socket or device); left out"]
    assert watcher.poll() == ([], [])  # said once


def test_a_file_stamped_in_the_future_is_taken_once_unchanged_for_settle_s(tmp_path):
    path = write_voyage(tmp_path, n_files=1)[0]
    ahead = time.time() + 2 * 3600  # a file server's clock two hours ahead
    os.utime(path, (ahead, ahead))
    watcher = FolderWatcher(tmp_path, settle_s=1.0)
    now = time.time()
    assert watcher.poll(now=now) == ([], [])
    assert watcher.pending == {Path(path)}
    assert watcher.poll(now=now + 0.5) == ([], [])  # unchanged for less than settle_s
    landed, messages = watcher.poll(now=now + 1.0)
    assert [f.path for f in landed] == [path] and messages == []
    assert watcher.pending == set()
