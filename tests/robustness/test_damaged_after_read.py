"""An acceleration file read whole by an earlier ``identify`` into the store and damaged on
disk since (a bad checksum, cut short) does not stop the rerun: the blocks computed from
its good content stay as they are, one warning names the file and those blocks, the
other files' blocks are identified, and new blocks that need it are skipped with the
reason as on a first run. Repaired, it is read again and the store equals a fresh run.

Before: the rerun stopped with exit 1, "acc_003.npz: input changed since the store ...
was made (other content than acc_003.npz for ...); its results would be of other data:
use another --store or delete this one", identifying none of the new files' blocks
(a file cut short, whose header cannot be read, instead had its stored blocks dropped
and skipped: computed results lost).

A file with other content that reads whole is still a changed input, refused.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): block k needs files k and k + 1, so file 3 feeds blocks
2 and 3.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main

from .test_damaged_inputs import DAMAGE
from .voyage import IDENTIFY_ARGS, write_voyage

DAMAGED = 3
RATES = pytest.mark.parametrize("rate", ["native", "16"], ids=["per block", "per file"])


def _identify(capsys, voyage: Path, out: Path, rate: str) -> tuple[int, str, str]:
    status = main(["identify", str(voyage), "--out", str(out), *IDENTIFY_ARGS, "--rate", rate])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return status, captured.out, captured.err


def _tables(out: Path) -> dict[str, pd.DataFrame]:
    return {kind: pd.read_parquet(out / f"{kind}.parquet") for kind in ("selected", "poles")}


def _rows(table: pd.DataFrame, blocks) -> pd.DataFrame:
    return table[table["block"].isin(blocks)].reset_index(drop=True)


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("warning:")]


def _copy(paths, folder: Path) -> None:
    folder.mkdir(exist_ok=True)
    for path in paths:
        shutil.copyfile(path, folder / path.name)


@RATES
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_blocks_read_before_are_kept_and_the_run_goes_on(tmp_path, capsys, damage, rate):
    source = write_voyage(tmp_path / "source", n_files=10)
    voyage, out = tmp_path / "voyage", tmp_path / "out"
    _copy(source[:8], voyage)
    assert _identify(capsys, voyage, out, rate)[0] == 0
    first = _tables(out)
    # later: two more files land, and file 3 is damaged on disk
    _copy(source[8:], voyage)
    DAMAGE[damage](voyage / source[DAMAGED].name)
    status, text, err = _identify(capsys, voyage, out, rate)
    assert status == 0, err
    assert "2 block(s) processed, 0 skipped, 7 already done" in text
    named = _warnings(err)
    assert len(named) == 1, err
    assert named[0].startswith(f"warning: {voyage / source[DAMAGED].name}: unreadable (")
    assert named[0].endswith(
        "damaged since an earlier run read it; block(s) 2-3 computed from that read are kept"
    )
    # the stored blocks are those of the first run, bit for bit
    after = _tables(out)
    for kind in first:
        pd.testing.assert_frame_equal(_rows(after[kind], range(7)), first[kind], check_exact=True)
    # the new blocks equal those of a fresh run over the ten good files
    fresh = tmp_path / "fresh"
    assert _identify(capsys, tmp_path / "source", fresh, rate)[0] == 0
    for kind, table in _tables(fresh).items():
        pd.testing.assert_frame_equal(
            _rows(after[kind], [7, 8]), _rows(table, [7, 8]), check_exact=True
        )
    assert (pd.read_csv(out / "blocks.csv")["status"] == "ok").all()


@RATES
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_new_blocks_that_need_it_are_skipped_then_a_repair_reads_it(tmp_path, capsys, damage, rate):
    """Run 1 over files 0-3 (blocks 0-2); file 3 is damaged, files 4-7 land: block 3 (files
    3 and 4) is skipped naming file 3, blocks 4-6 are identified as on a first run with
    file 3 damaged; a third run changes nothing; the repaired file is read again and the
    store then equals a fresh run over the good files."""
    source = write_voyage(tmp_path / "source", n_files=8)
    voyage, out = tmp_path / "voyage", tmp_path / "out"
    _copy(source[:4], voyage)
    assert _identify(capsys, voyage, out, rate)[0] == 0
    first = _tables(out)
    damaged = voyage / source[DAMAGED].name
    good_bytes = damaged.read_bytes()
    _copy(source[4:], voyage)
    DAMAGE[damage](damaged)
    status, text, err = _identify(capsys, voyage, out, rate)
    assert status == 0, err
    assert "3 block(s) processed, 1 skipped, 3 already done" in text
    warning = f"warning: {damaged}: unreadable ("
    named = _warnings(err)
    assert len(named) == 1 and named[0].startswith(warning), err
    assert named[0].endswith(
        "damaged since an earlier run read it; block(s) 2 computed from that read are kept; "
        "block(s) 3 that need it not identified"
    )
    blocks = pd.read_csv(out / "blocks.csv")
    assert blocks.loc[blocks["status"] == "skipped", "block"].tolist() == [3]
    assert blocks.loc[blocks["block"] == 3, "reason"].iloc[0].startswith(f"{damaged}: unreadable (")
    after = _tables(out)
    for kind in first:
        pd.testing.assert_frame_equal(_rows(after[kind], range(3)), first[kind], check_exact=True)
    # the new blocks are those of a first run over the voyage with file 3 damaged
    damaged_first = tmp_path / "damaged_first"
    _copy(sorted(voyage.iterdir()), damaged_first)
    assert _identify(capsys, damaged_first, tmp_path / "damaged_first_out", rate)[0] == 0
    for kind, table in _tables(tmp_path / "damaged_first_out").items():
        pd.testing.assert_frame_equal(
            _rows(after[kind], [4, 5, 6]), _rows(table, [4, 5, 6]), check_exact=True
        )
    # still damaged: nothing computed again, the same warning
    status, text, err = _identify(capsys, voyage, out, rate)
    assert status == 0 and "0 block(s) processed, 0 skipped, 7 already done" in text, err
    assert _warnings(err) == named
    # repaired: read again; the store equals a fresh run over the good files
    damaged.write_bytes(good_bytes)
    status, text, err = _identify(capsys, voyage, out, rate)
    assert status == 0, err
    assert f"{damaged}: unreadable in an earlier run and changed since: read now" in err
    fresh = tmp_path / "fresh"
    assert _identify(capsys, tmp_path / "source", fresh, rate)[0] == 0
    for kind, table in _tables(fresh).items():
        pd.testing.assert_frame_equal(_tables(out)[kind], table, check_exact=True)
    assert (pd.read_csv(out / "blocks.csv")["status"] == "ok").all()


def test_other_content_that_reads_is_still_a_changed_input(tmp_path, capsys):
    """The store's guard is unchanged for data that reads: another voyage's file at the
    same time is refused, naming it, and nothing is computed."""
    source = write_voyage(tmp_path / "source", n_files=6)
    other = write_voyage(tmp_path / "other", n_files=6, seed=1)
    voyage, out = tmp_path / "voyage", tmp_path / "out"
    _copy(source, voyage)
    assert _identify(capsys, voyage, out, "native")[0] == 0
    shutil.copyfile(other[DAMAGED], voyage / other[DAMAGED].name)
    status, _, err = _identify(capsys, voyage, out, "native")
    assert status == 1
    assert f"{voyage / other[DAMAGED].name}: input changed since the store" in err


def test_a_file_damaged_from_the_first_run_on_is_not_said_to_have_been_read(tmp_path, capsys):
    """Damaged on the first run, damaged otherwise on the next (another byte): still the
    first run's case, its blocks skipped and the warning of an unreadable file."""
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    out = tmp_path / "out"
    DAMAGE["bad checksum"](paths[DAMAGED])
    assert _identify(capsys, tmp_path / "voyage", out, "native")[0] == 0
    data = bytearray(paths[DAMAGED].read_bytes())
    data[len(data) // 2] ^= 0xFF  # a second byte: other damaged content
    paths[DAMAGED].write_bytes(bytes(data))
    status, _, err = _identify(capsys, tmp_path / "voyage", out, "native")
    assert status == 0, err
    named = _warnings(err)  # read again (other content), unreadable again: as on main
    assert not [line for line in named if "damaged since" in line], err
    assert named[-1].endswith("left out: block(s) 2-3 not identified")
    blocks = pd.read_csv(out / "blocks.csv")
    assert blocks.loc[blocks["status"] == "skipped", "block"].tolist() == [2, 3]
