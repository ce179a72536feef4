"""A ship log whose shaft speed drops out for half an hour (the speed still logged): the
monitor marks the harmonics as ``identify --dship`` does - the outage's blocks tested from
the speed times the ship's shaft speed per knot - and its tracked table equals the batch
run's. Before, the monitor left the outage's blocks unmarked (4 harmonic rows there), so a
line seen in an outage could be tracked as a mode on the bridge and not in the batch run."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

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

#: the outage of the shaft speed, from the voyage's start [min]
OUTAGE_MIN = (15, 45)


@pytest.fixture(scope="module")
def shaft_voyage(tmp_path_factory):
    """The monitor tests' voyage with shaft orders 1 and 2 and a 5-blade propeller."""
    shaft = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5)
    return write_voyage(tmp_path_factory.mktemp("shaft_voyage"), shaft=shaft)


def _damaged(source, target):
    """A copy of the voyage whose ship log has no shaft speed over OUTAGE_MIN."""
    shutil.copytree(source, target)
    lines = (source / "dship.tsv").read_text(encoding="utf-8").splitlines(keepends=True)
    end = next(i for i, line in enumerate(lines) if line.startswith("*/"))
    header, names, rows = lines[: end + 1], lines[end + 1], lines[end + 2 :]
    column = names.rstrip("\n").split("\t").index("Shaft speed [rpm]")
    t0 = pd.Timestamp(rows[0].split("\t", 1)[0])
    out = []
    for row in rows:
        cells = row.rstrip("\n").split("\t")
        minutes = (pd.Timestamp(cells[0]) - t0).total_seconds() / 60
        if OUTAGE_MIN[0] <= minutes < OUTAGE_MIN[1]:
            cells[column] = ""
        out.append("\t".join(cells) + "\n")
    (target / "dship.tsv").write_text("".join([*header, names, *out]), encoding="utf-8")
    return target


def test_the_monitor_marks_a_shaft_speed_outage_as_identify_does(shaft_voyage, tmp_path):
    source = _damaged(shaft_voyage, tmp_path / "voyage")
    batch = batch_run(source, tmp_path / "batch")
    selected = pd.read_parquet(tmp_path / "batch" / "id" / "selected.parquet")
    # not vacuous: blocks in the outage are marked from the speed, and checked
    shaft = pd.read_csv(tmp_path / "batch" / "id" / "shaft.csv")
    assert (shaft["shaft_rpm_from"] == "speed").sum() >= 4
    assert selected["harmonic_checked"].all()
    from_speed = set(shaft.loc[shaft["shaft_rpm_from"] == "speed", "block"])
    assert selected[selected["block"].isin(from_speed)]["harmonic"].notna().sum() >= 4
    # the monitor's marks of the identified modes equal identify's, outage included

    from data_contracts import read_dship

    monitor = marking_monitor(read_dship(source / "dship.tsv"))
    columns = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]
    marked = marked_frame(monitor, selected.drop(columns=columns))
    pd.testing.assert_frame_equal(marked[columns], selected[columns])
    # and the monitor run over the folder tracks what identify + track do
    state = tmp_path / "state"
    assert cli(
        "monitor", "--watch", source / "accelerations", "--state", state,
        "--dship", source / "dship.tsv", *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    tracked = pd.read_parquet(state / "tracked.parquet")
    pd.testing.assert_frame_equal(tracked, batch["tracked"])
    # the order lines at identify's shaft speed of every tracked block, the outage's from
    # the speed included (main left those blocks out)
    lines = pd.read_parquet(state / "harmonics.parquet")
    assert lines["block"].unique().tolist() == sorted(tracked["block"].unique())
    assert from_speed <= set(lines["block"])
    rpm = shaft.set_index("block")["shaft_rpm"]
    np.testing.assert_allclose(
        lines["frequency_hz"], lines["order"] * rpm.loc[lines["block"]].to_numpy() / 60.0,
        rtol=1e-12,
    )  # fmt: skip


def test_block_by_block_the_outage_is_marked_as_identify_marks_it(shaft_voyage, tmp_path):
    """The monitor marks the blocks one at a time as they are tracked: a block inside the
    outage is tested from the speed times the voyage's shaft speed per knot, as identify
    tests it, not by the speed-following test over that block's modes alone (which never
    sweeps: 4 harmonic rows of the outage's blocks left unmarked before)."""

    from data_contracts import read_dship

    source = _damaged(shaft_voyage, tmp_path / "voyage")
    batch_run(source, tmp_path / "batch")
    selected = pd.read_parquet(tmp_path / "batch" / "id" / "selected.parquet")
    columns = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]
    monitor = marking_monitor(read_dship(source / "dship.tsv"))
    frame = selected.drop(columns=columns)
    for block in sorted(frame["block"].unique()):
        marked = marked_frame(monitor, frame[frame["block"] <= block])
    pd.testing.assert_frame_equal(marked[columns], selected[columns])
