"""Tests for workbench.sid.plscf: pLSCF (PolyMAX) on systems with analytic modal parameters.

Tolerances as for SSI (issue 19): frequencies within 0.5 %, damping ratios within 20 %
(relative), MAC above 0.99. The statistical scatter of the damping ratio of these records
is 3-6 % (1/sqrt(π ζ f T), see test_ssi.py); the exponential correlation window is undone
exactly for the poles, its leakage adds a few per cent more.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import linalg

from data_contracts import POLES
from workbench.sid import plscf as lscf_module
from workbench.sid import select_modes
from workbench.sid.assurance import mac
from workbench.sid.plscf import half_spectra, lscf
from workbench.simulate.hull import CHANNELS

# the package exports the function lscf under the module's name


def _match(result, system, order):
    poles = result.poles
    rows = np.flatnonzero(poles["model_order"].to_numpy() == order)
    frequency = poles["frequency_hz"].to_numpy()
    matched = []
    for m, true_frequency in enumerate(system.frequency_hz):
        near = rows[np.abs(frequency[rows] / true_frequency - 1) < 0.02]
        assert near.size, f"no pole near mode {m + 1} ({true_frequency:.3f} Hz) at order {order}"
        macs = mac(result.mode_shapes[:, near], system.mode_shapes[:, m])
        matched.append(near[np.argmax(np.atleast_1d(macs))])
    return np.array(matched)


@pytest.mark.parametrize(("system_name", "polynomial_order"), [("chain3", 8), ("chain5", 8)])
def test_chains_recover_analytic_modes(system_name, polynomial_order, request):
    system = request.getfixturevalue(system_name)
    result = lscf(system.acceleration, system.sampling_rate_hz, orders=range(1, 13))
    n_refs = system.acceleration.shape[1]
    assert result.orders == tuple(p * n_refs for p in range(1, 13))
    rows = _match(result, system, polynomial_order * n_refs)
    poles = result.poles.iloc[rows]
    frequency_error = poles["frequency_hz"].to_numpy() / system.frequency_hz - 1
    damping_error = poles["damping_ratio"].to_numpy() / system.damping_ratio - 1
    macs = np.diag(np.atleast_2d(mac(result.mode_shapes[:, rows], system.mode_shapes)))
    assert np.all(np.abs(frequency_error) < 0.005), frequency_error
    assert np.all(np.abs(damping_error) < 0.20), damping_error
    assert np.all(macs > 0.99), macs
    assert poles["stable"].all()
    assert np.all(poles["mpc"].to_numpy() > 0.99)  # proportional damping: real modes


def test_frequency_band_and_reference_channels(chain5):
    band = (20.0, 50.0)  # modes 2-4 of 5 (26.4, 41.6, 53.4 Hz -> 2 and 3 inside)
    result = lscf(
        chain5.acceleration,
        chain5.sampling_rate_hz,
        orders=range(1, 16),
        band_hz=band,
        reference_channels=[0, 4],
    )
    frequency = result.poles["frequency_hz"].to_numpy()
    assert np.all((frequency >= band[0]) & (frequency <= band[1]))
    assert result.participation_factors.shape == (2, len(result.poles))
    assert set(result.poles["model_order"]) <= {2 * p for p in range(1, 16)}
    inside = [m for m, f in enumerate(chain5.frequency_hz) if band[0] < f < band[1]]
    stable = result.poles[result.poles["stable"]]
    for m in inside:
        error = np.abs(stable["frequency_hz"].to_numpy() / chain5.frequency_hz[m] - 1)
        assert error.min() < 0.005, (m, error.min())


def test_moment_normal_equations_equal_the_direct_least_squares():
    """The Toeplitz-moment construction of M gives the poles of the textbook normal
    equations (explicit X, Y_o per output, as in Peeters et al. 2004, eqs. 5-9)."""
    rng = np.random.default_rng(0)
    n_lines, n_channels, n_refs, p = 40, 3, 2, 3
    spectra = rng.standard_normal((n_lines, n_channels, n_refs)) + 1j * rng.standard_normal(
        (n_lines, n_channels, n_refs)
    )
    rate = 100.0
    frequency = np.linspace(1.0, 45.0, n_lines)
    band = (0.0, 50.0)
    parts = lscf_module._fit_orders(spectra, frequency, rate, [p], 0.0, band)
    z = np.exp(2j * np.pi * frequency / rate)
    x = z[:, None] ** np.arange(p + 1)[None, :]
    r = np.real(x.conj().T @ x)
    m = np.zeros(((p + 1) * n_refs, (p + 1) * n_refs))
    for o in range(n_channels):
        y = -np.stack([np.kron(x[f], spectra[f, o]) for f in range(n_lines)])
        s = np.real(x.conj().T @ y)
        t = np.real(y.conj().T @ y)
        m += t - s.T @ np.linalg.solve(r, s)
    head = p * n_refs
    alpha = -np.linalg.solve(m[:head, :head], m[:head, head:])
    companion = np.zeros((head, head))
    companion[:-n_refs, n_refs:] = np.eye(head - n_refs)
    companion[-n_refs:] = -np.hstack([alpha[j * n_refs : (j + 1) * n_refs] for j in range(p)])
    mu = linalg.eigvals(companion)
    mu = mu[mu.imag > 0]
    expected = np.sort(np.abs(np.log(mu)) * rate / (2 * np.pi))
    got = np.sort(np.concatenate([part[1] for part in parts]))
    np.testing.assert_allclose(got, expected, rtol=1e-8)


def test_half_spectra_of_white_noise_are_flat():
    """For white noise, 2 Re S⁺ is the PSD of unit-variance channels: 1 at every line.

    Scatter of one line: var = 4 Σ w_k² / N ≈ 7e-4 (σ 0.026); 0.12 is 4.5 σ, the mean
    over 65 lines has σ 0.003."""
    rng = np.random.default_rng(1)
    data = rng.standard_normal((200_000, 2))
    spectra = half_spectra(data - data.mean(0), 10.0, np.arange(2), 64, window_end=0.5)
    auto = 2 * spectra.spectra[:, [0, 1], [0, 1]].real
    np.testing.assert_allclose(auto, 1.0, atol=0.12)
    np.testing.assert_allclose(auto.mean(axis=0), 1.0, atol=0.015)
    np.testing.assert_allclose(spectra.channel_scale, 1.0, atol=0.01)


def test_poles_frame_follows_the_contract_and_selection_takes_it(hull_block):
    result = lscf(
        hull_block.acceleration,
        hull_block.sampling_rate_hz,
        orders=range(1, 10),
        band_hz=(1.0, 12.0),
    )
    frame = POLES.validate(result.poles_frame(CHANNELS, block=3))
    assert (frame["block"] == 3).all()
    assert len(frame) == len(result.poles)
    selection = select_modes(result, band_hz=(1.0, 12.0))
    found = selection.modes["frequency_hz"].to_numpy()
    for f in hull_block.frequency_hz:
        assert np.abs(found / f - 1).min() < 0.005, (f, found)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"orders": []}, "orders"),
        ({"orders": [0, 1]}, "orders"),
        ({"band_hz": (30.0, 20.0)}, "band_hz"),
        ({"band_hz": (1.0, 150.0)}, "Nyquist"),
        ({"n_lags": 4}, "n_lags"),
        ({"orders": range(1, 40), "band_hz": (20.0, 21.0)}, "spectral lines"),
        ({"window_end": 0.0}, "window_end"),
        ({"reference_channels": [7]}, "reference_channels"),
    ],
)
def test_bad_options_raise(chain3, kwargs, match):
    with pytest.raises(ValueError, match=match) as error:
        lscf(chain3.acceleration[:5000], chain3.sampling_rate_hz, **kwargs)
    assert "\n" not in str(error.value)


def test_nan_channel_is_named(chain3):
    data = chain3.acceleration[:5000].copy()
    data[10, 1] = np.nan
    with pytest.raises(ValueError, match=r"\[1\]"):
        lscf(data, chain3.sampling_rate_hz)


SHEAR_FRAME = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "shear_frame"


@pytest.mark.skipif(not SHEAR_FRAME.is_dir(), reason="../shared/realdata is absent")
def test_koma_shear_frame_frequencies():
    """KOMA's simulated five-storey shear frame (../shared/realdata/shear_frame/README).

    Frequencies scored against the values corrected for the Newmark period elongation
    (README): 0.5 %, as for the analytic chains. Damping is not asserted: LSCF reads the
    upper two modes 45-90 % high here (SSI-cov: within 30 %), see the issue-19 report.
    """
    data = np.load(SHEAR_FRAME / "data_shearframe.npy")
    truth = np.array([0.1811, 0.5256, 0.8209, 1.0443, 1.1824])
    result = lscf(data, 12.0, orders=range(1, 21), n_lags=1024)  # whole 0..6 Hz range
    selection = select_modes(result, band_hz=(0.05, 2.0))
    found = selection.modes["frequency_hz"].to_numpy()
    assert found.size == truth.size, found
    np.testing.assert_allclose(np.sort(found), truth, rtol=0.005)
