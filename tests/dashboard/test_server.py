"""The dashboard's HTTP server and JSON panels, checked against the state tables."""

from __future__ import annotations

import json
import math
import os
import re
import threading
import urllib.error
import urllib.request

import numpy as np
import pandas as pd
import pytest

from workbench.dashboard import DashboardOptions, make_server
from workbench.dashboard.server import PANELS, Panel

from .conftest import publish


def get(url: str, headers: dict | None = None) -> tuple[int, dict, bytes]:
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, dict(response.headers), response.read()
    except urllib.error.HTTPError as error:
        return error.code, dict(error.headers), error.read()


def strict_json(body: bytes):
    """JSON as a browser parses it: NaN or Infinity are errors."""

    def reject(name):
        raise ValueError(f"{name} is not JSON")

    return json.loads(body, parse_constant=reject)


def panel(served, name: str) -> dict:
    status, _, body = get(served.url + f"api/{name}")
    assert status == 200, body
    return strict_json(body)


def listing(folder) -> dict:
    return {p.name: (p.stat().st_mtime_ns, p.stat().st_size) for p in folder.iterdir()}


def test_empty_folder_every_panel_waits(tmp_path, serve):
    served = serve(tmp_path)
    for name in PANELS:
        data = panel(served, name)
        assert data["available"] is False, name
        assert "not written yet" in data["message"], data
    versions = strict_json(get(served.url + "api/versions")[2])
    assert set(versions["panels"]) == set(PANELS)
    assert versions["poll_seconds"] == 1.0


def test_absent_folder_waits(tmp_path, serve):
    served = serve(tmp_path / "not-yet")
    data = panel(served, "modes")
    assert data["available"] is False
    assert "does not exist" in data["message"]


def test_modes_are_the_newest_block_of_the_tables(tmp_path, voyage, serve):
    state = publish(voyage, tmp_path, 200)
    data = panel(serve(tmp_path), "modes")
    assert data["available"] and data["block"] == 200 and data["option"] == "A"
    forecast = state.forecast[(state.forecast["block"] == 200)].set_index("mode")
    tracked = state.tracked[state.tracked["block"] == 200].set_index("mode")
    assert [c["mode"] for c in data["modes"]] == sorted(state.tracked["mode"].unique())
    for card in data["modes"]:
        row = forecast.loc[card["mode"]]
        assert card["model_lower_hz"] == row["model_lower_hz"]
        assert card["model_upper_hz"] == row["model_upper_hz"]
        assert card["kalman_frequency_hz"] == row["kalman_frequency_hz"]
        if card["mode"] in tracked.index:
            assert card["current"] is True
            assert card["frequency_hz"] == tracked.loc[card["mode"], "frequency_hz"]
            inside = row["model_lower_hz"] <= row["ssi_frequency_hz"] <= row["model_upper_hz"]
            assert card["inside_bounds"] is bool(inside)
        else:  # not identified in the newest block: no old number passed off as current
            assert card["current"] is False and card["frequency_hz"] is None
            assert (
                card["last_block"] == state.tracked.query(f"mode == {card['mode']}")["block"].max()
            )
            assert card["ssi_frequency_hz"] is None and card["inside_bounds"] is None


def test_a_mode_missing_from_the_newest_block_is_flagged(tmp_path, voyage, serve):
    # the simulated voyage misses 10 % of the estimates: find a block missing one mode
    counts = voyage.tracked.groupby("block")["mode"].nunique()
    block = int(counts[counts < counts.max()].index[-1])
    publish(voyage, tmp_path, block)
    cards = panel(serve(tmp_path), "modes")["modes"]
    present = set(voyage.tracked.query(f"block == {block}")["mode"])
    assert {c["mode"] for c in cards if c["current"]} == present
    assert any(not c["current"] for c in cards)


def test_tracked_series_cover_the_window(tmp_path, voyage, serve):
    publish(voyage, tmp_path, 150)
    data = panel(serve(tmp_path, DashboardOptions(hours=3.0)), "tracked")
    tracked = voyage.tracked[voyage.tracked["block"] <= 150]
    newest = tracked["block_start"].max()
    window = tracked[tracked["block_start"] > newest - pd.Timedelta(hours=3)]
    # 3 h of 5-min steps: 36 blocks, 115 to 150
    assert window["block"].min() == 115
    assert [s["mode"] for s in data["series"]] == sorted(window["mode"].unique())
    assert sum(len(s["frequency_hz"]) for s in data["series"]) == len(window)
    for series in data["series"]:
        rows = window[window["mode"] == series["mode"]].sort_values("block")
        assert series["block"] == rows["block"].tolist()
        np.testing.assert_array_equal(series["frequency_hz"], rows["frequency_hz"])
        assert series["t"][0] == rows["block_start"].iloc[0].value // 1_000_000


def test_tracked_panel_draws_the_shaft_orders_in_the_modes_range(tmp_path, voyage, serve):
    from data_contracts import write_table
    from workbench.dashboard.state import HARMONIC_LINES

    publish(voyage, tmp_path, 150)
    blocks = voyage.tracked[["block", "block_start"]].drop_duplicates("block")
    blocks = blocks[blocks["block"] <= 150]
    # 180 rpm: order 1 at 3 Hz (among the modes), order 5 at 15 Hz (above them)
    lines = pd.concat(
        [blocks.assign(order=k, frequency_hz=k * 180.0 / 60.0) for k in (1.0, 5.0)],
        ignore_index=True,
    )
    write_table(lines, tmp_path / "harmonics.parquet", HARMONIC_LINES)
    data = panel(serve(tmp_path, DashboardOptions(hours=3.0)), "tracked")
    window = voyage.tracked[voyage.tracked["block"].between(115, 150)]
    low, high = 0.9 * window["frequency_hz"].min(), 1.1 * window["frequency_hz"].max()
    assert low < 3.0 < high < 15.0
    assert [h["order"] for h in data["harmonics"]] == [1.0]  # 15 Hz would stretch the axis
    assert data["harmonics"][0]["block"] == list(range(115, 151))
    assert data["harmonics"][0]["frequency_hz"] == [3.0] * 36
    # the modes are unchanged
    assert sum(len(s["frequency_hz"]) for s in data["series"]) == len(window)


def test_tracked_panel_in_percent_of_each_modes_reference(tmp_path, voyage, serve):
    """Before the health chart exists the reference is the model's median so far; the
    changes, the band and the shared block times follow from the tables."""
    from workbench.dashboard.views import mode_references

    publish(voyage, tmp_path, 150)  # the health chart starts after its reference (block 215)
    data = panel(serve(tmp_path, DashboardOptions(hours=3.0)), "tracked")
    tracked = voyage.tracked[voyage.tracked["block"] <= 150]
    forecast = voyage.forecast[voyage.forecast["block"] <= 150]
    model = forecast[forecast["option"] == "A"].groupby("mode")["model_frequency_hz"].median()
    assert data["reference"] == "median of the model so far" and data["option"] == "A"
    assert data["start"] == "2024-03-01T09:35:00Z" and data["end"] == "2024-03-01T12:30:00Z"
    assert data["blocks"]["block"] == list(range(115, 151))
    times = dict(zip(data["blocks"]["block"], data["blocks"]["t"], strict=True))
    for series in data["series"]:
        reference = model[series["mode"]]
        assert series["reference_hz"] == reference
        rows = tracked[(tracked["mode"] == series["mode"]) & (tracked["block"] >= 115)]
        np.testing.assert_allclose(
            series["change_percent"], 100 * (rows["frequency_hz"] / reference - 1), atol=5e-5
        )
        band = forecast[(forecast["mode"] == series["mode"]) & (forecast["block"] >= 115)]
        assert series["band"]["block"] == band["block"].tolist()
        np.testing.assert_allclose(
            series["band"]["upper_percent"],
            100 * (band["model_upper_hz"] / reference - 1),
            atol=5e-5,
        )
        assert [times[b] for b in series["block"]] == series["t"]
    # without forecast nor health: the tracked median; with the health chart: its reference
    alone, what = mode_references(tracked)
    assert what == "median tracked frequency so far"
    assert alone == tracked.groupby("mode")["frequency_hz"].median().to_dict()
    health = voyage.health
    charted, what = mode_references(voyage.tracked, voyage.forecast, health)
    blocks = health.loc[health["phase"] == "reference", "block"]
    assert what == f"median over the health reference period (blocks {blocks.min()}-{blocks.max()})"
    in_reference = voyage.tracked[voyage.tracked["block"].isin(blocks)]
    assert charted == in_reference.groupby("mode")["frequency_hz"].median().to_dict()


def test_health_and_alarms_follow_the_chart(tmp_path, voyage, serve):
    onset = int(voyage.alarms["start_block"].iloc[0])
    publish(voyage, tmp_path, onset + 5)
    served = serve(tmp_path)
    health = panel(served, "health")
    table = voyage.health[voyage.health["block"] <= onset + 5]
    assert health["block"] == onset + 5 and health["alarm"] is True
    assert health["limit"] == pytest.approx(table["limit"].iloc[-1], rel=1e-12)
    assert sum(health["points"]["alarm"]) == int(table["alarm"].sum())
    assert sum(health["points"]["reference"]) == int((table["phase"] == "reference").sum())
    shares = {c["mode"]: c["share"] for c in health["contributions"]}
    newest = table.iloc[-1]
    assert shares == {m: newest[f"contribution_{m}"] for m in range(1, 8)}
    assert [c["share"] for c in health["contributions"]] == sorted(shares.values(), reverse=True)
    alarms = panel(served, "alarms")
    assert alarms["count"] == 1 and alarms["active"] is True
    episode = alarms["alarms"][0]
    assert (episode["start_block"], episode["end_block"]) == (onset, onset + 5)
    seen = table[table["block"] >= onset]
    assert episode["peak_statistic"] == pytest.approx(seen["statistic"].max(), rel=1e-12)
    assert episode["top_mode"] == 3  # the damaged mode


def test_health_waits_for_the_reference_period(tmp_path, voyage, serve):
    publish(voyage, tmp_path, voyage.reference_end_block - 1)
    served = serve(tmp_path)
    assert panel(served, "health")["available"] is False
    assert panel(served, "alarms")["available"] is False
    assert panel(served, "modes")["available"] is True


def test_data_health_summary(tmp_path, voyage, serve):
    publish(voyage, tmp_path, 100)
    data = panel(serve(tmp_path, DashboardOptions(hours=6.0)), "data_health")
    table = voyage.data_health[voyage.data_health["block"].between(29, 100)]  # 72 blocks
    assert data["summary"]["blocks"] == 72
    assert data["summary"]["median_latency_s"] == pytest.approx(table["latency_s"].median())
    assert data["summary"]["worst_latency_s"] == pytest.approx(table["latency_s"].max())
    assert data["summary"]["gap_seconds"] == pytest.approx(table["gap_seconds"].sum())
    dropped = (table["dropped_channels"] != "").sum()
    assert data["summary"]["blocks_with_dropped_channels"] == dropped > 0
    latest = table.iloc[-1]
    assert data["latest"]["block"] == 100
    assert data["latest"]["n_channels"] == latest["n_channels"]
    assert data["latest"]["dropped_channels"] == [
        c for c in latest["dropped_channels"].split(",") if c
    ]
    assert [r["block"] for r in data["rows"]] == list(range(100, 88, -1))


def test_etags_send_only_changed_panels(tmp_path, voyage, serve):
    state = publish(voyage, tmp_path, 220)
    served = serve(tmp_path)
    status, headers, _ = get(served.url + "api/modes")
    tag = headers["ETag"]
    assert get(served.url + "api/modes", {"If-None-Match": tag})[0] == 304
    before = strict_json(get(served.url + "api/versions")[2])["panels"]
    # only the heartbeat changes: only the status panel's version moves
    status_file = tmp_path / "status.json"
    status_file.write_text(status_file.read_text().replace('"running"', '"stopped"'))
    after = strict_json(get(served.url + "api/versions")[2])["panels"]
    assert {k for k in before if before[k] != after[k]} == {"status"}
    assert panel(served, "status")["state"] == "stopped"
    state.append()
    status, headers, body = get(served.url + "api/modes", {"If-None-Match": tag})
    assert status == 200 and headers["ETag"] != tag
    assert strict_json(body)["block"] == 221


def test_unreadable_file_keeps_last_good_data_and_says_why(tmp_path, voyage, serve):
    publish(voyage, tmp_path, 120)
    served = serve(tmp_path)
    assert panel(served, "tracked")["block"] == 120
    (tmp_path / "tracked.parquet").write_bytes(b"PAR1 half a file")
    data = panel(served, "tracked")
    assert data["available"] is True and data["block"] == 120
    assert "tracked.parquet" in data["message"] and "cannot read" in data["message"]


def test_corrupt_files_before_any_good_one_wait_with_the_reason(tmp_path, serve):
    (tmp_path / "tracked.parquet").write_bytes(b"")
    (tmp_path / "status.json").write_text('{"state": "running"')
    (tmp_path / "data_health.parquet").write_text("block,n_channels\n1,2\n")
    served = serve(tmp_path)
    for name in ("tracked", "status", "data_health"):
        data = panel(served, name)
        assert data["available"] is False
        assert re.search(r"\w+\.(parquet|json)", data["message"]), data
    assert "not valid JSON" in panel(served, "status")["message"]


def test_status_with_a_missing_key_names_it(tmp_path, serve):
    (tmp_path / "status.json").write_text(json.dumps({"updated_at": "2026-01-01T00:00:00Z"}))
    data = panel(serve(tmp_path), "status")
    assert data["available"] is False
    assert "missing key 'last_block'" in data["message"]


def test_contract_violation_names_the_column(tmp_path, voyage, serve):
    state = publish(voyage, tmp_path, 100)
    bad = state.data_health.iloc[:5].drop(columns=["latency_s"])
    bad.to_parquet(tmp_path / "data_health.parquet")
    data = panel(serve(tmp_path), "data_health")
    assert data["message"].startswith("data_health.parquet") and "latency_s" in data["message"]


def test_json_has_no_nan(tmp_path, voyage, serve):
    publish(voyage, tmp_path, voyage.last_block)
    served = serve(tmp_path)
    for name in PANELS:
        panel(served, name)  # strict_json raises on NaN/Infinity
    cards = panel(served, "modes")["modes"]
    assert all(c["frequency_hz"] is None or math.isfinite(c["frequency_hz"]) for c in cards)


def test_the_dashboard_never_writes_into_the_state_folder(tmp_path, voyage, serve):
    publish(voyage, tmp_path, 230)
    (tmp_path / "alarms.parquet").write_bytes(b"junk")
    os.chmod(tmp_path, 0o555)
    try:
        before = listing(tmp_path)
        served = serve(tmp_path)
        for _ in range(2):
            for name in PANELS:
                panel(served, name)
        assert listing(tmp_path) == before
    finally:
        os.chmod(tmp_path, 0o755)


def test_page_and_assets_are_served_by_the_package(tmp_path, serve):
    served = serve(tmp_path)
    status, headers, body = get(served.url)
    page = body.decode()
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    assert not re.search(r"(src|href)=\"(https?:)?//", page), "page loads from the network"
    assets = re.findall(r"(?:src|href)=\"([^\"]+)\"", page)
    assert sorted(assets) == ["static/dashboard.css", "static/dashboard.js"]
    for asset in assets:
        status, headers, body = get(served.url + asset)
        assert status == 200 and len(body) > 500
        assert "http://" not in body.decode().replace("http://www.w3.org/2000/svg", "")
    assert '"poll_ms": 1000' in page and '"stale_s": 900.0' in page


@pytest.mark.parametrize(
    "path", ["static/../state.py", "static/state.py", "api/../server.py", "etc/passwd", "api/"]
)
def test_other_paths_are_404_json(tmp_path, serve, path):
    status, headers, body = get(serve(tmp_path).url + path)
    assert status == 404
    assert headers["Content-Type"] == "application/json"
    assert "Traceback" not in body.decode()


def test_an_internal_error_is_one_json_line(tmp_path, serve, monkeypatch):
    served = serve(tmp_path)

    def broken(state, options):
        raise RuntimeError("boom")

    monkeypatch.setitem(PANELS, "modes", Panel(("tracked",), broken))
    status, headers, body = get(served.url + "api/modes")
    assert status == 500
    assert strict_json(body) == {"available": False, "message": "internal error: RuntimeError"}


def test_tables_without_rows_wait(tmp_path, voyage, serve):
    """The monitor has started but identified nothing yet: empty tables, no block."""
    state = publish(voyage, tmp_path)
    state.write(-1)
    served = serve(tmp_path)
    for name in ("modes", "tracked", "data_health"):
        data = panel(served, name)
        assert data == {"available": False, "message": "no block identified yet"}, name
    status = panel(served, "status")
    assert status["last_block"] is None and status["blocks_done"] == 0


@pytest.mark.parametrize(
    "host, status",
    [("127.0.0.1:8050", 200), ("localhost", 200), ("[::1]:8050", 200),
     ("attacker.example:8050", 421), ("192.168.1.20", 421)],
)  # fmt: skip
def test_a_localhost_dashboard_answers_local_names_only(tmp_path, serve, host, status):
    """DNS rebinding: a page of another site must not read a localhost dashboard."""
    served = serve(tmp_path)
    assert get(served.url + "api/versions", {"Host": host})[0] == status


def test_a_dashboard_on_the_network_answers_any_name(tmp_path):
    server = make_server(tmp_path, host="0.0.0.0", port=0)
    try:
        assert server.host_allowed("bridge-pc.local:8050")
        assert server.host_allowed(None)
    finally:
        server.server_close()


def test_many_screens_while_blocks_arrive(tmp_path, voyage, serve):
    """Eight clients poll every panel while the state is republished block by block:
    every answer is a 200 with strict JSON, and the blocks they see never go back."""
    state = publish(voyage, tmp_path, 240)
    served = serve(tmp_path)
    stop = threading.Event()
    failures: list[str] = []

    def client() -> None:
        seen = 0
        while not stop.is_set():
            for name in PANELS:
                status, _, body = get(served.url + f"api/{name}")
                try:
                    data = strict_json(body)
                except ValueError as error:
                    failures.append(f"{name}: {error}")
                    continue
                if status != 200:
                    failures.append(f"{name}: HTTP {status}")
                if name == "modes" and data.get("block") is not None:
                    if data["block"] < seen:
                        failures.append(f"modes went back from {seen} to {data['block']}")
                    seen = data["block"]

    threads = [threading.Thread(target=client) for _ in range(8)]
    for thread in threads:
        thread.start()
    try:
        for _ in range(4):
            state.append()
    finally:
        stop.set()
        for thread in threads:
            thread.join(timeout=30)
    assert failures == []
    assert panel(served, "modes")["block"] == 244


def test_empty_health_chart_says_when_it_starts(tmp_path, voyage, serve):
    """While the chart learns, the health panel says from which block and when it charts
    (the monitor's status.json ``health_note``, issue 29)."""
    from data_contracts import HEALTH, write_table

    publish(voyage, tmp_path, 20)
    write_table(
        pd.DataFrame(columns=list(HEALTH.column_names)), tmp_path / "health.parquet", HEALTH
    )
    status_file = tmp_path / "status.json"
    status = json.loads(status_file.read_text())
    note = (
        "health: the chart starts at block 216 (2024-03-01 18:00Z), after this voyage's 12-h "
        "model and 6-h reference; with a saved baseline (monitor --baseline) it starts at the "
        "first block"
    )
    status_file.write_text(json.dumps({**status, "health_note": note}))
    served = serve(tmp_path)
    data = panel(served, "health")
    assert data["available"] is False
    assert data["message"] == "the health chart has no block yet; " + note.removeprefix("health: ")
    assert panel(served, "status")["state"] == status["state"]  # the key is valid there
