"""A ship log with the speed but no shaft speed (``workbench simulate --no-shaft-rpm``):
the monitor marks the harmonics from the speed as ``identify --dship`` does (the
speed-following test over the whole voyage so far), so its tracked table, what the bridge
sees, equals identify + track. Before, the monitor marked nothing without a shaft-speed
column: on this 3-h voyage (6 channels) it tracked a harmonic line at 5.0 Hz (11 blocks,
82 % of its rows marked by identify) as a mode, 95 tracked rows against identify + track's
84 (both tests fail on the commit before)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import read_dship
from workbench.simulate.voyage import ShaftHarmonics

from .conftest import (
    FORECAST,
    IDENTIFY,
    MONITOR_FAST,
    batch_run,
    cli,
    marked_frame,
    marking_monitor,
    write_voyage,
)

HARMONICS = ["--harmonic-orders", "1,2", "--blades", "5"]
COLUMNS = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]


@pytest.fixture(scope="module")
def speed_only(tmp_path_factory):
    """The monitor tests' voyage with shaft orders 1 and 2 and a 5-blade propeller, its
    ship log without the shaft speed; identify + track over it."""
    shaft = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5, log_rpm=False)
    root = tmp_path_factory.mktemp("speed_only")
    source = write_voyage(root, shaft=shaft, hours=3.0, seed=0)
    batch = batch_run(source, root / "batch", identify=[*IDENTIFY, *HARMONICS])
    selected = pd.read_parquet(root / "batch" / "id" / "selected.parquet")
    return source, batch, selected


def _monitor(log):
    """A monitor holding only what the marking uses, reading *log* as its ship log."""
    from workbench.sid.harmonics import HarmonicOptions

    return marking_monitor(log, HarmonicOptions(orders=(1, 2), blades=5))


def test_the_monitor_tracks_no_harmonic_from_a_speed_only_log(speed_only, tmp_path):
    source, batch, selected = speed_only
    # not vacuous: the log has no shaft speed, and identify marks from the speed
    log = read_dship(source / "dship.tsv")
    assert "shaft_rpm" not in log.columns and "speed_kn" in log.columns
    marked = selected[selected["harmonic"].notna()]
    assert (marked["harmonic"] == 0).all() and len(marked) >= 10
    state = tmp_path / "state"
    assert cli(
        "monitor", "--watch", source / "accelerations", "--state", state,
        "--dship", source / "dship.tsv", *IDENTIFY, *HARMONICS, *FORECAST, *MONITOR_FAST,
        "--once",
    ) == 0  # fmt: skip
    tracked = pd.read_parquet(state / "tracked.parquet")
    pd.testing.assert_frame_equal(tracked, batch["tracked"])
    # the line left out is listed as a harmonic (its marked rows: order unknown, 0)
    tracks = pd.read_parquet(state / "harmonic_tracks.parquet")
    assert tracks["track"].nunique() == 1 and set(tracks["order"].dropna()) == {0.0}


def test_marks_block_by_block_with_the_log_growing_equal_identify(speed_only):
    """The speed-following test fed block by block, the ship log growing with the blocks
    (half a block behind: the newest block is tested with the speed logged so far, then
    again once the log covers it), ends with identify's marks, and each step's marks equal
    the test run afresh on the blocks so far with the log so far."""
    from workbench.sid.harmonics import HarmonicOptions, mark_harmonics

    source, _, selected = speed_only
    log = read_dship(source / "dship.tsv")
    frame = selected.drop(columns=COLUMNS)
    monitor = _monitor(log)
    blocks = np.sort(frame["block"].unique())
    ends = pd.to_datetime(frame.drop_duplicates("block").set_index("block")["block_end"])
    options = HarmonicOptions(orders=(1, 2), blades=5)
    pending_seen = False
    for block in blocks:
        so_far = frame[frame["block"] <= block]
        now = ends[block] - pd.Timedelta(minutes=10)
        grown = log[pd.to_datetime(log["time"], utc=True) < now].reset_index(drop=True)
        monitor._read_log = lambda grown=grown: grown
        marked = marked_frame(monitor, so_far)
        pending_seen |= monitor._marks_pending
        afresh = mark_harmonics(so_far, so_far.iloc[:0], grown, options).selected
        pd.testing.assert_frame_equal(marked[COLUMNS], afresh[COLUMNS], check_names=False)
    assert pending_seen
    monitor._read_log = lambda: log
    marked = marked_frame(monitor, frame)
    pd.testing.assert_frame_equal(marked[COLUMNS], selected[COLUMNS])
