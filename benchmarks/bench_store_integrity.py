"""Benchmark: the cost of the store's file check on open, against reading the store.

Issue 28, item 2: every batch file of the per-block store is checked against the manifest
(size and SHA-256) when the store is opened, so a rerun never exports damaged results. The
check must stay small beside what a rerun does anyway: reading the stored results for the
export. Both run here, in the same process, on the same store: a synthetic store of
``--blocks`` blocks of pole tables shaped as identify's (one row per pole and model order,
19-channel mode shapes), written ``--batch`` blocks per batch.

Printed: median over ``--repeats`` of (a) :meth:`BlockStore.open` (lock, manifest read,
every file hashed), (b) ``store.read("poles")`` (the export's read of the largest kind), and
their ratio. Target: the check costs at most a quarter of the read.

Run: ``python benchmarks/bench_store_integrity.py [--blocks 400] [--batch 16] [--repeats 5]``
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.store import BlockStore

TARGET_RATIO = 0.25
CHANNELS = [f"acc{k:02d}" for k in range(1, 20)]


def _batch(blocks: list[int], rng: np.random.Generator) -> tuple[pd.DataFrame, dict]:
    t0 = pd.Timestamp("2026-03-01T00:00Z")
    starts = [t0 + pd.Timedelta(minutes=5 * b) for b in blocks]
    status = pd.DataFrame({"block": blocks, "block_start": starts, "status": "ok", "reason": ""})
    orders = np.arange(4, 61, 2)
    rows = []
    for block, start in zip(blocks, starts, strict=True):
        n = int(orders.sum() // 2)  # about half the order's poles survive the band
        frame = pd.DataFrame(
            {
                "block": block,
                "block_start": start,
                "model_order": np.repeat(orders, orders // 2)[:n],
                "frequency_hz": rng.uniform(2, 12, n),
                "damping_ratio": rng.uniform(0.005, 0.05, n),
                "mpc": rng.uniform(0.5, 1, n),
                "stable": rng.random(n) < 0.5,
            }
        )
        shapes = rng.standard_normal((n, 2 * len(CHANNELS)))
        for k, channel in enumerate(CHANNELS):
            frame[f"shape_re_{channel}"] = shapes[:, k]
            frame[f"shape_im_{channel}"] = shapes[:, len(CHANNELS) + k]
        rows.append(frame)
    return status, {"poles": pd.concat(rows, ignore_index=True)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=400)
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder) / "store"
        with BlockStore.open(root, {}) as store:
            for first in range(0, args.blocks, args.batch):
                store.write_batch(
                    *_batch(list(range(first, min(first + args.batch, args.blocks))), rng)
                )
        size = sum(p.stat().st_size for p in root.rglob("*.parquet"))
        checks, reads = [], []
        for _ in range(args.repeats):
            started = time.perf_counter()
            store = BlockStore.open(root, {})
            checks.append(time.perf_counter() - started)
            assert not store.notices
            started = time.perf_counter()
            store.read("poles")
            reads.append(time.perf_counter() - started)
            store.close()
    check, read = statistics.median(checks), statistics.median(reads)
    print(
        f"store: {args.blocks} blocks in batches of {args.batch}, {size / 1e6:.1f} MB of "
        "batch files"
    )
    print(f"open with the file check: {check * 1e3:.1f} ms (median of {args.repeats})")
    print(f"read of the poles:         {read * 1e3:.1f} ms")
    ratio = check / read
    verdict = "meets" if ratio <= TARGET_RATIO else "misses"
    print(f"ratio check / read: {ratio:.3f} ({verdict} the target {TARGET_RATIO})")


if __name__ == "__main__":
    main()
