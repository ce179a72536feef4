"""Tests for workbench.reporting.stabilisation_plot: spectra and the written figure."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from workbench.reporting.stabilisation_plot import (  # noqa: E402
    cross_spectral_density,
    mode_indicator,
    plot_stabilisation,
    write_stabilisation_figure,
)
from workbench.sid.selection import select_modes  # noqa: E402
from workbench.sid.ssi import ssi_cov  # noqa: E402


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def test_white_noise_density_and_hermitian_csd():
    """One-sided PSD of white noise with variance σ² sampled at f_s is 2σ²/f_s."""
    rng = np.random.default_rng(0)
    data = rng.standard_normal((200_000, 2)) * [1.0, 3.0]
    frequency, csd = cross_spectral_density(data, 100.0, segment_length=256)
    assert frequency[0] == 0 and frequency[-1] == 50.0
    np.testing.assert_allclose(csd, np.conj(np.transpose(csd, (0, 2, 1))), atol=1e-15)
    inner = slice(1, -1)
    np.testing.assert_allclose(csd[inner, 0, 0].real.mean(), 2 * 1.0 / 100.0, rtol=0.02)
    np.testing.assert_allclose(csd[inner, 1, 1].real.mean(), 2 * 9.0 / 100.0, rtol=0.02)
    # independent channels: cross density near zero
    assert np.abs(csd[inner, 0, 1]).mean() < 0.05 * csd[inner, 1, 1].real.mean()
    _, values = mode_indicator(data, 100.0, n_values=2, segment_length=256)
    assert np.all(values[:, 0] >= values[:, 1])


def test_cmif_peaks_at_the_hull_modes(hull_block):
    """Each mode is a local maximum of the first or (T1, hidden under VB2) second CMIF curve."""
    frequency, values = mode_indicator(
        hull_block.acceleration, hull_block.sampling_rate_hz, n_values=2
    )
    for true_frequency in hull_block.frequency_hz:
        centre = int(np.argmin(np.abs(frequency - true_frequency)))
        peaked = False
        for curve in values.T:
            local = curve[centre - 2 : centre + 3].max()
            shoulders = max(curve[centre - 5], curve[centre + 5])
            peaked |= local > 1.5 * shoulders
        assert peaked, true_frequency


def test_figure_shows_every_pole_and_is_written(hull_block, tmp_path):
    result = ssi_cov(hull_block.acceleration, hull_block.sampling_rate_hz, orders=range(2, 41, 2))
    selection = select_modes(result)
    fig = plot_stabilisation(result, hull_block.acceleration, selection=selection, band_hz=(0, 12))
    ax = fig.axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    stable = result.poles["stable"].to_numpy()
    assert len(lines["unstable pole"].get_xdata()) == int((~stable).sum())
    stable_line = next(line for label, line in lines.items() if label.startswith("stable"))
    np.testing.assert_allclose(stable_line.get_xdata(), result.poles["frequency_hz"][stable])
    assert ax.get_xlim() == (0, 12)
    assert len(fig.axes) == 2  # the spectrum on a twin axis
    path = write_stabilisation_figure(
        result, tmp_path / "fig" / "stab.png", hull_block.acceleration, background="psd"
    )
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="background"):
        plot_stabilisation(result, background="fft")
