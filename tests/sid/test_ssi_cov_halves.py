"""SSI-cov on the two halves of a record from the whole record's correlations
(:func:`~workbench.sid.ssi.covariance_driven.ssi_cov_halves`): the same lagged products and
poles as :func:`ssi_cov` on each half alone (up to rounding), and the same half-block
differences of the identification."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from workbench.sid import ssi_cov
from workbench.sid.ssi.covariance_driven import ssi_cov_halves
from workbench.sid.ssi.hankel import _halves_lagged_products, _lagged_products
from workbench.simulate.prescribed import prescribed_mode_record

FREQUENCY = np.array([1.1, 2.3, 3.4, 4.6, 5.9])


def _record(seed: int, duration_s: float = 300.0):
    rng = np.random.default_rng(500 + seed)
    return prescribed_mode_record(
        FREQUENCY,
        0.01,
        rng.standard_normal((8, 5)),
        sampling_rate_hz=16.0,
        duration_s=duration_s,
        sensor_noise=0.2,
        seed=seed,
    )


@pytest.mark.parametrize("columns", [np.arange(6), np.array([0, 4])])
@pytest.mark.parametrize("n_samples", [4000, 4001])
def test_halves_lagged_products_are_those_of_each_half(columns, n_samples):
    """Against :func:`_lagged_products` of each half centred on its own mean, for a record
    with channel offsets (so the centring terms matter) and an odd length: within
    1e-14 |S[0]| (rounding of sums of about N products: the second half's with another
    FFT length, the first half's the whole record's less the second half's)."""
    rng = np.random.default_rng(1)
    data = rng.standard_normal((n_samples, 6)) @ rng.standard_normal((6, 6))
    data += 3.0 * rng.standard_normal(6)
    middle = n_samples // 2
    first_half = data[:middle] - data[:middle].mean(axis=0)
    second_half = data[middle:] - data[middle:].mean(axis=0)
    whole = _lagged_products(data - data.mean(axis=0), 17, columns)

    first, second = _halves_lagged_products(data, second_half, whole, 17, columns)

    for derived, half in ((first, first_half), (second, second_half)):
        direct = _lagged_products(half, 17, columns)
        assert np.abs(derived - direct).max() <= 1e-14 * np.abs(direct[0]).max()


def test_ssi_cov_halves_has_the_poles_of_ssi_cov_on_each_half():
    """The same poles at every order of each half (frequencies and damping ratios within
    1e-9 relative: the rounding of the lagged products, amplified by the subspace
    problem)."""
    acceleration = _record(0).acceleration
    orders = tuple(range(20, 41, 4))
    whole = ssi_cov(acceleration, 16.0, block_rows=20, orders=range(4, 41, 2))
    first, second = ssi_cov_halves(
        acceleration, 16.0, whole.output_correlations, block_rows=20, orders=orders
    )
    middle = acceleration.shape[0] // 2
    alone = [
        ssi_cov(part, 16.0, block_rows=20, orders=orders)
        for part in (acceleration[:middle], acceleration[middle:])
    ]
    for half, own in zip((first, second), alone, strict=True):
        np.testing.assert_array_equal(half.model_order, own.poles["model_order"])
        np.testing.assert_allclose(half.frequency_hz, own.poles["frequency_hz"], rtol=1e-9)
        np.testing.assert_allclose(half.damping_ratio, own.poles["damping_ratio"], rtol=1e-9)


def test_ssi_cov_halves_checks_the_halves_and_the_correlations():
    acceleration = _record(0, duration_s=60.0).acceleration
    whole = ssi_cov(acceleration, 16.0, block_rows=20, orders=range(4, 41, 2))
    with pytest.raises(ValueError, match="block_rows=40 needs at least"):
        ssi_cov_halves(acceleration, 16.0, np.zeros((80, 8, 8)), block_rows=40, orders=(40,))
    with pytest.raises(ValueError, match="whole_correlations of shape"):
        ssi_cov_halves(acceleration, 16.0, whole.output_correlations, block_rows=10, orders=(20,))


def test_half_differences_from_the_whole_block_agree_with_each_half_alone():
    """The scenario of ``tests/forecast/test_ssi_guard.py::
    test_half_differences_measure_the_block_estimates_scatter`` (5-min blocks, 10 seeds):
    half_differences from the block's result (the identification's path) gives the
    differences of SSI-cov on each half alone, the same modes found, within 1e-8 Hz (the
    differences themselves are of order 1e-3 Hz)."""
    from workbench.identification.engine import _identify_method, half_differences
    from workbench.identification.options import IdentifyOptions

    options = IdentifyOptions()
    for seed in range(10):
        record = _record(seed)
        data = SimpleNamespace(
            acceleration=record.acceleration - record.acceleration.mean(axis=0),
            sampling_rate_hz=16.0,
            channels=tuple(f"ch{j}" for j in range(8)),
        )
        result, selection = _identify_method("cov", data, None, options)
        alone = half_differences("cov", data, None, options, selection)
        whole = half_differences("cov", data, None, options, selection, whole=result)
        np.testing.assert_array_equal(np.isnan(whole), np.isnan(alone))
        np.testing.assert_allclose(whole, alone, rtol=0, atol=1e-8)
