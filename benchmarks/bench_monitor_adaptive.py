"""The monitor's adaptive blocks against the batch run on the ice voyages.

For each voyage of ``bench_adaptive_blocks.py`` (station, transit, 0-10 kn alternation,
then ice breaking), in this session, one after the other and each in a fresh process:

* **batch**: ``workbench identify ACC --out DIR --block-minutes auto --dship LOG
  --scheduler synchronous`` then ``workbench track DIR/selected.parquet``;
* **monitor**: ``workbench monitor --watch ACC --state DIR --dship LOG --block-minutes auto
  --once`` (in-process forecast and health at the end, one worker like the batch run).

Printed per voyage: blocks and their lengths, whether the monitor's tables equal the
batch's (block lengths and stationarity measures per block, the selected modes'
frequencies per block, the tracked table), the largest frequency difference, and the
wall time of each run per block with the ratio monitor / batch. The monitor's time is
given whole and up to its last block's state (``identified_at`` of the last block in
``data_health.parquet``: identification and tracking, without the final forecast, which
the batch pair does not run).

Run: ``python benchmarks/bench_monitor_adaptive.py [--seeds 0,1,2,3,4] [--work
/tmp/bench_adaptive]`` (voyages simulated where missing; the runs are made again each
time, in ``WORK/<voyage>/monitor_bench``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_adaptive_blocks import add_voyage_arguments, voyages  # noqa: E402

_CODE = "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))"


def _run(*argv) -> float:
    """Run ``workbench ARGV`` in a fresh process; its wall time. [s]"""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _CODE, *map(str, argv)], capture_output=True, text=True
    )
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"workbench {' '.join(map(str, argv))}: exit {done.returncode}\n"
                         f"{done.stderr[-2000:]}")  # fmt: skip
    return seconds


def _store_table(store: Path, kind: str) -> pd.DataFrame:
    files = sorted((store / kind).glob("day=*/*.parquet"))
    frame = pd.concat([pd.read_parquet(p) for p in files], ignore_index=True)
    return frame.drop(columns=["day"], errors="ignore")


def compare(folder: Path) -> dict:
    """Run the pair on the voyage in *folder*; what they gave and took."""
    work = folder / "monitor_bench"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    accelerations, log = folder / "accelerations", folder / "dship.tsv"
    started = pd.Timestamp.now(tz="UTC")
    batch_s = _run(
        "identify", accelerations, "--out", work / "batch", "--block-minutes", "auto",
        "--dship", log, "--scheduler", "synchronous", "--quiet",
    )  # fmt: skip
    batch_s += _run(
        "track", work / "batch" / "selected.parquet", "--out", work / "batch_tracked.parquet"
    )
    state = work / "state"
    monitor_started = pd.Timestamp.now(tz="UTC")
    monitor_s = _run(
        "monitor", "--watch", accelerations, "--state", state, "--dship", log,
        "--block-minutes", "auto", "--once", "--quiet",
    )  # fmt: skip
    health = pd.read_parquet(state / "data_health.parquet")
    to_last_block_s = (health["identified_at"].max() - monitor_started).total_seconds()
    blocks = pd.read_csv(work / "batch" / "blocks.csv")
    lengths = _store_table(state / "store", "lengths").sort_values("block")
    measures = ["block_length_s", "excitation_range_db", "speed_range_kn"]
    same_lengths = blocks["block"].tolist() == lengths["block"].tolist() and all(
        np.allclose(blocks[c], lengths[c], rtol=1e-12, atol=0, equal_nan=True) for c in measures
    )
    keys = ["block", "model_order", "frequency_hz"]
    batch_selected = pd.read_parquet(work / "batch" / "selected.parquet")
    batch_selected = batch_selected.sort_values(keys).reset_index(drop=True)
    selected = _store_table(state / "store", "selected").sort_values(keys).reset_index(drop=True)
    same_selected = len(selected) == len(batch_selected) and np.array_equal(
        selected["block"], batch_selected["block"]
    )
    df_selected = (
        float(np.max(np.abs(selected["frequency_hz"] - batch_selected["frequency_hz"])))
        if same_selected
        else float("nan")
    )
    tracked = pd.read_parquet(state / "tracked.parquet")
    batch_tracked = pd.read_parquet(work / "batch_tracked.parquet")
    try:
        pd.testing.assert_frame_equal(tracked, batch_tracked)
        same_tracked = True
    except AssertionError:
        same_tracked = False
    df_tracked = (
        float(np.max(np.abs(tracked["frequency_hz"] - batch_tracked["frequency_hz"])))
        if len(tracked) == len(batch_tracked)
        else float("nan")
    )
    counts = blocks["block_length_s"].value_counts().sort_index()
    return {
        "voyage": folder.name,
        "started": started.strftime("%H:%M:%SZ"),
        "blocks": len(blocks),
        "lengths": ", ".join(f"{n}x{length / 60:g}" for length, n in counts.items()),
        "lengths equal": same_lengths,
        "selected rows": f"{len(selected)}/{len(batch_selected)}",
        "max |df| selected [Hz]": df_selected,
        "tracked equal": same_tracked,
        "max |df| tracked [Hz]": df_tracked,
        "batch s/block": batch_s / len(blocks),
        "monitor s/block": monitor_s / len(blocks),
        "monitor to last block s/block": to_last_block_s / len(blocks),
        "ratio": monitor_s / batch_s,
        "ratio to last block": to_last_block_s / batch_s,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_voyage_arguments(parser, "0,1,2,3,4")
    args = parser.parse_args(argv)
    found = voyages(args)
    if found is None:
        return 2
    rows = [compare(folder) for _, folder in found]
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(
        f"\nall equal: lengths {table['lengths equal'].all()}, tracked "
        f"{table['tracked equal'].all()}; ratio monitor / batch: median "
        f"{table['ratio'].median():.3f} (to the last block {table['ratio to last block'].median():.3f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
