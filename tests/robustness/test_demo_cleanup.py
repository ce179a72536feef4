"""``workbench dashboard --demo`` removes its temporary folder on every way out (issue 28,
item 4): an error, SIGTERM while the voyage is still being simulated (before the
server's own SIGTERM handling starts; it used to leave the folder), and Ctrl-C, SIGTERM
or SIGHUP (the terminal closed; it used to leave the folder) while serving."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from workbench.cli import main

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")


@pytest.fixture
def temporary(tmp_path, monkeypatch) -> Path:
    """Where ``tempfile`` makes its folders during the test."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    return tmp_path


def test_sigterm_while_the_voyage_is_simulated(temporary, monkeypatch):
    import workbench.dashboard as dashboard

    original = dashboard.DemoReplay
    made = []

    class KilledWhileBuilding(original):
        def __init__(self, folder, **kwargs):
            made.append(Path(folder))
            assert Path(folder).is_dir()
            # without a handler of the demo's own, SIGTERM would end the test run
            assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, previous[0])
            os.kill(os.getpid(), signal.SIGTERM)  # raises here, in the main thread
            raise AssertionError("SIGTERM did not stop the demo")

    monkeypatch.setattr(dashboard, "DemoReplay", KilledWhileBuilding)
    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)
    assert main(["dashboard", "--demo", "--port", "0"]) == 0
    assert made and made[0].parent == temporary
    assert list(temporary.iterdir()) == []
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)) == previous


def test_an_error_while_starting_the_server(temporary, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["dashboard", "--demo", "--port", str(port)]) == 1
    assert "cannot listen" in capsys.readouterr().err
    assert list(temporary.iterdir()) == []


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_signal_while_serving(tmp_path, signum):
    process = subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", "dashboard", "--demo", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        env={
            **os.environ,
            "TMPDIR": str(tmp_path),
            "PYTHONPATH": str(Path(__file__).resolve().parents[2]),
        },
    )
    try:
        assert process.stdout.readline().startswith("dashboard of ")  # serving
        folders = list(tmp_path.iterdir())
        assert len(folders) == 1 and (folders[0] / "status.json").is_file()
        time.sleep(0.2)
        process.send_signal(signum)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    # a stop asked for, not a failure (Ctrl-C before the server loop: "interrupted", 130)
    assert process.returncode in (0, 130), err
    assert err.strip() in ("", "interrupted")
    assert list(tmp_path.iterdir()) == []
