"""Identify's store never mixes runs or data, and crafted HDF5 files read no other file.

* Concurrent runs: a store held by a live process is refused with a message naming the
  holder (pid, host, start time); once that process dies (SIGKILL), the next run goes on.
* Changed inputs: a rerun on other data for the stored time span (another voyage with the
  same start times and channels, or a file edited in place with size and mtime restored)
  is refused; the same data under another folder are reused.
* HDF5 (MATLAB v7.3) external storage, external links and virtual datasets are refused
  before anything is read, and the pointed-at file's content never appears in a message.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main

from .voyage import CHANNELS, IDENTIFY_ARGS, RATE_HZ, write_voyage

SECRET = "SECRET-TOKEN-12345"


def _identify(inputs, out: Path, *extra: str) -> int:
    return main(["identify", *map(str, inputs), "--out", str(out), *IDENTIFY_ARGS, *extra])


# ------------------------------------------------------------------------------- the lock
def test_second_run_on_a_busy_store_is_refused_naming_the_holder(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4)
    store = tmp_path / "out" / "store"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            textwrap.dedent(
                f"""
                import sys, time
                from workbench.store import BlockStore
                store = BlockStore.open({str(store)!r}, {{}})
                print("locked", flush=True)
                time.sleep(120)
                """
            ),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert _identify([tmp_path / "voyage"], tmp_path / "out") == 1
        err = capsys.readouterr().err.strip()
        assert f"store is in use by another run (pid {holder.pid} on {socket.gethostname()}" in err
        assert "since 20" in err and len(err.splitlines()) == 1
        assert not (tmp_path / "out" / "blocks.csv").exists()
    finally:
        holder.send_signal(signal.SIGKILL)  # a killed holder leaves a stale lock file
        holder.wait()


def test_stale_lock_of_a_killed_run_does_not_block(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4)
    store = tmp_path / "out" / "store"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"from workbench.store import BlockStore\n"
            f"s = BlockStore.open({str(store)!r}, {{}})\nimport os\nos.kill(os.getpid(), 9)\n",
        ]
    )
    holder.wait()
    assert (store / "lock").exists()
    (store / "store.json").unlink()  # the killed run had only made an empty store
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    assert not (store / "lock").exists()  # released at the end of the run
    # and a second run resumes: every block is stored once
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    assert "3 already done" in capsys.readouterr().out
    poles = pd.read_parquet(tmp_path / "out" / "poles.parquet")
    assert not poles.duplicated(["block", "model_order", "frequency_hz"]).any()


# ---------------------------------------------------------------------- changed inputs
def test_other_data_for_the_stored_span_is_refused(tmp_path, capsys):
    write_voyage(tmp_path / "first", n_files=4, seed=0)
    write_voyage(tmp_path / "second", n_files=4, seed=1)  # same times and channels
    assert _identify([tmp_path / "first"], tmp_path / "out") == 0
    first = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    capsys.readouterr()
    assert _identify([tmp_path / "second"], tmp_path / "out") == 1
    err = capsys.readouterr().err.strip()
    assert "acc_000.npz: input changed since the store" in err and len(err.splitlines()) == 1
    # nothing exported from the first voyage's results under the second's name
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "out" / "selected.parquet"), first)


def test_file_edited_in_place_with_size_and_mtime_kept_is_refused(tmp_path, capsys):
    paths = write_voyage(tmp_path / "voyage", n_files=4)
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    capsys.readouterr()
    target = paths[2]
    stat = target.stat()
    record = read_accelerations(target)
    changed = record.acceleration.copy()
    changed[100, 1] += 0.5  # one sample changed: same size, same header
    write_accelerations(
        AccelerationRecord(changed, record.sampling_rate_hz, record.start_time, record.channels),
        target,
    )
    assert target.stat().st_size == stat.st_size
    os.utime(target, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 1
    assert "acc_002.npz: input changed since the store" in capsys.readouterr().err


def test_same_data_in_another_folder_is_reused(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4)
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    (tmp_path / "voyage").rename(tmp_path / "moved")
    capsys.readouterr()
    assert _identify([tmp_path / "moved"], tmp_path / "out") == 0
    assert "0 block(s) processed, 0 skipped, 3 already done" in capsys.readouterr().out


def test_voyage_extended_with_new_files_resumes(tmp_path, capsys):
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    for path in paths[4:]:
        path.rename(tmp_path / path.name)
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    for path in paths[4:]:
        (tmp_path / path.name).rename(path)
    capsys.readouterr()
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    assert "2 block(s) processed, 0 skipped, 3 already done" in capsys.readouterr().out


def test_a_file_landing_late_in_a_hole_is_identified_by_the_rerun(tmp_path, capsys):
    """Before: the blocks over the missing file were stored as skipped (gap) and the rerun
    with the file there counted them done ("0 block(s) processed, 0 skipped, 5 already
    done"): the rerun kept the hole a fresh run does not have. Now they are computed
    again, named in one line, and the tables equal a fresh run's."""
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    late = tmp_path / paths[2].name
    paths[2].rename(late)
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok", "skipped", "skipped", "ok", "ok"]
    late.rename(paths[2])
    capsys.readouterr()
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0
    out, err = capsys.readouterr()
    assert "2 block(s) processed, 0 skipped, 3 already done" in out
    assert err.splitlines() == [
        "warning: block(s) 1-2 skipped by an earlier run for data missing: the files given "
        "now hold it, identified"
    ]
    assert _identify([tmp_path / "voyage"], tmp_path / "fresh") == 0
    for name in ("selected.parquet", "poles.parquet"):
        pd.testing.assert_frame_equal(
            pd.read_parquet(tmp_path / "out" / name), pd.read_parquet(tmp_path / "fresh" / name)
        )
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert (blocks["status"] == "ok").all()


# --------------------------------------------------------------------- HDF5 external data
def _mat73(path: Path, *, start_time=None) -> None:
    """A MATLAB v7.3-style HDF5 file (column-major matrix, uint16 char arrays)."""
    n = 64
    with h5py.File(path, "w") as mat:
        mat["acceleration"] = np.random.default_rng(0).standard_normal((n, 4)).T
        mat["sampling_rate_hz"] = np.array([[RATE_HZ]])
        chans = [
            mat.create_dataset(f"#refs#/c{j}", data=np.array([ord(ch) for ch in c], "u2"))
            for j, c in enumerate(CHANNELS)
        ]
        mat.create_dataset("channels", data=np.array([c.ref for c in chans]), dtype=h5py.ref_dtype)
        if start_time is None:
            text = "2026-03-01T00:00:00Z"
            mat["start_time"] = np.array([ord(ch) for ch in text], dtype="u2")
        else:
            start_time(mat)


@pytest.fixture
def secret(tmp_path) -> Path:
    path = tmp_path / "secret.txt"
    path.write_bytes(SECRET.encode("utf-16-le"))
    return path


def test_plain_mat73_file_is_valid(tmp_path, capsys):
    _mat73(tmp_path / "ok.mat")
    assert main(["validate", "accelerations", str(tmp_path / "ok.mat")]) == 0
    assert "64 samples x 4 channels at 32 Hz" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("kind", "fragment"),
    [
        ("external", "HDF5 external storage"),
        ("link", "HDF5 external link"),
        ("virtual", "HDF5 virtual dataset"),
    ],
)
def test_hdf5_data_in_another_file_is_refused_unread(tmp_path, secret, capsys, kind, fragment):
    n_chars = len(SECRET)

    def pointing(mat):
        if kind == "external":
            mat.create_dataset(
                "start_time", shape=(n_chars,), dtype="u2", external=[(str(secret), 0, 2 * n_chars)]
            )
        elif kind == "link":
            with h5py.File(tmp_path / "other.h5", "w") as other:
                other["x"] = np.frombuffer(secret.read_bytes(), dtype="u2")
            mat["start_time"] = h5py.ExternalLink(str(tmp_path / "other.h5"), "/x")
        else:
            with h5py.File(tmp_path / "other.h5", "w") as other:
                other["x"] = np.frombuffer(secret.read_bytes(), dtype="u2")
            layout = h5py.VirtualLayout(shape=(n_chars,), dtype="u2")
            layout[:] = h5py.VirtualSource(str(tmp_path / "other.h5"), "x", shape=(n_chars,))
            mat.create_virtual_dataset("start_time", layout)

    path = tmp_path / "crafted.mat"
    _mat73(path, start_time=pointing)
    assert main(["validate", "accelerations", str(path)]) == 1
    err = capsys.readouterr().err
    assert fragment in err and "start_time" in err and len(err.strip().splitlines()) == 1
    assert SECRET not in err
    # identify refuses the file the same way
    assert _identify([path], tmp_path / "out") == 1
    err = capsys.readouterr().err
    assert fragment in err and SECRET not in err


def test_blocks_stored_twice_by_an_unlocked_past_run_are_read_once(tmp_path):
    """Stores written by two concurrent runs before stores were locked hold every block
    twice; reading (and so exporting) takes each block from one batch only."""
    from workbench.store import BlockStore

    start = pd.Timestamp("2026-03-01T00:00Z")

    def batch(blocks, value):
        status = pd.DataFrame({"block": blocks, "block_start": start, "status": "ok", "reason": ""})
        rows = pd.DataFrame(
            {
                "block": np.repeat(blocks, 2),
                "block_start": start,
                "model_order": np.tile([2, 4], len(blocks)),
                "value": value,
            }
        )
        return status, {"poles": rows}

    with BlockStore.open(tmp_path, {}) as store:
        store.write_batch(*batch([0, 1, 2], 1.0))
        store.write_batch(*batch([1, 2, 3], 2.0))  # the second run's copy of blocks 1, 2
        poles = store.read("poles")
        assert poles["block"].tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
        assert poles.groupby("block")["value"].nunique().max() == 1
        chunks = pd.concat(store.read_chunks("poles", blocks_per_chunk=2), ignore_index=True)
        pd.testing.assert_frame_equal(chunks, poles)
        assert store.read("blocks")["block"].tolist() == [0, 1, 2, 3]


# ------------------------------------------------------------------ file-system errors
def test_disk_full_on_export_is_one_line_and_keeps_the_store(tmp_path, capsys, monkeypatch):
    import errno

    import workbench.identification.export as export

    write_voyage(tmp_path / "voyage", n_files=4)

    def full(frame, path):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(export, "_write_csv", full)
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith(".csv: No space left on device") and len(err.splitlines()) == 1
    assert not (tmp_path / "out" / "store" / "lock").exists()
    monkeypatch.undo()
    assert _identify([tmp_path / "voyage"], tmp_path / "out") == 0  # nothing computed is lost
    assert "0 block(s) processed, 0 skipped, 3 already done" in capsys.readouterr().out


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root ignores modes")
def test_read_only_output_folder_is_one_line(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4)
    (tmp_path / "out").mkdir()
    (tmp_path / "out").chmod(0o500)
    try:
        assert _identify([tmp_path / "voyage"], tmp_path / "out") == 1
    finally:
        (tmp_path / "out").chmod(0o700)
    err = capsys.readouterr().err.strip()
    assert "Permission denied" in err and len(err.splitlines()) == 1


def test_input_spans_touching_by_rounding_are_not_a_change(tmp_path):
    """File ends computed as n / rate may pass the next file's start by nanoseconds; times
    come with and without fractions. Neither makes a new adjacent file a changed input."""
    from workbench.errors import WorkbenchError
    from workbench.store import BlockStore

    def fingerprint(k: int, digest: str, end_s: float) -> dict:
        start = pd.Timestamp("2026-03-01T00:00Z") + pd.Timedelta(seconds=300 * k)
        end = start + pd.Timedelta(seconds=end_s)
        return {"path": f"f{k}", "start": start.isoformat(), "end": end.isoformat(),
                "size": 10, "mtime_ns": 0, "sha256": digest}  # fmt: skip

    with BlockStore.open(tmp_path, {}) as store:
        store.check_inputs([fingerprint(0, "a", 300.00000001)])
        store.check_inputs([fingerprint(0, "a", 300.00000001), fingerprint(1, "b", 300.0)])
        with pytest.raises(WorkbenchError, match="f1: input changed"):
            store.check_inputs([fingerprint(1, "c", 300.0)])
