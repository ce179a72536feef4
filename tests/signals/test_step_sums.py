"""Faulty-channel statistics assembled from per-step sums (workbench.signals.step_sums)
against the reference computed on the whole block (workbench.signals.faulty_channels).

The sums are taken piece by piece in row chunks (a chunk holding a NaN is summed again
over its finite samples), the block's statistics assembled from them exactly, so the two
paths differ by rounding only. The tolerance 1e-9 (relative) is far above the rounding of
sums of 10^4-10^5 terms (measured below 1e-13 on these cases and 4e-15 on the 2048-Hz
benchmark voyage) and far below any threshold of the channel check.
"""

from __future__ import annotations

import numpy as np
import pytest

from workbench.signals import faulty_channels
from workbench.signals.step_sums import _block_statistics, _step_sums

RATE = 256.0
NS = 1_000_000_000


def _block(seed: int, n: int) -> np.ndarray:
    """Noise with a line, large offsets (a channel's gravity over a small variance), NaN
    runs inside a chunk, across a chunk join and at the ends, and a channel all NaN."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    x = rng.standard_normal((n, 6)) * np.array([1.0, 0.01, 3.0, 1.0, 1.0, 0.2])
    x[:, 2] = rng.standard_t(4, n)  # heavy tails: kurtosis well above 3
    x += np.array([0.0, 9.81, -2.0, 0.0, 0.5, 100.0]) + 0.01 * t[:, None]
    x[100:300, 0] = np.nan
    x[4090:4100, 0] = np.nan  # across the join of two 4096-row chunks
    x[:, 3] = np.nan
    x[-7:, 4] = np.nan
    x[:5, 5] = np.nan
    return x


@pytest.mark.parametrize("cuts", [(), (5000,), (4096, 8192), (1, 9000)])
def test_statistics_from_step_sums_equal_the_whole_block(cuts):
    x = _block(3, 12_345)
    bounds = [0, *cuts, len(x)]
    pieces = [
        _step_sums(x[a:b], int(round(a / RATE * NS)), RATE)
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    nan_fraction, longest, variance, kurtosis = _block_statistics(pieces, len(x), RATE)
    reference = faulty_channels(x, RATE)

    np.testing.assert_allclose(nan_fraction, reference["nan_fraction"], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(longest, reference["longest_nan_run_s"])
    assert longest[0] == pytest.approx(200 / RATE)  # the longer of the two runs
    assert np.isnan(variance[3]) and np.isnan(kurtosis[3])  # all NaN
    np.testing.assert_allclose(variance, reference["variance"], rtol=1e-9)
    np.testing.assert_allclose(kurtosis, reference["kurtosis"], rtol=1e-9)
    assert kurtosis[2] > 4.0 and abs(kurtosis[1] - 3.0) < 0.3  # t(4) against Gaussian


def test_step_sums_count_and_runs_of_missing_samples():
    x = _block(4, 9000)
    sums = _step_sums(x, 0, RATE)
    finite = (~np.isnan(x)).sum(axis=0)
    np.testing.assert_array_equal(sums.sums[0, 0], finite)  # counts are exact
    assert sums.sums[0, 0, 3] == 0 and (sums.sums[:, :, 3] == 0).all()
    np.testing.assert_array_equal(sums.leading_nan, [0, 0, 0, 9000, 0, 5])
    np.testing.assert_array_equal(sums.trailing_nan, [0, 0, 0, 9000, 7, 0])
    np.testing.assert_array_equal(sums.longest_nan, [200, 0, 0, 9000, 7, 5])
    # only the sums of u**i tau**j with i + j <= 4 are kept
    for i in range(5):
        assert (sums.sums[i, 5 - i :] == 0).all()


def test_offset_of_a_channel_finite_only_between_the_subsample_rows():
    """A channel NaN but for a short stretch (none of it in the offset's subsample) keeps
    a well-conditioned offset: a large mean over a small variance still gives its
    statistics to rounding."""
    rng = np.random.default_rng(5)
    x = rng.standard_normal((40_000, 2))
    x[:, 1] = np.nan
    x[20_001:20_008, 1] = 9.81 + 0.001 * rng.standard_normal(7)  # between subsample rows
    sums = _step_sums(x, 0, RATE)
    assert sums.offset[1] == pytest.approx(9.81, abs=0.01)
    _, _, variance, _ = _block_statistics([sums], len(x), RATE)
    reference = faulty_channels(x, RATE)
    np.testing.assert_allclose(variance, reference["variance"], rtol=1e-9)
