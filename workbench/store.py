"""A resumable, crash-safe store of per-block results: Parquet datasets partitioned by day.

Layout under the store root::

    <root>/store.json                      parameters the results were computed with
    <root>/<kind>/day=YYYY-MM-DD/<batch>.parquet

``kind`` is a result family (``poles``, ``selected``, ``moments``, ``faults``, ...). Results
arrive in *batches*: one batch writes one Parquet file per kind and day, and finally its
``blocks`` file, which lists the blocks it completed (status ``ok`` or ``skipped`` with a
reason). A block counts as done only once its ``blocks`` file exists, and every file is
written to a temporary name and renamed, so killing the process at any moment leaves either
a whole batch or files that :meth:`BlockStore.open` removes as orphans. Any Parquet engine
reads a kind as a hive-partitioned dataset (``pd.read_parquet(root / "poles")``).
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from data_contracts import atomic_path

from .errors import WorkbenchError

__all__ = ["BLOCKS_KIND", "BlockStore"]

#: The kind whose files mark blocks as done.
BLOCKS_KIND = "blocks"
_CONFIG = "store.json"


@dataclass
class BlockStore:
    """Per-block results of one job, on disk.

    Use :meth:`open`, which creates the store or checks that an existing one was made with
    the same parameters (so a resumed job never mixes results of different settings).
    """

    root: Path

    @classmethod
    def open(cls, root: str | os.PathLike, parameters: Mapping[str, object]) -> BlockStore:
        """Open (or create) the store at *root* for a job with *parameters*.

        Raises
        ------
        WorkbenchError
            If the store exists and was made with other parameters.
        """
        root = Path(root)
        root.mkdir(parents=True, exist_ok=True)
        config_path = root / _CONFIG
        wanted = json.loads(json.dumps(dict(parameters), sort_keys=True, default=str))
        if config_path.is_file():
            found = json.loads(config_path.read_text(encoding="utf-8"))
            if found != wanted:
                changed = sorted(
                    k for k in set(found) | set(wanted) if found.get(k) != wanted.get(k)
                )
                raise WorkbenchError(
                    f"{root}: store was made with other parameters ({', '.join(changed)}); "
                    "use another --store directory or delete this one"
                )
        else:
            with atomic_path(config_path) as tmp:
                tmp.write_text(json.dumps(wanted, indent=2, sort_keys=True), encoding="utf-8")
        store = cls(root)
        store._remove_orphans()
        return store

    # ------------------------------------------------------------------ reading
    def _files(self, kind: str) -> list[Path]:
        return sorted((self.root / kind).glob("day=*/*.parquet"))

    def _remove_orphans(self) -> None:
        """Delete batch files of kinds whose batch never wrote its ``blocks`` file."""
        committed = {p.stem for p in self._files(BLOCKS_KIND)}
        for kind_dir in self.root.iterdir():
            if not kind_dir.is_dir() or kind_dir.name == BLOCKS_KIND:
                continue
            for path in kind_dir.glob("day=*/*.parquet"):
                if path.stem not in committed:
                    path.unlink()
        for leftover in self.root.glob("**/.*.tmp*"):  # temporary files of a killed write
            leftover.unlink(missing_ok=True)

    def completed_blocks(self) -> set[int]:
        """Blocks already processed (successfully or skipped with a recorded reason)."""
        table = self.read(BLOCKS_KIND)
        return set() if table.empty else set(table["block"].astype(int).tolist())

    def read(self, kind: str) -> pd.DataFrame:
        """All rows of *kind*, sorted by block (and model order when present)."""
        files = self._files(kind)
        if not files:
            return pd.DataFrame()
        frames = [pd.read_parquet(path) for path in files]
        table = pd.concat([f for f in frames if len(f)] or frames[:1], ignore_index=True)
        keys = [k for k in ("block", "model_order") if k in table.columns]
        if keys:
            table = table.sort_values(keys, kind="stable").reset_index(drop=True)
        return table

    def read_chunks(self, kind: str, blocks_per_chunk: int = 512):
        """Yield the rows of *kind* in block order, *blocks_per_chunk* blocks at a time.

        Memory stays bounded by the chunk, whatever the size of the store: each batch file's
        block range is in its name, so a chunk reads only the files overlapping it (and of
        those only its rows).
        """
        ranges = []
        for path in self._files(kind):
            low, high = (
                int(part[1:] if part.startswith("b") else part) for part in path.stem.split("-")[:2]
            )
            ranges.append((low, high, path))
        if not ranges:
            return
        keys = None
        first = min(r[0] for r in ranges)
        last = max(r[1] for r in ranges)
        for start in range(first, last + 1, blocks_per_chunk):
            stop = start + blocks_per_chunk
            frames = [
                pd.read_parquet(path, filters=[("block", ">=", start), ("block", "<", stop)])
                for low, high, path in ranges
                if low < stop and high >= start
            ]
            frames = [f for f in frames if len(f)]
            if not frames:
                continue
            table = pd.concat(frames, ignore_index=True)
            if keys is None:
                keys = [k for k in ("block", "model_order") if k in table.columns]
            yield table.sort_values(keys, kind="stable").reset_index(drop=True)

    # ------------------------------------------------------------------ writing
    def write_batch(self, blocks: pd.DataFrame, results: Mapping[str, pd.DataFrame]) -> str:
        """Write one batch atomically per file, the ``blocks`` file last.

        Parameters
        ----------
        blocks : DataFrame
            One row per block of the batch: ``block``, ``block_start``, ``status``
            (``ok``/``skipped``), ``reason``.
        results : mapping of kind -> DataFrame
            Result rows; each must have ``block`` and ``block_start`` columns.

        Returns
        -------
        str
            The batch name (file stem shared by all its files).
        """
        if blocks.empty:
            return ""
        batch = (
            f"b{int(blocks['block'].min()):07d}-{int(blocks['block'].max()):07d}-"
            f"{uuid.uuid4().hex[:8]}"
        )
        for kind, frame in results.items():
            if kind == BLOCKS_KIND:
                raise ValueError(f"kind {BLOCKS_KIND!r} is reserved")
            self._write_partitioned(kind, frame, batch, blocks)
        self._write_partitioned(BLOCKS_KIND, blocks, batch, blocks)
        return batch

    def _write_partitioned(
        self, kind: str, frame: pd.DataFrame, batch: str, blocks: pd.DataFrame
    ) -> None:
        starts = dict(
            zip(blocks["block"], pd.to_datetime(blocks["block_start"], utc=True), strict=True)
        )
        if frame.empty:
            return
        days = frame["block"].map(starts).dt.strftime("%Y-%m-%d")
        for day, part in frame.groupby(days.to_numpy(), sort=True):
            path = self.root / kind / f"day={day}" / f"{batch}.parquet"
            with atomic_path(path) as tmp:
                part.reset_index(drop=True).to_parquet(tmp, index=False)


def batched(items: Iterable, size: int):
    """Yield lists of up to *size* consecutive items."""
    batch: list = []
    for item in items:
        batch.append(item)
        if len(batch) >= size:
            yield batch
            batch = []
    if batch:
        yield batch
