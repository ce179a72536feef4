"""Sample-clock drift and stamp jitter: how often ``place_files`` keeps a record whole and
tells a real gap, from the files' headers alone.

Each case is a day (``--files``) of 5-min files at 2048 Hz whose sample clock runs *ppm*
fast (file k stamped k * 300 s / (1 + ppm) after the first) plus a stamp jitter uniform in
+-J ms, over ``--seeds`` draws. Printed per jitter and ppm: the draws whose files are not
one record (an "overlap" error, or a false gap), and, with ``--gap G``, the draws in which
a real gap (G > 0) or overlap (G < 0) of G ms after the middle file is told (a gap, or the
error naming that file); with ``--lost``, the middle file lost, the draws whose plan
(20-min blocks every 5 min from the first stamp) keeps the last block, which the files'
samples cover. Run against two trees with PYTHONPATH to compare them.

Run: ``python benchmarks/bench_clock_drift.py --seeds 100``,
``python benchmarks/bench_clock_drift.py --seeds 50 --gap 250`` and
``python benchmarks/bench_clock_drift.py --seeds 30 --lost`` (seconds each).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.blocks import BlockGrid
from workbench.signals.block_plan import FileInfo, place_files, plan_file_infos

RATE_HZ = 2048.0
T0 = pd.Timestamp("2026-03-01T00:00:00Z")


def _headers(n_files: int, ppm: float, jitter_ms: float, seed: int, gap_ms: float):
    rng = np.random.default_rng(seed)
    stamps = np.arange(n_files) * 300.0 / (1 + ppm * 1e-6)
    stamps += rng.uniform(-jitter_ms, jitter_ms, n_files) / 1e3
    stamps[n_files // 2 :] += gap_ms / 1e3
    n = int(300 * RATE_HZ)
    return [
        FileInfo(Path(f"acc_{k:03d}.npz"), T0 + pd.Timedelta(seconds=float(s)), RATE_HZ, n, ("a",))
        for k, s in enumerate(stamps)
    ]


def _outcome(infos, gap_ms: float) -> bool:
    """Without a gap: whether the files are not one record; with one: whether it is told."""
    middle = len(infos) // 2
    try:
        placed = place_files(infos)
    except ValueError as error:
        return not gap_ms or str(error).startswith(f"{infos[middle].path}:")
    breaks = [k for k in range(1, len(placed)) if placed[k].start_time != placed[k - 1].end_time]
    return breaks != [] if not gap_ms else breaks == [middle]


def _last_block_kept(infos) -> bool:
    """With the middle file lost: whether the plan keeps the last block (not when the
    record breaks: an "overlap" error)."""
    n_files = len(infos)
    kept = infos[: n_files // 2] + infos[n_files // 2 + 1 :]
    try:
        plan = plan_file_infos(kept, BlockGrid(kept[0].start_time, 1200.0, 300.0))
    except ValueError:
        return False
    return plan.blocks[-1].block == n_files - 4


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--files", type=int, default=96, help="5-min files (96: 8 h)")
    parser.add_argument("--gap", type=float, default=0.0, metavar="MS")
    parser.add_argument("--lost", action="store_true", help="the middle file lost")
    args = parser.parse_args()
    ppms = (-100, -50, -20, 0, 20, 50, 100)
    what = f"real gap of {args.gap:+g} ms told" if args.gap else "record broken"
    if args.lost:
        what = "middle file lost, last block kept"

    def outcome(infos) -> bool:
        return _last_block_kept(infos) if args.lost else _outcome(infos, args.gap)

    print(f"{args.files} 5-min files at 2048 Hz, {args.seeds} draws each: {what}")
    for jitter in (0, 5, 10, 15, 20, 25):
        counts = [
            sum(
                outcome(_headers(args.files, ppm, jitter, seed, 0.0 if args.lost else args.gap))
                for seed in range(args.seeds)
            )
            for ppm in ppms
        ]
        row = " ".join(f"{p:+4d} ppm {c:3d}" for p, c in zip(ppms, counts, strict=True))
        print(f"jitter +-{jitter:2d} ms: {row}")


if __name__ == "__main__":
    main()
