"""Rows of acquisition files for the file conditioner: partial reads of uncompressed
``.npz`` files, and a small per-process cache of files that can only be read whole."""

from __future__ import annotations

import collections
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from data_contracts import AccelerationRecord, read_accelerations, validate_accelerations
from data_contracts.npz import read_sample_rows

from .block_plan import FileInfo, align_channels

# ----------------------------------------------------------------------------------------
# partial reads
# ----------------------------------------------------------------------------------------
#: Files read whole (formats without partial reads: CSV, MATLAB, HDF5, UFF, compressed
#: ``.npz``) kept per process. Conditioning a file also needs its neighbours' edges, and
#: the next file conditioned is usually a neighbour: with the last three files kept, a
#: voyage conditioned in order parses each file once instead of three times. [files]
WHOLE_READS_KEPT = 3
_whole_reads: collections.OrderedDict = collections.OrderedDict()


def _read_whole(path: Path, read_options=None):
    """:func:`data_contracts.read_accelerations` of *path*, from the per-process cache of
    the last :data:`WHOLE_READS_KEPT` files when neither the file (size, modification
    time) nor the reading options changed."""
    stat = path.stat()
    key = (str(path), stat.st_size, stat.st_mtime_ns, repr(sorted((read_options or {}).items())))
    record = _whole_reads.get(key)
    if record is None:
        record = read_accelerations(path, **(read_options or {}))
        _whole_reads[key] = record
        while len(_whole_reads) > WHOLE_READS_KEPT:
            _whole_reads.popitem(last=False)
    else:
        _whole_reads.move_to_end(key)
    return record


def _read_rows(
    info: FileInfo, channels: Sequence[str], first: int, stop: int, read_options=None
) -> np.ndarray:
    """Rows [first, stop) of a file's samples, channels in *channels* order.

    Uncompressed ``.npz`` files are read in place (only the wanted rows); other files are
    read whole (kept for the next few reads, :data:`WHOLE_READS_KEPT`). Either way the rows
    obey the reader's rule for infinite or implausible values (*read_options*'
    ``glitches``): read in place, the rule is applied to the rows read (a channel holding
    such a value there is NaN in them; rows where every channel does are refused).

    Raises
    ------
    ContractError
        The rows (or the file read whole) are refused under that rule.
    """
    first, stop = max(0, int(first)), min(info.n_samples, int(stop))
    if stop <= first:
        return np.zeros((0, len(channels)))
    rows = None
    if info.path.suffix.lower() == ".npz":
        rows = read_sample_rows(info.path, first, stop)
    if rows is not None and stop - first >= 2:
        # the rule the reader applies to the whole file, applied to these rows: a glitch
        # in a neighbour's edge must not reach the filters of the file it pads
        part = AccelerationRecord(rows, info.sampling_rate_hz, info.start_time, info.channels)
        glitches = (read_options or {}).get("glitches", "refuse")
        rows = validate_accelerations(part, source=info.path, glitches=glitches).acceleration
    if rows is None:
        record = _read_whole(info.path, read_options)
        rows, names = record.acceleration[first:stop], record.channels
    else:
        names = info.channels
    return align_channels(np.asarray(rows, dtype=float), names, channels)


def _edge_rows(info: FileInfo, channels, first: int, stop: int | None = None, read_options=None):
    """Rows of a neighbouring file for padding, or None when they cannot be read or are
    refused (then the chain of contiguous files breaks there; the blocks holding that file
    report it)."""
    try:
        return _read_rows(
            info, channels, first, info.n_samples if stop is None else stop, read_options
        )
    except (OSError, ValueError):
        return None
