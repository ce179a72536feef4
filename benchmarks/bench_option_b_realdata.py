"""Validation of option B's pole choice on recordings this project did not generate.

Option B measures, in each block, the stabilisation-diagram column nearest the Kalman
prediction (:class:`workbench.forecasting.measurement.ClusterChooser`). This benchmark checks
that choice on the real and third-party recordings in ``../shared/realdata`` (see its
README), whose modes do not move: a prediction that is off by a known amount must still
lead to the mode's own column.

For each recording: ``workbench identify`` in overlapping blocks (as a user would, block
length and decimation rate only), ``track`` of the selected modes (the tracked table gives
the modes' reference shapes), then for every reference mode in reach, every block and
every prediction offset ``d`` (the prior is the reference frequency x (1 + d), the gate
``max_gate`` = 2 % of it, as the memory forecast caps it), the chooser's measurement.
Printed per recording and offset, with and without mode shapes: the share of
(mode, block) pairs measured, of those the share within the recording's tolerance of the
reference frequency (shear frame 0.5 %, its identification target; lab frame 2 %) and the
median relative error, beside the same for option A (the tracked pole of the track whose
median frequency is nearest the reference).

Run: ``python benchmarks/bench_option_b_realdata.py`` (needs ``../shared/realdata``; a few
minutes on one core).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_real_data import REALDATA, _write_npz, identify_command, recordings  # noqa: E402
from child_library import pin_library  # noqa: E402

from workbench.forecasting.measurement import PoleIndex  # noqa: E402
from workbench.forecasting.memory.poles import option_b_chooser  # noqa: E402
from workbench.forecasting.options import ForecastOptions  # noqa: E402

pin_library()  # child processes import this library, not the current folder's

#: Relative offsets of the prediction from the reference frequency. [-]
OFFSETS = (0.0, 0.01, -0.01)
#: Blocks per record: block length = record / 4, step = block / 4 (75 % overlap). [-]
BLOCK_FRACTION = 0.25


def _identify(recording, data: Path, out: Path) -> bool:
    record_minutes = recording.block_minutes  # bench_real_data: one block = the record
    minutes = record_minutes * BLOCK_FRACTION
    workbench = [sys.executable, "-m", "workbench.cli"]
    command = identify_command(recording, data, out, minutes, minutes / 4, workbench)
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"{recording.name}: identify failed: {done.stderr.strip()[-300:]}", file=sys.stderr)
        return False
    return (out / "poles.parquet").is_file() and (out / "selected.parquet").is_file()


def _drop_shapes(frame: pd.DataFrame) -> pd.DataFrame:
    return frame[[c for c in frame.columns if not str(c).startswith("shape_")]]


def evaluate(recording, poles: pd.DataFrame, tracked: pd.DataFrame) -> list[dict]:
    reference = recording.reference
    f_ref = reference["frequency_hz"].to_numpy()
    z_ref = reference["damping_ratio"].to_numpy()
    keep = f_ref < recording.scored_below_hz
    blocks = np.sort(poles["block"].unique())
    # each reference mode's tracked label: the track whose median frequency is nearest
    medians = tracked.groupby("mode")["frequency_hz"].median()
    labels = np.array(
        [int(medians.index[np.argmin(np.abs(medians.to_numpy() / f - 1))]) for f in f_ref]
    )
    rows = []
    for shapes in (True, False):
        pol = poles if shapes else _drop_shapes(poles)
        mod = tracked if shapes else _drop_shapes(tracked)
        index = PoleIndex(pol, blocks)
        for offset in OFFSETS:
            chooser = option_b_chooser(
                pol, mod, blocks, labels, index, ForecastOptions(options=("B",)), Counter()
            )
            errors, a_errors = [], []
            n = 0
            for j in np.flatnonzero(keep):
                track = tracked[tracked["mode"] == labels[j]].set_index("block")["frequency_hz"]
                for i, block in enumerate(blocks):
                    n += 1
                    prior = f_ref[j] * (1 + offset)
                    gate = 0.02 * prior
                    choice = chooser.choose(i, j, prior, gate, z_ref[j])
                    if choice is not None:
                        errors.append(abs(choice.cluster.frequency_hz / f_ref[j] - 1))
                    if block in track.index:
                        a_errors.append(abs(float(track.loc[block]) / f_ref[j] - 1))
            errors, a_errors = np.array(errors), np.array(a_errors)
            tol = recording.target_tol
            rows.append(
                {
                    "recording": recording.name,
                    "shapes": shapes,
                    "offset_%": 100 * offset,
                    "pairs": n,
                    "B_measured": errors.size / n,
                    "B_within_tol": float(np.mean(errors <= tol)) if errors.size else np.nan,
                    "B_err_med_%": 100 * float(np.median(errors)) if errors.size else np.nan,
                    "A_measured": a_errors.size / n,
                    "A_within_tol": float(np.mean(a_errors <= tol)) if a_errors.size else np.nan,
                    "A_err_med_%": 100 * float(np.median(a_errors)) if a_errors.size else np.nan,
                }
            )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, help="folder for the files (default: a temporary one)")
    args = parser.parse_args(argv)
    if not REALDATA.is_dir():
        print(f"no validation data at {REALDATA}; nothing to do", file=sys.stderr)
        return 1
    from workbench.stages import track

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        for recording in recordings():
            key = recording.name.replace("/", "_")
            data = _write_npz(recording, work / key / "data")
            out = work / key / "blocks"
            if not (out / "poles.parquet").is_file() and not _identify(recording, data, out):
                continue
            poles = pd.read_parquet(out / "poles.parquet")
            tracked = track(out / "selected.parquet").table
            rows += evaluate(recording, poles, tracked)
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
