"""The monitor's forecast of both options equals ``identify --dship`` + ``track`` +
``forecast --option both --poles`` where a shaft order crosses a mode.

The monitor tests' voyage with shaft orders 1 and 2 and a 5-blade propeller (1.5 h, 15
blocks, seed 11): identify marks 8 of its 768 poles as harmonics (those of the marked
selected modes), and the forecast leaves them out of option A's measurement scale and of
option B's columns (but for a mode's own column). The monitor read the poles from its
store without marks: on main block 14's mode 1 differed, A by 0.62 mHz (4.642785 against
4.642162 Hz) and B by 20.8 mHz (4.670431 against 4.649586 Hz).
"""

from __future__ import annotations

import pandas as pd
import pytest

from workbench.simulate.voyage import ShaftHarmonics

from .conftest import FORECAST, IDENTIFY, MONITOR_FAST, cli, write_voyage

HARMONICS = ["--harmonic-orders", "1,2", "--blades", "5"]


@pytest.fixture(scope="module")
def crossing_voyage(tmp_path_factory):
    shaft = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5)
    return write_voyage(tmp_path_factory.mktemp("crossing_voyage"), shaft=shaft)


def test_the_monitor_forecasts_both_options_as_the_batch_run(crossing_voyage, tmp_path):
    source, out = crossing_voyage, tmp_path / "batch"
    dship = ["--dship", source / "dship.tsv"]
    assert cli(
        "identify", source / "accelerations", "--out", out / "id", *IDENTIFY, *HARMONICS, *dship,
        "--scheduler", "synchronous", "--quiet",
    ) == 0  # fmt: skip
    assert cli("track", out / "id" / "selected.parquet", "--out", out / "tracked.parquet") == 0
    assert cli(
        "forecast", "--modal", out / "tracked.parquet", *dship, *FORECAST, "--option", "both",
        "--poles", out / "id" / "poles.parquet", "--out", out / "forecast.parquet", "--quiet",
    ) == 0  # fmt: skip
    state = tmp_path / "state"
    assert cli(
        "monitor", "--watch", source / "accelerations", "--state", state, *dship, *IDENTIFY,
        *HARMONICS, *FORECAST, "--option", "both", *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    # not vacuous: poles marked, forecast rows of both options
    poles = pd.read_parquet(out / "id" / "poles.parquet")
    assert poles["harmonic"].notna().sum() == 8
    batch = pd.read_parquet(out / "forecast.parquet")
    assert batch.groupby("option")["kalman_frequency_hz"].count().tolist() == [25, 25]
    pd.testing.assert_frame_equal(
        pd.read_parquet(state / "tracked.parquet"), pd.read_parquet(out / "tracked.parquet")
    )
    # the monitor's table is a parted one, sorted by block (stable: A's rows, then B's)
    batch = batch.sort_values("block", kind="stable").reset_index(drop=True)
    monitor = pd.read_parquet(state / "forecast.parquet")
    pd.testing.assert_frame_equal(monitor, batch, check_exact=False, rtol=0, atol=1e-9)
