"""``workbench dashboard``: usage errors, busy ports, the warning off localhost."""

from __future__ import annotations

import os
import signal
import socket
import threading
from pathlib import Path

import pytest

import workbench.dashboard
from workbench.cli import main
from workbench.dashboard import is_loopback, make_server, serve_until_stopped


class _FakeServer:
    url = "http://192.0.2.1:8050/"

    def __init__(self, state, **kwargs):
        self.state, self.kwargs = state, kwargs
        self.closed = False

    def serve_forever(self):
        raise KeyboardInterrupt  # Ctrl+C at once

    def server_close(self):
        self.closed = True


@pytest.fixture
def fake_server(monkeypatch):
    made = []

    def make(state, **kwargs):
        made.append(_FakeServer(state, **kwargs))
        return made[-1]

    monkeypatch.setattr(workbench.dashboard, "make_server", make)
    return made


@pytest.mark.parametrize(
    "host, loopback",
    [("127.0.0.1", True), ("localhost", True), ("::1", True), ("127.0.0.2", True),
     ("0.0.0.0", False), ("192.168.1.20", False), ("bridge.local", False), ("::", False)],
)  # fmt: skip
def test_is_loopback(host, loopback):
    assert is_loopback(host) is loopback


def test_localhost_by_default_without_warning(tmp_path, fake_server, capsys):
    assert main(["dashboard", "--state", str(tmp_path)]) == 0
    (server,) = fake_server
    assert server.kwargs["host"] == "127.0.0.1" and server.kwargs["port"] == 8050
    assert server.closed
    out, err = capsys.readouterr()
    assert "on http://" in out
    assert err == ""


def test_another_interface_warns(tmp_path, fake_server, capsys):
    assert main(["dashboard", "--state", str(tmp_path), "--host", "0.0.0.0"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: listening on 0.0.0.0") and "no login" in err


def test_options_reach_the_server(tmp_path, fake_server):
    argv = ["dashboard", "--state", str(tmp_path), "--hours", "3", "--poll", "0.5"]
    assert main([*argv, "--option", "B", "--health-hours", "48"]) == 0
    options = fake_server[0].kwargs["options"]
    assert (options.hours, options.poll_seconds, options.option, options.health_hours) == (
        3.0,
        0.5,
        "B",
        48.0,
    )


def test_absent_state_folder_warns_and_serves(tmp_path, fake_server, capsys):
    assert main(["dashboard", "--state", str(tmp_path / "later")]) == 0
    assert "does not exist yet" in capsys.readouterr().err
    assert not (tmp_path / "later").exists()  # read-only: not even created


@pytest.mark.parametrize(
    "extra, message",
    [(["--port", "70000"], "--port=70000"), (["--poll", "0"], "poll=0"),
     (["--hours", "-1"], "hours=-1"), (["--option", "C"], "invalid choice")],
)  # fmt: skip
def test_usage_errors_exit_2(tmp_path, fake_server, capsys, extra, message):
    assert main(["dashboard", "--state", str(tmp_path), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not fake_server


def test_state_that_is_a_file_exits_2(tmp_path, capsys):
    path = tmp_path / "status.json"
    path.write_text("{}")
    assert main(["dashboard", "--state", str(path)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_busy_port_is_one_line_exit_1(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["dashboard", "--state", str(tmp_path), "--port", str(port)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: cannot listen on 127.0.0.1:{port}") and err.count("\n") == 1


def test_demo_serves_a_replayed_voyage_and_cleans_up(fake_server, capsys):
    assert main(["dashboard", "--demo", "--port", "0"]) == 0
    (server,) = fake_server
    folder = Path(server.state)
    assert folder.name.startswith("workbench-dashboard-demo-")
    assert not folder.exists()  # the temporary state folder is removed on exit


def test_sigterm_stops_the_server_cleanly(tmp_path):
    server = make_server(tmp_path, port=0)
    previous = signal.getsignal(signal.SIGTERM)
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGTERM))
    timer.start()
    serve_until_stopped(server)  # returns instead of killing the test process
    timer.join()
    assert signal.getsignal(signal.SIGTERM) is previous
    with pytest.raises(OSError):
        server.socket.getsockname()  # closed
