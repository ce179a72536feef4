"""The block's channel statistics (channels.csv: RMS and kurtosis) computed in one pass
(workbench.identification.engine._rms_and_kurtosis) against their reference,
``np.sqrt(np.nanmean(x**2))`` and ``scipy.stats.kurtosis(fisher=False)``: the same
operations in the same order, so equal to the last bit (no tolerance)."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from workbench.identification.engine import _channel_statistics, _rms_and_kurtosis


def _reference(x):
    return (
        np.sqrt(np.nanmean(x**2, axis=0)),
        stats.kurtosis(x, axis=0, fisher=False, nan_policy="omit"),
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_rms_and_kurtosis_equal_numpy_and_scipy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((7680, 6)) * [1.0, 0.01, 3.0, 1.0, 1.0, 2.0]
    x[:, 1] += 9.81  # a small variance about gravity
    x[:, 2] = rng.standard_t(4, len(x))  # heavy tails
    rms, kurtosis = _rms_and_kurtosis(x)
    reference_rms, reference_kurtosis = _reference(x)
    np.testing.assert_array_equal(rms, reference_rms)
    np.testing.assert_array_equal(kurtosis, reference_kurtosis)
    assert kurtosis[2] > 4.0 and abs(kurtosis[0] - 3.0) < 0.2


def test_constant_channel_has_no_kurtosis_and_warns_like_scipy():
    x = np.random.default_rng(2).standard_normal((500, 3))
    x[:, 1] = 0.25
    with pytest.warns(RuntimeWarning, match="catastrophic cancellation") as ours:
        _, kurtosis = _rms_and_kurtosis(x)
    with warnings.catch_warnings(record=True) as theirs:
        warnings.simplefilter("always")
        _, reference = _reference(x)
    assert len(ours) == 1 and any("catastrophic" in str(w.message) for w in theirs)
    assert np.isnan(kurtosis[1])
    np.testing.assert_array_equal(kurtosis, reference)


def test_channel_statistics_with_missing_samples_take_the_reference_path():
    x = np.random.default_rng(3).standard_normal((400, 2))
    x[10:20, 0] = np.nan
    frame = _channel_statistics(x, ["a", "b"], 4, pd.Timestamp("2024-01-01", tz="UTC"))
    reference_rms, reference_kurtosis = _reference(x)
    np.testing.assert_array_equal(frame["rms"], reference_rms)
    np.testing.assert_array_equal(frame["kurtosis"], reference_kurtosis)
    assert list(frame["channel"]) == ["a", "b"] and (frame["block"] == 4).all()
