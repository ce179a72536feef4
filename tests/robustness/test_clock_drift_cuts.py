"""Where a drifting record's blocks were cut is kept, and judged, when more files arrive.

A drifting record's block k is cut where the record's clock line (the least-squares line
of its stamps on its sample count) puts the UTC of its label
(``tests/robustness/test_clock_drift_utc.py``). More files refit that line, so a block
cut from fewer files may lie a sample or more from where the line of all of them cuts
it; and a block whose UTC span the data missed by at most ``EDGE_SHIFT_S`` was cut at the
data's last sample, which later files move. The store now keeps each drifting block's
cut (its first sample's file, by content, and index there: ``cut_sha256``,
``cut_sample``):

- identify resumed over a store with more files computes again the stored blocks the
  line of the files given now cuts elsewhere (before: kept, so the resumed run differed
  from a fresh one), with one notice;
- the monitor keeps its decided blocks and judges them by the span they were cut from; a
  decided block the line of the files landed since cuts elsewhere by more than the clock
  jitter or one analysis sample (``cut_tolerance_s``) is said once, also after a restart
  (before: nothing said, the block silently off identify's);
- identify's summary names the blocks a drifting record's data misses by more than
  ``EDGE_SHIFT_S`` (before: left out silently).

The records are those of :mod:`tests.robustness.test_clock_drift` (5-min files at 128 Hz,
20-min blocks every 10 min, analysed at 16 Hz: a lattice of 8 raw samples, 62.5 ms).
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd

from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor
from workbench.fingerprints import sha256
from workbench.store import BlockStore

from .test_clock_drift import ARGS, FILE_S, JITTER_S, MONITOR_ARGS, _drifting, _identify, _write
from .voyage import identify_run, selected_modes

LIVE_ARGS = [a for a in MONITOR_ARGS if a != "--once"]


def _modes(out) -> pd.DataFrame:
    return selected_modes(out).sort_values(["block", "frequency_hz"]).reset_index(drop=True)


#: What the monitor says of block 4 of the 100-ppm record when the other files land.
BLOCK_4_MOVED = (
    "block(s) 4 of a drifting record, decided from the clock line of the files landed "
    "then, are cut up to +250.0 ms elsewhere by the line of the files landed now "
    "(beyond 62.5 ms: the clock jitter, or one analysis sample); they are kept as "
    "decided"
)


def test_identify_resumed_with_more_files_computes_a_moved_cut_again(tmp_path, capsys):
    """20 ppm fast, stamps jittered by up to 10 ms: the first 10 files (50 min) miss block
    3's UTC span (1800-3000 s) by 60 ms, so it is cut at their last sample; all 24 files
    hold its span, and the line of them cuts it one 16-Hz sample (62.5 ms) later. identify
    over the 10 files, then over all 24 into the same store, gives a fresh run's blocks:
    block 3 computed again and said (before: kept, a sample off)."""
    files = _write(tmp_path / "all", _drifting(20) + JITTER_S)
    part = tmp_path / "part"
    part.mkdir()
    for path in files[:10]:
        shutil.copy(path, part / path.name)
    code, _, err = _identify(capsys, part, tmp_path / "out")
    assert code == 0, err
    stored = BlockStore(tmp_path / "out" / "store").read("blocks").set_index("block")
    assert stored.index.tolist() == [0, 1, 2, 3]
    assert stored.loc[2, "cut_sample"] == 0  # 1200 s from the line: acc_004.npz's first
    # block 3's first sample: 1200 s before the data's end, the first of acc_006.npz
    assert stored.loc[3, "cut_sha256"] == sha256(part / "acc_006.npz")
    assert stored.loc[3, "cut_sample"] == 0
    code, out, err = _identify(capsys, tmp_path / "all", tmp_path / "out")
    assert code == 0, err
    said = [line for line in err.splitlines() if "cut elsewhere than when stored" in line]
    assert said == [
        "warning: block(s) 3 cut elsewhere than when stored (by up to +62.5 ms: the clock line "
        "of the drifting record, refitted over the files given now, puts their labels "
        "elsewhere on its samples): computed again"
    ]
    code, _, err = _identify(capsys, tmp_path / "all", tmp_path / "fresh")
    assert code == 0, err
    again, fresh = _modes(tmp_path / "out"), _modes(tmp_path / "fresh")
    assert fresh["block"].unique().tolist() == list(range(11))
    assert again["block"].tolist() == fresh["block"].tolist()
    for column in ("frequency_hz", "damping_ratio"):  # before: block 3's differ
        np.testing.assert_allclose(again[column], fresh[column], rtol=0, atol=1e-12)
    # the exported table is identify's own: the cut is the store's bookkeeping
    again = BlockStore(tmp_path / "out" / "store").read("blocks").set_index("block")
    assert again.loc[3, "cut_sample"] == 8
    assert "cut_sha256" not in pd.read_csv(tmp_path / "out" / "blocks.csv").columns


def _monitor(watch, state):
    return prepare_monitor(
        parse_arguments(["monitor", "--watch", str(watch), "--state", str(state), *LIVE_ARGS])
    )


def _watched(tmp_path, stamps):
    """The voyage's files written with *stamps* into a source folder; an empty watch folder
    and a state folder beside it: (files, watch, state)."""
    files = _write(tmp_path / "source", stamps)
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    return files, watch, state


def _land(monitor, files, watch, *, flush: bool) -> None:
    for path in files:
        shutil.copy(path, watch / path.name)
        monitor.step()
    if flush:
        monitor.step(flush=True)


def test_the_monitor_says_a_decided_blocks_cut_moved_by_later_files(tmp_path):
    """100 ppm fast: the first 12 files (1 h) land and are flushed (the recorder idle):
    block 4 (2400-3600 s), whose UTC span the data misses by 0.36 s, is cut at the data's
    last sample. The other 12 files land: the line of all the files cuts block 4 at its
    label's UTC, 250 ms (4 samples of the 62.5-ms analysis lattice) later. The block is
    kept as decided and that is said once; the cut it was decided from is in the store."""
    files, watch, state = _watched(tmp_path, _drifting(100))
    monitor = _monitor(watch, state)
    try:
        _land(monitor, files[:12], watch, flush=True)
        assert sorted(monitor.done) == [0, 1, 2, 3, 4]
        assert not [m for m in monitor.messages if "cut up to" in m]
        _land(monitor, files[12:], watch, flush=True)
    finally:
        monitor.close()
    said = [m for m in monitor.messages if "cut up to" in m]
    assert said == [BLOCK_4_MOVED]
    blocks = BlockStore(state / "store").read("blocks").set_index("block")
    # block 4 cut 1200 s before the first 12 files' end (3600 s on the sample count): the
    # first sample of acc_008.npz; the line puts its label 2400 s UTC at 2400 s x (1 + 100
    # ppm) = 2400.24 s on the sample count, 30.72 samples in, on the lattice: sample 32
    # (250 ms later)
    assert blocks.loc[4, "cut_sha256"] == sha256(watch / "acc_008.npz")
    assert blocks.loc[4, "cut_sample"] == 0
    assert round(8 * FILE_S * 100e-6 * 128 / 8) * 8 == 32
    assert len(blocks) == 11


def test_a_restarted_monitor_judges_the_cut_it_stored(tmp_path):
    """As above, the monitor stopped after the first flush and started again before the
    other files land: the cut is read from the store, and the moved cut said."""
    files, watch, state = _watched(tmp_path, _drifting(100))
    monitor = _monitor(watch, state)
    try:
        _land(monitor, files[:12], watch, flush=True)
    finally:
        monitor.close()
    monitor = _monitor(watch, state)
    try:
        _land(monitor, files[12:], watch, flush=True)
    finally:
        monitor.close()
    said = [m for m in monitor.messages if "cut up to" in m]
    assert said == [BLOCK_4_MOVED]


def test_the_monitor_says_nothing_of_cuts_within_the_tolerance(tmp_path):
    """20 ppm fast with jitter, the files landing one by one: the line refits as they
    land, moving the cuts of blocks not decided yet (normal) and of decided ones by at
    most a sample: nothing is said."""
    files, watch, state = _watched(tmp_path, _drifting(20) + JITTER_S)
    monitor = _monitor(watch, state)
    try:
        _land(monitor, files, watch, flush=True)
    finally:
        monitor.close()
    assert sorted(monitor.done) == list(range(11))
    assert not [m for m in monitor.messages if "cut up to" in m]
    cuts = BlockStore(state / "store").block_cuts()
    # block 0 was decided before the stamps told the drift from jitter: cut at its label
    assert sorted(cuts) == list(range(1, 11))


def test_identify_names_a_block_its_drifting_record_misses(tmp_path, capsys):
    """150 ppm fast: the 2-h record's 921 600 samples last 2 h / (1 + 150 ppm) of UTC,
    1.08 s short of block 10's UTC span (6000-7200 s), beyond EDGE_SHIFT_S: the block is
    not identified (blocks 0-9), and the summary says so (before: left out unsaid)."""
    _write(tmp_path / "voyage", _drifting(150))
    code, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out")
    assert code == 0, err
    assert pd.read_csv(tmp_path / "out" / "blocks.csv")["block"].tolist() == list(range(10))
    missed = 7200 * 150 / (1e6 + 150)
    assert f"{missed:.2f}" == "1.08"
    assert [line for line in out.splitlines() if "not identified" in line] == [
        "block(s) not identified, whose span a drifting record's samples hold on their count "
        "but whose UTC span runs more than 1 s past the record's first or last sample: "
        "block 10 by 1.08 s at its end"
    ]


#: The live monitor's arguments with blocks of varying length (``--block-minutes auto``:
#: 5 to 35 min centred on 5-min steps; without a ship log, by the excitation alone).
AUTO_ARGS = [
    *LIVE_ARGS[: LIVE_ARGS.index("--block-minutes")],
    "--block-minutes",
    "auto",
    *LIVE_ARGS[LIVE_ARGS.index("--step-minutes") + 2 :],
]


def _auto_monitor(watch, state):
    return prepare_monitor(
        parse_arguments(["monitor", "--watch", str(watch), "--state", str(state), *AUTO_ARGS])
    )


def test_the_adaptive_monitor_judges_the_cuts_it_stored(tmp_path):
    """As the fixed-block monitor, with blocks of varying length, stopped after the first
    flush and started again: after the first 12 files (1 h, 100 ppm fast: 0.36 s short of
    its UTC hour) blocks 8-11, whose spans (35, 25, 15 and 5 min) end at 1 h, are cut at
    the data's last sample; the line of all 24 files cuts them at their labels' UTC, up to
    312.5 ms (5 analysis samples) later. Said once, from the cuts and lengths in the store
    (before: nothing said, the fixed-block check not run with varying lengths)."""
    files, watch, state = _watched(tmp_path, _drifting(100))
    monitor = _auto_monitor(watch, state)
    try:
        _land(monitor, files[:12], watch, flush=True)
        assert sorted(monitor.done) == list(range(12))
        assert not [m for m in monitor.messages if "cut up to" in m]
    finally:
        monitor.close()
    lengths = BlockStore(state / "store").read("lengths").set_index("block")["block_length_s"]
    assert lengths.loc[8:11].tolist() == [2100.0, 1500.0, 900.0, 300.0]
    monitor = _auto_monitor(watch, state)
    try:
        _land(monitor, files[12:], watch, flush=True)
        monitor.step(flush=True)
    finally:
        monitor.close()
    assert sorted(monitor.done) == list(range(24))
    said = [m for m in monitor.messages if "cut up to" in m]
    assert said == [BLOCK_4_MOVED.replace("block(s) 4", "block(s) 8-11").replace("250.0", "312.5")]
    # block 11 (3300-3600 s UTC): 3300 s x (1 + 100 ppm) = 3300.33 s on the sample count,
    # 42.24 samples of 128 Hz, on the lattice of 8 samples 40 (312.5 ms) from its cut
    assert round(3300 * 100e-6 * 128 / 8) * 8 == 40


def test_the_monitor_names_a_block_its_drifting_record_misses(tmp_path):
    """150 ppm fast, all files landed and flushed (twice): the record's last sample lies
    1.08 s before the end of block 10's UTC span (with varying lengths: of block 23's,
    the shortest span), beyond EDGE_SHIFT_S: not identified, and one note says so, as
    identify's summary does (before: nothing said)."""
    files = _write(tmp_path / "source", _drifting(150))
    said = {}
    for name, make, expected in (("fixed", _monitor, 10), ("auto", _auto_monitor, 23)):
        watch, state = tmp_path / name / "watch", tmp_path / name / "state"
        watch.mkdir(parents=True)
        monitor = make(watch, state)
        try:
            _land(monitor, files, watch, flush=True)
            monitor.step(flush=True)
        finally:
            monitor.close()
        assert sorted(monitor.done) == list(range(expected))
        said[name] = [m for m in monitor.messages if "not identified" in m]
    line = (
        "block(s) not identified, whose span a drifting record's samples hold on their count "
        "but whose UTC span runs more than 1 s past the record's first or last sample: "
    )
    assert said == {
        "fixed": [f"{line}block 10 by 1.08 s at its end"],
        "auto": [f"{line}block 23 by 1.08 s at its end"],
    }


def test_identify_with_varying_lengths_names_only_the_block_it_misses(tmp_path, capsys):
    """The same 150-ppm record, ``identify --block-minutes auto``: blocks 0-22 identified
    (20-22 shortened to 25, 15 and 5 min at the data's end), block 23's shortest span
    (5 min) runs 1.08 s past the last sample. One line names block 23 (before: one line
    per length, naming blocks 20, 21 and 22 too, which their own length identified)."""
    _write(tmp_path / "voyage", _drifting(150))
    auto = ARGS[ARGS.index("--step-minutes") + 2 :]
    code, out, err = identify_run(
        capsys, tmp_path / "voyage", tmp_path / "out", ["--block-minutes", "auto", *auto]
    )
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["block"].tolist() == list(range(23))
    assert blocks["block_length_s"].tolist()[-3:] == [1500.0, 900.0, 300.0]
    assert [line for line in out.splitlines() if "not identified" in line] == [
        "block(s) not identified, whose span a drifting record's samples hold on their count "
        "but whose UTC span runs more than 1 s past the record's first or last sample: "
        "block 23 by 1.08 s at its end"
    ]
