"""Tiny acceleration voyages for the robustness tests (seconds to identify).

Four channels at 32 Hz, 60-s files, two lightly damped modes (3.1 Hz and 5.7 Hz) under
white-noise excitation plus measurement noise: enough for SSI to run on 2-minute blocks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from data_contracts import AccelerationRecord, write_accelerations

RATE_HZ = 32.0
FILE_S = 60.0
CHANNELS = ("acc01", "acc02", "acc03", "acc04")
T0 = pd.Timestamp("2026-03-01T00:00:00Z")
#: Block settings for the CLI: 2-minute blocks every minute, small SSI.
IDENTIFY_ARGS = [
    "--block-minutes",
    "2",
    "--step-minutes",
    "1",
    "--block-rows",
    "10",
    "--min-order",
    "4",
    "--max-order",
    "16",
    "--scheduler",
    "synchronous",
    "--quiet",
]


def response(n_samples: int, seed: int, rate_hz: float = RATE_HZ) -> np.ndarray:
    """Accelerations of two modes (3.1 and 5.7 Hz, 2 % damping) seen by four sensors,
    sampled at *rate_hz*."""
    rng = np.random.default_rng(seed)
    shapes = np.array([[1.0, 0.6, -0.4, -1.0], [0.7, -1.0, 1.0, -0.5]])
    out = np.zeros((n_samples, len(CHANNELS)))
    for f_hz, shape in zip((3.1, 5.7), shapes, strict=True):
        w = 2 * np.pi * f_hz
        system = signal.cont2discrete(([w**2], [1, 2 * 0.02 * w, w**2]), 1 / rate_hz)
        b, a = np.squeeze(system[0]), system[1]
        modal = signal.lfilter(b, a, rng.standard_normal(n_samples))
        out += np.outer(modal, shape)
    return out + 0.05 * rng.standard_normal(out.shape)


def write_voyage(
    folder: Path,
    *,
    n_files: int = 4,
    seed: int = 0,
    t0: pd.Timestamp = T0,
    short_s: float = 0.0,
) -> list[Path]:
    """*n_files* consecutive 60-s files in *folder*; each *short_s* shorter than 60 s (a gap
    of *short_s* before the next file)."""
    folder.mkdir(parents=True, exist_ok=True)
    n = int(FILE_S * RATE_HZ)
    data = response(n * n_files, seed)
    paths = []
    for k in range(n_files):
        keep = n - int(round(short_s * RATE_HZ))
        record = AccelerationRecord(
            data[k * n : k * n + keep], RATE_HZ, t0 + pd.Timedelta(seconds=k * FILE_S), CHANNELS
        )
        paths.append(write_accelerations(record, folder / f"acc_{k:03d}.npz"))
    return paths
