"""Voyage-scale identification: kill -9 and resume, Dask cluster path, exported tables.

A short simulated voyage (2 h: 24 five-minute files, 21 blocks) is identified three ways:
uninterrupted in-process; killed with SIGKILL while running and then run again; on a real
Dask ``LocalCluster``. All three must give exactly the same tables.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from data_contracts import POLES, read_table
from workbench.identification import IdentifyOptions, identify_voyage

#: Small but real settings: 10 block rows, orders 4..40 (fast enough for a test).
OPTIONS = IdentifyOptions(block_rows=10, orders=tuple(range(4, 41, 2)))
HOURS = 2.0


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    from workbench.simulate import simulate_voyage

    root = tmp_path_factory.mktemp("voyage")
    simulation = simulate_voyage(root, seed=5, hours=HOURS)
    return simulation


@pytest.fixture(scope="module")
def reference(voyage, tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    result = identify_voyage([voyage.out_dir], out, options=OPTIONS, scheduler="synchronous")
    return out, result


def _tables(out: Path) -> dict[str, pd.DataFrame]:
    return {
        "poles": read_table(out / "poles.parquet", POLES),
        "selected": pd.read_parquet(out / "selected.parquet"),
        "blocks": pd.read_csv(out / "blocks.csv"),
    }


def test_reference_run_covers_every_block(reference, voyage):
    out, result = reference
    tables = _tables(out)
    n_blocks = voyage.n_blocks
    assert result.run.processed + result.run.skipped == n_blocks
    assert sorted(tables["blocks"]["block"]) == list(range(n_blocks))
    assert tables["selected"]["block"].nunique() >= n_blocks - 1
    # acc12 is dead during the voyage's second hour: the faults table says so
    faults = pd.read_csv(out / "faults.csv")
    assert "acc12" in set(faults["channel"])


def _identify_command(voyage, out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "workbench.cli",
        "identify",
        str(voyage.out_dir),
        "--out",
        str(out),
        "--block-rows",
        "10",
        "--min-order",
        "4",
        "--max-order",
        "40",
        "--scheduler",
        "synchronous",
        "--batch-blocks",
        "2",
        "--quiet",
    ]


def test_kill_and_resume_gives_identical_tables(voyage, reference, tmp_path):
    """SIGKILL while identifying, then the same command again: nothing lost, nothing
    recomputed that was stored, and the final tables equal those of an uninterrupted run."""
    ref_out, _ = reference
    out = tmp_path / "run"
    command = _identify_command(voyage, out)
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    blocks_dir = out / "store" / "blocks"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # wait until at least two batches are stored
        if len(list(blocks_dir.glob("day=*/*.parquet"))) >= 2 or process.poll() is not None:
            break
        time.sleep(0.05)
    assert process.poll() is None, "the job finished before it could be killed"
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert process.returncode == -signal.SIGKILL
    stored_before = len(list(blocks_dir.glob("day=*/*.parquet")))
    assert stored_before >= 2

    finished = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert finished.returncode == 0, finished.stderr
    already = int(finished.stdout.split(" already done")[0].rsplit(",", 1)[1].strip().split()[0])
    assert already >= 2 * stored_before - 2  # the stored blocks were not recomputed

    ours, theirs = _tables(out), _tables(ref_out)
    for kind in ours:
        pd.testing.assert_frame_equal(ours[kind], theirs[kind], check_exact=True, obj=kind)


def test_store_refuses_other_options(voyage, reference):
    from workbench.errors import WorkbenchError

    out, _ = reference
    other = IdentifyOptions(block_rows=12, orders=OPTIONS.orders)
    with pytest.raises(WorkbenchError, match="block_rows"):
        identify_voyage([voyage.out_dir], out, options=other, scheduler="synchronous")


def test_local_dask_cluster_gives_the_same_tables(voyage, reference, tmp_path):
    """The distributed path (a real LocalCluster with 2 worker processes) gives the same
    tables, gathered in block order whatever the completion order."""
    ref_out, _ = reference
    out = tmp_path / "dask"
    result = identify_voyage(
        [voyage.out_dir], out, options=OPTIONS, n_workers=2, blocks=range(0, 8)
    )
    assert result.run.processed + result.run.skipped == 8
    ours = _tables(out)
    theirs = _tables(ref_out)
    for kind in ("poles", "selected"):
        expected = theirs[kind][theirs[kind]["block"] < 8].reset_index(drop=True)
        pd.testing.assert_frame_equal(ours[kind], expected, check_exact=True, obj=kind)
