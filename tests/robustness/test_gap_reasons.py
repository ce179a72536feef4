"""A block skipped for a hole in the recordings names the files on either side of the
hole, in ``identify``'s ``blocks.csv`` and the monitor's ``data_health.parquet`` alike.

Before: the block builder, which sees only the block's own files, named the edge of the
data instead ("gap of 60.0 s between acc_001.npz and the end of the data" for a block
whose next file, acc_003.npz, was there), and a block wholly inside the hole said "no
acceleration files"; the voyage's plan knew the files beyond the block all along.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): 6 files give blocks 0-4, block k holding files k and k + 1.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from workbench.blocks import BlockGrid
from workbench.cli import main
from workbench.signals import load_block

from .voyage import IDENTIFY_ARGS, T0, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


@pytest.mark.parametrize(
    ("missing", "reasons"),
    [
        (
            [2],
            [
                "",
                "gap of 60.0 s between acc_001.npz and acc_003.npz",
                "gap of 60.0 s between acc_001.npz and acc_003.npz",
                "",
                "",
            ],
        ),
        (
            [2, 3],
            [
                "",
                "gap of 60.0 s between acc_001.npz and acc_004.npz",
                "no data (gap between acc_001.npz and acc_004.npz)",
                "gap of 60.0 s between acc_001.npz and acc_004.npz",
                "",
            ],
        ),
    ],
    ids=["one file", "two files"],
)
def test_a_hole_is_named_by_the_files_on_either_side(tmp_path, capsys, missing, reasons):
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    for k in missing:
        paths[k].unlink()
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "voyage"), "--out", str(out), *IDENTIFY_ARGS]) == 0
    blocks = pd.read_csv(out / "blocks.csv", keep_default_na=False)
    assert blocks["reason"].tolist() == reasons
    state = tmp_path / "state"
    argv = ["monitor", "--watch", str(tmp_path / "voyage"), "--state", str(state)]
    assert main([*argv, *MONITOR_ARGS]) == 0
    capsys.readouterr()
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["reason"].tolist() == reasons


@pytest.mark.parametrize(
    ("missing", "reasons"),
    [
        ([2], ["gap of 60.0 s between acc_001.npz and acc_003.npz"] * 2),
        (
            [2, 3],
            [
                "gap of 60.0 s between acc_001.npz and acc_004.npz",
                "no data (gap between acc_001.npz and acc_004.npz)",
                "gap of 60.0 s between acc_001.npz and acc_004.npz",
            ],
        ),
    ],
    ids=["one file", "two files"],
)
def test_load_block_names_the_hole_as_the_plan_does(tmp_path, missing, reasons):
    """The library's load_block given the voyage's files. Before, it planned only the
    files touching the block: "gap of 60.0 s between acc_001.npz and the end of the data"
    (block 1), "... between the start of the data and acc_003.npz" (block 2), and "outside
    the span of the acceleration files" for block 2 wholly inside a 2-file hole."""
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    for k in missing:
        paths[k].unlink()
    files = [p for p in paths if p.exists()]
    grid = BlockGrid.from_first_time(T0, 120.0, 60.0)
    got = [load_block(files, k, grid).skipped_reason for k in range(1, 2 + len(missing))]
    assert got == reasons
    assert load_block(files, 0, grid).skipped_reason == ""  # the blocks beside it are built
    assert load_block(files, 2 + len(missing), grid).skipped_reason == ""


def test_a_file_without_samples_is_named_unreadable_not_a_hole(tmp_path, capsys):
    """Before: a file of 0 samples (a recorder stopped right after writing its header)
    passed the header read as a file of no length: identify skipped its blocks for "gap of
    60.0 s between acc_002.npz and the end of the data" without a word on the file, which
    ``validate`` refuses ("needs at least 2 samples, got 0")."""
    paths = write_voyage(tmp_path / "voyage", n_files=6)
    with np.load(paths[2], allow_pickle=False) as archive:
        record = dict(archive)
    with open(paths[2], "wb") as handle:
        np.savez(handle, **{**record, "acceleration": record["acceleration"][:0]})
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "voyage"), "--out", str(out), *IDENTIFY_ARGS]) == 0
    why = f"{paths[2]}: unreadable (column 'acceleration': needs at least 2 samples, got 0)"
    assert capsys.readouterr().err.splitlines() == [
        f"warning: {why}; left out: block(s) 1-2 not identified"
    ]
    blocks = pd.read_csv(out / "blocks.csv", keep_default_na=False)
    assert blocks["reason"].tolist() == ["", why, why, "", ""]
