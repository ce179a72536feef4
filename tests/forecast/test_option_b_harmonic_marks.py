"""Option B and the poles marked as shaft or blade-pass harmonics (``harmonic`` column).

Where an order sits on a hull mode, SSI finds one pole for both: identify marks that
selected mode and its column of poles, tracking keeps the row as the mode's (its shape
joins the label) and option A measures it. Option B measures the same column there; a
marked column away from every tracked pole of its block is the harmonic's and is never
measured.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from workbench.forecasting import ForecastOptions
from workbench.forecasting.measurement import CLUSTER_HALF_WIDTH, measurable_poles
from workbench.stages import forecast

ORDERS = np.arange(20, 61, 2)
#: Blocks where order 1 sits on the mode: the mode's own column is marked.
SITTING = range(60, 80)
#: Blocks where the mode is not excited and only a marked harmonic's column is in the gate.
HARMONIC_ONLY = range(90, 100)


def test_measurable_poles_keeps_marked_poles_only_in_a_tracked_poles_column():
    poles = pd.DataFrame(
        {
            "block": [0, 0, 0, 0, 1, 1],
            "frequency_hz": [5.0, 5.009, 5.011, 5.3, 5.0, 5.0],
            "harmonic": [1.0, 1.0, 1.0, np.nan, 2.0, np.nan],
        }
    )
    modal = pd.DataFrame({"block": [0, 0], "mode": [1, 2], "frequency_hz": [5.0, 5.3]})
    kept = measurable_poles(poles, modal)
    # block 0: the marked poles within 0.2 % (0.010 Hz) of the tracked 5.0 Hz and the
    # unmarked pole; block 1 has no tracked pole: only its unmarked pole
    assert CLUSTER_HALF_WIDTH == 2e-3
    assert kept["frequency_hz"].tolist() == [5.0, 5.009, 5.3, 5.0]
    assert kept["harmonic"].isna().tolist() == [False, False, True, True]
    assert kept.index.tolist() == [0, 1, 2, 3]
    # without marks the table is what it was
    unmarked = poles.drop(columns="harmonic")
    assert measurable_poles(unmarked, modal) is unmarked


def _voyage(seed=0, n=140):
    """One mode near 5 Hz following the speed; blocks SITTING: the order on the mode (its
    column marked, the tracked row there); blocks HARMONIC_ONLY: the mode not excited (no
    tracked row), a marked harmonic column 0.01 Hz above the prediction."""
    rng = np.random.default_rng(seed)
    block = np.arange(n)
    start = pd.Timestamp("2025-01-01T00:00:00Z") + pd.to_timedelta(block * 300, unit="s")
    speed = 8.0 + rng.normal(0, 1.0, n)
    truth = 5.0 - 0.02 * (speed - 8.0)
    seen = truth + 0.002 * rng.standard_normal(n)
    predictors = pd.DataFrame(
        {"block": block, "block_start": start, "block_end": start + pd.Timedelta(minutes=20)}
    )
    predictors["speed_kn"] = speed
    tracked = np.isin(block, HARMONIC_ONLY, invert=True)
    modal = pd.DataFrame(
        {
            "block": block[tracked],
            "block_start": start[tracked],
            "mode": 1,
            "frequency_hz": seen[tracked],
            "damping_ratio": 0.01,
        }
    )
    rows = []
    for b in block:
        if b in HARMONIC_ONLY:
            centre, mark = truth[b] + 0.01, 1.0
        else:
            centre, mark = seen[b], (1.0 if b in SITTING else np.nan)
        rows += [(b, o, centre + 5e-4 * rng.standard_normal(), 0.01, True, mark) for o in ORDERS]
    poles = pd.DataFrame(
        rows,
        columns=["block", "model_order", "frequency_hz", "damping_ratio", "stable", "harmonic"],
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = forecast(
            modal,
            predictors,
            poles=poles,
            options=ForecastOptions(options=("A", "B"), scheme="rolling", model="memory"),
        )
    return result.table, seen, truth


def test_option_b_measures_the_modes_marked_column_and_never_a_harmonics():
    table, seen, truth = _voyage()
    b = table[table["option"] == "B"].set_index("block")
    a = table[table["option"] == "A"].set_index("block")
    sitting = list(SITTING)
    # where the order sits on the mode, B measures the mode's column as A measures its
    # tracked pole (main left the whole column out: NaN in all 20 blocks)
    measured = b.loc[sitting, "ssi_frequency_hz"].to_numpy()
    assert np.isfinite(measured).all()
    assert np.max(np.abs(measured - seen[sitting])) < 1e-3
    # and its blend is no worse than the raw SSI there (0.0095 against 0.0346 Hz summed)
    kalman_b = np.abs(b.loc[sitting, "kalman_frequency_hz"].to_numpy() - truth[sitting]).sum()
    raw = np.abs(seen[sitting] - truth[sitting]).sum()
    assert kalman_b < 0.5 * raw
    # option A measures its tracked pole there too (its scale from the unmarked poles)
    assert np.allclose(a.loc[sitting, "ssi_frequency_hz"], seen[sitting])
    # a marked column with no tracked pole in its block is the harmonic's: never measured
    assert b.loc[list(HARMONIC_ONLY), "ssi_frequency_hz"].isna().all()
