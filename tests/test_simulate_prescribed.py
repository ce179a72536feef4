"""Records of prescribed modes (workbench.simulate.prescribed)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from workbench.sid.assurance import mac
from workbench.simulate.prescribed import prescribed_mode_record, shapes_with_mac


@pytest.mark.parametrize("mac_value", [0.0, 0.2, 0.5, 0.9, 1.0])
def test_shapes_with_mac_has_the_target_mac(mac_value):
    rng = np.random.default_rng(4)
    base = rng.standard_normal(8)
    shape = shapes_with_mac(base, mac_value, rng)
    assert np.linalg.norm(shape) == pytest.approx(1.0)
    assert float(mac(base, shape)) == pytest.approx(mac_value, abs=1e-12)


def test_shapes_with_mac_rejects_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="mac_value") as error:
        shapes_with_mac(np.ones(4), 1.5, rng)
    assert "[0, 1]" in str(error.value)
    with pytest.raises(ValueError, match="base"):
        shapes_with_mac(np.ones(1), 0.5, rng)


def test_record_levels_and_peaks():
    """Orthonormal shapes: projecting the channels onto a shape gives that mode's modal
    acceleration (plus projected sensor noise); its RMS ratio is the prescribed level,
    and its spectrum peaks at the mode's frequency."""
    shapes = np.linalg.qr(np.random.default_rng(2).standard_normal((6, 2)))[0]
    record = prescribed_mode_record(
        [2.0, 3.0],
        0.01,
        shapes,
        sampling_rate_hz=20.0,
        duration_s=600.0,
        level_db=[0.0, -15.0],
        sensor_noise=0.0,
        seed=3,
    )
    modal = record.acceleration @ shapes
    ratio_db = 20 * np.log10(modal[:, 1].std() / modal[:, 0].std())
    assert ratio_db == pytest.approx(-15.0, abs=1e-9)
    for k, f in enumerate([2.0, 3.0]):
        frequency, density = signal.welch(modal[:, k], fs=20.0, nperseg=2048)
        assert abs(frequency[np.argmax(density)] - f) <= 20.0 / 2048
    with pytest.raises(ValueError, match="mode_shapes"):
        prescribed_mode_record([2.0], 0.01, shapes, sampling_rate_hz=20.0, duration_s=1.0)
