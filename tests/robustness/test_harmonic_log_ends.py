"""A ship log that ends before the recordings leaves the last blocks' shaft harmonics
unchecked: identify says which blocks (and tracking keeps a line seen only there out).

Before: ``identify --dship`` marked the harmonics of the blocks the log covers and said
only "harmonics (orders 1, 2, 3 of the logged shaft speed): 14 of 283 selected modes ...
marked" - on a 3-h voyage whose log ended at 1.5 h, 31 with the whole log: the harmonics
of the unlogged blocks went into tracking as hull modes, without a word.

The voyage is the small one of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute; 6 files give blocks 0-4); the log, one row a second, has
the shaft turning at the first mode's 3.1 Hz / 2 for its first 150 s only.
"""

from __future__ import annotations

import json

import pandas as pd

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, T0, write_voyage


def _log(path, seconds: int) -> None:
    times = pd.date_range(T0.tz_localize(None), periods=seconds, freq="1s")
    rows = [f"{t:%Y-%m-%dT%H:%M:%S}\t10.0\t93.0" for t in times]
    path.write_text("\n".join(["Date/Time\tSpeed [kn]\tShaft speed [rpm]", *rows]) + "\n")


def test_blocks_past_the_end_of_the_log_are_named(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=6)
    _log(tmp_path / "dship.tsv", 150)
    argv = ["identify", str(tmp_path / "voyage"), "--out", str(tmp_path / "out")]
    assert main([*argv, "--dship", str(tmp_path / "dship.tsv"), *IDENTIFY_ARGS]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "ship log:" in line]
    # block 2 (120-240 s) has 30 s of the log: under half of it, not tested
    assert warned == [
        "warning: ship log: no usable shaft speed or speed over block(s) 2-4 (3 of 5 blocks): "
        "harmonics there cannot be told from modes; tracking leaves out a line seen (almost) "
        "only there"
    ]
    shaft = pd.read_csv(tmp_path / "out" / "shaft.csv")
    assert shaft["shaft_rpm"].isna().tolist() == [False, False, True, True, True]
    selected = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    checked = selected.groupby("block")["harmonic_checked"].first()
    assert checked.tolist() == [True, True, False, False, False]
    summary = json.loads((tmp_path / "out" / "harmonics.json").read_text(encoding="utf-8"))
    assert summary["method"] == "shaft speed"


def test_a_log_covering_every_block_says_nothing_more(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=6)
    _log(tmp_path / "dship.tsv", 360)
    argv = ["identify", str(tmp_path / "voyage"), "--out", str(tmp_path / "out")]
    assert main([*argv, "--dship", str(tmp_path / "dship.tsv"), *IDENTIFY_ARGS]) == 0
    assert "ship log: no shaft speed" not in capsys.readouterr().err
