"""Option B's reference shape: the consensus of a mode's recent tracked shapes.

Synthetic shapes on 19 channels (the demo hull's sensor count): a unit shape plus complex
Gaussian noise of relative size σ (E‖noise‖² = σ²). For σ = 0.24 (the ice regime of
benchmarks/forecast_regimes.py) the MAC of a pole with the true shape is about
1 / (1 + σ²) = 0.945, with another noisy shape about 1 / (1 + σ²)² = 0.894: half of the
mode's own poles fail a 0.9 check against a single tracked shape. Against the consensus of
12 shapes (noise σ²/12) the MAC is about 1 / ((1 + σ²)(1 + σ²/12)) = 0.941.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from data_contracts import shapes_to_frame
from workbench.forecasting.pole_selection import _mac_on_common_channels
from workbench.forecasting.shape_reference import consensus_references

CHANNELS = [f"ch{c:02d}" for c in range(19)]


def _unit(s):
    return s / np.linalg.norm(s)


def _noisy(rng, shape, sigma, n):
    noise = rng.standard_normal((n, shape.size)) + 1j * rng.standard_normal((n, shape.size))
    # a random complex factor per shape: a shape is defined up to scale and phase
    factor = rng.uniform(0.5, 2.0, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    return factor[:, None] * (shape[None, :] + sigma * noise / np.sqrt(2 * shape.size))


def _modal(shapes, mode=1):
    n = shapes.shape[0]
    frame = pd.DataFrame({"block": np.arange(n), "mode": mode, "frequency_hz": 5.0})
    return pd.concat([frame, shapes_to_frame(CHANNELS, shapes)], axis=1)


def test_consensus_reference_passes_the_modes_noisy_poles_a_single_shape_does_not():
    rng = np.random.default_rng(0)
    true = _unit(rng.standard_normal(19) + 0.3j * rng.standard_normal(19))
    sigma, n = 0.24, 200
    tracked = _noisy(rng, true, sigma, n)
    references, row = consensus_references(
        _modal(tracked), np.arange(n), np.array([1]), CHANNELS, mac_min=0.9
    )
    poles = _noisy(rng, true, sigma, 400)
    # after the first 12 blocks the consensus holds 12 shapes
    late = references[row[20:, 0]]
    mac_consensus = np.concatenate(
        [_mac_on_common_channels(r, poles[k::180]) for k, r in enumerate(late)]
    )
    mac_single = np.concatenate(
        [_mac_on_common_channels(t, poles[k::180]) for k, t in enumerate(tracked[20:])]
    )
    # expected medians 0.941 and 0.894 (module docstring); the MAC's spread over the
    # 2 x 18 real noise dimensions is about +-0.015
    assert abs(np.median(mac_consensus) - 0.941) < 0.01
    assert abs(np.median(mac_single) - 0.894) < 0.01
    assert (mac_consensus >= 0.9).mean() > 0.95
    assert (mac_single >= 0.9).mean() < 0.6
    # the consensus is close to the true shape: MAC ~ 1 / (1 + σ²/12) = 0.995
    assert np.median(_mac_on_common_channels(true, late)) > 0.99


def test_a_mislabelled_tracked_shape_stays_out_and_a_changed_shape_restarts():
    rng = np.random.default_rng(1)
    first = _unit(rng.standard_normal(19) + 0j)
    second = _unit(rng.standard_normal(19) + 0j)
    assert _mac_on_common_channels(first, second[None, :])[0] < 0.3
    tracked = _noisy(rng, first, 0.05, 60)
    tracked[30] = _noisy(rng, second, 0.05, 1)[0]  # one wrong pole in the tracked table
    tracked[45:] = _noisy(rng, second, 0.05, 15)  # from block 45 the mode's shape changes
    references, row = consensus_references(
        _modal(tracked), np.arange(60), np.array([1]), CHANNELS, mac_min=0.9
    )
    mac_first = _mac_on_common_channels(first, references[row[:, 0]])
    mac_second = _mac_on_common_channels(second, references[row[:, 0]])
    assert (mac_first[:45] > 0.99).all()  # block 30 did not enter the consensus
    assert mac_first[45] > 0.99  # one unlike shape: not yet a change
    assert (mac_second[46:] > 0.99).all()  # two agreeing ones: restarted from them


def test_no_reference_before_the_first_tracked_shape_and_dead_channels():
    rng = np.random.default_rng(2)
    true = _unit(rng.standard_normal(19) + 0j)
    tracked = _noisy(rng, true, 0.05, 10)
    tracked[4:7, 3] = np.nan  # a dead channel for three blocks
    modal = _modal(tracked)
    modal["block"] += 5
    references, row = consensus_references(
        modal, np.arange(15), np.array([1, 2]), CHANNELS, mac_min=0.9
    )
    assert (row[:5, 0] == -1).all() and (row[5:, 0] >= 0).all()
    assert (row[:, 1] == -1).all()  # mode 2 has no tracked rows
    assert np.isfinite(references).all()  # the other blocks fill the dead channel
    assert (_mac_on_common_channels(true, references) > 0.99).all()
