"""A recorder whose sample clock runs some ppm off its rate is still one record.

The recorder writes 5-min files of 38 400 samples at a nominal 128 Hz; its sample clock
runs 20 ppm (or 100 ppm) fast, so each file really lasts 299.994 s (299.97 s), while its
start is stamped by the recorder's disciplined system clock: every stamp lies 6 ms (30 ms)
before the previous file's nominal end. Before, re-timing chained on the placed ends, the
placed times walked 6 ms per file away from the stamps and, after 45 min (10 min), the next
stamp lay more than the 50-ms clock jitter before the placed end: identify exited 1 for the
whole voyage ("acc_009.npz: starts 0.054 s before the end of acc_008.npz (overlapping or
duplicate files)"; 20 ppm at 128 Hz: 6 ms is 0.77 samples, beyond the half sample ignored).
Now the stamps are judged against the least-squares line of the run's stamps on its
sample count, the jitter being the distance from that line: every block is identified from
the recorder's consecutive samples, cut where that line puts the UTC of the block's label
(``tests/robustness/test_clock_drift_utc.py``), and the summary says the clock's rate
offset. A fast clock records the 2 h in 2 h less its walk (144 ms at 20 ppm), so the last
block's span (1:40-2:00 UTC) is not recorded whole: it is cut at the record's last sample
(``EDGE_SHIFT_S``), its first sample 0.12 s before its label's UTC, and the summary says
so. A real gap is still a gap and a real overlap an error naming the file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, write_accelerations
from workbench.cli import main

from .voyage import (
    CHANNELS,
    SMALL_SSI_ARGS,
    T0,
    assert_store_equals_identify,
    identify_run,
    response,
    selected_modes,
)

RATE_HZ = 128.0
FILE_S = 300.0
N_FILES = 24  # 2 h
#: 20-min blocks every 10 min (11 in 2 h), decimated to 16 Hz, small SSI.
ARGS = [
    "--block-minutes",
    "20",
    "--step-minutes",
    "10",
    "--rate",
    "16",
    "--band",
    "1",
    "6.3",
    *SMALL_SSI_ARGS,
]
#: The file conditioner (each file once) and the block builder (each block from raw files).
PATHS = {"per-file": [], "per-block": ["--conditioning", "per-block"]}
MONITOR_ARGS = [*ARGS, "--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _write(folder: Path, stamps_s) -> list[Path]:
    """The 2-h record in 5-min files, file k stamped *stamps_s[k]* seconds after T0."""
    folder.mkdir(parents=True)
    n = int(FILE_S * RATE_HZ)
    data = response(n * N_FILES, 0, RATE_HZ)
    return [
        write_accelerations(
            AccelerationRecord(
                data[k * n : (k + 1) * n], RATE_HZ, T0 + pd.Timedelta(seconds=stamp), CHANNELS
            ),
            folder / f"acc_{k:03d}.npz",
        )
        for k, stamp in enumerate(stamps_s)
    ]


def _drifting(ppm: float) -> np.ndarray:
    """Stamps of files whose sample clock runs *ppm* fast (each lasts 300 s / (1 + ppm))."""
    return np.arange(N_FILES) * FILE_S / (1 + ppm * 1e-6)


#: Clock jitter on top of the drift: up to +-10 ms, the same draw in every run. [s]
JITTER_S = np.random.default_rng(7).uniform(-0.010, 0.010, N_FILES)


@pytest.fixture(scope="module")
def voyages(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("drift")
    _write(root / "clean", np.arange(N_FILES) * FILE_S)
    _write(root / "20ppm", _drifting(20))
    _write(root / "100ppm", _drifting(100))
    _write(root / "20ppm+jitter", _drifting(20) + JITTER_S)
    return {name: root / name for name in ("clean", "20ppm", "100ppm", "20ppm+jitter")}


def _identify(capsys, folder, out, extra=()):
    return identify_run(capsys, folder, out, [*ARGS, *extra])


_modes = selected_modes


def _edge_note(out: str) -> str:
    """The blocks the summary says were cut at the edge of a drifting record's data."""
    (line,) = [line for line in out.splitlines() if line.startswith("block(s) cut at")]
    assert line.startswith(
        "block(s) cut at the first or last sample of a drifting record (or of its data "
        "between gaps), which misses their UTC span by at most 1 s; their first sample "
        "recorded this long after the UTC of their label: "
    )
    return line.split("label: ")[1]


def _drift_note(out: str) -> str:
    notes = [line for line in out.splitlines() if line.startswith("clock drift")]
    assert len(notes) == 1
    return notes[0]


@pytest.fixture(scope="module")
def clean_modes(voyages, tmp_path_factory) -> dict[str, pd.DataFrame]:
    modes = {}
    for path, extra in PATHS.items():
        out = tmp_path_factory.mktemp("clean")
        code = main(["identify", str(voyages["clean"]), "--out", str(out), *ARGS, *extra])
        assert code == 0
        modes[path] = _modes(out)
        assert modes[path]["block"].drop_duplicates().tolist() == list(range(11))
    return modes


@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize(("voyage", "ppm"), [("20ppm", 20.0), ("100ppm", 100.0)])
def test_a_drifting_sample_clock_gives_every_block(
    voyages, clean_modes, tmp_path, capsys, path, voyage, ppm
):
    code, out, err = _identify(capsys, voyages[voyage], tmp_path / "out", PATHS[path])
    assert code == 0, err  # main: exit 1, acc_009.npz (acc_002.npz) "overlapping or duplicate"
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    # block 10 (1:40-2:00 UTC) ends 144 ms (720 ms) after the record's last sample: cut at
    # it (h54's branch: blocks 0-9)
    assert blocks["block"].tolist() == list(range(11))
    assert (blocks["status"] == "ok").all()
    # block 0 starts at the first sample (the line's time there, to rounding) and block 10
    # ends at the last: the numbers of the voyage stamped without drift
    modes, clean = _modes(tmp_path / "out"), clean_modes[path]
    for block in (0, 10):
        ends, clean_ends = modes[modes["block"] == block], clean[clean["block"] == block]
        assert len(ends) == len(clean_ends) > 0
        for column in ("frequency_hz", "damping_ratio"):
            np.testing.assert_allclose(ends[column], clean_ends[column], rtol=0, atol=1e-12)
    # the later blocks hold other samples: those recorded in their UTC spans
    later = modes[modes["block"] == 9]["frequency_hz"].to_numpy()
    assert np.abs(later - clean[clean["block"] == 9]["frequency_hz"].to_numpy()).max() > 1e-6
    # the stamps lie on a line (no jitter): its slope is the clock's rate offset, to
    # rounding; the last file starts 23 * 300 s * ppm / (1 + ppm) after its stamp
    walk_ms = 23 * FILE_S * ppm / (1e6 + ppm) * 1e3
    assert _drift_note(out) == (
        f"clock drift: acc_000.npz .. acc_023.npz (24 files, one record): the sample clock "
        f"runs {ppm:+.1f} ppm from 128 Hz (stamps regressed on the sample count; up to 0.0 ms "
        f"about that line); the files follow the sample count, up to {walk_ms:+.1f} ms from "
        "their stamps (acc_023.npz)"
    )
    assert "clock jitter" not in out
    # block 10's first sample: where the line puts 6000 s UTC less 6000 s x ppm / (1 + ppm)
    assert _edge_note(out) == f"block 10 {-6000 * ppm / (1e6 + ppm):+.2f} s"


def test_drift_and_jitter_give_every_block(voyages, clean_modes, tmp_path, capsys):
    # the block builder: files whose stamps miss the previous end by less than half a
    # sample stay at their stamps (as before), off the conditioner's lattice, which then
    # builds those blocks from the raw files too
    code, out, err = _identify(
        capsys, voyages["20ppm+jitter"], tmp_path / "out", PATHS["per-block"]
    )
    assert code == 0, err  # main: exit 1, acc_009.npz "overlapping or duplicate files"
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert (blocks["status"] == "ok").all() and len(blocks) == 11  # as without jitter
    note = _drift_note(out)
    # the line of the stamps on the sample count, fitted here independently
    x = np.arange(N_FILES) * FILE_S  # the sample count in nominal seconds
    y = _drifting(20) + JITTER_S - x
    beta, alpha = np.polyfit(x, y, 1)
    ppm = -beta / (1 + beta) * 1e6
    about_ms = np.abs(y - (alpha + beta * x)).max() * 1e3
    walk_ms = -y[-1] * 1e3 + JITTER_S[0] * 1e3  # the last file from its stamp
    # 24 stamps jittered by up to 10 ms over 2 h give 20 ppm within 1 ppm (its standard
    # error: 5.8 ms / 2 h * sqrt(12 / 24) = 0.6 ppm)
    assert abs(ppm - 20.0) < 1.0
    assert note == (
        f"clock drift: acc_000.npz .. acc_023.npz (24 files, one record): the sample clock "
        f"runs {ppm:+.1f} ppm from 128 Hz (stamps regressed on the sample count; up to "
        f"{about_ms:.1f} ms about that line); the files follow the sample count, up to "
        f"{walk_ms:+.1f} ms from their stamps (acc_023.npz)"
    )


def test_a_real_gap_in_a_drifting_record_stays_a_gap(tmp_path, capsys):
    stamps = _drifting(20)
    stamps[12:] += 2.0  # 2 s of data lost between acc_011 and acc_012
    _write(tmp_path / "acc", stamps)
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    # acc_012's stamp, 3602 s - 12 * 300 s * 20 ppm = 3601.928 s, lies 2 s after where
    # the first record's clock (its stamps' line) puts the next file; the new record
    # starts those 2 s of samples after the first record's sample count ends (3600 s), on
    # the same time (before: at its stamp, the gap 72 ms short, "gap of 1.9 s")
    assert blocks["block"].tolist() == list(range(11))
    skipped = blocks.loc[blocks["status"] == "skipped"]
    assert skipped["block"].tolist() == [5, 6]  # 3000-4200 s and 3600-4800 s
    assert skipped["reason"].iloc[0] == "gap of 2.0 s between acc_011.npz and acc_012.npz"
    # block 6's UTC span (from 3600 s) begins 72 ms after the first record's last sample
    # (3600 s / (1 + 20 ppm)): 1.93 s of the gap lie in it
    assert skipped["reason"].iloc[1] == "gap of 1.9 s between acc_011.npz and acc_012.npz"
    assert (blocks.loc[~blocks["block"].isin([5, 6]), "status"] == "ok").all()
    assert _drift_note(out).startswith(
        "clock drift: acc_000.npz .. acc_023.npz (24 files in 2 records): the sample clock "
        "runs +20.0 to +20.0 ppm from 128 Hz"
    )


@pytest.mark.parametrize("path", list(PATHS))
def test_a_lost_file_in_a_drifting_record_keeps_the_last_block(clean_modes, tmp_path, capsys, path):
    """40 ppm fast, acc_012.npz lost. Before, the record after the gap started at its
    stamp, 13 * 300 s * 40 ppm = 156 ms before the first record's sample count would have
    put it, so it ended 156 ms before the last block's end (7200 s): block 10 was neither
    identified nor said (blocks 0-9). The clock line of the record before the gap carries
    its time over the gap (its stamps lie on it to rounding): the record after the gap
    follows on the samples the recorder counted. Block 4 (2400-3600 s UTC) ends 144 ms
    after the first record's last sample (3600 s / (1 + 40 ppm)), in the lost file, and
    block 10 288 ms after the last sample: each is cut at that sample, 96 ms (240 ms)
    before its label's UTC, and said (h54's branch: block 4 skipped, "gap of 0.1 s", and
    block 10 not listed)."""
    files = _write(tmp_path / "acc", _drifting(40))
    files[12].unlink()
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out", PATHS[path])
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["block"].tolist() == list(range(11))
    skipped = blocks.loc[blocks["status"] == "skipped"]
    assert skipped["block"].tolist() == [5, 6]  # 3000-4200 and 3600-4800 s
    # the file's 300 s of samples (main: "gap of 299.8 s", the stamps' time)
    # (block 6's UTC span begins 144 ms after the gap does)
    assert skipped["reason"].tolist() == [
        f"gap of {gap} s between acc_011.npz and acc_013.npz" for gap in ("300.0", "299.9")
    ]
    assert _edge_note(out) == "block 4 -0.10 s, block 10 -0.24 s"
    # block 0, cut at the first sample, and block 10 (and, from the raw files, block 4),
    # cut at the last ones, are the voyage's without the loss and the drift (the file
    # conditioner pads block 4's filters with the lost file's raw edge there)
    modes, clean = _modes(tmp_path / "out"), clean_modes[path]
    for block in [0, 10] if path == "per-file" else [0, 4, 10]:
        ends, clean_ends = modes[modes["block"] == block], clean[clean["block"] == block]
        assert len(ends) == len(clean_ends) > 0
        np.testing.assert_allclose(ends["frequency_hz"], clean_ends["frequency_hz"], atol=1e-12)
    assert _drift_note(out).startswith(
        "clock drift: acc_000.npz .. acc_023.npz (23 files in 2 records): the sample clock "
        "runs +40.0 to +40.0 ppm from 128 Hz"
    )


def test_a_real_overlap_in_a_drifting_record_is_still_an_error(tmp_path, capsys):
    stamps = _drifting(20)
    stamps[14:] -= 1.0  # acc_014 starts 1 s before acc_013 ends: not the same recorder
    files = _write(tmp_path / "acc", stamps)
    code, _, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 1
    assert err.strip().splitlines() == [
        f"error: {files[14]}: starts 1 s before the end of acc_013.npz "
        "(overlapping or duplicate files)"
    ]


def test_the_monitor_gives_the_blocks_identify_gives(voyages, tmp_path, capsys):
    watch, state = tmp_path / "watch", tmp_path / "state"
    shutil.copytree(voyages["20ppm+jitter"], watch)
    code = main(["monitor", "--watch", str(watch), "--state", str(state), *MONITOR_ARGS])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "Traceback" not in captured.err
    health = pd.read_parquet(state / "data_health.parquet").sort_values("block")
    # as identify: block 10's UTC span ends 144 ms after the last sample, so it is cut at
    # it (main: 0-9, block 10 listed on the sample count but never decided)
    assert health["block"].tolist() == list(range(11))
    assert (health["status"] == "ok").all()
    notes = (state / "notes.txt").read_text(encoding="utf-8")
    drift = [line for line in notes.splitlines() if "clock drift" in line]
    assert len(drift) == 1  # said once, when the record's drift is told apart from jitter
    code, out, err = _identify(capsys, voyages["20ppm+jitter"], tmp_path / "batch")
    assert code == 0, err
    assert_store_equals_identify(state, tmp_path / "batch")


def test_the_monitor_keeps_the_last_block_after_a_lost_file_as_identify(tmp_path, capsys):
    """The monitor places the files as identify does: the same blocks, the same modes."""
    files = _write(tmp_path / "watch", _drifting(40))
    files[12].unlink()
    state = tmp_path / "state"
    code = main(
        ["monitor", "--watch", str(tmp_path / "watch"), "--state", str(state)] + MONITOR_ARGS
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    health = pd.read_parquet(state / "data_health.parquet").sort_values("block")
    assert health["block"].tolist() == list(range(11))  # as identify (its docstring)
    assert health.loc[health["status"] == "skipped", "block"].tolist() == [5, 6]
    # the record after the gap is said once, as placed: on the sample count, 13 * 300 s *
    # 40 ppm / (1 + 40 ppm) = 156.0 ms after its stamp (main: "acc_013.npz: start re-timed
    # by +156.0 ms to the previous file's end", and so on for each file until its run's
    # own stamps told the drift)
    notes = (state / "notes.txt").read_text(encoding="utf-8").splitlines()
    clock = [line.split("Z ", 1)[1] for line in notes if "acc_0" in line]
    # (the first files re-timed by 12 ms more each until the walk passes the jitter)
    assert [line.split(":")[0] for line in clock] == [f"acc_00{k}.npz" for k in range(1, 6)] + [
        "acc_013.npz"
    ]
    assert clock[3].startswith("acc_004.npz: start re-timed by +48.0 ms to the previous file's")
    assert clock[4].startswith("acc_005.npz: clock drift: acc_000.npz .. acc_005.npz")
    assert clock[5] == (
        "acc_013.npz: after a gap of 300.0 s from acc_011.npz, on the record's sample count "
        "(the line of its stamps carries the time over the gap): +156.0 ms from its stamp"
    )
    code, out, err = _identify(capsys, tmp_path / "watch", tmp_path / "batch")
    assert code == 0, err
    assert_store_equals_identify(state, tmp_path / "batch")


def test_a_file_landing_in_order_after_a_carried_gap_is_not_called_late(tmp_path):
    """40 ppm fast, acc_012.npz lost, the files landing one by one (--late 0): block 5
    (3000-4200 s) is skipped for the gap when acc_013.npz lands. acc_014.npz, landing
    next in order, starts where block 5 ends (4200 s on the sample count); only its stamp
    lies 14 * 300 s * 40 ppm = 168 ms earlier. Before, the monitor judged the file by its
    stamp and noted "acc_014.npz: landed after blocks 5-5 were decided without it
    (skipped: gap); they are not redone" for a file neither late nor used by block 5."""
    from workbench.cli import parse_arguments
    from workbench.cli.monitoring import prepare_monitor

    files = _write(tmp_path / "source", _drifting(40))
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    argv = ["monitor", "--watch", str(watch), "--state", str(state), *MONITOR_ARGS]
    argv += PATHS["per-block"]  # no neighbouring file waited for: block 5 decided at once
    monitor = prepare_monitor(parse_arguments([a for a in argv if a != "--once"]))
    try:
        for path in files[:12] + files[13:16]:
            shutil.copy(path, watch / path.name)
            monitor.step()
    finally:
        monitor.close()
    health = pd.read_parquet(state / "data_health.parquet").set_index("block")
    assert health.loc[5, "status"] == "skipped"  # decided when acc_013.npz landed
    assert not [m for m in monitor.messages if "landed after" in m]  # main: acc_014.npz
