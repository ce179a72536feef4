"""SHA-256 of input files hashed ahead while the command line imports
(workbench.fingerprints): the same digest as hashing when asked, and never a stale one."""

from __future__ import annotations

import hashlib
import os

import pytest

from workbench import fingerprints


@pytest.fixture(autouse=True)
def _fresh():
    fingerprints.stop_prefetch()
    fingerprints._digests.clear()
    yield
    fingerprints.stop_prefetch()
    fingerprints._digests.clear()


def _finish():
    """Let the prefetching thread hash everything, then end it."""
    if fingerprints._thread is not None:
        fingerprints._thread.join()
    fingerprints.stop_prefetch()


def _files(folder, n=3, size=100_000):
    paths = []
    for k in range(n):
        path = folder / f"acc_{k}.npz"
        path.write_bytes(os.urandom(size))
        paths.append(path)
    return paths


def test_prefetched_digests_equal_hashlib_and_are_used(tmp_path):
    paths = _files(tmp_path)
    (tmp_path / "notes.csv").write_text("not an acceleration archive")
    fingerprints.prefetch([str(tmp_path), "--out", str(tmp_path / "elsewhere.npz")])
    _finish()
    assert sorted(fingerprints._digests) == sorted(os.path.realpath(p) for p in paths)
    for path in paths:
        expected = hashlib.sha256(path.read_bytes()).hexdigest()
        assert fingerprints._digests[os.path.realpath(path)][1] == expected
        assert fingerprints.sha256(path) == expected
    assert fingerprints._thread is None


def test_a_file_changed_after_prefetching_is_hashed_again(tmp_path):
    path, other = _files(tmp_path, n=2)
    fingerprints.prefetch([str(path), str(other)])
    _finish()
    stale = fingerprints._digests[os.path.realpath(path)][1]
    path.write_bytes(os.urandom(100_000))  # same size, new content
    fresh = hashlib.sha256(path.read_bytes()).hexdigest()
    assert fresh != stale
    assert fingerprints.sha256(path) == fresh
    assert fingerprints.sha256(other) == hashlib.sha256(other.read_bytes()).hexdigest()


def test_only_npz_files_named_before_the_first_option_are_hashed_ahead(tmp_path):
    first, second = _files(tmp_path, n=2)
    fingerprints.prefetch(["--band", str(first)])
    assert fingerprints._thread is None  # an option first: nothing to do
    fingerprints.prefetch([str(tmp_path / "missing.npz"), str(second)])
    _finish()
    assert list(fingerprints._digests) == [os.path.realpath(second)]
    # a file never prefetched is hashed when asked
    assert fingerprints.sha256(first) == hashlib.sha256(first.read_bytes()).hexdigest()


def test_stop_drops_the_file_being_hashed(tmp_path, monkeypatch):
    monkeypatch.setattr(fingerprints, "_CHUNK_BYTES", 1024)
    (path,) = _files(tmp_path, n=1, size=4096)
    fingerprints._stop.set()  # stopped before the first chunk
    assert fingerprints.file_sha256(path, fingerprints._stop) is None
    fingerprints._stop.clear()
    assert fingerprints.file_sha256(path) == hashlib.sha256(path.read_bytes()).hexdigest()
    with pytest.raises(OSError):
        fingerprints.sha256(tmp_path / "missing.npz")


def test_the_launcher_prefetches_for_identify_only(tmp_path, monkeypatch):
    import workbench.cli
    from workbench import launch

    seen = []
    monkeypatch.setattr(fingerprints, "prefetch", seen.append)
    monkeypatch.setattr(workbench.cli, "main", lambda argv: len(argv))
    assert launch.main(["identify", str(tmp_path), "--out", "x"]) == 4
    assert launch.main(["track", str(tmp_path)]) == 2
    assert seen == [[str(tmp_path), "--out", "x"]]
