"""Fixtures for the stats and report tests: small block tables with known dependences."""

from __future__ import annotations

import matplotlib
import numpy as np
import pandas as pd
import pytest

matplotlib.use("Agg")

START = pd.Timestamp("2024-03-01T00:00:00Z")


def make_block_tables(n_blocks: int = 80, seed: int = 0, n_modes: int = 3):
    """(modal, predictors): PREDICTORS-like and MODAL-like tables on a 5-minute grid.

    Mode k's frequency follows 2.9 k - 0.012 speed + 0.004 (water - 4) + 0.003 speed *
    (water - 4) (mode 1 only) plus noise; damping 0.012 + 0.0004 speed plus noise; wind
    speed has no effect.
    """
    rng = np.random.default_rng(seed)
    block = np.arange(n_blocks)
    start = START + pd.to_timedelta(block * 5, unit="min")
    speed = 8 + 4 * np.sin(block / 9) + rng.normal(0, 0.4, n_blocks)
    water = 4 + 1.5 * np.cos(block / 13) + rng.normal(0, 0.1, n_blocks)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": water - 3 + rng.normal(0, 0.8, n_blocks),
            "wind_speed_ms": rng.gamma(4, 2, n_blocks),
            "wind_dir_rel_deg": rng.uniform(0, 360, n_blocks),
        }
    )
    rows = []
    for mode in range(1, n_modes + 1):
        frequency = (
            2.9 * mode
            - 0.012 * speed
            + 0.004 * (water - 4)
            + (0.003 * speed * (water - 4) if mode == 1 else 0.0)
            + rng.normal(0, 0.002, n_blocks)
        )
        damping = 0.012 + 0.0004 * speed + rng.normal(0, 0.0008, n_blocks)
        rows.append(
            pd.DataFrame(
                {
                    "block": block,
                    "block_start": start,
                    "block_end": start + pd.Timedelta(minutes=20),
                    "mode": mode,
                    "frequency_hz": frequency,
                    "damping_ratio": damping,
                }
            )
        )
    return pd.concat(rows, ignore_index=True), predictors


@pytest.fixture
def block_tables():
    return make_block_tables()


@pytest.fixture
def close_figures():
    """Close every figure a test opened (and check the code under test closed its own)."""
    import matplotlib.pyplot as plt

    before = set(plt.get_fignums())
    yield before
    for number in set(plt.get_fignums()) - before:
        plt.close(number)
