"""The monitor's taken files kept incrementally equal the batch computation.

TakenFiles keeps the files in time order and their placement as files land (one at a time,
some late); the monitor plans only the blocks it has not decided (placed_blocks). Both must
give what identify computes from all the files at once: place_files of the sorted headers,
and plan_file_infos' blocks. The headers are those of a recorder whose sample clock runs
some ppm off (5-min files at 2048 Hz, stamps jittered by up to 8 ms), with a real gap.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.blocks import BlockGrid
from workbench.monitor.taken import TakenFiles
from workbench.monitor.watcher import LandedFile
from workbench.signals.block_plan import (
    FileInfo,
    place_files,
    placed_block_numbers,
    placed_blocks,
    plan_file_infos,
)

RATE_HZ = 2048.0
N_SAMPLES = int(300 * RATE_HZ)
T0 = pd.Timestamp("2026-03-01T00:00:00Z")
LANDED = pd.Timestamp("2026-03-02T00:00:00Z")


def _headers(ppm: float, seed: int, n_files: int, gap_s: float, gap_at: int) -> list[FileInfo]:
    rng = np.random.default_rng(seed)
    stamps = np.arange(n_files) * 300.0 / (1 + ppm * 1e-6)
    stamps += rng.uniform(-0.008, 0.008, n_files)
    stamps[gap_at:] += gap_s
    return [
        FileInfo(Path(f"acc_{k:03d}.npz"), T0 + pd.Timedelta(seconds=float(s)), RATE_HZ,
                 N_SAMPLES, ("a",))
        for k, s in enumerate(stamps)
    ]  # fmt: skip


def _landing_order(n_files: int, late: list[tuple[int, int]]) -> list[int]:
    """The files in time order, each (file, delay) landing *delay* files after its turn."""
    order = list(range(n_files))
    for index, delay in late:
        position = order.index(index)
        order.pop(position)
        order.insert(min(position + delay, len(order)), index)
    return order


@settings(max_examples=40, deadline=None)
@given(
    ppm=st.sampled_from([-60.0, 0.0, 20.0, 100.0]),
    gap_s=st.sampled_from([0.0, 2.0, 600.0]),
    gap_at=st.integers(1, 39),
    late=st.lists(st.tuples(st.integers(0, 39), st.integers(1, 6)), max_size=3),
    seed=st.integers(0, 50),
)
def test_taken_files_equal_the_whole_placement_however_they_land(ppm, gap_s, gap_at, late, seed):
    infos = _headers(ppm, seed, 40, gap_s, gap_at)
    taken = TakenFiles()
    for index in _landing_order(len(infos), late):
        taken.add(LandedFile(infos[index], LANDED, index, index))
        taken.placed()  # placed as each file lands, as the monitor asks for them
    whole = place_files(sorted(infos, key=lambda i: (i.start_time, str(i.path))))
    assert [f.info for f in taken] == infos  # in time order, as taken (their stamps)
    assert tuple(taken.placed_infos()) == whole
    assert tuple(f.info for f in taken.placed()) == whole
    assert [f.size for f in taken.placed()] == list(range(len(infos)))  # the same files
    starts, ends = taken.coverage()
    assert starts.tolist() == [i.start_time.value for i in whole]
    assert ends.tolist() == [i.end_time.value for i in whole]
    placement = taken.placement()
    assert tuple(placement.files) == whole
    for k in (0, gap_at, len(infos) - 1):
        path = infos[k].path
        assert taken.placed_index(path) == k
        assert taken.placed_file(path).info == whole[k]
        assert taken.get(path).info == infos[k]
    assert taken.placed_file(Path("acc_999.npz")) is None


def test_taken_files_cleared_are_given_back_in_order():
    infos = _headers(20.0, 1, 6, 0.0, 3)
    taken = TakenFiles()
    for index in (1, 0, 2, 5, 3, 4):
        taken.add(LandedFile(infos[index], LANDED, index, index))
    assert len(taken.placed()) == 6
    files = taken.clear()
    assert [f.info for f in files] == infos
    assert len(taken) == 0 and taken.placed() == [] and taken.coverage()[0].size == 0
    assert taken.get(infos[0].path) is None


def test_the_blocks_planned_from_the_placed_files_equal_the_whole_plan():
    # drift and jitter, a gap NaN-padded inside a block (3 s) and one that skips blocks
    infos = _headers(20.0, 7, 30, 3.0, 10)
    infos[20:] = [
        FileInfo(i.path, i.start_time + pd.Timedelta(seconds=400.0), RATE_HZ, N_SAMPLES, ("a",))
        for i in infos[20:]
    ]
    grid = BlockGrid(T0, 1200.0, 300.0)
    whole = plan_file_infos(infos, grid, max_gap_s=5.0, channels=("a",))
    assert {b.skipped_reason != "" for b in whole.blocks} == {True, False}
    placed = list(place_files(infos))
    assert tuple(place_files(placed)) == tuple(placed)  # placed files come back unchanged
    starts = np.array([i.start_time.value for i in placed], dtype=np.int64)
    ends = np.array([i.end_time.value for i in placed], dtype=np.int64)
    numbers = placed_block_numbers(placed, grid)
    assert numbers.tolist() == [b.block for b in whole.blocks]
    every = placed_blocks(placed, starts, ends, grid, numbers, max_gap_s=5.0)
    assert tuple(every) == whole.blocks
    some = [int(k) for k in numbers[::7]]  # any few of them: as in the whole plan
    assert placed_blocks(placed, starts, ends, grid, some, max_gap_s=5.0) == [
        b for b in whole.blocks if b.block in some
    ]
