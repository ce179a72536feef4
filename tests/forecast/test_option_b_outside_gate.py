"""Option B (memory model) when the mode's column is seen only outside the gate.

The column is a measurement there, flagged ``outside_gate`` and never a reset of the prior:
whether it is an outlier stretch (the blocks sharing a corrupted stretch of data) or a mode
that moved is decided by the Kalman update (Huber weight, persistence of large innovations
of one sign beyond the blocks sharing data), not by counting blocks in the chooser.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from workbench.forecasting import ForecastOptions, sliding_forecast
from workbench.forecasting.measurement import ClusterChooser, PoleIndex

ORDERS = np.arange(20, 61, 2)


def _diagrams(centres_hz, damping=0.01, seed=0):
    """One 21-order column per block at *centres_hz* (NaN: the mode is not excited)."""
    rng = np.random.default_rng(seed)
    rows = [
        (b, n, f + 5e-4 * rng.standard_normal(), damping)
        for b, f in enumerate(centres_hz)
        if np.isfinite(f)
        for n in ORDERS
    ]
    poles = pd.DataFrame(rows, columns=["block", "model_order", "frequency_hz", "damping_ratio"])
    poles["stable"] = True
    return PoleIndex(poles, np.arange(len(centres_hz)))


def _chooser(index, reacquire_blocks):
    return ClusterChooser(
        index,
        None,
        shape_mac_min=0.9,
        reacquire_blocks=reacquire_blocks,
        reacquire_band=0.05,
    )


def test_column_outside_the_gate_is_measured_after_k_blocks_and_while_it_stays_there():
    # blocks 0-4 at 5.00 Hz, 5-8 at 5.10 Hz (outside a ±0.03 Hz gate about 5.00 Hz, inside
    # the ±5 % band), block 9 not excited, block 10 at 5.10 Hz, block 11 back at 5.00 Hz
    centres = [5.0] * 5 + [5.1] * 4 + [np.nan, 5.1, 5.0]
    chooser = _chooser(_diagrams(centres), reacquire_blocks=2)
    got = [chooser.choose(b, 0, prior_hz=5.0, gate_hz=0.03, damping_ref=0.01) for b in range(12)]
    assert all(c is not None and not c.outside_gate for c in got[:5])
    assert got[5] is None  # first block outside: predict-only (k = 2)
    for c in got[6:9] + [got[10]]:  # measured, not a reset of the prior
        assert c is not None and c.outside_gate
        assert abs(c.cluster.frequency_hz - 5.1) < 1e-3 and c.cluster.n_orders == 21
    assert got[9] is None  # no column at all: no evidence either way, the count stays
    assert got[11] is not None and not got[11].outside_gate
    # k = 1: at once
    chooser = _chooser(_diagrams(centres), reacquire_blocks=1)
    got = [chooser.choose(b, 0, prior_hz=5.0, gate_hz=0.03, damping_ref=0.01) for b in range(6)]
    assert got[5] is not None and got[5].outside_gate


def test_a_column_outside_the_gate_needs_the_modes_damping():
    # a lightly damped harmonic (0.2 % against the mode's 1 %: more than x3 off) outside
    # the gate is not the mode
    chooser = _chooser(_diagrams([5.1] * 3, damping=0.002), reacquire_blocks=1)
    for b in range(3):
        assert chooser.choose(b, 0, prior_hz=5.0, gate_hz=0.03, damping_ref=0.01) is None


def test_a_harmonic_in_the_gate_is_not_the_mode_when_the_modes_column_is_outside_it():
    # wander_40min_2x hold-out seed 8, option B without shapes, block 44: a refit moved
    # the prediction to 4.47 Hz, so the gate (±0.09 Hz) held the blade-rate harmonic
    # sweeping down through 4.52 Hz (21 orders, damping 0.2 %) and not the mode's own
    # column near 4.59 Hz (damping 0.8 %; here as it was at block 43, 22 orders). Taking
    # the harmonic (as the chooser did before its damping test applied inside the gate)
    # pulled the filter 0.9 Hz below the mode over 30 blocks; the mode's column, 0.12 Hz
    # off the prediction (within the ±5 % band), is the measurement, flagged outside the
    # gate (benchmarks/results/forecast_holdout_53.txt).
    rng = np.random.default_rng(1)
    rows = [(0, n, 4.5162 + 2e-4 * rng.standard_normal(), 0.002) for n in ORDERS]
    rows += [(0, n, 4.5885 + 5e-4 * rng.standard_normal(), 0.008) for n in ORDERS]
    poles = pd.DataFrame(rows, columns=["block", "model_order", "frequency_hz", "damping_ratio"])
    poles["stable"] = True
    chooser = _chooser(PoleIndex(poles, np.arange(1)), reacquire_blocks=1)
    got = chooser.choose(0, 0, prior_hz=4.4728, gate_hz=0.0895, damping_ref=0.0092)
    assert got is not None and got.outside_gate
    assert abs(got.cluster.frequency_hz - 4.5885) < 1e-3
    assert got.cluster.n_orders == ORDERS.size


def _voyage(seed=0, n=200, outlier=range(100, 104), step_block=150, step_hz=0.08):
    """One mode near 5 Hz; its column leaves the gate in two ways: an outlier stretch of
    four blocks (one corrupted stretch of data shared by four 75 %-overlapping blocks)
    0.10 Hz high, and from *step_block* a permanent move of *step_hz* the predictors do
    not explain (a loading change)."""
    rng = np.random.default_rng(seed)
    block = np.arange(n)
    start = pd.Timestamp("2025-01-01T00:00:00Z") + pd.to_timedelta(block * 300, unit="s")
    speed = 8.0 + rng.normal(0, 1.0, n)
    truth = 5.0 - 0.002 * (speed - 8.0) + np.where(block >= step_block, step_hz, 0.0)
    seen = truth + 0.002 * rng.standard_normal(n)
    seen[list(outlier)] += 0.10
    predictors = pd.DataFrame(
        {"block": block, "block_start": start, "block_end": start + pd.Timedelta(minutes=20)}
    )
    predictors["speed_kn"] = speed
    modal = pd.DataFrame({"block": block, "mode": 1, "frequency_hz": seen, "damping_ratio": 0.01})
    modal.insert(1, "block_start", start)
    rows = [
        (b, o, seen[b] + 5e-4 * rng.standard_normal(), 0.01, True) for b in block for o in ORDERS
    ]
    poles = pd.DataFrame(
        rows, columns=["block", "model_order", "frequency_hz", "damping_ratio", "stable"]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = sliding_forecast(
            modal,
            predictors,
            ForecastOptions(options=("B",), scheme="rolling", model="memory"),
            poles=poles,
        ).table
    return table.set_index("block"), truth


def test_an_outlier_stretch_pulls_little_and_a_mode_that_moved_is_followed():
    table, truth = _voyage()
    kalman = table["kalman_frequency_hz"].to_numpy()
    measured = table["ssi_frequency_hz"].to_numpy()
    # the outlier column is measured (outside the gate), but its pull is bounded: the
    # estimate stays within a tenth of the 0.10 Hz outliers of the truth
    assert np.isfinite(measured[100:104]).all()
    # and the table says so, row by row (only where the column was outside the gate)
    flagged = table["warning"].fillna("").str.contains("measured outside the gate")
    assert flagged.loc[100:103].all()
    assert not flagged.loc[60:99].any()
    assert np.max(np.abs(kalman[100:104] - truth[100:104])) < 0.01
    # the move is taken once its run of large innovations outlasts the blocks sharing
    # data (persistence 5 blocks: block 154), and followed for good from about 15 blocks
    # after it (in between the filter lets part of the move sag into its identification
    # error state for a few blocks)
    assert abs(kalman[154] - truth[154]) < 0.01
    assert np.max(np.abs(kalman[154:] - truth[154:])) < 0.04
    assert np.max(np.abs(kalman[165:] - truth[165:])) < 0.01
