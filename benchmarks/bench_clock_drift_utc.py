"""How far a drifting record's blocks lie from the UTC their labels say, and what that does
to the ship-log means averaged over the labelled spans.

A contiguous record of 5-min files at 2048 Hz whose sample clock runs *ppm* fast (file k
stamped k * 300 s / (1 + ppm) after the first, from headers alone, as
``bench_clock_drift.py``) is planned on 20-min blocks every 5 min. For each block the
offset is its labelled ``block_start`` less the UTC at which its first sample was recorded
(sample s of the record at s / (2048 Hz x (1 + ppm)) after the first stamp): positive when
the block is labelled after its samples were recorded (a fast clock). Printed per record
length (6 h to ``--days``) and ppm: the offsets of the first and last block and the
largest.

Then the effect on the predictors: a 12-h operating profile (speed 0 -> 10 kn, a 0-10 kn
alternation, a temperature drift; :func:`workbench.simulate.profile.operating_profile`)
averaged over each labelled block span and over the span its samples were recorded in
(the labelled span less the offset of a record's last block, taken as constant over the
12 h: what the blocks of that day see). Printed: the largest and median difference of the
block means of speed, water and air temperature.

Run against two trees with PYTHONPATH to compare them:
``python benchmarks/bench_clock_drift_utc.py --days 51`` (about 30 s).
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.blocks import BlockGrid
from workbench.predictors import block_predictors
from workbench.signals.block_plan import FileInfo, plan_file_infos
from workbench.simulate.profile import operating_profile

RATE_HZ = 2048.0
T0 = pd.Timestamp("2026-03-01T00:00:00Z")
FILE_S = 300.0
PPMS = (-100, -20, 20, 100)


def _headers(n_files: int, ppm: float, jitter_ms: float, seed: int) -> list[FileInfo]:
    rng = np.random.default_rng(seed)
    stamps = np.arange(n_files) * FILE_S / (1 + ppm * 1e-6)
    stamps += rng.uniform(-jitter_ms, jitter_ms, n_files) / 1e3
    n = int(FILE_S * RATE_HZ)
    return [
        FileInfo(Path(f"acc_{k:05d}.npz"), T0 + pd.Timedelta(seconds=float(s)), RATE_HZ, n, ("a",))
        for k, s in enumerate(stamps)
    ]


def block_offsets_s(n_files: int, ppm: float, jitter_ms: float = 0.0, seed: int = 0) -> np.ndarray:
    """Labelled start less the UTC of the first sample, of every planned block. [s]"""
    plan = plan_file_infos(_headers(n_files, ppm, jitter_ms, seed), BlockGrid(T0, 1200.0, 300.0))
    first = plan.files[0].start_time
    out = []
    for block in plan.blocks:
        if block.skipped_reason:
            continue
        # where the block's samples begin on the record's sample count (the plan's placed
        # times): its start, or, where a plan cuts blocks elsewhere, that start
        start = getattr(block, "sample_start", block.block_start)
        count = (start - first).total_seconds() * RATE_HZ
        # a sample's time (to the ns) is that sample; else the first sample at or after it
        sample = round(count) if abs(count - round(count)) < 1e-3 else int(np.ceil(count - 1e-6))
        recorded = T0 + pd.Timedelta(seconds=sample / (RATE_HZ * (1 + ppm * 1e-6)))
        out.append((block.block_start - recorded).total_seconds())
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=51.0)
    parser.add_argument("--jitter", type=float, default=10.0, metavar="MS")
    args = parser.parse_args()
    lengths = [(0.25, "6 h"), (1.0, "1 day"), (7.0, "7 days"), (args.days, f"{args.days:g} days")]
    lengths = [(d, label) for d, label in lengths if d <= args.days]
    last: dict[tuple[str, int], float] = {}
    print(
        "offset = labelled block_start - UTC of the block's first sample; 5-min files at "
        f"2048 Hz, stamps +-{args.jitter:g} ms (seed 0), 20-min blocks every 5 min"
    )
    for days, label in lengths:
        n_files = int(round(days * 86400 / FILE_S))
        cells = []
        for ppm in PPMS:
            offsets = block_offsets_s(n_files, ppm, args.jitter)
            last[(label, ppm)] = offsets[-1]
            cells.append(
                f"{ppm:+4d} ppm: {offsets.size} blocks, first {offsets[0] * 1e3:+6.1f} ms, "
                f"last {offsets[-1]:+10.4f} s, largest but the last "
                f"{np.abs(offsets[:-1]).max():9.4f} s"
            )
        print(f"  {label:>8s} ({n_files:5d} files): " + "; ".join(cells))

    log = operating_profile(T0, 12.0, rng=np.random.default_rng(1)).predictors
    grid = BlockGrid(T0, 1200.0, 300.0)
    numbers = np.arange(int((12 * 3600 - 1200) / 300) + 1)
    labelled = pd.DataFrame(
        {
            "block": numbers,
            "block_start": [grid.start(k) for k in numbers],
            "block_end": [grid.end(k) for k in numbers],
        }
    )
    columns = ("speed_kn", "water_temp_c", "air_temp_c")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        means = block_predictors(log, blocks=labelled, despike=False)
        print(
            f"ship-log block means over the labelled span vs the recorded span "
            f"({len(numbers)} blocks of a 12-h operating profile, 1-s rows), "
            "the offset of the record's last block:"
        )
        for (label, ppm), offset in last.items():
            if ppm < 0:
                continue
            shift = pd.Timedelta(seconds=offset)
            recorded = labelled.assign(
                block_start=labelled.block_start - shift, block_end=labelled.block_end - shift
            )
            other = block_predictors(log, blocks=recorded, despike=False)
            cells = []
            for column in columns:
                difference = (means[column] - other[column]).abs()
                cells.append(
                    f"{column} largest {difference.max():.3f}, median {difference.median():.3f}"
                )
            print(f"  {label:>8s} {ppm:+4d} ppm ({offset:+9.4f} s): " + "; ".join(cells))


if __name__ == "__main__":
    main()
