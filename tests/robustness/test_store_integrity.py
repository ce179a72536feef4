"""The store notices when its own files change (issue 28, item 2).

After a complete identify run, a block file of the store deleted, truncated, overwritten
with another batch's file or renamed, then identify run again: the blocks that file held
are named on stderr, computed again, and the exported tables equal those of the first run
(never exported with blocks missing or misplaced). An input file removed since the store
was made is named, and by default its blocks are dropped so that the rerun's tables equal
a fresh run over the remaining files; ``--keep-removed-inputs`` keeps them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

#: 6 one-minute files, 2-minute blocks every minute: blocks 0-4, stored two per batch, so
#: batches hold blocks {0, 1}, {2, 3} and {4}.
BATCH = ["--batch-blocks", "2"]
TABLES = ("poles.parquet", "selected.parquet", "blocks.csv", "channels.csv")


def _identify(inputs, out: Path, *extra: str) -> int:
    return main(["identify", *map(str, inputs), "--out", str(out), *IDENTIFY_ARGS, *BATCH, *extra])


def _tables(out: Path) -> dict[str, pd.DataFrame]:
    read = {".parquet": pd.read_parquet, ".csv": pd.read_csv}
    return {name: read[Path(name).suffix](out / name) for name in TABLES}


def _assert_same_tables(out: Path, reference: dict[str, pd.DataFrame]) -> None:
    for name, table in _tables(out).items():
        pd.testing.assert_frame_equal(table, reference[name], obj=name)


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    """A complete run over 6 files, kept aside: (voyage folder, output folder, tables)."""
    root = tmp_path_factory.mktemp("store_integrity")
    write_voyage(root / "voyage", n_files=6)
    assert _identify([root / "voyage"], root / "out") == 0
    return root / "voyage", root / "out", _tables(root / "out")


@pytest.fixture
def run(first_run, tmp_path, capsys):
    """A copy of the first run's output (store included) and its voyage."""
    voyage, out, tables = first_run
    shutil.copytree(voyage, tmp_path / "voyage")
    shutil.copytree(out, tmp_path / "out")
    capsys.readouterr()
    return tmp_path / "voyage", tmp_path / "out", tables


def _batch_file(store: Path, kind: str, first_block: int) -> Path:
    (path,) = (store / kind).glob(f"day=*/b{first_block:07d}-*.parquet")
    return path


def _delete(path: Path, store: Path) -> None:
    path.unlink()


def _truncate(path: Path, store: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _overwrite_with_other_batch(path: Path, store: Path) -> None:
    kind = path.parent.parent.name
    shutil.copyfile(_batch_file(store, kind, 0), path)  # blocks 0-1's rows over 2-3's


def _rename(path: Path, store: Path) -> None:
    path.rename(path.with_name("b0000009-0000009-0badf00d.parquet"))


@pytest.mark.parametrize(
    ("kind", "damage", "word"),
    [
        ("poles", _delete, "missing"),
        ("selected", _delete, "missing"),
        ("blocks", _delete, "missing"),
        ("poles", _truncate, "truncated"),
        ("selected", _overwrite_with_other_batch, "overwritten"),
        ("poles", _rename, "missing"),
    ],
)
def test_damaged_store_file_is_found_and_its_blocks_computed_again(run, capsys, kind, damage, word):
    voyage, out, reference = run
    store = out / "store"
    target = _batch_file(store, kind, 2)
    damage(target, store)
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    notices = [line for line in captured.err.splitlines() if target.name in line]
    assert len(notices) == 1, captured.err
    assert f"{kind}/day=" in notices[0] and word in notices[0] and "block(s) 2-3" in notices[0]
    assert "2 block(s) processed, 0 skipped, 3 already done" in captured.out
    _assert_same_tables(out, reference)
    # the repaired store is whole: the next run finds nothing and redoes nothing
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert "0 block(s) processed, 0 skipped, 5 already done" in captured.out


def test_same_size_other_content_is_found(run, capsys):
    """A file changed in place with its size kept (one byte flipped) is told by its SHA-256."""
    voyage, out, reference = run
    target = _batch_file(out / "store", "poles", 4)
    data = bytearray(target.read_bytes())
    data[len(data) // 2] ^= 0xFF
    target.write_bytes(bytes(data))
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    assert "of other content than written" in captured.err and "block(s) 4 " in captured.err
    assert "1 block(s) processed, 0 skipped, 4 already done" in captured.out
    _assert_same_tables(out, reference)


def test_store_without_manifest_is_computed_again(run, capsys):
    voyage, out, reference = run
    (out / "store" / "manifest.jsonl").unlink()
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    assert "the store's manifest does not list removed (blocks 0-4 are computed again)" in (
        captured.err
    )
    assert "5 block(s) processed, 0 skipped, 0 already done" in captured.out
    _assert_same_tables(out, reference)


def test_torn_manifest_line_uncommits_its_batch(run, capsys):
    """A run killed while appending a batch's manifest line: that batch is not done."""
    voyage, out, reference = run
    manifest = out / "store" / "manifest.jsonl"
    lines = manifest.read_text().splitlines(keepends=True)
    last = next(line for line in lines if '"batch":"b0000004-' in line)
    lines.remove(last)
    manifest.write_text("".join(lines) + last[: len(last) // 2])
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    assert "(blocks 4 are computed again)" in captured.err
    assert "1 block(s) processed, 0 skipped, 4 already done" in captured.out
    _assert_same_tables(out, reference)


# -------------------------------------------------------------------------- removed inputs
def test_removed_input_drops_its_blocks_like_a_fresh_run(run, tmp_path, capsys):
    voyage, out, reference = run
    removed = voyage / "acc_003.npz"  # minutes 3-4: blocks 2 (2-4 min) and 3 (3-5 min)
    removed.rename(tmp_path / removed.name)
    assert _identify([voyage], out) == 0
    captured = capsys.readouterr()
    (notice,) = [line for line in captured.err.splitlines() if "acc_003.npz" in line]
    assert "input no longer given" in notice and "block(s) 2-3" in notice
    assert "are dropped" in notice
    assert _identify([voyage], tmp_path / "fresh") == 0
    fresh = _tables(tmp_path / "fresh")
    _assert_same_tables(out, fresh)
    blocks = fresh["blocks.csv"].set_index("block")["status"]
    assert blocks.loc[[2, 3]].eq("skipped").all() and blocks.drop([2, 3]).eq("ok").all()
    assert len(reference["selected.parquet"]) > len(fresh["selected.parquet"])
    # reported once: the next run has nothing to say
    capsys.readouterr()
    assert _identify([voyage], out) == 0
    assert "acc_003" not in capsys.readouterr().err


def test_removed_input_blocks_kept_on_request(run, tmp_path, capsys):
    voyage, out, reference = run
    (voyage / "acc_005.npz").rename(tmp_path / "acc_005.npz")  # block 4 (4-6 min)
    for _ in range(2):  # named on every run while kept
        assert _identify([voyage], out, "--keep-removed-inputs") == 0
        captured = capsys.readouterr()
        (notice,) = [line for line in captured.err.splitlines() if "acc_005.npz" in line]
        assert "block(s) 4 computed from it are kept (--keep-removed-inputs)" in notice
        # the 4 blocks still planned are done; block 4 is no longer planned but exported
        assert "0 block(s) processed, 0 skipped, 4 already done" in captured.out
        _assert_same_tables(out, reference)


def test_damaged_file_rewrite_keeps_the_other_blocks_of_its_batch(tmp_path):
    """Library level: a batch loses only the blocks of its damaged file; the rows of its
    other blocks stay, byte-identical in content."""
    from workbench.store import BlockStore

    start = pd.Timestamp("2026-03-01T00:00Z")
    status = pd.DataFrame({"block": [0, 1, 2], "block_start": start, "status": "ok", "reason": ""})
    poles = pd.DataFrame({"block": [0, 0, 1, 2], "block_start": start, "value": [1.0, 2, 3, 4]})
    faults = pd.DataFrame({"block": [1], "block_start": start, "channel": ["acc01"]})
    with BlockStore.open(tmp_path, {}) as store:
        store.write_batch(status, {"poles": poles, "faults": faults})
    (fault_file,) = (tmp_path / "faults").glob("day=*/*.parquet")
    fault_file.unlink()
    with BlockStore.open(tmp_path, {}) as store:
        assert len(store.notices) == 1 and "block(s) 1 are taken out" in store.notices[0]
        assert store.completed_blocks() == {0, 2}
        kept = store.read("poles")
        np.testing.assert_array_equal(kept["block"], [0, 0, 2])
        np.testing.assert_array_equal(kept["value"], [1.0, 2.0, 4.0])
        assert store.read("faults").empty
    with BlockStore.open(tmp_path, {}) as store:  # and the rewritten store is whole
        assert store.notices == []


# ------------------------------------------------------------------- the live monitor
def test_monitor_redoes_the_blocks_of_a_damaged_store_file(tmp_path, capsys):
    """The monitor reuses the store: a block file deleted between two runs is named in its
    notes and the block is identified again; the tracked table equals the first run's."""
    write_voyage(tmp_path / "voyage", n_files=6)
    monitor = ["monitor", "--watch", str(tmp_path / "voyage"), "--state", str(tmp_path / "st"),
               "--once", "--poll", "0.05", "--settle", "0.2",
               *[a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]]  # fmt: skip
    assert main(monitor) == 0
    first = pd.read_parquet(tmp_path / "st" / "tracked.parquet")
    assert set(first["block"]) == {0, 1, 2, 3, 4}
    (target,) = (tmp_path / "st" / "store" / "selected").glob("day=*/b0000002-*.parquet")
    target.unlink()
    capsys.readouterr()
    assert main(monitor) == 0
    out = capsys.readouterr().out
    (note,) = [line for line in out.splitlines() if target.name in line]
    assert note.startswith("note: ") and "missing: block(s) 2 are taken out" in note
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "st" / "tracked.parquet"), first)
    health = pd.read_parquet(tmp_path / "st" / "data_health.parquet")
    assert sorted(health["block"]) == [0, 1, 2, 3, 4]
