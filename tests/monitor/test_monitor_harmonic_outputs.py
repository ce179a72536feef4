"""What the monitor writes about the harmonics for the bridge: ``harmonic_tracks.parquet``
(the tracked lines left out as harmonics, block by block) and ``harmonics.parquet`` (the
orders' frequencies), each as the batch run says it.

A 4-h voyage (seed 3) whose orders 1 and 2 and 5-blade pass cross the modes, with the
shaft speed logged and with the speed only. identify + track leaves out 5 lines as
harmonics in both; their rows are those of the labels tracking gives them (the tracked
table of the selected modes without their marks, which decide only which labels are
harmonics). Before, the monitor looked the rows up by the tracker's serial numbers
instead of the labels: with either log it wrote 5, 15, 2, 26 and 2 rows for lines of 5,
15, 10, 26 and 8 blocks (those of whichever modes had the labels' numbers as serials).
With the speed only it wrote no order lines, though it knows the shaft rate per knot its
marks use (identify did not write that rate either).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from workbench.simulate.voyage import ShaftHarmonics

from .conftest import FORECAST, MONITOR_FAST, batch_run, cli

HARMONICS = ["--harmonic-orders", "1,2", "--blades", "5"]
IDENTIFY = ["--band", "2", "12", *HARMONICS]
COLUMNS = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]


@pytest.fixture(scope="module", params=["shaft speed", "speed only"])
def monitored(request, tmp_path_factory):
    """The voyage (all its channels, SSI's default orders), identify + track + forecast
    over it, and the monitor run over its folder. (The monitor tests' voyage reduced to 6
    channels tracks 6 such lines, but there each line's label equals the tracker's serial
    number: main wrote their rows right.)"""
    from workbench.simulate import simulate_voyage

    log_rpm = request.param == "shaft speed"
    shaft = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5, log_rpm=log_rpm)
    root = tmp_path_factory.mktemp("harmonic_outputs")
    source = root / "voyage"
    simulate_voyage(source, seed=3, hours=4.0, shaft=shaft)
    batch = batch_run(source, root / "batch", identify=IDENTIFY)
    state = root / "state"
    assert cli(
        "monitor", "--watch", source / "accelerations", "--state", state,
        "--dship", source / "dship.tsv", *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    return request.param, root / "batch" / "id", batch, state


def _batch_lines(identified) -> pd.DataFrame:
    """identify + track's harmonic lines: the rows of each label tracking leaves out as a
    harmonic, numbered by median frequency (HARMONIC_TRACKS's ``track``)."""
    from workbench.sid.tracking import track_modes

    selected = pd.read_parquet(identified / "selected.parquet")
    left_out = track_modes(selected).attrs["harmonic_labels"]
    every = track_modes(selected.drop(columns=COLUMNS))  # the same labels, none left out
    parts = []
    for track, line in enumerate(sorted(left_out, key=lambda h: h["frequency_hz"]), start=1):
        rows = every[every["mode"] == line["label"]]
        assert len(rows) == line["blocks"]
        parts.append(rows[["block", "frequency_hz"]].assign(track=track))
    lines = pd.concat(parts, ignore_index=True)
    return lines.sort_values(["block", "track"], kind="stable").reset_index(drop=True)


def test_harmonic_tracks_hold_the_rows_of_the_lines_tracking_left_out(monitored):
    log, identified, batch, state = monitored
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), batch["tracked"])
    want = _batch_lines(identified)
    # the lines and their lengths, by median frequency (2.75, 2.98, 4.29, 5.88 and
    # 10.72 Hz), as `track` reports them (main wrote 5, 15, 2, 26 and 2 rows)
    lengths = [5, 15, 10, 26, 8]
    assert want.groupby("track").size().tolist() == lengths
    got = pd.read_parquet(state / "harmonic_tracks.parquet")
    assert got.groupby("track").size().tolist() == lengths
    pd.testing.assert_frame_equal(got[["block", "frequency_hz", "track"]], want, check_dtype=False)
    # each row's order is identify's mark of that mode (0: found from the speed)
    selected = pd.read_parquet(identified / "selected.parquet")
    marks = got.merge(selected, on=["block", "frequency_hz"], how="left")
    assert len(marks) == len(got)
    np.testing.assert_array_equal(marks["order"], marks["harmonic"])
    assert marks["harmonic"].notna().mean() > 0.8


def test_order_lines_as_identify_gives_the_shaft_rate(monitored):
    """harmonics.parquet: each order's frequency at every tracked block, from the logged
    shaft speed, or with the speed only from the speed x the shaft rate per knot the
    speed-following test found (harmonics.json's ``shaft_hz_per_kn``, shaft.csv)."""
    log, identified, batch, state = monitored
    summary = json.loads((identified / "harmonics.json").read_text(encoding="utf-8"))
    shaft = pd.read_csv(identified / "shaft.csv")
    orders = [float(k) for k in summary["orders"]]
    assert orders == [1.0, 2.0, 5.0, 10.0]  # orders 1 and 2, the blade pass 5 and 10
    if log == "shaft speed":
        assert summary["method"] == "shaft speed" and shaft["shaft_rpm"].notna().all()
        rate_hz = shaft.set_index("block")["shaft_rpm"] / 60.0
    else:
        assert summary["method"] == "speed" and shaft["shaft_rpm"].isna().all()
        # the simulated propeller turns 0.3 Hz per knot; the test finds it within 2 %
        per_kn = summary["shaft_hz_per_kn"]
        assert per_kn == pytest.approx(0.3, rel=0.02)
        rate_hz = shaft.set_index("block")["speed_energy_kn"] * per_kn
    lines = pd.read_parquet(state / "harmonics.parquet")
    blocks = np.sort(batch["tracked"]["block"].unique())
    assert lines["block"].unique().tolist() == blocks.tolist()
    for order, part in lines.groupby("order"):
        np.testing.assert_allclose(
            part["frequency_hz"], order * rate_hz.loc[part["block"]].to_numpy(), rtol=1e-9
        )
    assert sorted(lines["order"].unique()) == orders


def test_the_bridge_dashboard_shows_the_orders_and_the_harmonic_lines(monitored):
    """The dashboard's shaft panel over the monitor's state: the 4 orders at the newest
    block's shaft rate and the 5 harmonic lines with their lengths (main: no order with
    the speed only; lines of 2 blocks for those of 10 and 8)."""
    import threading
    import urllib.request

    from workbench.dashboard import make_server

    log, identified, batch, state = monitored
    server = make_server(state, port=0)
    thread = threading.Thread(
        target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
    )
    thread.start()
    try:
        with urllib.request.urlopen(server.url + "api/shaft", timeout=10) as response:
            data = json.loads(response.read())
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)
    assert data["available"] and data["block"] == 44
    assert [o["order"] for o in data["orders"]] == [1.0, 2.0, 5.0, 10.0]
    lines = pd.read_parquet(state / "harmonics.parquet")
    rate_hz = lines.loc[(lines["block"] == 44) & (lines["order"] == 1.0), "frequency_hz"]
    assert data["shaft_rpm"] == pytest.approx(60.0 * float(rate_hz.iloc[0]), rel=1e-12)
    assert [t["blocks"] for t in data["tracks"]] == [5, 15, 10, 26, 8]
    want = _batch_lines(identified).groupby("track")["frequency_hz"].median()
    np.testing.assert_allclose([t["median_frequency_hz"] for t in data["tracks"]], want)
