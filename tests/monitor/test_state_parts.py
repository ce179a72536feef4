"""The state folder's growing tables written a day of blocks per part (issue 29, item 4):
the parts concatenate to the batch table, only the changed parts are rewritten, a crash
between a part and the index leaves a readable table, and the folder's format is checked."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from data_contracts import MODAL, ContractError, read_table
from data_contracts.parts import INDEX_NAME, PartWriter, summarize
from workbench.errors import WorkbenchError
from workbench.monitor.state_format import FORMAT_FILE, STATE_FORMAT, check_state_format
from workbench.monitor.tracking import IncrementalTracking
from workbench.sid.tracking import TrackingOptions, track_modes

from .test_labels import _block

#: Blocks per part in these tests: small, so that 60 blocks make 9 parts.
PART_BLOCKS = 7


@pytest.fixture(scope="module")
def blocks() -> list[pd.DataFrame]:
    rng = np.random.default_rng(5)
    return [_block(b, rng) for b in range(60)]


def _modal(n_blocks: int, seed: int = 0) -> pd.DataFrame:
    """A tracked table: three modes, one missing in some blocks."""
    rng = np.random.default_rng(seed)
    start = pd.Timestamp("2025-01-01T00:00:00Z")
    rows = [
        {
            "block": b,
            "block_start": start + pd.Timedelta(minutes=5 * b),
            "block_end": start + pd.Timedelta(minutes=5 * b + 20),
            "mode": m,
            "frequency_hz": f * (1 + 0.002 * rng.standard_normal()),
            "damping_ratio": 0.01,
        }
        for b in range(n_blocks)
        for m, f in ((1, 4.7), (2, 6.1), (3, 8.2))
        if not (m == 3 and b % 4 == 0)
    ]
    columns = ["block", "block_start", "block_end", "mode", "frequency_hz", "damping_ratio"]
    return MODAL.validate(pd.DataFrame(rows, columns=columns))


def test_tracked_parts_equal_batch_track_at_every_block(blocks, tmp_path):
    """The live tracked table, built again only from its first changed block and written
    only where it changed, read back as one table equals the batch ``track`` of the
    blocks so far, at every block (an intermittent mode and a late one included: their
    earlier rows join the table when they are labelled)."""
    options = TrackingOptions()
    live = IncrementalTracking(options)
    writer = PartWriter(tmp_path / "tracked.parquet", MODAL, part_blocks=PART_BLOCKS)
    rewritten = []
    for block, part in enumerate(blocks):
        live.add(block, part)
        live.advance(set(range(block + 1)))
        table = live.table()
        writer.write(table, since_block=live.changed_from)
        if live.changed_from is not None:  # parts before the changed block kept
            assert min(writer.rewritten, default=10**9) >= live.changed_from // PART_BLOCKS
        rewritten.append(len(writer.rewritten))
        batch = track_modes(pd.concat(blocks[: block + 1], ignore_index=True), options=options)
        pd.testing.assert_frame_equal(table, batch)
        if len(batch):
            pd.testing.assert_frame_equal(read_table(tmp_path / "tracked.parquet", MODAL), batch)
    # once the modes are labelled, a block rewrites one part (two across a part boundary)
    assert max(rewritten[35:]) <= 2 and np.median(rewritten[35:]) == 1
    files = sorted(p.name for p in (tmp_path / "tracked.parquet").iterdir())
    assert files == [INDEX_NAME, *(f"part-{k:06d}.parquet" for k in range(9))]
    whole = pd.read_parquet(tmp_path / "tracked.parquet")  # a Parquet dataset reader too
    pd.testing.assert_frame_equal(whole, batch, check_dtype=False)


def test_parts_written_from_a_hint_equal_the_table(tmp_path):
    """Growing writes given only the rows from the first changed block on (the outlook's
    tails): the rows before it are kept (those of its part from the writer's memory, or
    from the file after a restart), and the table read back is the whole table; the
    index's counts equal the table's."""
    table = _modal(40)
    writer = PartWriter(tmp_path / "t.parquet", MODAL, part_blocks=PART_BLOCKS)
    writer.write(table[table["block"] < 3])
    for last in range(3, 40):
        if last % 10 == 0:  # a restarted writer: the part's head read from its file
            writer = PartWriter(tmp_path / "t.parquet", MODAL, part_blocks=PART_BLOCKS)
        since = last - 2  # the newest block and two before it may have changed
        rows = table[(table["block"] >= since) & (table["block"] <= last)]
        writer.write(rows, since_block=since)
        assert writer.rewritten and min(writer.rewritten) >= since // PART_BLOCKS
    back = read_table(tmp_path / "t.parquet", MODAL)
    pd.testing.assert_frame_equal(back, table)
    summary = summarize(tmp_path / "t.parquet")
    assert summary["mode_blocks"] == table.groupby("mode")["block"].nunique().to_dict()
    assert (summary["first_block"], summary["last_block"], summary["blocks"]) == (0, 39, 40)


def test_a_crash_between_a_part_and_the_index_leaves_a_readable_table(tmp_path, monkeypatch):
    """Killed after a part was replaced and before the index was: the table read is the
    new one (the files present are the table), the index's stale counts are not taken,
    and a half-written temporary part (a crash inside the part's write) is not read."""
    path = tmp_path / "t.parquet"
    table = _modal(30)
    PartWriter(path, MODAL, part_blocks=PART_BLOCKS).write(table[table["block"] < 20])

    def killed(self):
        raise KeyboardInterrupt("killed before the index")

    monkeypatch.setattr(PartWriter, "_write_index", killed)
    writer = PartWriter(path, MODAL, part_blocks=PART_BLOCKS)
    with pytest.raises(KeyboardInterrupt):
        writer.write(table, since_block=20)
    monkeypatch.undo()
    (path / ".part-000004.parquet.tmp.parquet").write_bytes(b"PAR1 half a part")
    pd.testing.assert_frame_equal(read_table(path, MODAL), table)
    pd.testing.assert_frame_equal(pd.read_parquet(path), table, check_dtype=False)
    expected = table.groupby("mode")["block"].nunique().to_dict()
    assert summarize(path)["mode_blocks"] == expected  # parts 2-4 counted from their files
    # the restarted writer takes the folder up and writes a consistent index
    PartWriter(path, MODAL, part_blocks=PART_BLOCKS).write(table, since_block=28)
    index = json.loads((path / INDEX_NAME).read_text())
    assert [p["key"] for p in index["parts"]] == [0, 1, 2, 3, 4]
    assert sum(p["rows"] for p in index["parts"]) == len(table)


def test_a_parted_table_of_another_format_is_refused_in_one_line(tmp_path):
    path = tmp_path / "t.parquet"
    PartWriter(path, MODAL, part_blocks=PART_BLOCKS).write(_modal(10))
    index = json.loads((path / INDEX_NAME).read_text())
    (path / INDEX_NAME).write_text(json.dumps({**index, "schema": "workbench.parts/9"}))
    with pytest.raises(ContractError) as caught:
        read_table(path, MODAL)
    message = str(caught.value)
    assert "workbench.parts/9" in message and INDEX_NAME in message
    assert len(message.strip().splitlines()) == 1


def test_an_empty_table_keeps_its_columns(tmp_path):
    path = tmp_path / "t.parquet"
    writer = PartWriter(path, MODAL, part_blocks=PART_BLOCKS)
    writer.write(_modal(10))
    writer.write(_modal(0))  # e.g. the forecast started over and has no rows yet
    back = read_table(path, MODAL)
    assert back.empty and list(back.columns) == list(_modal(1).columns)
    assert pd.read_parquet(path).empty


def test_state_format_1_is_migrated_and_another_refused(tmp_path):
    """A state folder of the former layout (whole tables) is migrated with a one-line
    note: the tables rebuilt from the store or computed again are removed; a folder of
    another format is refused in one line naming the file."""
    old = tmp_path / "old"
    (old / "outlook").mkdir(parents=True)
    for name in ("tracked.parquet", "forecast.parquet", "health.parquet", "data_health.parquet"):
        _modal(3).to_parquet(old / name)
    (old / "labels.json").write_text("{}")
    note = check_state_format(old)
    assert note is not None and "format 1" in note and STATE_FORMAT in note
    assert len(note.splitlines()) == 1
    assert not (old / "tracked.parquet").exists() and not (old / "outlook").exists()
    assert (old / "labels.json").is_file()  # checked again at the restart, kept
    assert json.loads((old / FORMAT_FILE).read_text()) == {"schema": STATE_FORMAT}
    assert check_state_format(old) is None  # now of this format
    newer = tmp_path / "newer"
    newer.mkdir()
    (newer / FORMAT_FILE).write_text(json.dumps({"schema": "workbench.monitor.state/3"}))
    with pytest.raises(WorkbenchError) as caught:
        check_state_format(newer)
    message = str(caught.value)
    assert "workbench.monitor.state/3" in message and FORMAT_FILE in message
    assert len(message.splitlines()) == 1


def test_monitor_refuses_a_state_folder_of_another_format(tmp_path, capsys):
    """``workbench monitor`` on a folder of another format: exit 1, one line, no
    traceback, nothing written."""
    from workbench.cli import main

    state, watch = tmp_path / "state", tmp_path / "watch"
    state.mkdir()
    watch.mkdir()
    (state / FORMAT_FILE).write_text(json.dumps({"schema": "workbench.monitor.state/3"}))
    code = main(["monitor", "--watch", str(watch), "--state", str(state), "--once"])
    err = capsys.readouterr().err.strip()
    assert code == 1
    assert "workbench.monitor.state/3" in err and len(err.splitlines()) == 1
    assert "Traceback" not in err
    assert not (state / "status.json").exists()
