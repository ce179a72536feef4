"""Forked local workers of run_blocks (workbench.local_workers, issue 33): contiguous
ranges, shared inputs computed once across ranges, errors and dead workers reported, and
the same store as in-process."""

from __future__ import annotations

import collections
import os
import signal
import sys

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from workbench import parallel
from workbench.local_workers import _owners, fork_available, run_forked, split_ranges
from workbench.parallel import BlockOutcome, SharedInput, run_blocks
from workbench.store import BlockStore

pytestmark = pytest.mark.skipif(not fork_available(), reason="processes cannot be forked")

T0 = pd.Timestamp("2026-03-01T00:00Z")


class Task:
    def __init__(self, block: int, log_dir=None, n_files: int = 4):
        self.block = block
        self.block_start = T0 + pd.Timedelta(minutes=5 * block)
        if log_dir is not None:  # block b needs files b .. b + n_files - 1
            self.shared_inputs = tuple(
                SharedInput(f"file{k}", logged_value, (k, str(log_dir)))
                for k in range(block, block + n_files)
            )


def logged_value(argument):
    """A stand-in for conditioning a file: logs the process computing it."""
    k, log_dir = argument
    with open(f"{log_dir}/file{k}", "a") as log:
        log.write(f"{os.getpid()}\n")
    return np.full(3, 10.0 * k)


def summed(task, inputs=None):
    value = 0.0 if inputs is None else float(sum(v.sum() for v in inputs.values()))
    rows = pd.DataFrame(
        {"block": [task.block], "block_start": [task.block_start], "value": [value]}
    )
    return BlockOutcome(task.block, task.block_start, {"poles": rows}, notes=(str(os.getpid()),))


def test_split_ranges_is_contiguous_and_balanced():
    assert split_ranges(9, 2) == [range(0, 5), range(5, 9)]
    assert split_ranges(10, 3) == [range(0, 4), range(4, 7), range(7, 10)]
    assert split_ranges(2, 4) == [range(0, 1), range(1, 2)]
    assert split_ranges(0, 2) == []
    with pytest.raises(ValueError, match="n_workers=0"):
        split_ranges(3, 0)


def test_inputs_at_the_join_go_to_the_worker_with_less_work():
    # a 1-h voyage: 9 blocks of 4 five-minute files; ranges of 5 and 4 blocks. The files
    # 5-7 both ranges need: counted at two blocks' work each, 5 and 6 go to the second
    # worker, 7 to the first (5 blocks + 6 files against 4 blocks + 6 files)
    needs = [tuple(f"file{k}" for k in range(b, b + 4)) for b in range(9)]
    owner = _owners(needs, split_ranges(9, 2))
    mine = {w: sorted(int(k[4:]) for k, o in owner.items() if o == w) for w in (0, 1)}
    assert mine == {0: [0, 1, 2, 3, 4, 7], 1: [5, 6, 8, 9, 10, 11]}
    # counted at one task's work, the later worker takes the ties (its first tasks)
    owner = _owners(needs, split_ranges(9, 2), weight=1.0)
    assert sorted(int(k[4:]) for k, o in owner.items() if o == 1) == [5, 6, 7, 8, 9, 10, 11]
    # a day: 288 blocks, 291 files, split 145 / 146
    needs = [tuple(range(b, b + 4)) for b in range(288)]
    counts = collections.Counter(_owners(needs, split_ranges(288, 2)).values())
    assert sorted(counts.values()) == [145, 146]


@pytest.mark.parametrize("n_workers", [2, 3])
def test_inputs_shared_by_two_ranges_are_computed_once_and_handed_over(tmp_path, n_workers):
    logs = tmp_path / "calls"
    logs.mkdir()
    tasks = [Task(b, logs) for b in range(10)]
    outcomes = []
    run_forked(
        tasks,
        lambda task, inputs: summed(task, inputs),
        parallel._compute_shared,
        n_workers,
        outcomes.append,
    )
    # 13 files, each computed once although up to four blocks (and two ranges) need it
    calls = {p.name: p.read_text().split() for p in logs.iterdir()}
    assert sorted(calls) == sorted(f"file{k}" for k in range(13))
    assert all(len(pids) == 1 for pids in calls.values())
    # every block got the values of its four files: 10 * (4 b + 6) per element, 3 elements
    values = {o.block: o.tables["poles"]["value"].iloc[0] for o in outcomes}
    assert values == {b: 30.0 * (4 * b + 6) for b in range(10)}
    # the blocks ran in n_workers processes, none of them this one
    workers = {o.notes[0] for o in outcomes}
    assert len(workers) == n_workers and str(os.getpid()) not in workers


class Broken(Exception):
    """Not a data error: run_blocks lets it through."""


def failing(task, inputs=None):
    if task.block == 6:
        raise Broken("block 6: a bug")
    return summed(task, inputs)


def dying(task, inputs=None):
    if task.block == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return summed(task, inputs)


def test_a_bug_in_a_worker_is_raised_here_and_a_dead_worker_reported(tmp_path):
    store = BlockStore.open(tmp_path / "bug", {})
    with pytest.raises(Broken, match="block 6: a bug"):
        run_blocks((Task(b) for b in range(8)), failing, store=store, n_workers=2)
    # what finished before is kept: blocks 4 and 5 came before block 6 in the same range
    assert {4, 5} <= store.completed_blocks()
    assert 6 not in store.completed_blocks()
    store = BlockStore.open(tmp_path / "dead", {})
    with pytest.raises(RuntimeError, match="worker process 0 ended without finishing"):
        run_blocks((Task(b) for b in range(8)), dying, store=store, n_workers=2)


def test_forked_workers_and_a_dask_cluster_fill_the_store_as_this_process(tmp_path, monkeypatch):
    def run(name, **kwargs):
        store = BlockStore.open(tmp_path / name, {})
        summary = run_blocks((Task(b, tmp_path) for b in range(9)), summed, store=store, **kwargs)
        assert (summary.processed, summary.skipped) == (9, 0)
        return store.read("poles")

    here = run("here", scheduler="synchronous")
    forked = run("forked", n_workers=2)
    pd.testing.assert_frame_equal(forked, here)
    # where processes cannot be forked, a local Dask cluster runs the same tasks
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    monkeypatch.setattr(parallel, "fork_available", lambda: False)
    dask = run("dask", n_workers=2)
    pd.testing.assert_frame_equal(dask, here)
