"""The reference (window) forecast equals its recording (tests/forecast/results/).

window_reference.csv was written by make_window_reference.py from the window path before
it was split into named steps; the split must not change a single number (tolerance
1e-9 Hz: round-off of reordered but identical arithmetic, far below any modal precision).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

RESULTS = Path(__file__).resolve().parent / "results"
sys.path.insert(0, str(RESULTS))

from make_window_reference import COLUMNS, forecast  # noqa: E402


def test_window_forecast_equals_the_recorded_reference():
    expected = pd.read_csv(RESULTS / "window_reference.csv", keep_default_na=False, na_values=[""])
    actual = forecast()
    assert len(actual) == len(expected)
    assert actual[["run", "block", "mode"]].equals(expected[["run", "block", "mode"]])
    assert (actual["phase"].astype(str) == expected["phase"].astype(str)).all()
    for column in COLUMNS:
        a = actual[column].to_numpy(dtype=float)
        e = expected[column].to_numpy(dtype=float)
        assert np.array_equal(np.isnan(a), np.isnan(e)), column
        assert np.nanmax(np.abs(a - e)) < 1e-9, column
    warn_a = actual["warning"].fillna("").astype(str).to_numpy()
    warn_e = expected["warning"].fillna("").astype(str).to_numpy()
    assert (warn_a == warn_e).all()
