"""A block's shaft speed, once the monitor keeps it, is ``identify --dship``'s over the whole
log, whether or not the monitor was restarted.

The ship log's shaft-speed readings are judged with readings after them
(:func:`~workbench.sid.harmonics.usable_shaft_speed`): a reading's spike test with the
:data:`~workbench.sid.harmonics.SPIKE_WINDOW` // 2 readings after it (15 s of this 1-s log),
a run of equal readings is a frozen sensor once it lasts
:data:`~workbench.sid.harmonics.FROZEN_SECONDS` (300 s). The replay below lands the files
one at a time with the log 10 minutes behind, cut at a block's end each time, so a block
is covered by the log before the readings that judge its last ones have arrived. On main
the monitor kept the block's shaft speed then: the uninterrupted run differed from
identify in block 3 (the sensor frozen for 400 s from 100 s before its end: 178.40 rpm,
identify 178.95 rpm, the frozen readings left out) and block 8 (the shaft 30 % faster from
8 s before its end: 183.75 rpm against identify's 190.60, its last readings taken for
spikes); a monitor restarted once the log reached 00:40 had block 3 right, block 8 not.
Now a block's marks and shaft speed are kept once those readings' verdicts are final
(:meth:`~workbench.sid.harmonics.LiveShaftLog.settled_until`).

Block 7 (mostly a log gap and the frozen stretch: its shaft speed is the speed x the
voyage's shaft speed per knot in identify) has no tracked mode here, so no order line.
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor
from workbench.simulate.voyage import ShaftHarmonics

from .conftest import IDENTIFY, cli, file_end, write_voyage

#: the frozen sensor: 100 s before block 3's end (00:35) to 300 s after [s from the start]
FROZEN = (2000, 2400)
#: the shaft 30 % faster: 8 s before block 8's end (01:00) to 40 s after [s]
FASTER = (3592, 3640)
#: the log is this far behind the newest file's end (a block's end each time)
LOG_LAG = pd.Timedelta(minutes=10)


@pytest.fixture(scope="module")
def faulty_voyage(tmp_path_factory):
    """The monitor tests' shaft voyage, its shaft speed frozen and raised at block ends."""
    shaft = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5)
    source = write_voyage(tmp_path_factory.mktemp("shaft_restart"), shaft=shaft)
    path = source / "dship.tsv"
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    end = next(i for i, line in enumerate(lines) if line.startswith("*/")) + 1
    column = lines[end].rstrip("\n").split("\t").index("Shaft speed [rpm]")
    rows = [line.rstrip("\n").split("\t") for line in lines[end + 1 :]]
    seconds = pd.to_datetime([cells[0] for cells in rows], utc=True)
    seconds = ((seconds - seconds[0]) / pd.Timedelta(seconds=1)).to_numpy()
    frozen = np.flatnonzero((seconds >= FROZEN[0]) & (seconds < FROZEN[1]))
    for k in frozen:
        rows[k][column] = rows[frozen[0]][column]
    for k in np.flatnonzero((seconds >= FASTER[0]) & (seconds < FASTER[1])):
        rows[k][column] = f"{1.3 * float(rows[k][column]):.1f}"
    body = "".join("\t".join(cells) + "\n" for cells in rows)
    path.write_text("".join(lines[: end + 1]) + body, encoding="utf-8")
    out = source.parent / "batch"
    assert cli(
        "identify", source / "accelerations", "--out", out, *IDENTIFY, "--dship", path,
        "--scheduler", "synchronous", "--quiet",
    ) == 0  # fmt: skip
    return source, pd.read_csv(out / "shaft.csv").set_index("block")["shaft_rpm"]


def _replay(source, folder, restart_after: int | None = None) -> pd.Series:
    """Land the files one at a time, the log LOG_LAG behind each file's end (its row at
    that time included), a monitor step each; the monitor closed and started again on its
    state after the step of file *restart_after*. The shaft speed of each block, from
    ``harmonics.parquet`` (order 1 x 60)."""
    watch, state, log = folder / "watch", folder / "state", folder / "dship.tsv"
    watch.mkdir(parents=True)
    text = (source / "dship.tsv").read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    end = next(i for i, line in enumerate(lines) if line.startswith("*/")) + 2
    header, rows = lines[:end], lines[end:]
    times = pd.to_datetime([row.split("\t", 1)[0] for row in rows], utc=True)
    log.write_text("".join(header), encoding="utf-8")
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", log, *IDENTIFY]
    argv += ["--poll", "0.05", "--settle", "0", "--late", "0", "--foreground"]

    def start():
        return prepare_monitor(parse_arguments([str(a) for a in argv]))

    monitor, written = start(), 0
    try:
        for k, path in enumerate(sorted((source / "accelerations").glob("*.npz"))):
            shutil.copy(path, watch / path.name)
            stop = int(np.searchsorted(times, file_end(path) - LOG_LAG, side="right"))
            with open(log, "a", encoding="utf-8") as handle:
                handle.writelines(rows[written:stop])
            written = max(written, stop)
            monitor.step()
            if k == restart_after:
                monitor.close()
                monitor = start()
        with open(log, "a", encoding="utf-8") as handle:
            handle.writelines(rows[written:])
        monitor.step(flush=True)
    finally:
        monitor.close()
    lines = pd.read_parquet(state / "harmonics.parquet")
    return lines[lines["order"] == 1.0].set_index("block")["frequency_hz"] * 60.0


def test_a_blocks_shaft_speed_does_not_depend_on_a_restart(faulty_voyage, tmp_path):
    source, batch = faulty_voyage
    uninterrupted = _replay(source, tmp_path / "uninterrupted")
    restarted = _replay(source, tmp_path / "restarted", restart_after=9)  # the log at 00:40
    blocks = uninterrupted.index
    assert restarted.index.equals(blocks) and len(blocks) == 14  # block 7: no tracked mode
    np.testing.assert_allclose(uninterrupted, batch.loc[blocks], rtol=1e-12)
    np.testing.assert_allclose(restarted, batch.loc[blocks], rtol=1e-12)
    # not vacuous: the frozen readings left out of block 3 and the faster ones kept in block
    # 8 (main: 178.40 and 183.75 rpm uninterrupted)
    assert batch[3] == pytest.approx(178.954, abs=1e-3)
    assert batch[8] == pytest.approx(190.598, abs=1e-3)
