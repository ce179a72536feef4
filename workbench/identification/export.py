"""The store's results exported as contract tables, atomically."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from data_contracts import POLES, SELECTED, atomic_path
from data_contracts.tables import metadata_with_grid, write_grid_sidecar

from ..blocks import BlockGrid
from ..store import BlockStore


def export_store(
    store: BlockStore,
    out_dir: str | os.PathLike,
    channels: Sequence[str],
    *,
    grid: BlockGrid | None = None,
):
    """Write the store's results as tables in *out_dir*; return them by kind.

    Poles and selected modes are streamed chunk by chunk into one Parquet file each (rows in
    block order), so exporting a voyage of any length needs the memory of one chunk. Every
    table records the block *grid* (Parquet metadata, or a ``<name>.grid.json`` sidecar
    beside the CSV files; see :mod:`data_contracts.grid`).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for kind, sort, name, contract in (
        ("poles", ["block", "model_order", "frequency_hz"], "poles.parquet", POLES),
        ("selected", ["block", "frequency_hz"], "selected.parquet", SELECTED),
    ):
        chunks = (
            chunk.sort_values(sort, kind="stable").reset_index(drop=True)
            for chunk in store.read_chunks(kind, blocks_per_chunk=64)
        )
        path = _write_parquet_chunks(chunks, out / name, contract, grid=grid)
        if path is not None:
            files[kind] = path
    for kind in ("faults", "channels", "crosscheck", "blocks"):
        table = store.read(kind)
        if kind == "blocks" and not table.empty:
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
