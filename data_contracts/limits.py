"""What a reader may allocate: sizes a file declares are checked before anything is read.

A container file states the size of its arrays before their data: the ``.npy`` header in
an ``.npz`` archive, the dataspace of an HDF5 dataset, the array header of a MATLAB file.
A crafted (or damaged) file of a few kilobytes can declare gigabytes: an HDF5 dataset of
10 000 000 x 19 chunks that were never written reads as 1.5 GB of fill values. Every
reader passes each array it is about to read through :func:`check_declared_size`, which
refuses it, before any allocation, when

* the file does not hold it: the bytes stored for the array, times
  :data:`MAX_COMPRESSION_RATIO` (deflate's ceiling is about 1032:1), are fewer than the
  bytes declared; or
* it is larger than the memory budget :func:`max_array_bytes`, counted as float64 (the
  readers convert samples to float64): 4 GiB unless the environment variable
  ``WORKBENCH_MAX_ARRAY_BYTES`` says otherwise (a number of bytes, optionally with a
  suffix ``K``, ``M``, ``G`` or ``T``, powers of 1024).

Text files declare nothing (their memory grows with their size), but a header line can
name any number of columns, each costing the parser a fixed overhead: no file may have more
than :data:`MAX_CHANNELS` channels.

Options that size what is built from a file have one limit each too, shared by the command
line, the ship's configuration file and the library: :data:`MAX_MODEL_ORDER` and
:data:`MAX_LSCF_ORDER`.
"""

from __future__ import annotations

import os
import re

from ._core import ContractError, Violation

__all__ = [
    "DEFAULT_MAX_ARRAY_BYTES",
    "MAX_ARRAY_BYTES_VARIABLE",
    "MAX_CHANNELS",
    "MAX_COMPRESSION_RATIO",
    "MAX_LSCF_ORDER",
    "MAX_MODEL_ORDER",
    "check_channel_count",
    "check_declared_size",
    "max_array_bytes",
]

#: Highest SSI model order (state-space dimension): beyond what a block of real data
#: identifies, and each order costs an eigenvalue problem of its size. [-]
MAX_MODEL_ORDER = 2000
#: Highest LSCF polynomial order (p·r poles with r references). [-]
MAX_LSCF_ORDER = 500

#: Memory budget of one array a reader allocates, unless overridden. [B]
DEFAULT_MAX_ARRAY_BYTES = 4 * 1024**3

#: Environment variable overriding :data:`DEFAULT_MAX_ARRAY_BYTES` (``8G``, ``500M``, bytes).
MAX_ARRAY_BYTES_VARIABLE = "WORKBENCH_MAX_ARRAY_BYTES"

#: Largest ratio of declared to stored bytes taken as compression (deflate reaches about
#: 1032:1 on constant data).
MAX_COMPRESSION_RATIO = 1100

#: Most channels one acceleration file may have (an SSI of that many channels is already
#: far beyond what a block can identify).
MAX_CHANNELS = 1024

_SUFFIXES = {"": 1, "k": 1024, "m": 1024**2, "g": 1024**3, "t": 1024**4}


def max_array_bytes() -> int:
    """The memory budget of one array: ``WORKBENCH_MAX_ARRAY_BYTES`` or 4 GiB. [B]

    Raises
    ------
    ValueError
        When the environment variable is set to something other than a positive size.
    """
    text = os.environ.get(MAX_ARRAY_BYTES_VARIABLE, "").strip()
    if not text:
        return DEFAULT_MAX_ARRAY_BYTES
    match = re.fullmatch(r"(\d+(?:\.\d*)?)\s*([kmgt]?)i?b?", text.lower())
    value = float(match.group(1)) * _SUFFIXES[match.group(2)] if match else 0.0
    if not value >= 1:
        raise ValueError(
            f"{MAX_ARRAY_BYTES_VARIABLE}={text!r} must be a positive size in bytes "
            "(e.g. 8G, 500M or 2000000000)"
        )
    return int(value)


def _size(n_bytes: float) -> str:
    for unit, factor in (("GB", 1e9), ("MB", 1e6), ("KB", 1e3)):
        if n_bytes >= factor:
            return f"{n_bytes / factor:.3g} {unit}"
    return f"{int(n_bytes)} bytes"


def check_declared_size(
    shape,
    itemsize: int,
    *,
    stored_bytes: int | None,
    source,
    what: str,
) -> None:
    """Refuse an array whose declared size the file cannot hold or memory cannot take.

    Parameters
    ----------
    shape : sequence of int
        Declared shape of the array.
    itemsize : int
        Bytes per element as stored. [B]
    stored_bytes : int or None
        Bytes the file stores for the array (compressed size; None when unknown: only the
        budget is checked). [B]
    source : path-like
        The file, named in the message.
    what : str
        The array (``dataset /acceleration``, ``variable data``), named in the message.

    Raises
    ------
    ContractError
        Before anything is allocated, with one line naming the file, the array, the declared
        and the stored size, or the budget.
    """
    n_elements = 1
    for n in shape:
        n_elements *= int(n)
    declared = n_elements * int(itemsize)
    shown = "x".join(str(int(n)) for n in shape) or "scalar"
    if stored_bytes is not None and declared > MAX_COMPRESSION_RATIO * max(int(stored_bytes), 1):
        raise ContractError(
            [
                Violation(
                    None,
                    f"{what} declares {shown} values ({_size(declared)}) but the file stores "
                    f"{_size(stored_bytes)} for it: not read",
                )
            ],
            source=source,
            contract="accelerations",
        )
    needed = n_elements * max(int(itemsize), 8)  # read as float64
    budget = max_array_bytes()
    if needed > budget:
        raise ContractError(
            [
                Violation(
                    None,
                    f"{what} declares {shown} values ({_size(needed)} as float64), more than "
                    f"the memory budget of {_size(budget)}: not read (raise the budget with "
                    f"{MAX_ARRAY_BYTES_VARIABLE}, e.g. {MAX_ARRAY_BYTES_VARIABLE}=16G, or "
                    "split the file)",
                )
            ],
            source=source,
            contract="accelerations",
        )


def check_channel_count(n_channels: int, *, source, what: str = "the file") -> None:
    """Refuse a file with more than :data:`MAX_CHANNELS` channels (before parsing them).

    Raises
    ------
    ContractError
        Naming the file and the count.
    """
    if n_channels > MAX_CHANNELS:
        raise ContractError(
            [
                Violation(
                    None,
                    f"{what} has {n_channels} channels; an acceleration file has at most "
                    f"{MAX_CHANNELS}: not read",
                )
            ],
            source=source,
            contract="accelerations",
        )
