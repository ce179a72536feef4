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
#: A small SSI (seconds per voyage) for the identify runs of the robustness tests.
SMALL_SSI_ARGS = ["--block-rows", "10", "--min-order", "4", "--max-order", "16"]
#: Block settings for the CLI: 2-minute blocks every minute, small SSI.
IDENTIFY_ARGS = [
    "--block-minutes",
    "2",
    "--step-minutes",
    "1",
    *SMALL_SSI_ARGS,
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


def identify_run(capsys, folder: Path, out: Path, args) -> tuple[int, str, str]:
    """``workbench identify FOLDER --out OUT *args``: its exit code, stdout and stderr (a
    user's error is one line: never a traceback)."""
    from workbench.cli import main

    code = main(["identify", str(folder), "--out", str(out), *args])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.out, captured.err


def selected_modes(out: Path) -> pd.DataFrame:
    """The selected modes (block, frequency, damping) an identify run wrote into *out*."""
    selected = pd.read_parquet(out / "selected.parquet")
    return selected[["block", "frequency_hz", "damping_ratio"]].reset_index(drop=True)


def assert_store_equals_identify(state: Path, out: Path) -> None:
    """The monitor's stored selected modes (state folder *state*) are identify's (*out*)
    to 1e-12: the same blocks, frequencies and damping ratios."""
    from workbench.store import BlockStore

    batch = selected_modes(out)
    stored = BlockStore(state / "store").read("selected")
    monitor = stored.sort_values(["block", "frequency_hz"])[
        ["block", "frequency_hz", "damping_ratio"]
    ].reset_index(drop=True)
    assert monitor["block"].tolist() == batch["block"].tolist()
    np.testing.assert_allclose(monitor["frequency_hz"], batch["frequency_hz"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(monitor["damping_ratio"], batch["damping_ratio"], rtol=0, atol=1e-12)
