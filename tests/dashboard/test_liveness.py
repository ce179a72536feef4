"""Liveness of the monitor as the dashboard judges it (issue 29): the staleness rule,
the status panel and the validation of ``heartbeat.json``."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from workbench.dashboard import server as server_module
from workbench.dashboard.server import PANELS, make_server
from workbench.dashboard.state import StateFolder, read_heartbeat
from workbench.dashboard.views import heartbeat_stale, status_view

T0 = pd.Timestamp("2026-03-01T06:00:00Z")


def _status(state: str = "running") -> dict:
    return {
        "updated_at": "2026-03-01T05:59:00.000000Z",
        "last_block": 41,
        "blocks_done": 42,
        "state": state,
        "pid": 4242,
        "watch": "/data/acc",
        "message": "",
    }


def _heartbeat(
    state: str = "running",
    *,
    poll_s: float = 5.0,
    worker=None,
    doing: str = "waiting for files",
    doing_since: str = "2026-03-01T05:59:58.000000Z",
) -> dict:
    return {
        "time": "2026-03-01T06:00:00.000000Z",
        "pid": 4242,
        "host": "bridge-pc",
        "poll_s": poll_s,
        "state": state,
        "last_file": "acc_20260301_0555.npz",
        "last_file_taken_at": "2026-03-01T05:55:03Z",
        "doing": doing,
        "doing_since": doing_since,
        "stall_s": 300.0,
        "worker": worker or {"state": "alive", "pid": 4243, "message": ""},
    }


@pytest.mark.parametrize(
    ("poll_s", "age_s", "stale"),
    [
        (1.0, 0.0, False),
        (1.0, 1.999, False),
        (1.0, 2.0, False),  # exactly two intervals: not yet missed
        (1.0, 2.001, True),
        (5.0, 9.9, False),
        (5.0, 10.1, True),
        (0.2, 0.5, True),
        (300.0, 599.0, False),
    ],
)
def test_a_heartbeat_older_than_two_poll_intervals_is_missed(poll_s, age_s, stale):
    now = T0 + pd.Timedelta(seconds=age_s)
    assert heartbeat_stale(T0, now, poll_s) is stale


def test_the_rule_refuses_a_poll_interval_that_is_not_positive():
    with pytest.raises(ValueError, match="poll_s") as caught:
        heartbeat_stale(T0, T0, 0.0)
    assert "positive" in str(caught.value) and "0.0" in str(caught.value)


def test_status_view_says_not_responding_and_names_the_last_file():
    fresh = status_view(_status(), T0 + pd.Timedelta(seconds=9), _heartbeat())
    assert fresh["liveness"] == "running"
    missed = status_view(_status(), T0 + pd.Timedelta(seconds=11), _heartbeat())
    assert missed["liveness"] == "not responding" and missed["state"] == "running"
    beat = missed["heartbeat"]
    assert beat["last_file"] == "acc_20260301_0555.npz"
    assert beat["last_file_taken_at"] == "2026-03-01T05:55:03Z"
    assert beat["age_s"] == pytest.approx(11.0) and beat["limit_s"] == 10.0
    assert (beat["pid"], beat["host"]) == (4242, "bridge-pc")
    # a clean stop is a stop, however old its last heartbeat
    stopped = status_view(_status("stopped"), T0 + pd.Timedelta(hours=5), _heartbeat("stopped"))
    assert stopped["liveness"] == "stopped"
    # no heartbeat file (a state written by something else): the status stands as written
    assert status_view(_status(), T0 + pd.Timedelta(hours=5))["liveness"] == "running"


@pytest.mark.parametrize(
    ("busy_s", "liveness"),
    [(0.0, "running"), (299.0, "running"), (300.0, "running"), (301.0, "not responding")],
)
def test_a_main_loop_stuck_beside_a_live_heartbeat_is_not_responding(busy_s, liveness):
    """The heartbeat thread beats on while the main loop hangs in one block: longer than
    stall_s (300 s) in one activity is not responding, and the view says in which."""
    since = T0 - pd.Timedelta(seconds=busy_s)
    beat = _heartbeat(doing="identifying block 44", doing_since=since.isoformat())
    view = status_view(_status(), T0 + pd.Timedelta(seconds=1), beat)  # a fresh heartbeat
    assert view["liveness"] == liveness
    assert view["heartbeat"]["stalled"] is (liveness == "not responding")
    assert view["heartbeat"]["doing"] == "identifying block 44"
    assert view["heartbeat"]["busy_s"] == pytest.approx(busy_s)
    # a stopped monitor is stopped, whatever its last activity
    stopped = status_view(_status("stopped"), T0, {**beat, "state": "stopped"})
    assert stopped["liveness"] == "stopped" and not stopped["heartbeat"]["stalled"]


def test_a_stopped_worker_reaches_the_status_panel():
    worker = {"state": "stopped", "pid": 4243, "message": "worker (pid 4243) stopped"}
    view = status_view(_status(), T0, _heartbeat(worker=worker))
    assert view["liveness"] == "running"
    assert view["heartbeat"]["worker"] == worker


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"poll_s": 0}, "key 'poll_s' is 0"),
        ({"poll_s": True}, "key 'poll_s' has type bool"),
        ({"state": "sleeping"}, "key 'state' is 'sleeping'"),
        ({"time": "yesterday"}, "key 'time' is not an ISO-8601 time"),
        ({"last_file": 3}, "key 'last_file' has type int"),
        ({"worker": {"state": "alive"}}, "key 'worker': missing key 'pid'"),
        ({"worker": {"state": "gone", "pid": None, "message": ""}}, "state 'gone'"),
    ],
)
def test_a_malformed_heartbeat_is_named(tmp_path, change, fragment):
    path = tmp_path / "heartbeat.json"
    path.write_text(json.dumps({**_heartbeat(), **change}), encoding="utf-8")
    with pytest.raises(ValueError, match="heartbeat.json") as caught:
        read_heartbeat(path)
    assert fragment in str(caught.value)


def test_a_missing_key_is_named_with_every_other(tmp_path):
    beat = _heartbeat()
    del beat["host"], beat["pid"]
    path = tmp_path / "heartbeat.json"
    path.write_text(json.dumps(beat), encoding="utf-8")
    with pytest.raises(ValueError) as caught:
        read_heartbeat(path)
    assert "missing key 'pid'" in str(caught.value) and "missing key 'host'" in str(caught.value)


def test_the_status_panel_changes_when_the_heartbeat_is_missed(tmp_path, monkeypatch):
    """No file changes when a monitor dies: the panel's ETag carries the verdict, so the
    page fetches the panel again when the heartbeat is missed."""
    (tmp_path / "status.json").write_text(json.dumps(_status()), encoding="utf-8")
    (tmp_path / "heartbeat.json").write_text(json.dumps(_heartbeat()), encoding="utf-8")
    clock = {"now": T0 + pd.Timedelta(seconds=3)}
    monkeypatch.setattr(server_module, "_now", lambda: clock["now"])
    assert "heartbeat" in PANELS["status"].files
    server = make_server(tmp_path, port=0)
    try:
        tag, body = server.answer("status")
        assert json.loads(body)["liveness"] == "running"
        clock["now"] = T0 + pd.Timedelta(seconds=9)
        assert server.etag("status") == tag  # nothing changed yet
        clock["now"] = T0 + pd.Timedelta(seconds=10.5)
        missed_tag, body = server.answer("status")
        assert missed_tag != tag
        shown = json.loads(body)
        assert shown["liveness"] == "not responding"
        assert shown["heartbeat"]["last_file"] == "acc_20260301_0555.npz"
    finally:
        server.server_close()
    # a malformed heartbeat is named on the panel, the status still shown
    (tmp_path / "heartbeat.json").write_text("{}", encoding="utf-8")
    assert StateFolder(tmp_path).read("heartbeat").error.startswith("heartbeat.json: missing key")
