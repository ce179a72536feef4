"""The block store and the parallel runner: resume, orphan cleanup, block order, Dask path."""

from __future__ import annotations

import json
import sys

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from workbench.errors import WorkbenchError
from workbench.parallel import BlockOutcome, SharedInput, run_blocks
from workbench.store import BlockStore

T0 = pd.Timestamp("2026-03-01T23:00Z")  # the blocks straddle midnight: two day partitions


class Task:
    def __init__(self, block: int):
        self.block = block
        self.block_start = T0 + pd.Timedelta(minutes=5 * block)


def square_block(task: Task) -> BlockOutcome:
    """A stand-in for identification: deterministic rows per block, some blocks fail."""
    if task.block % 7 == 3:
        raise ValueError(f"block {task.block}: too short")
    rows = pd.DataFrame(
        {
            "block": [task.block] * 2,
            "block_start": [task.block_start] * 2,
            "model_order": [2, 4],
            "value": [task.block**2, -task.block],
        }
    )
    return BlockOutcome(
        task.block,
        task.block_start,
        {"poles": rows},
        notes=("acc03 dropped: kurtosis",) if task.block % 5 == 0 else (),
    )


def test_synchronous_run_stores_everything_in_block_order(tmp_path):
    store = BlockStore.open(tmp_path, {"method": "test"})
    summary = run_blocks(
        (Task(b) for b in range(30)),
        square_block,
        store=store,
        scheduler="synchronous",
        batch_blocks=8,
    )
    assert (summary.processed, summary.skipped) == (26, 4)
    assert summary.skip_reasons == {f"block {b}: too short": 1 for b in (3, 10, 17, 24)}
    assert summary.notes == {"acc03 dropped: kurtosis": 5}  # block 10 failed
    poles = store.read("poles")
    assert poles["block"].tolist() == sorted(b for b in range(30) if b % 7 != 3 for _ in (0, 1))
    assert sorted({p.parent.name for p in (tmp_path / "poles").rglob("*.parquet")}) == [
        "day=2026-03-01",
        "day=2026-03-02",
    ]
    # readable as one hive-partitioned dataset by any Parquet engine
    assert len(pd.read_parquet(tmp_path / "poles")) == 52


def test_resume_skips_done_blocks_and_removes_orphans(tmp_path):
    store = BlockStore.open(tmp_path, {"method": "test"})
    run_blocks(
        (Task(b) for b in range(10)),
        square_block,
        store=store,
        scheduler="synchronous",
        batch_blocks=4,
    )
    # a batch killed after writing its poles but before its blocks file: an orphan
    orphan = tmp_path / "poles" / "day=2026-03-01" / "b0000099-0000099-deadbeef.parquet"
    square_block(Task(99)).tables["poles"].to_parquet(orphan)
    store = BlockStore.open(tmp_path, {"method": "test"})
    assert not orphan.exists()
    summary = run_blocks(
        (Task(b) for b in range(14)), square_block, store=store, scheduler="synchronous"
    )
    assert (summary.already_done, summary.processed + summary.skipped) == (10, 4)
    assert store.read("poles")["block"].nunique() == 12
    assert store.completed_blocks() == set(range(14))


def test_other_parameters_refuse_to_resume(tmp_path):
    BlockStore.open(tmp_path, {"block_rows": 40})
    with pytest.raises(
        WorkbenchError, match=r"store was made with other parameters \(block_rows\)"
    ):
        BlockStore.open(tmp_path, {"block_rows": 60})


def test_dask_local_cluster_matches_synchronous(tmp_path):
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    sync = BlockStore.open(tmp_path / "sync", {})
    run_blocks((Task(b) for b in range(24)), square_block, store=sync, scheduler="synchronous")
    parallel = BlockStore.open(tmp_path / "dask", {})
    summary = run_blocks(
        (Task(b) for b in range(24)),
        square_block,
        store=parallel,
        n_workers=2,
        max_in_flight=3,
        batch_blocks=5,
    )
    assert (summary.processed, summary.skipped) == (21, 3)
    pd.testing.assert_frame_equal(parallel.read("poles"), sync.read("poles"))
    np.testing.assert_array_equal(parallel.read("blocks")["block"], np.arange(24))


class SharingTask(Task):
    """Block *b* needs "files" b .. b+3, as a 20-min block with 75 % overlap does."""

    def __init__(self, block: int, log_dir):
        super().__init__(block)
        self.shared_inputs = tuple(
            SharedInput(f"file{k}", file_value, (k, str(log_dir))) for k in range(block, block + 4)
        )


def file_value(argument):
    """A stand-in for conditioning a file: logs each call (any process), file 5 is bad."""
    k, log_dir = argument
    with open(f"{log_dir}/file{k}", "a") as log:
        log.write("x")
    if k == 5:
        raise ValueError("file5: cannot read")
    return 10.0 * k


def sum_of_files(task, inputs):
    values = [inputs[f"file{k}"] for k in range(task.block, task.block + 4)]
    if any(v is None for v in values):
        raise ValueError(f"block {task.block}: a file failed")
    rows = pd.DataFrame({"block": [task.block], "block_start": [task.block_start]})
    return BlockOutcome(task.block, task.block_start, {"poles": rows.assign(value=sum(values))})


@pytest.mark.parametrize("scheduler", ["synchronous", None])
def test_shared_inputs_are_computed_once_and_handed_to_each_task(tmp_path, scheduler):
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    logs = tmp_path / "calls"
    logs.mkdir()
    store = BlockStore.open(tmp_path / "store", {})
    summary = run_blocks(
        (SharingTask(b, logs) for b in range(12)),
        sum_of_files,
        store=store,
        scheduler=scheduler,
        n_workers=2,
        max_in_flight=3,
    )
    # each of the 15 files computed once although 4 blocks use each (the first, 1..3)
    calls = {p.name: len(p.read_text()) for p in logs.iterdir()}
    assert calls == {f"file{k}": 1 for k in range(15)}
    # blocks 2..5 hold the failing file 5: skipped with the task's own reason
    assert summary.skip_reasons == {f"block {b}: a file failed": 1 for b in (2, 3, 4, 5)}
    poles = store.read("poles")
    assert poles["block"].tolist() == [0, 1, *range(6, 12)]
    np.testing.assert_array_equal(poles["value"], [10.0 * (4 * b + 6) for b in poles["block"]])


def test_read_chunks_streams_block_order_from_unordered_batches(tmp_path):
    """Batches written out of order (as a cluster finishes them) read back in block order,
    a few blocks at a time, with exactly the rows of a full read."""
    store = BlockStore.open(tmp_path, {})
    start = pd.Timestamp("2025-01-01T00:00Z")
    for blocks in ([4, 5, 9], [0, 1, 2], [3, 6, 7, 8]):
        frame = pd.DataFrame(
            {
                "block": np.repeat(blocks, 2),
                "block_start": start,
                "model_order": np.tile([4, 2], len(blocks)),
                "value": np.arange(2 * len(blocks), dtype=float),
            }
        )
        status = pd.DataFrame({"block": blocks, "block_start": start, "status": "ok", "reason": ""})
        store.write_batch(status, {"poles": frame})
    chunks = list(store.read_chunks("poles", blocks_per_chunk=3))
    assert [sorted(c["block"].unique()) for c in chunks] == [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9]]
    streamed = pd.concat(chunks, ignore_index=True)
    pd.testing.assert_frame_equal(streamed, store.read("poles"))
    assert (streamed.groupby("block")["model_order"].apply(list) == [[2, 4]] * 10).all()


def _fingerprint(k: int, sha: str | None = None) -> dict:
    start = pd.Timestamp("2026-03-01T00:00:00Z") + pd.Timedelta(seconds=300 * k)
    return {
        "path": f"/watch/acc_{k:03d}.npz",
        "start": start.isoformat(),
        "end": (start + pd.Timedelta(seconds=300)).isoformat(),
        "size": 1000,
        "mtime_ns": k,
        "sha256": sha or f"{k:064x}",
    }


def test_inputs_checked_one_file_at_a_time_as_checked_all_at_once(tmp_path):
    # the monitor checks each landed file: the store keeps inputs.jsonl as it last read or
    # wrote it instead of parsing every file's fingerprint again, and appends a line per
    # new file; the file written, and a changed input's refusal, are those of one check of
    # all files
    one = BlockStore.open(tmp_path / "one", {})
    for k in range(40):
        one.check_inputs([_fingerprint(k)])
        one.check_inputs([_fingerprint(k // 2)])  # a file taken again: nothing written
    whole = BlockStore.open(tmp_path / "whole", {})
    whole.check_inputs([_fingerprint(k) for k in range(40)])
    assert (tmp_path / "one" / "inputs.jsonl").read_bytes() == (
        tmp_path / "whole" / "inputs.jsonl"
    ).read_bytes()
    with pytest.raises(WorkbenchError, match="acc_007.npz: input changed since the store"):
        one.check_inputs([_fingerprint(7, sha="e" * 64)])
    assert len(one.recorded_inputs()) == 40


def test_inputs_rewritten_since_the_last_check_are_read_again(tmp_path):
    store = BlockStore.open(tmp_path, {})
    store.check_inputs([_fingerprint(k) for k in range(5)])
    changed = _fingerprint(3, sha="e" * 64)
    store.forget_inputs([_fingerprint(3)])  # another writer of inputs.jsonl: read again
    store.check_inputs([changed])
    assert [r["sha256"] for r in store.recorded_inputs()][-1] == "e" * 64
    store.set_unreadable_files(["/watch/bad.npz"])
    store.check_inputs([_fingerprint(9)])  # the unreadable files are kept
    assert store.unreadable_files() == ["/watch/bad.npz"]
    with pytest.raises(WorkbenchError, match="acc_003.npz: input changed"):
        store.check_inputs([_fingerprint(3)])


def test_a_new_input_is_a_line_appended_to_the_index(tmp_path):
    # before: inputs.json written whole again for each new file (3.8 MB at day 51 of
    # 5-min files, 70 ms a file); now a line appended: the same inode, grown by the line
    store = BlockStore.open(tmp_path, {})
    store.check_inputs([_fingerprint(k) for k in range(30)])
    index = tmp_path / "inputs.jsonl"
    before = index.stat()
    store.check_inputs([_fingerprint(30)])
    after = index.stat()
    line = json.dumps({"file": _fingerprint(30)}, sort_keys=True, separators=(",", ":")) + "\n"
    assert after.st_ino == before.st_ino
    assert after.st_size == before.st_size + len(line.encode())
    assert index.read_text(encoding="utf-8").endswith(line)
    assert [r["sha256"] for r in store.recorded_inputs()] == [f"{k:064x}" for k in range(31)]


def test_an_index_of_the_earlier_format_is_converted_when_opened(tmp_path):
    # a store written before inputs.jsonl: inputs.json, one object written whole
    files = [_fingerprint(k) for k in range(5)]
    (tmp_path / "inputs.json").write_text(
        json.dumps({"files": files, "unreadable": ["/watch/bad.npz"]}, indent=1),
        encoding="utf-8",
    )
    store = BlockStore.open(tmp_path, {})
    assert store.notices == [
        f"{tmp_path}: inputs.json (5 input file(s), written whole for each file) converted "
        "to inputs.jsonl (a line appended for each file)"
    ]
    assert not (tmp_path / "inputs.json").exists()
    assert store.recorded_inputs() == files
    assert store.unreadable_files() == ["/watch/bad.npz"]
    with pytest.raises(WorkbenchError, match="acc_003.npz: input changed since the store"):
        store.check_inputs([_fingerprint(3, sha="e" * 64)])


def test_an_unreadable_index_of_the_earlier_format_is_refused(tmp_path):
    (tmp_path / "inputs.json").write_text('{"cut', encoding="utf-8")
    with pytest.raises(WorkbenchError) as error:
        BlockStore.open(tmp_path, {})
    message = str(error.value)
    assert len(message.splitlines()) == 1
    assert message.startswith(f"{tmp_path}: inputs.json is unreadable (")
    assert f"mv {tmp_path / 'inputs.json'} {tmp_path / 'inputs.json'}.damaged" in message


def test_a_line_cut_short_by_a_killed_run_is_left_out(tmp_path):
    store = BlockStore.open(tmp_path, {})
    store.check_inputs([_fingerprint(k) for k in range(3)])
    store.close()
    index = tmp_path / "inputs.jsonl"
    whole = index.read_bytes()
    with open(index, "ab") as handle:  # a run killed while appending the line of file 3
        handle.write(b'{"file":{"end":"2026-03-01T00:20')
    store = BlockStore.open(tmp_path, {})
    assert store.notices == [
        f"{tmp_path}: the last line of inputs.jsonl was cut short (a run killed while "
        "recording an input file): left out, the file is fingerprinted again when taken"
    ]
    assert index.read_bytes() == whole
    store.check_inputs([_fingerprint(3)])
    assert [r["sha256"] for r in store.recorded_inputs()] == [f"{k:064x}" for k in range(4)]
    # a whole line that is no fingerprint: the index is damaged, refused
    with open(index, "a", encoding="utf-8") as handle:
        handle.write('{"files": []}\n')
    with pytest.raises(WorkbenchError, match=r"inputs.jsonl is unreadable \(line 5: neither"):
        store.check_inputs([_fingerprint(9)])
