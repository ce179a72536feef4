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
found modes (relative to the reference). Repeatability: the recording is also identified
in two windows sharing 95 % of their samples (length 0.95 of the record, step 0.05), and
``overlap`` gives the modes found in both windows (within 0.5 %) over those found in
either. A reference mode is *found* when a selected mode
lies within ``--match`` (default 2 %) of it, one-to-one (Hungarian assignment on the
relative frequency difference); the shear frame's target is 0.5 %, shown in its own
column.

``--methods`` also prints, per recording and block, the found, missed and spurious
reference modes and the errors of SSI-cov, LSCF and their combined modal model
(:func:`workbench.sid.combined.combine_modes`), identified as ``identify --cross-check``
does.

Run: ``python benchmarks/bench_real_data.py`` (needs ``../shared/realdata``; about a
minute on one core). ``--band LOW HIGH`` overrides the band of every recording (to compare
with a version whose default band does not suit these structures).

``--demo-ab N`` also times the identification of N blocks of a simulated demo voyage
in this process (one BLAS thread), block by block alternating the present defaults
(clustering selection, channel check with excitation and coherence tests) with the
former rule (library selection, absolute kurtosis limit, variance z-score alone), and
prints the median time per block of each and their ratio.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_library import pin_library  # noqa: E402

pin_library()  # child processes import this library, not the current folder's

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


def identify_command(
    recording: Recording,
    data: Path,
    out: Path,
    minutes: float,
    step: float,
    workbench: list[str],
    band=None,
) -> list[str]:
    """``workbench identify`` of *recording*'s file in *data* into *out*, as a user would
    run it: block length and step [min], the recording's decimation rate, *band* [Hz]."""
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
        f"{minutes:g}",
        "--step-minutes",
        f"{step:g}",
    ]
    if recording.rate_hz is not None:
        command += ["--rate", f"{recording.rate_hz:g}"]
    if band is not None:
        command += ["--band", f"{band[0]:g}", f"{band[1]:g}"]
    return command


def _identify(
    recording: Recording, data: Path, out: Path, band, workbench: list[str], overlap=False
):
    minutes = recording.block_minutes * (0.95 if overlap else 1.0)
    step = recording.block_minutes * (0.05 if overlap else 1.0)
    command = identify_command(recording, data, out, minutes, step, workbench, band)
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
    parser.add_argument(
        "--methods", action="store_true", help="also SSI, LSCF and combined, block by block"
    )
    parser.add_argument("--demo-ab", type=int, default=0, metavar="N", help="A/B timing")
    parser.add_argument("--demo", type=Path, help="demo voyage folder to reuse (--demo-ab)")
    args = parser.parse_args(argv)
    if args.demo_ab:
        demo_ab(args.demo_ab, args.demo)
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
            windows, _, _ = _identify(
                recording, data, work / key / "overlap", args.band, workbench, overlap=True
            )
            overlap = _overlap(windows)
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
                        "overlap": overlap,
                        "seconds": seconds,
                    }
                )
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        if args.methods:
            print()
            print(methods_table(args.match).to_string(index=False, float_format=_short))
    return 0


def _short(value: float) -> str:
    return f"{value:.3g}"


def methods_table(match_tol: float) -> pd.DataFrame:
    """SSI-cov, LSCF and their combination (:func:`workbench.sid.combined.combine_modes`)
    on every recording, block by block, as ``identify --cross-check`` computes them (the
    same conditioning and options as the command line above, in this process)."""
    from threadpoolctl import threadpool_limits

    from workbench.identification.engine import BlockTask, _identify_data
    from workbench.identification.options import IdentifyOptions
    from workbench.identification.planning import acceleration_files, plan_identification
    from workbench.sid.combined import combine_modes

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for recording in recordings():
            data = _write_npz(recording, Path(tmp) / recording.name.replace("/", "_"))
            options = IdentifyOptions(
                length_s=60.0 * recording.block_minutes,
                step_s=60.0 * recording.block_minutes,
                target_rate_hz=recording.rate_hz or "auto",
                cross_check=True,
            )
            plan, options = plan_identification(acceleration_files([data]), options)
            reference = recording.reference
            required = np.flatnonzero(
                reference["frequency_hz"].to_numpy() < recording.scored_below_hz
            )
            for planned in [b for b in plan.blocks if not b.skipped_reason]:
                task = BlockTask(planned.block, planned.block_start, tuple(map(str, planned.files)))
                with threadpool_limits(limits=1):
                    _, _, ssi, other = _identify_data(task, plan.grid, options, cross=True)
                selections = {"SSI": ssi.modes, "LSCF": other[1].modes}
                pair = {"ssi": ssi, "lscf": other[1]}
                selections["combined"] = combine_modes(pair)
                for variant in ("weighted", "reference"):
                    selections[variant] = combine_modes(pair, estimate=variant)
                for method, modes in selections.items():
                    result = score(modes, reference, match_tol)
                    found = np.isin(required, result["found_rows"])
                    rows.append(
                        {
                            "recording": recording.name,
                            "block": planned.block,
                            "method": method,
                            "found": int(found.sum()),
                            "missed": int(required.size - found.sum()),
                            "spurious": result["spurious"],
                            "median |df|/f": _median(result["frequency_error"]),
                            "max |df|/f": _max(result["frequency_error"]),
                            "median |dz|/z": _median(result["damping_error"]),
                        }
                    )
    return pd.DataFrame(rows)


def _overlap(selected: pd.DataFrame | None) -> str:
    """Modes of the first two windows that agree within 0.5 %, over the modes of either."""
    if selected is None or selected["block"].nunique() < 2:
        return "n/a"
    first, second = (
        selected.loc[selected["block"] == b, "frequency_hz"].dropna().to_numpy()
        for b in sorted(selected["block"].unique())[:2]
    )
    if not first.size or not second.size:
        return f"0 of {max(first.size, second.size)}"
    distance = np.abs(first[:, None] / second[None, :] - 1.0)
    rows, cols = linear_sum_assignment(np.where(distance < 0.005, distance, 1e6))
    both = int(np.sum(distance[rows, cols] < 0.005))
    return f"{both} of {first.size + second.size - both}"


def demo_ab(n_blocks: int, folder: Path | None) -> None:
    """Median identify time per demo block: present defaults vs the former rules."""
    import dataclasses

    from threadpoolctl import threadpool_limits

    from workbench.demo import DEMO_IDENTIFY_OPTIONS
    from workbench.identification.engine import BlockTask, _identify_data
    from workbench.identification.planning import acceleration_files, plan_identification

    with tempfile.TemporaryDirectory() as tmp:
        if folder is None or not (folder / "voyage.json").is_file():
            from workbench.simulate import simulate_voyage

            folder = folder or Path(tmp) / "voyage"
            print(f"simulating a demo voyage into {folder} (not timed) ...", flush=True)
            simulate_voyage(folder, seed=0, hours=max(2.0, n_blocks / 12 + 0.5))
        new = DEMO_IDENTIFY_OPTIONS
        old = dataclasses.replace(
            new,
            selection="library",
            fault_options=(("max_kurtosis_z", -math.inf), ("coherence_check", False)),
        )
        plan, new = plan_identification(acceleration_files([folder]), new)
        _, old = plan_identification(acceleration_files([folder]), old)
        blocks = [b for b in plan.blocks if not b.skipped_reason][:n_blocks]
        times: dict[str, list[float]] = {"former": [], "present": []}
        modes: dict[str, int] = {"former": 0, "present": 0}
        with threadpool_limits(limits=1):
            for k, planned in enumerate(blocks):
                task = BlockTask(planned.block, planned.block_start, tuple(map(str, planned.files)))
                pair = [("former", old), ("present", new)]
                for name, options in pair if k % 2 else pair[::-1]:
                    started = time.perf_counter()
                    _, _, selection = _identify_data(task, plan.grid, options)
                    times[name].append(time.perf_counter() - started)
                    modes[name] += len(selection.modes)
    former, present = np.median(times["former"]), np.median(times["present"])
    print(
        f"demo identify time per block over {len(blocks)} blocks (median): former "
        f"{former:.3f} s, present {present:.3f} s, ratio {present / former:.3f}; "
        f"modes selected {modes['former']} vs {modes['present']}"
    )


def _median(values: np.ndarray) -> float:
    return float(np.median(values)) if values.size else math.nan


def _max(values: np.ndarray) -> float:
    return float(np.max(values)) if values.size else math.nan


if __name__ == "__main__":
    sys.exit(main())
