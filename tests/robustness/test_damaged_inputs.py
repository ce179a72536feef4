"""A damaged acceleration file among a voyage's files (cut short mid-way, a bad checksum)
is left out: identify goes on, names the file in one warning, records the blocks that
needed it as skipped with the file as the reason, and identifies every other block as a
run without the file does. A rerun after the file is repaired identifies its blocks.

Before: the first such file ended the whole run (exit 1, one line naming it), or -- a bad
checksum found while a block was read -- its blocks were skipped with no warning and the
repaired file was then refused as a changed input.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): block k needs files k and k + 1, so a damaged file 3 takes
blocks 2 and 3.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

DAMAGED = 3
#: The blocks that need file 3 (blocks 2 and 3 hold files 2-3 and 3-4).
TOUCHING = {2, 3}


def _cut(path: Path) -> None:
    """Cut short mid-way (a copy or a disk write that stopped): the archive's directory at
    its end is gone, so not even the header can be read."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _bad_checksum(path: Path) -> None:
    """One byte of the samples flipped: the header reads, the samples fail their CRC-32."""
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF
    path.write_bytes(bytes(data))


def _cut_csv(path: Path) -> Path:
    """The file as CSV (time column, one column per channel), cut short mid-row."""
    from data_contracts import read_accelerations

    record = read_accelerations(path)
    times = record.start_time + pd.to_timedelta(
        np.arange(record.n_samples) / record.sampling_rate_hz, unit="s"
    )
    frame = pd.DataFrame(record.acceleration, columns=list(record.channels))
    frame.insert(0, "time", times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    text = path.with_suffix(".csv")
    frame.to_csv(text, index=False)
    path.unlink()
    _cut(text)
    return text


DAMAGE = {"cut short": _cut, "bad checksum": _bad_checksum}


def _identify(capsys, voyage: Path, out: Path, *extra: str) -> tuple[int, str, str]:
    status = main(["identify", str(voyage), "--out", str(out), *IDENTIFY_ARGS, *extra])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _without(voyage: Path, name: str, folder: Path) -> Path:
    """A copy of *voyage* without the file *name*."""
    shutil.copytree(voyage, folder)
    (folder / name).unlink()
    return folder


def _tables(out: Path, blocks=None) -> dict[str, pd.DataFrame]:
    tables = {}
    for kind in ("selected", "poles"):
        frame = pd.read_parquet(out / f"{kind}.parquet")
        if blocks is not None:
            frame = frame[frame["block"].isin(blocks)].reset_index(drop=True)
        tables[kind] = frame
    return tables


def _assert_same_tables(out: Path, reference: Path, blocks=None) -> None:
    ours, theirs = _tables(out, blocks), _tables(reference, blocks)
    for kind in ours:
        assert len(ours[kind]), kind
        pd.testing.assert_frame_equal(ours[kind], theirs[kind], check_exact=True)


@pytest.mark.parametrize("rate", ["native", "16"], ids=["per block", "per file"])
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_file_is_left_out_and_named_once(tmp_path, capsys, damage, rate):
    """The other blocks equal a run on the voyage with the file deleted, whether the
    blocks are conditioned one by one or cut from files decimated once each (there the
    damaged file's neighbours lose its edges as filter padding, as they do without it)."""
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    DAMAGE[damage](paths[DAMAGED])
    status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out", "--rate", rate)
    assert status == 0, err
    assert "Traceback" not in err
    named = [line for line in err.splitlines() if "acc_003.npz" in line]
    assert named == [
        f"warning: {paths[DAMAGED]}: unreadable (not a valid .npz acceleration file (a NumPy "
        "archive of the numeric arrays acceleration, sampling_rate_hz, start_time and "
        "channels)); left out: block(s) 2-3 not identified"
    ]
    assert "5 block(s) processed, 2 skipped" in out
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert list(blocks.columns) == ["block", "block_start", "status", "reason"]
    skipped = blocks[blocks["status"] == "skipped"]
    assert set(skipped["block"]) == TOUCHING
    assert skipped["reason"].str.startswith(f"{paths[DAMAGED]}: unreadable (").all()
    assert (blocks.loc[~blocks["block"].isin(TOUCHING), "status"] == "ok").all()
    # the blocks that do not need the file: as without it
    reference = _without(tmp_path / "voyage", paths[DAMAGED].name, tmp_path / "deleted")
    assert _identify(capsys, reference, tmp_path / "reference", "--rate", rate)[0] == 0
    kept = sorted(set(blocks["block"]) - TOUCHING)
    _assert_same_tables(tmp_path / "out", tmp_path / "reference", kept)


def test_a_csv_file_cut_mid_row_is_left_out(tmp_path, capsys):
    """CSV files are parsed whole when planned: the one cut short mid-row is left out."""
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    texts = [_cut_csv(path) if k == 2 else path for k, path in enumerate(paths)]
    status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out")
    assert status == 0, err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and f"{texts[2]}: unreadable (" in warnings[0]
    assert "the file ends mid-row" in warnings[0] and "block(s) 1-2 not identified" in warnings[0]
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks.loc[blocks["status"] == "skipped", "block"].tolist() == [1, 2]


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_every_file_damaged_is_exit_1_naming_them(tmp_path, capsys, damage):
    """Nothing identified is never a success: one line naming the files, also on a rerun
    into the store of the first (whose blocks it holds as skipped)."""
    paths = write_voyage(tmp_path / "voyage", n_files=3)
    for path in paths:
        DAMAGE[damage](path)
    for _ in range(2):
        status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out")
        assert status == 1
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        if damage == "cut short":
            assert lines[0].startswith(
                f"error: 3 files ({paths[0]} .. {paths[2]}): unreadable (not a valid .npz"
            )
            assert lines[0].endswith("no acceleration file can be read, nothing identified")
        else:  # each block fails at the first file it reads
            assert lines[0].startswith("error: no block identified: all 2 block(s) skipped")
            assert "acc_000.npz: unreadable (not a valid .npz" in lines[0]
            assert "acc_001.npz: unreadable (" in lines[0]


def test_what_is_left_without_the_damaged_files_names_them(tmp_path, capsys):
    """Two files, one cut short: the other alone is shorter than a block."""
    paths = write_voyage(tmp_path / "voyage", n_files=2)
    _cut(paths[1])
    status, _, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out")
    assert status == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"error: {paths[1]}: unreadable (not a valid .npz")
    assert "left out; then acc_000.npz: record of 1.00 min is shorter than one block" in lines[0]


@pytest.mark.parametrize("rate", ["native", "16"], ids=["per block", "per file"])
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_repaired_file_is_identified_by_the_next_run(tmp_path, capsys, damage, rate):
    """The store keeps the damaged file's blocks skipped while the file stays as it is
    (a rerun computes nothing, and warns again); once it is repaired they are computed
    (and, with files decimated once each, its neighbours' blocks, unpadded before): the
    tables then equal a fresh run over the whole voyage. Before, the repaired file was
    refused as a changed input (bad checksum) or its blocks stayed skipped (cut short)."""
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    good = paths[DAMAGED].read_bytes()
    DAMAGE[damage](paths[DAMAGED])
    out = tmp_path / "out"
    assert _identify(capsys, tmp_path / "voyage", out, "--rate", rate)[0] == 0
    status, printed, err = _identify(capsys, tmp_path / "voyage", out, "--rate", rate)
    assert status == 0 and "0 block(s) processed" in printed
    assert "acc_003.npz: unreadable (" in err and "block(s) 2-3 not identified" in err
    paths[DAMAGED].write_bytes(good)
    status, printed, err = _identify(capsys, tmp_path / "voyage", out, "--rate", rate)
    assert status == 0, err
    # blocks 2-3, and 1 and 4 when their files were decimated without file 3's edges
    assert f"{4 if rate == '16' else 2} block(s) processed, 0 skipped" in printed
    assert "acc_003.npz: unreadable in an earlier run and changed since: read now" in err
    assert "unreadable (" not in err
    blocks = pd.read_csv(out / "blocks.csv")
    assert (blocks["status"] == "ok").all()
    assert _identify(capsys, tmp_path / "voyage", tmp_path / "fresh", "--rate", rate)[0] == 0
    _assert_same_tables(out, tmp_path / "fresh")


AUTO = ["--block-minutes", "auto", "--step-minutes", "3"]


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_auto_block_minutes_leaves_the_file_out_too(tmp_path, capsys, damage):
    """``--block-minutes auto``: no block spans the damaged file (its half-steps' excitation
    is unknown, as over a gap); the blocks whose shortest span holds it are listed skipped,
    the rest equal a run without the file, and after the repair a fresh run's."""
    paths = write_voyage(tmp_path / "voyage", n_files=30)
    good = paths[14].read_bytes()
    DAMAGE[damage](paths[14])
    out = tmp_path / "out"
    status, printed, err = _identify(capsys, tmp_path / "voyage", out, *AUTO)
    assert status == 0, err
    named = [line for line in err.splitlines() if "acc_014.npz" in line]
    assert len(named) == 1 and "Traceback" not in err
    assert named[0].startswith(f"warning: {paths[14]}: unreadable (not a valid .npz")
    assert named[0].endswith("; left out: block(s) 3-5 not identified")
    blocks = pd.read_csv(out / "blocks.csv")
    skipped = blocks[blocks["status"] == "skipped"]
    assert skipped["block"].tolist() == [3, 4, 5]
    assert skipped["reason"].str.startswith(f"{paths[14]}: unreadable (").all()
    reference = _without(tmp_path / "voyage", paths[14].name, tmp_path / "deleted")
    assert _identify(capsys, reference, tmp_path / "reference", *AUTO)[0] == 0
    _assert_same_tables(out, tmp_path / "reference")
    paths[14].write_bytes(good)
    status, printed, err = _identify(capsys, tmp_path / "voyage", out, *AUTO)
    assert status == 0 and "unreadable (" not in err, err
    assert (pd.read_csv(out / "blocks.csv")["status"] == "ok").all()
    assert _identify(capsys, tmp_path / "voyage", tmp_path / "fresh", *AUTO)[0] == 0
    _assert_same_tables(out, tmp_path / "fresh")


def test_unreadable_input_error_names_the_file_once(tmp_path):
    from data_contracts import ContractError, read_accelerations
    from workbench.errors import UnreadableInputError, WorkbenchError

    path = tmp_path / "a.npz"
    path.write_bytes(b"PK\x03\x04 cut")
    with pytest.raises(ContractError) as raised:
        read_accelerations(path)
    error = UnreadableInputError.of(path, raised.value)
    assert str(error) == f"{path}: unreadable ({error.detail})"
    assert str(path) not in error.detail and error.detail.startswith("not a valid .npz")
    assert isinstance(error, ValueError) and isinstance(error, WorkbenchError)


def test_a_file_cut_short_after_a_run_keeps_the_blocks_read_before(tmp_path, capsys):
    """A file the store's results came from, cut short since (a bad disk): the rerun keeps
    the blocks computed from its good content (and, with files decimated once each, its
    neighbours' padded with its edges) as they are, in one warning line and no 'input no
    longer given'. Until session 42 they were dropped and the file left out as a fresh
    run without it would: results computed from good data lost (the same rule for every
    damage after a read: tests/robustness/test_damaged_after_read.py)."""
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    out = tmp_path / "out"
    assert _identify(capsys, tmp_path / "voyage", out, "--rate", "16")[0] == 0
    first = _tables(out)
    _cut(paths[DAMAGED])
    status, text, err = _identify(capsys, tmp_path / "voyage", out, "--rate", "16")
    assert status == 0, err
    assert "0 block(s) processed, 0 skipped, 7 already done" in text
    assert [line for line in err.splitlines() if "acc_003.npz" in line] == [
        f"warning: {paths[DAMAGED]}: unreadable (not a valid .npz acceleration file (a NumPy "
        "archive of the numeric arrays acceleration, sampling_rate_hz, start_time and "
        "channels)), damaged since an earlier run read it; block(s) 2-3 computed from that "
        "read are kept"
    ]
    for kind, table in _tables(out).items():
        pd.testing.assert_frame_equal(table, first[kind], check_exact=True)
