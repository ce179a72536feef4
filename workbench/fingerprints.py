"""SHA-256 digests of input files, hashed ahead of time where the command line names them.

``workbench identify`` records the SHA-256 of every input file in its store (a resumed run
tells changed data apart by it): for a 1-h voyage at 2048 Hz that is 1.1 GB and 0.75 s of
CPU, before any block can start. Meanwhile the command line's first second goes to
importing numpy, pandas and scipy on one core. The entry point
(:mod:`workbench.launch`) therefore calls :func:`prefetch` with the command's first
arguments, which hashes the ``.npz`` files they name on a background thread while the
imports run, and :func:`sha256` takes a prefetched digest only for a file that has not
changed since it was hashed: same device, inode, size, modification and change time
before and after hashing and when asked (any write to a file moves its change time, which
no program can set back). Any other file is hashed when asked, as it always was.

Only this module's standard-library imports are paid before the command line's: it is
imported by the entry point.
"""

from __future__ import annotations

import hashlib
import os
import threading
from collections.abc import Sequence
from pathlib import Path

__all__ = ["file_sha256", "prefetch", "sha256", "stop_prefetch"]

#: Bytes hashed per read. Large, so that the hashing thread (which releases the GIL while
#: it reads and hashes) takes the GIL back rarely while the main thread imports. [B]
_CHUNK_BYTES = 16 * 2**20

_lock = threading.Lock()
_digests: dict[str, tuple[tuple, str]] = {}  # real path -> (stat key, hex digest)
_stop = threading.Event()
_thread: threading.Thread | None = None


def _stat_key(path: str | os.PathLike) -> tuple:
    status = os.stat(path)
    return (status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns, status.st_ctime_ns)


def file_sha256(path: str | os.PathLike, stop: threading.Event | None = None) -> str | None:
    """Hex SHA-256 of every byte of the file *path* (None when *stop* was set meanwhile).

    Raises
    ------
    OSError
        The file cannot be read.
    """
    digest = hashlib.sha256()
    buffer = bytearray(_CHUNK_BYTES)
    view = memoryview(buffer)
    with open(path, "rb", buffering=0) as handle:
        while True:
            if stop is not None and stop.is_set():
                return None
            size = handle.readinto(buffer)
            if not size:
                return digest.hexdigest()
            digest.update(view[:size])


def sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of the file *path*: the digest :func:`prefetch` took if the file is
    unchanged since, else hashed now.

    Raises
    ------
    OSError
        The file cannot be read.
    """
    key = _stat_key(path)
    with _lock:
        found = _digests.get(os.path.realpath(path))
    if found is not None and found[0] == key:
        return found[1]
    digest = file_sha256(path)
    assert digest is not None  # no stop event: hashed to the end
    return digest


def _hash_ahead(files: Sequence[Path]) -> None:
    for path in files:
        try:
            before = _stat_key(path)
            digest = file_sha256(path, _stop)
            if digest is None:
                return
            if _stat_key(path) == before:
                with _lock:
                    _digests[os.path.realpath(path)] = (before, digest)
        except OSError:
            continue  # hashed again when asked, which reports the error


def prefetch(arguments: Sequence[str]) -> None:
    """Start hashing, on a background thread, the ``.npz`` files named by *arguments* up
    to the first option: files, or folders holding them (not searched below). Returns at
    once; :func:`stop_prefetch` ends the thread (the process's fork of workers must not
    inherit it)."""
    global _thread
    files: list[Path] = []
    for argument in arguments:
        if argument.startswith("-"):
            break
        path = Path(argument)
        try:
            if path.is_dir():
                files += sorted(
                    p for p in path.iterdir() if p.suffix.lower() == ".npz" and p.is_file()
                )
            elif path.suffix.lower() == ".npz" and path.is_file():
                files.append(path)
        except OSError:
            continue
    if not files or _thread is not None:
        return
    _stop.clear()
    _thread = threading.Thread(
        target=_hash_ahead, args=(files,), name="workbench-prefetch", daemon=True
    )
    _thread.start()


def stop_prefetch() -> None:
    """End the prefetching thread, if any (a file being hashed is dropped; the digests
    taken so far stay)."""
    global _thread
    thread = _thread
    if thread is None:
        return
    _stop.set()
    thread.join()
    _thread = None
