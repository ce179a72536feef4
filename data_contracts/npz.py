"""The sample array of a canonical ``.npz`` acceleration file, without loading it.

Planning a voyage needs only each file's header (shape and dtype of ``acceleration``), and
cutting a block needs only some of its rows. :func:`read_sample_header` parses the ``.npy``
header of the ``acceleration`` member once; :func:`read_sample_rows` reads rows in place
when the member is stored uncompressed (as :func:`~data_contracts.write_accelerations`
writes it). Whole files are read by :func:`~data_contracts.read_accelerations`.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "NpzSampleHeader",
    "check_sample_header",
    "read_sample_header",
    "read_checked_arrays",
    "read_sample_headers",
    "read_sample_rows",
    "read_stored_samples",
]

_MEMBER = "acceleration.npy"
_LOCAL_HEADER = b"PK\x03\x04"


@dataclass(frozen=True)
class NpzSampleHeader:
    """What the ``.npy`` header of the ``acceleration`` member says.

    Parameters
    ----------
    shape : tuple of int
    dtype : numpy.dtype
    fortran_order : bool
    header_bytes : int
        Length of the ``.npy`` header (magic included): the samples start there. [B]
    member_size, compressed_size : int
        Size of the member uncompressed and as stored in the archive. [B]
    data_offset : int or None
        Offset of the first sample in the ``.npz`` file when the member is stored
        uncompressed, else None. [B]
    crc32 : int or None
        The member's CRC-32 as the archive records it (None where not read).
    """

    shape: tuple[int, ...]
    dtype: np.dtype
    fortran_order: bool
    header_bytes: int
    member_size: int
    compressed_size: int
    data_offset: int | None
    crc32: int | None = None

    @property
    def claimed_bytes(self) -> int:
        """Bytes the member must hold for the samples its header claims. [B]"""
        return self.header_bytes + int(np.prod(self.shape)) * self.dtype.itemsize


def _read_npy_header(handle) -> tuple[tuple[int, ...], bool, np.dtype]:
    version = np.lib.format.read_magic(handle)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(handle)
    return np.lib.format.read_array_header_2_0(handle)


def read_sample_header(path: str | os.PathLike, member: str = _MEMBER) -> NpzSampleHeader:
    """Header of the ``acceleration`` array (or of the array *member*, ``channels.npy``)
    of the ``.npz`` file *path*.

    Raises
    ------
    KeyError
        The archive has no such member.
    OSError, ValueError, zipfile.BadZipFile
        The file or its header cannot be read.
    """
    return read_sample_headers(path, (member,))[member]


def read_sample_headers(
    path: str | os.PathLike, members: tuple[str, ...]
) -> dict[str, NpzSampleHeader]:
    """Headers of the arrays *members* (``acceleration.npy``, ...) of the ``.npz`` file
    *path*, the archive opened once. Errors as :func:`read_sample_header`."""
    path = Path(path)
    headers = {}
    with zipfile.ZipFile(path) as archive, open(path, "rb") as raw:
        for name in members:
            member = archive.getinfo(name)
            with archive.open(member) as handle:
                shape, fortran, dtype = _read_npy_header(handle)
                header_bytes = handle.tell()
            offset = None
            if member.compress_type == zipfile.ZIP_STORED:
                raw.seek(member.header_offset)
                local = raw.read(30)
                if local[:4] == _LOCAL_HEADER:
                    name_length = int.from_bytes(local[26:28], "little")
                    extra_length = int.from_bytes(local[28:30], "little")
                    offset = member.header_offset + 30 + name_length + extra_length + header_bytes
            headers[name] = NpzSampleHeader(
                tuple(int(n) for n in shape),
                np.dtype(dtype),
                bool(fortran),
                int(header_bytes),
                int(member.file_size),
                int(member.compress_size),
                offset,
                int(member.CRC),
            )
    return headers


def read_checked_arrays(path: str | os.PathLike, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The arrays *keys* (``channels``, ...) of the ``.npz`` file *path*, each header
    checked (:func:`check_sample_header`, no object arrays) before its array is allocated;
    the archive opened once.

    Raises
    ------
    ContractError
        For a header claiming more than the archive holds or the memory budget.
    KeyError, OSError, ValueError, zipfile.BadZipFile
        For a missing member, an object array or an unreadable file.
    """
    values = {}
    with zipfile.ZipFile(path) as archive:
        for key in keys:
            member = archive.getinfo(f"{key}.npy")
            with archive.open(member) as handle:
                shape, fortran, dtype = _read_npy_header(handle)
                header = NpzSampleHeader(
                    tuple(int(n) for n in shape),
                    np.dtype(dtype),
                    bool(fortran),
                    int(handle.tell()),
                    int(member.file_size),
                    int(member.compress_size),
                    None,
                )
                if header.dtype.hasobject:
                    raise ValueError(f"array {key} holds Python objects")
                check_sample_header(header, path, f"array {key}")
                count = int(np.prod(header.shape))
                data = handle.read(count * header.dtype.itemsize)
                if len(data) != count * header.dtype.itemsize:
                    raise ValueError(f"array {key} is cut short")
                values[key] = np.frombuffer(data, dtype=header.dtype).reshape(
                    header.shape, order="F" if header.fortran_order else "C"
                )
    return values


def check_sample_header(header: NpzSampleHeader, path: str | os.PathLike, what: str) -> None:
    """Refuse an array whose ``.npy`` header claims more than its archive member holds, or
    more than the memory budget (:func:`data_contracts.limits.check_declared_size`).

    Raises
    ------
    ContractError
        Naming the file and the array, before the array is allocated.
    """
    from ._core import ContractError, Violation
    from .limits import check_declared_size

    path = Path(path)
    # the member must hold the samples its header claims, the stored bytes lie within the
    # file, and the compression ratio stays within deflate's (checked with the budget)
    if header.member_size < header.claimed_bytes or header.compressed_size > path.stat().st_size:
        shown = "x".join(map(str, header.shape)) or "scalar"
        raise ContractError(
            [Violation(None, f"{what} declares {shown} values but the file holds fewer: not read")],
            source=path,
            contract="accelerations",
        )
    check_declared_size(
        header.shape,
        header.dtype.itemsize,
        stored_bytes=header.compressed_size,
        source=path,
        what=what,
    )


def read_sample_rows(path: str | os.PathLike, first: int, stop: int) -> np.ndarray | None:
    """Rows ``[first, stop)`` of the ``acceleration`` array, read in place.

    Returns None when the rows cannot be read in place (compressed member, Fortran order,
    object dtype, not 2-D, unreadable): read the whole file then.
    """
    try:
        header = read_sample_header(path)
        if (
            header.data_offset is None
            or header.fortran_order
            or len(header.shape) != 2
            or header.dtype.hasobject
        ):
            return None
        n_channels = header.shape[1]
        with open(path, "rb") as handle:
            handle.seek(header.data_offset + first * n_channels * header.dtype.itemsize)
            rows = np.fromfile(handle, dtype=header.dtype, count=(stop - first) * n_channels)
        return rows.reshape(stop - first, n_channels)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return None


def read_stored_samples(path: str | os.PathLike, header: NpzSampleHeader) -> np.ndarray | None:
    """The whole array of an uncompressed member read straight into its array (one copy
    from the file, where ``np.load`` copies each chunk twice), its CRC-32 checked against
    the archive's as ``zipfile`` checks it.

    *header* is the member's header from :func:`read_sample_headers` (already checked with
    :func:`check_sample_header`). Returns None where the member is not read this way
    (compressed, object dtype, no CRC recorded): read it with ``np.load`` then.

    Raises
    ------
    ValueError
        The member is cut short or its CRC-32 differs from the archive's (a damaged file).
    OSError
        The file cannot be read.
    """
    if header.data_offset is None or header.crc32 is None or header.dtype.hasobject:
        return None
    count = int(np.prod(header.shape))
    array = np.empty(count, dtype=header.dtype)
    data = array.view(np.uint8)  # the bytes, whatever the byte order
    start = header.data_offset - header.header_bytes  # the member's first byte
    with open(path, "rb") as handle:
        handle.seek(start)
        npy_header = handle.read(header.header_bytes)
        read = handle.readinto(data)
        rest = handle.read(max(header.member_size - header.claimed_bytes, 0))
    if len(npy_header) != header.header_bytes or read != data.nbytes:
        raise ValueError(f"{path}: array data cut short")
    crc = zlib.crc32(rest, zlib.crc32(data, zlib.crc32(npy_header)))
    if crc != header.crc32 or len(rest) != header.member_size - header.claimed_bytes:
        raise ValueError(f"{path}: bad CRC-32 of the array data")
    return array.reshape(header.shape, order="F" if header.fortran_order else "C")
