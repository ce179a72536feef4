"""The vectorised memory path gives the results of the code before the speed-up.

memory_reference.csv was recorded by tests/forecast/results/make_memory_reference.py with the
memory path of commit 301f99c (before it was vectorised), and re-recorded when the method
changed on purpose (issue 11, the innovation-run rule across overlapping blocks; the
model-error floor from the out-of-sample residuals and the innovation-consistency
safeguard). The speed-up only reorganises the arithmetic (recursive sums instead of refits
from scratch), so the values may differ by
floating-point round-off: 1e-9 Hz is ~1e-10 relative on 2-8 Hz modes, far below any
modelling effect (the SSI scatter of the case is 3e-3 relative) and far above round-off.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd

RESULTS = Path(__file__).with_name("results")


def _reference_module():
    spec = importlib.util.spec_from_file_location(
        "make_memory_reference", RESULTS / "make_memory_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_memory_forecast_equals_the_recorded_reference():
    module = _reference_module()
    reference = pd.read_csv(RESULTS / "memory_reference.csv")
    table = module.forecast()
    assert (reference["phase"] == "forecast").sum() > 2000  # refits over 3 days, 3 modes
    pd.testing.assert_frame_equal(
        table[["block", "mode", "phase"]].astype(str),
        reference[["block", "mode", "phase"]].astype(str),
    )
    for column in module.COLUMNS:
        got, want = table[column].to_numpy(float), reference[column].to_numpy(float)
        assert np.array_equal(np.isnan(got), np.isnan(want)), column
        ok = np.isfinite(want)
        assert np.max(np.abs(got[ok] - want[ok])) <= 1e-9, column
