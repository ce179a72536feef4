"""The store's results exported as contract tables, atomically."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from data_contracts import POLES, SELECTED, atomic_path
from data_contracts.tables import metadata_with_grid, write_grid_sidecar

from ..blocks import BlockGrid
from ..store import CUT_COLUMNS, UNREADABLE_COLUMN, BlockStore


def export_store(
    store: BlockStore,
    out_dir: str | os.PathLike,
    channels: Sequence[str],
    *,
    grid: BlockGrid | None = None,
    harmonics=None,
):
    """Write the store's results as tables in *out_dir*; return them by kind.

    Poles are streamed chunk by chunk into one Parquet file (rows in block order), so
    exporting a voyage of any length needs the memory of one chunk of poles (the selected
    modes, a few per block, are marked as one table). Every table records the block *grid*
    (Parquet metadata, or a ``<name>.grid.json`` sidecar beside the CSV files; see
    :mod:`data_contracts.grid`). *harmonics* (a
    :class:`~workbench.sid.harmonics.HarmonicMarker`) adds the ``harmonic`` column to the
    selected modes and the poles and writes ``shaft.csv`` (the blocks' shaft speed and
    speed) when it had a ship log; without it the column is added empty.
    """
    from ..sid.harmonics import HarmonicMarker

    marker = harmonics if harmonics is not None else HarmonicMarker(None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    selected_chunks = [
        chunk.sort_values(["block", "frequency_hz"], kind="stable")
        for chunk in store.read_chunks("selected", blocks_per_chunk=64)
    ]
    if selected_chunks:
        selected = marker.mark_selected(pd.concat(selected_chunks, ignore_index=True))
        path = _write_parquet_chunks([selected], out / "selected.parquet", SELECTED, grid=grid)
        if path is not None:
            files["selected"] = path
    chunks = (
        marker.mark_poles(
            chunk.sort_values(["block", "model_order", "frequency_hz"], kind="stable")
        ).reset_index(drop=True)
        for chunk in store.read_chunks("poles", blocks_per_chunk=64)
    )
    path = _write_parquet_chunks(chunks, out / "poles.parquet", POLES, grid=grid)
    if path is not None:
        files["poles"] = path
    if marker.method != "none" and len(marker.shaft):
        files["shaft"] = _write_csv(marker.shaft.reset_index(drop=True), out / "shaft.csv")
        write_grid_sidecar(files["shaft"], grid)
        import json

        summary = {"method": marker.method, "orders": list(marker.orders), "lines": marker.lines()}
        if math.isfinite(marker.shaft_hz_per_kn):
            # the speed-following test's rate: the orders at speed x rate (the monitor's
            # harmonics.parquet, shaft.csv's speed_energy_kn)
            summary["shaft_hz_per_kn"] = marker.shaft_hz_per_kn
        with atomic_path(out / "harmonics.json") as tmp:
            tmp.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        files["harmonics"] = out / "harmonics.json"
    for kind in ("faults", "channels", "crosscheck", "blocks"):
        table = store.read(kind)
        if kind == "blocks" and not table.empty:
            # the files behind an unreadable-input skip and a drifting block's cut are the
            # store's own bookkeeping (the reason names the files; the summary the cuts
            # off their labels by more than a sample)
            table = table.drop(columns=[UNREADABLE_COLUMN, *CUT_COLUMNS], errors="ignore")
            table = table.sort_values("block", kind="stable")
        if not table.empty or kind == "blocks":
            files[kind] = _write_csv(table.reset_index(drop=True), out / f"{kind}.csv")
            write_grid_sidecar(files[kind], grid)
    return files


def _write_parquet_chunks(chunks, path: Path, contract=None, *, grid=None) -> Path | None:
    """Stream DataFrame chunks into one Parquet file (validated per chunk), atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    writer = None
    schema = None
    try:
        with atomic_path(path) as tmp:
            try:
                for chunk in chunks:
                    if contract is not None:
                        chunk = contract.validate(chunk)
                    table = pa.Table.from_pandas(chunk, preserve_index=False, schema=schema)
                    if writer is None:
                        schema = table.schema
                        if grid is not None:
                            schema = schema.with_metadata(metadata_with_grid(schema.metadata, grid))
                        writer = pq.ParquetWriter(tmp, schema)
                    writer.write_table(table)
            finally:
                if writer is not None:
                    writer.close()
            if writer is None:
                raise _NothingWritten
    except _NothingWritten:
        return None
    return path


class _NothingWritten(Exception):
    pass


def _write_csv(frame: pd.DataFrame, path: Path) -> Path:
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, date_format="%Y-%m-%dT%H:%M:%S.%fZ")
    return path
