"""Tests for the shared block grid (workbench.blocks).

Expected values follow from the grid definition in data_contracts/README.md: block k
covers [t0 + k*step, t0 + k*step + length), t0 = first time floored to the step.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import PREDICTORS
from workbench.blocks import BlockGrid

T0 = pd.Timestamp("2024-03-01T00:00:00Z")


def test_from_first_time_floors_to_the_step():
    grid = BlockGrid.from_first_time("2024-03-01T00:07:31.25Z", 1200, 300)
    assert grid.t0 == pd.Timestamp("2024-03-01T00:05:00Z")
    assert grid.t0.tz is not None and str(grid.t0.tz) == "UTC"
    # a time on the step is its own t0; naive times are UTC
    assert BlockGrid.from_first_time("2024-03-01 00:10:00").t0 == pd.Timestamp(
        "2024-03-01T00:10:00Z"
    )
    # other time zones are converted, not relabelled: 01:07 CET is 00:07 UTC
    assert BlockGrid.from_first_time(pd.Timestamp("2024-03-01 01:07", tz="CET")).t0 == (
        pd.Timestamp("2024-03-01T00:05:00Z")
    )


def test_start_and_end():
    grid = BlockGrid(T0)
    assert grid.start(0) == T0
    assert grid.end(0) == T0 + pd.Timedelta(minutes=20)
    assert grid.start(7) == T0 + pd.Timedelta(minutes=35)
    starts = grid.start(np.array([0, 1, 2]))
    assert isinstance(starts, pd.DatetimeIndex)
    assert list(starts.minute) == [0, 5, 10]
    assert (grid.end(np.arange(5)) - grid.start(np.arange(5)) == pd.Timedelta(minutes=20)).all()


def test_complete_blocks_of_one_hour():
    """One hour of data, 20-min blocks every 5 min: (60 - 20) / 5 + 1 = 9 blocks."""
    grid = BlockGrid(T0)
    blocks = grid.complete_blocks(T0, T0 + pd.Timedelta(hours=1))
    np.testing.assert_array_equal(blocks, np.arange(9))
    # data starting 1 s late cannot fill block 0
    late = grid.complete_blocks(T0 + pd.Timedelta(seconds=1), T0 + pd.Timedelta(hours=1))
    np.testing.assert_array_equal(late, np.arange(1, 9))
    # too short for any block
    assert grid.complete_blocks(T0, T0 + pd.Timedelta(minutes=19)).size == 0


def test_blocks_covering():
    grid = BlockGrid(T0)
    # [00:20, 00:25) touches blocks 1 (00:05-00:25) .. 4 (00:20-00:40)
    np.testing.assert_array_equal(
        grid.blocks_covering(T0 + pd.Timedelta(minutes=20), T0 + pd.Timedelta(minutes=25)),
        [1, 2, 3, 4],
    )
    # the end is exclusive: [00:00, 00:05) does not touch block 1
    np.testing.assert_array_equal(grid.blocks_covering(T0, T0 + pd.Timedelta(minutes=5)), [0])
    # before t0: nothing (block numbers are never negative)
    assert grid.blocks_covering(T0 - pd.Timedelta(hours=1), T0).size == 0


def test_frame_follows_the_predictors_contract_columns():
    grid = BlockGrid(T0, 600, 600)
    frame = grid.frame([3, 0])
    assert list(frame.columns) == ["block", "block_start", "block_end"]
    assert frame["block"].tolist() == [3, 0]
    assert frame["block_start"].iloc[0] == T0 + pd.Timedelta(minutes=30)
    assert str(frame["block_start"].dtype) == "datetime64[ns, UTC]"
    for column in PREDICTORS.columns[3:]:
        frame[column.name] = np.nan
    PREDICTORS.validate(frame)  # no ContractError


def test_non_multiple_length_and_fractional_step():
    grid = BlockGrid(T0, 1000.0, 300.0)
    assert grid.end(1) == T0 + pd.Timedelta(seconds=1300)
    np.testing.assert_array_equal(
        grid.complete_blocks(T0, T0 + pd.Timedelta(seconds=1899)), [0, 1, 2]
    )
    half = BlockGrid(T0, 1.5, 0.5)
    assert half.start(3) == T0 + pd.Timedelta(seconds=1.5)


@pytest.mark.parametrize(
    ("length", "step", "match"),
    [(300, 1200, "at least step_s"), (0, 300, "length_s"), (1200, -5, "step_s")],
)
def test_invalid_grids(length, step, match):
    with pytest.raises(ValueError, match=match):
        BlockGrid(T0, length, step)


def test_invalid_block_numbers_and_times():
    grid = BlockGrid(T0)
    with pytest.raises(ValueError, match=">= 0"):
        grid.start(-1)
    with pytest.raises(ValueError, match="whole"):
        grid.start(1.5)
    with pytest.raises(ValueError, match="t0"):
        BlockGrid("not a time")
