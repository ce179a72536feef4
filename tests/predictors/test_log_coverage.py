"""A ship log that covers only part of the modal table's blocks is said, not silently filled."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from workbench.errors import WorkbenchError
from workbench.joins import check_predictors_overlap


def _tables(logged: np.ndarray) -> tuple[pd.DataFrame, pd.DataFrame]:
    blocks = np.arange(len(logged))
    starts = pd.Timestamp("2024-03-01", tz="UTC") + pd.to_timedelta(blocks * 300, unit="s")
    modal = pd.DataFrame({"block": np.repeat(blocks, 2), "block_start": np.repeat(starts, 2)})
    speed = np.where(logged, 8.0, np.nan)
    predictors = pd.DataFrame(
        {"block": blocks, "block_start": starts, "speed_kn": speed, "water_temp_c": speed / 4}
    )
    return modal, predictors


def test_a_log_that_ends_early_names_the_unlogged_blocks():
    logged = np.arange(21) < 4
    modal, predictors = _tables(logged)
    with pytest.warns(UserWarning) as record:
        check_predictors_overlap(modal, predictors, "log.tsv")
    (message,) = [str(w.message) for w in record]
    assert "log.tsv: no predictor value on 17 of 21 blocks" in message
    assert "blocks 4 to 20, 2024-03-01T00:20:00Z to 2024-03-01T01:40:00Z" in message


def test_one_logged_predictor_is_enough_and_a_complete_log_is_silent():
    modal, predictors = _tables(np.ones(6, dtype=bool))
    predictors.loc[2, "speed_kn"] = np.nan  # water temperature still logged in block 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_predictors_overlap(modal, predictors, "log.tsv")


def test_no_overlap_at_all_is_an_error():
    modal, predictors = _tables(np.zeros(5, dtype=bool))
    with pytest.raises(WorkbenchError, match="does not overlap the blocks"):
        check_predictors_overlap(modal, predictors, "log.tsv")
