"""The monitor's tracked table with harmonic marks, built block by block, equals the batch
``track`` of the selected modes with the same marks: before, ``IncrementalTracking.table``
built every row again at each block when the marks were given (and the harmonic labels'
counts, which grow each block, made every part of ``tracked.parquet`` be written again);
now only the rows from the first block that changed are built while the labels left out
as harmonics stay the same."""

from __future__ import annotations

import numpy as np
import pandas as pd

from workbench.monitor.tracking import IncrementalTracking
from workbench.sid.tracking import TrackingOptions, track_modes

T0 = pd.Timestamp("2026-03-01T00:00:00Z")
N_BLOCKS = 90
#: blocks whose ship log has no shaft speed: their rows are not checked
OUTAGE = range(40, 52)
#: the newest blocks' marks are pending (the log does not cover them yet): unmarked
PENDING = 2
SHAPES = {
    0.8: [1.0, 0.5, -0.3, 0.2],
    1.6: [0.2, 1.0, 0.6, -0.5],
    2.9: [-0.4, 0.1, 1.0, 0.7],
    "order": [0.5, 0.5, 0.5, 0.5],
    "outage line": [-0.6, 0.8, -0.2, 0.1],
}


def _rpm(block: int) -> float:
    """Shaft speed: 90 +- 30 rpm over 60 blocks (order 1 crosses the 1.6 Hz mode). [rpm]"""
    return 90.0 + 30.0 * np.sin(2 * np.pi * block / 60.0)


def _part(block: int, rng) -> pd.DataFrame:
    rows = [(f * (1 + 0.002 * rng.standard_normal()), SHAPES[f]) for f in (0.8, 1.6, 2.9)]
    rows.append((_rpm(block) / 60.0, SHAPES["order"]))
    if block in OUTAGE:  # a line seen only where the log fails
        rows.append((3.7 * (1 + 0.002 * rng.standard_normal()), SHAPES["outage line"]))
    rows.sort(key=lambda r: r[0])
    shapes = np.array([r[1] for r in rows]) + 0.01 * rng.standard_normal((len(rows), 4))
    start = T0 + pd.Timedelta(minutes=5 * block)
    part = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "frequency_hz": [r[0] for r in rows],
            "damping_ratio": 0.01 + 0.001 * rng.standard_normal(len(rows)),
        }
    )
    for j, channel in enumerate("abcd"):
        part[f"shape_re_{channel}"] = shapes[:, j]
        part[f"shape_im_{channel}"] = 0.0
    return part


def _marks(frame: pd.DataFrame, newest: int) -> np.ndarray:
    """Order 1 within 2 % marked; the outage's rows unchecked; the newest PENDING blocks
    not marked yet (their marks change once the log covers them)."""
    block = frame["block"].to_numpy()
    order_hz = np.array([_rpm(b) / 60.0 for b in block])
    near = np.abs(frame["frequency_hz"].to_numpy() - order_hz) <= 0.02 * order_hz
    checked = ~np.isin(block, list(OUTAGE))
    marked = near & checked & (block <= newest - PENDING)
    return np.column_stack(
        [np.where(marked, 1.0, np.nan), np.where(marked, order_hz, np.nan), checked]
    )


def test_tracked_table_with_marks_equals_the_batch_track_block_by_block():
    rng = np.random.default_rng(5)
    parts = [_part(block, rng) for block in range(N_BLOCKS)]
    options = TrackingOptions()
    live = IncrementalTracking(options)
    incremental = 0
    for block, part in enumerate(parts):
        live.add(block, part)
        live.advance(set(range(block + 1)))
        table = live.table(marks=lambda frame, newest=block: _marks(frame, newest))
        incremental += live.changed_from is not None
        so_far = pd.concat(parts[: block + 1], ignore_index=True)
        marks = _marks(so_far, block)
        batch = track_modes(
            so_far.assign(
                harmonic=marks[:, 0],
                harmonic_frequency_hz=marks[:, 1],
                harmonic_checked=marks[:, 2] > 0.5,
            ),
            options=options,
        )
        pd.testing.assert_frame_equal(table, batch)
        assert table.attrs.get("harmonic_labels", []) == batch.attrs.get("harmonic_labels", []), (
            block
        )
    # not vacuous: the order's line left out as harmonics (8 labels as it sweeps 1.0-2.0
    # Hz), the outage's line unverified, the three modes kept in every block (the one the
    # order crosses too); most blocks built incrementally
    left_out = table.attrs["harmonic_labels"]
    assert sum(not h["unverified"] for h in left_out) == 8
    assert [round(h["frequency_hz"], 2) for h in left_out if h["unverified"]] == [3.7, 1.02]
    counts = table.groupby("mode")["frequency_hz"].agg(["median", "count"])
    assert counts["median"].round(1).tolist() == [0.8, 1.6, 2.9]
    assert counts["count"].tolist() == [N_BLOCKS] * 3
    assert incremental >= N_BLOCKS - 15
