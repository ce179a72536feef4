"""Block-time errors of tables whose blocks vary in length say "is centred at" with the
centre, not "starts" with it.

Before: a table of blocks of varying length is checked on its blocks' centres, but the
error said "block 7 starts 2024-03-01T00:45:30Z ... from block 0 at 2024-03-01T00:10:00Z"
of a block that starts at 00:36 and a block 0 that starts at 00:00: the reader looked for
a wrong start that is not in the file.
"""

from __future__ import annotations

import pandas as pd
import pytest

from workbench.errors import WorkbenchError
from workbench.joins import check_block_grid, check_block_times

T0 = pd.Timestamp("2024-03-01T00:00:00Z")


def _blocks(n: int = 10) -> pd.DataFrame:
    """20-min blocks every 5 min."""
    start = T0 + pd.to_timedelta(300 * pd.RangeIndex(n), unit="s")
    return pd.DataFrame(
        {"block": range(n), "block_start": start, "block_end": start + pd.Timedelta(minutes=20)}
    )


def test_a_block_off_the_grid_of_centres_is_said_by_its_centre():
    table = _blocks()
    table.loc[7, "block_start"] = T0 + pd.Timedelta(minutes=36)  # 19 min long: centres
    with pytest.raises(WorkbenchError) as error:
        check_block_grid(table, "modal.csv")
    assert str(error.value) == (
        "modal.csv: block 7 is centred at 2024-03-01T00:45:30Z, off the grid of the other "
        "blocks (a block every 300 s from block 0 centred at 2024-03-01T00:10:00Z): block "
        "numbers and times disagree"
    )


def test_fixed_blocks_still_say_starts():
    table = _blocks()
    shifted = table.copy()
    shifted["block_start"] += pd.Timedelta(minutes=1)
    shifted["block_end"] += pd.Timedelta(minutes=1)
    with pytest.raises(WorkbenchError, match=r"predictors.csv: block 0 starts 2024-03-01T00:01"):
        check_block_times(table, "modal.csv", shifted, "predictors.csv")
    varying = table.copy()
    varying.loc[3, "block_end"] -= pd.Timedelta(minutes=2)
    moved = varying.copy()
    moved["block_end"] += pd.Timedelta(minutes=2)
    moved.loc[3, "block_end"] += pd.Timedelta(minutes=2)
    with pytest.raises(WorkbenchError, match=r"predictors.csv: block 0 is centred at "):
        check_block_times(varying, "modal.csv", moved, "predictors.csv")


def test_times_apart_by_less_than_a_second_are_said_to_the_millisecond():
    """A grid 75.4 ms from another (past the 50-ms clock jitter, within which a grid
    anchored at a recorder's first stamp is the same grid) against one on whole seconds:
    both times are shown as they differ. Before: "block 0 starts 2024-03-01T00:00:00Z, but
    2024-03-01T00:00:00Z in modal.csv"."""
    table = _blocks()
    stamped = table.copy()
    stamped["block_start"] -= pd.Timedelta(microseconds=75397)
    stamped["block_end"] -= pd.Timedelta(microseconds=75397)
    with pytest.raises(WorkbenchError) as error:
        check_block_times(table, "modal.csv", stamped, "truth.csv")
    assert str(error.value) == (
        "truth.csv: block 0 starts 2024-02-29T23:59:59.924Z, but 2024-03-01T00:00:00Z in "
        "modal.csv (10 of 10 common blocks differ, first by -0.075397 s; starts within "
        "0.05 s, a recorder's clock jitter, are the same): block numbers must mean the same "
        "times in every input"
    )
