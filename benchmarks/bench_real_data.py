"""Validation: ``workbench identify`` on recordings this project did not generate.

Runs the command line exactly as a user would, with only the settings a user gives for the
structure (block length, decimation rate, optionally a band) and everything else at its
defaults, on the recordings in ``../shared/realdata`` (see its README):

* ``lab_frame`` records 1 and 6 -- a laboratory steel frame under fan excitation, 256 Hz,
  4 minutes, 6 channels (velocity and acceleration mixed); 11 reference modes (mean of 14
  records), of which the 10 below 13 Hz are in reach of a decimation to 32 Hz;
* ``shear_frame`` -- KOMA's simulated five-storey shear frame, 12 Hz, 20 minutes; scored
  against the frequencies corrected for the Newmark period elongation
  (f_data = fs/π · atan(π f / fs)) and the model's damping ratios.

For each recording it prints the reference modes found, missed and the spurious modes
(selected modes matching no reference mode), and the frequency and damping errors of the
found modes (relative to the reference). A reference mode is *found* when a selected mode
lies within ``--match`` (default 2 %) of it, one-to-one (Hungarian assignment on the
relative frequency difference); the shear frame's target is 0.5 %, shown in its own
column.

Run: ``python benchmarks/bench_real_data.py`` (needs ``../shared/realdata``; about a
minute on one core). ``--band LOW HIGH`` overrides the band of every recording (to compare
with a version whose default band does not suit these structures).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

ROOT = Path(__file__).resolve().parents[1]
REALDATA = ROOT.parent / "shared" / "realdata"
START = "2024-01-01T00:00:00Z"


@dataclass(frozen=True)
class Recording:
    """One recording and the settings a user would give for its structure."""

    name: str
    source: str  # path below REALDATA
    sampling_rate_hz: float
    block_minutes: float
    rate_hz: float | None
    reference: pd.DataFrame  # frequency_hz, damping_ratio
    target_tol: float  # relative frequency tolerance of the done criterion
    scored_below_hz: float  # reference modes above this are not required


def _lab_reference() -> pd.DataFrame:
    return pd.read_csv(REALDATA / "lab_frame" / "reference_modes.csv")


def _shear_reference() -> pd.DataFrame:
    omega = np.load(REALDATA / "shear_frame" / "omega_n.npy")
    xi = np.load(REALDATA / "shear_frame" / "xi_ref.npy")
    fs = 12.0
    f_model = omega / (2 * np.pi)
    # Newmark average acceleration: period elongation lowers the frequencies in the data
    f_data = fs / np.pi * np.arctan(np.pi * f_model / fs)
    return pd.DataFrame({"frequency_hz": f_data, "damping_ratio": xi})


def recordings() -> list[Recording]:
    lab = _lab_reference()
    shear = _shear_reference()
    return [
        Recording("lab_frame/1", "lab_frame/measurement_1.npy", 256.0, 4.0, 32.0, lab, 0.02, 13.0),
        Recording("lab_frame/6", "lab_frame/measurement_6.npy", 256.0, 4.0, 32.0, lab, 0.02, 13.0),
        Recording(
            "shear_frame", "shear_frame/data_shearframe.npy", 12.0, 20.0, None, shear, 0.005, 6.0
        ),
    ]


def _write_npz(recording: Recording, folder: Path) -> Path:
    """The recording as one canonical acceleration file (samples unchanged)."""
    from data_contracts import AccelerationRecord, write_accelerations

    samples = np.load(REALDATA / recording.source)
    channels = tuple(f"ch{j}" for j in range(samples.shape[1]))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / (Path(recording.source).stem + ".npz")
    record = AccelerationRecord(samples, recording.sampling_rate_hz, pd.Timestamp(START), channels)
    return write_accelerations(record, path)


def _identify(recording: Recording, data: Path, out: Path, band, workbench: list[str]):
    command = [
        *workbench,
        "identify",
        str(data),
        "--out",
        str(out),
        "--scheduler",
        "synchronous",
        "--quiet",
        "--block-minutes",
        f"{recording.block_minutes:g}",
        "--step-minutes",
        f"{recording.block_minutes:g}",
    ]
    if recording.rate_hz is not None:
        command += ["--rate", f"{recording.rate_hz:g}"]
    if band is not None:
        command += ["--band", f"{band[0]:g}", f"{band[1]:g}"]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    selected = out / "selected.parquet"
    blocks = out / "blocks.csv"
    if done.returncode != 0 or not blocks.is_file():
        message = (done.stderr.strip() or done.stdout.strip()).splitlines()
        return None, seconds, f"exit {done.returncode}: {message[-1] if message else ''}"
    status = pd.read_csv(blocks)
    ok = status[status["status"] == "ok"]
    if ok.empty:
        reasons = "; ".join(sorted(set(status["reason"].astype(str))))
        return None, seconds, f"no block identified ({reasons or 'no blocks'})"
    if not selected.is_file():  # blocks identified, no mode selected
        return pd.DataFrame({"block": ok["block"], "frequency_hz": np.nan}), seconds, ""
    return pd.read_parquet(selected), seconds, ""


def score(selected: pd.DataFrame, reference: pd.DataFrame, match_tol: float) -> dict:
    """One-to-one matching of selected modes to reference modes within *match_tol*."""
    f_sel = selected["frequency_hz"].to_numpy()
    f_ref = reference["frequency_hz"].to_numpy()
    distance = np.abs(f_sel[None, :] / f_ref[:, None] - 1.0)
    cost = np.where(distance < match_tol, distance, 1e6)
    rows, cols = linear_sum_assignment(cost) if f_sel.size else (np.array([], int),) * 2
    ok = cost[rows, cols] < 1e6
    rows, cols = rows[ok], cols[ok]
    frequency_error = np.abs(f_sel[cols] / f_ref[rows] - 1.0)
    z_sel = selected["damping_ratio"].to_numpy()[cols]
    z_ref = reference["damping_ratio"].to_numpy()[rows]
    return {
        "found_rows": rows,
        "frequency_error": frequency_error,
        "damping_error": np.abs(z_sel / z_ref - 1.0),
        "spurious": f_sel.size - rows.size,
        "spurious_hz": np.delete(f_sel, cols),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--band", type=float, nargs=2, metavar=("LOW", "HIGH"))
    parser.add_argument("--match", type=float, default=0.02, help="relative tolerance of a match")
    parser.add_argument("--work", type=Path, help="folder for the files (default: a temporary one)")
    parser.add_argument("--details", action="store_true", help="print every selected mode")
    args = parser.parse_args(argv)
    if not REALDATA.is_dir():
        print(f"no validation data at {REALDATA}; nothing to do", file=sys.stderr)
        return 1
    workbench = [sys.executable, "-m", "workbench.cli"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        for recording in recordings():
            key = recording.name.replace("/", "_")
            data = _write_npz(recording, work / key / "data")
            selected, seconds, failure = _identify(
                recording, data, work / key / "out", args.band, workbench
            )
            reference = recording.reference
            required = reference["frequency_hz"].to_numpy() < recording.scored_below_hz
            n_required = int(required.sum())
            if selected is None:
                rows.append(
                    {
                        "recording": recording.name,
                        "blocks": 0,
                        "required": n_required,
                        "found": 0,
                        "missed": n_required,
                        "spurious": 0,
                        "note": failure,
                        "seconds": seconds,
                    }
                )
                continue
            blocks = sorted(selected["block"].unique())
            for block in blocks or [None]:
                part = selected[selected["block"] == block].dropna(subset=["frequency_hz"])
                result = score(part, reference, args.match)
                found_required = np.isin(np.flatnonzero(required), result["found_rows"])
                within_target = int(np.sum(result["frequency_error"] < recording.target_tol))
                if args.details:
                    print(
                        part[
                            ["frequency_hz", "damping_ratio"]
                            + [c for c in part.columns if c.endswith(("_std", "n_poles"))]
                        ].to_string(index=False)
                    )
                rows.append(
                    {
                        "recording": recording.name,
                        "blocks": len(blocks),
                        "required": n_required,
                        "found": int(found_required.sum()),
                        "missed": int(n_required - found_required.sum()),
                        "spurious": result["spurious"],
                        "within target": within_target,
                        "median |df|/f": _median(result["frequency_error"]),
                        "max |df|/f": _max(result["frequency_error"]),
                        "median |dz|/z": _median(result["damping_error"]),
                        "max |dz|/z": _max(result["damping_error"]),
                        "note": ", ".join(f"{f:.3f}" for f in result["spurious_hz"])
                        and "spurious at "
                        + ", ".join(f"{f:.3f} Hz" for f in result["spurious_hz"]),
                        "seconds": seconds,
                    }
                )
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    return 0


def _median(values: np.ndarray) -> float:
    return float(np.median(values)) if values.size else math.nan


def _max(values: np.ndarray) -> float:
    return float(np.max(values)) if values.size else math.nan


if __name__ == "__main__":
    sys.exit(main())
