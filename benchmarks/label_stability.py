"""Measure whether the monitor's mode labels keep their meaning block by block.

Feeds a voyage's selected modes (``identify/selected.parquet`` of ``workbench demo`` or
``workbench identify``) block by block into the monitor's incremental tracker
(:class:`workbench.monitor.tracking.IncrementalTracking`) and counts the (block, label)
pairs shown whose median frequency so far differs by more than 2 % from that label's
median at the end (the label meant another mode then), the labels shown and withdrawn
later (harmonics; never reused), and whether the final table equals the batch
``track_modes`` of the same selected modes.

Usage::

    python benchmarks/label_stability.py reports/demo/identify/selected.parquet
"""

from __future__ import annotations

import sys

import pandas as pd

from workbench.monitor.tracking import IncrementalTracking
from workbench.sid.tracking import TrackingOptions, track_modes


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    selected = pd.read_parquet(argv[0])
    options = TrackingOptions()
    blocks = sorted(int(b) for b in selected["block"].unique())
    live = IncrementalTracking(options)
    history = []
    for block in blocks:
        live.add(block, selected[selected["block"] == block])
        live.advance({b for b in blocks if b <= block})
        table = live.table()
        if len(table):
            history.append((block, table.groupby("mode")["frequency_hz"].median().to_dict()))
    final = live.table()
    batch = track_modes(selected, options=options)
    end = final.groupby("mode")["frequency_hz"].median().to_dict()
    changed = [
        (block, mode, frequency, end[mode])
        for block, names in history
        for mode, frequency in names.items()
        if mode in end and abs(frequency / end[mode] - 1) > 0.02
    ]
    withdrawn = sorted(
        {(m, round(f, 3)) for _, names in history for m, f in names.items() if m not in end}
    )
    print(f"{len(blocks)} blocks; final labels { ({m: round(f, 3) for m, f in end.items()}) }")
    print(f"live final table equals batch track: {final.equals(batch)}")
    print(
        f"(block, label) pairs shown meaning another mode than at the end: {len(changed)} of "
        f"{sum(len(n) for _, n in history)}; labels affected "
        f"{sorted({m for _, m, _, _ in changed})}"
    )
    for block, mode, frequency, final_hz in changed[:8]:
        print(f"  block {block}: mode {mode} = {frequency:.3f} Hz, at the end {final_hz:.3f} Hz")
    print(f"labels shown and withdrawn later (harmonics), never reused: {withdrawn}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
