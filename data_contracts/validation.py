"""One entry point to check any file against its contract: :func:`validate_file`."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .accelerations import read_accelerations
from .dship import read_dship
from .tables import CONTRACTS, read_table

__all__ = ["FILE_KINDS", "ValidatedFile", "validate_file"]

#: Every kind :func:`validate_file` knows: the two raw inputs, then the table contracts.
FILE_KINDS: tuple[str, ...] = ("accelerations", "dship", *CONTRACTS)


@dataclass(frozen=True)
class ValidatedFile:
    """A file that passed its contract: what was read and a one-line description.

    Parameters
    ----------
    kind : str
        The contract (one of :data:`FILE_KINDS`).
    path : Path
    data : object
        What the reader returned: an :class:`~data_contracts.AccelerationRecord` or a
        validated DataFrame.
    summary : str
        E.g. ``"3 rows"`` or ``"19200 samples x 19 channels at 64 Hz from ..."``.
    """

    kind: str
    path: Path
    data: Any
    summary: str


def validate_file(
    kind: str,
    path: str | os.PathLike,
    *,
    layout: Any = None,
    dship_mapping: Mapping[str, str] | None = None,
    time_format: str | None = None,
    dship_utc_offset: str | None = None,
) -> ValidatedFile:
    """Read *path* as a file of contract *kind* and validate it.

    Parameters
    ----------
    kind : str
        ``"accelerations"``, ``"dship"`` or a table contract name (:data:`CONTRACTS`).
    path : path-like
    layout : AccelerationLayout or mapping, optional
        How to read an acceleration file in another format (see
        :func:`~data_contracts.read_accelerations`).
    dship_mapping : mapping, optional
        Canonical column -> source column of a ship log (see
        :func:`~data_contracts.read_dship`).
    time_format : str, optional
        Format of a ship log's times (:func:`~data_contracts.read_dship`); acceleration
        files take theirs from *layout*.
    dship_utc_offset : str, optional
        UTC offset of a ship log's times written without one (``"+02:00"``; see
        :func:`~data_contracts.read_dship`).

    Raises
    ------
    ValueError
        For an unknown *kind*.
    ContractError
        When the file is missing, unreadable or violates the contract (every problem).
    """
    path = Path(path)
    if kind == "accelerations":
        record = read_accelerations(path, layout=layout)
        summary = (
            f"{record.n_samples} samples x {len(record.channels)} channels at "
            f"{record.sampling_rate_hz:g} Hz from {record.start_time.isoformat()}"
        )
        return ValidatedFile(kind, path, record, summary)
    if kind == "dship":
        table = read_dship(
            path, mapping=dship_mapping, time_format=time_format, utc_offset=dship_utc_offset
        )
        summary = f"{len(table)} records, columns {', '.join(table.columns[1:])}"
        return ValidatedFile(kind, path, table, summary)
    if kind not in CONTRACTS:
        raise ValueError(f"kind={kind!r} is not a contract; use one of {', '.join(FILE_KINDS)}")
    table = read_table(path, CONTRACTS[kind])
    return ValidatedFile(kind, path, table, f"{len(table)} rows")
