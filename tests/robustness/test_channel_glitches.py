"""Infinite or implausible values (|a| > 500 m/s²) in one channel of one acceleration file
are that channel's fault in that file (an ADC overflow, a loose connector), not a damaged
file: identify sets the channel to NaN for the file, drops it from the blocks holding the
file (as a NaN channel), keeps the other channels and names the file and channel once.

Before: the file was "unreadable (column 'acceleration': infinite values in channel(s)
...)" and its blocks were skipped for every channel. A file where every channel is
implausible (wrong units) is still refused, and the contract still refuses both.

Voyages of :mod:`tests.robustness.voyage`: block k needs files k and k + 1.
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from data_contracts import ContractError, read_accelerations
from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

GLITCHED = 3
TOUCHING = {2, 3}


def _edit(path, change) -> None:
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays["acceleration"])
    np.savez(path, **arrays)


def _inf(a):
    a[a.shape[0] // 3, 2] = np.inf


def _huge(a):
    a[100:110, 2] = 1e6


def _identify(capsys, voyage, out, rate):
    status = main(["identify", str(voyage), "--out", str(out), *IDENTIFY_ARGS, "--rate", rate])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize("rate", ["native", "16"], ids=["per block", "per file"])
@pytest.mark.parametrize(
    ("glitch", "why"), [(_inf, "infinite values"), (_huge, "|a| above 500 m/s²")]
)
def test_a_glitch_in_one_channel_drops_that_channel_only(tmp_path, capsys, glitch, why, rate):
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    channel = read_accelerations(paths[GLITCHED]).channels[2]
    shutil.copytree(tmp_path / "voyage", tmp_path / "nan")
    _edit(paths[GLITCHED], glitch)
    _edit(
        tmp_path / "nan" / paths[GLITCHED].name, lambda a: a.__setitem__((slice(None), 2), np.nan)
    )
    with pytest.raises(ContractError, match=f"in channel\\(s\\) {channel}"):
        read_accelerations(paths[GLITCHED])  # the contract (and validate) still say it

    status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out", rate)
    assert status == 0, err
    assert "unreadable" not in err + out
    assert "7 block(s) processed, 0 skipped" in out
    assert (
        f"note (2): {paths[GLITCHED].name}: channel {channel} blanked ({why}), "
        "dropped for the file" in out
    )
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert (blocks["status"] == "ok").all()
    faults = pd.read_csv(tmp_path / "out" / "faults.csv")
    assert set(faults.loc[faults["channel"] == channel, "block"]) == TOUCHING
    channels = pd.read_csv(tmp_path / "out" / "channels.csv")
    held = channels[channels["block"].isin(TOUCHING)]
    assert channel not in set(held["channel"]) and held["block"].nunique() == 2

    assert _identify(capsys, tmp_path / "nan", tmp_path / "reference", rate)[0] == 0
    # the blocks holding the file as with the channel NaN there (per file, the neighbours'
    # blocks differ: their filter padding takes the file's real samples, not NaN)
    for kind in ("selected", "poles"):
        ours = pd.read_parquet(tmp_path / "out" / f"{kind}.parquet")
        theirs = pd.read_parquet(tmp_path / "reference" / f"{kind}.parquet")
        ours = ours[ours["block"].isin(TOUCHING)].reset_index(drop=True)
        theirs = theirs[theirs["block"].isin(TOUCHING)].reset_index(drop=True)
        assert len(ours), kind
        pd.testing.assert_frame_equal(ours, theirs, check_exact=True)


def test_every_channel_implausible_is_still_refused(tmp_path, capsys):
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    _edit(paths[GLITCHED], lambda a: a.__imul__(1e5))  # mm/s²-like: wrong units
    status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out", "native")
    assert status == 0, err
    assert f"{paths[GLITCHED]}: unreadable (" in err
    assert "5 block(s) processed, 2 skipped" in out


def _inf_at_end(a):
    a[-40, 2] = np.inf  # 1.25 s before the file's end: inside the next file's filter padding


def _huge_at_end(a):
    a[-50:-40, 2] = 1e6


@pytest.mark.parametrize(
    ("glitch", "why"), [(_inf_at_end, "infinite values"), (_huge_at_end, "|a| above 500 m/s²")]
)
def test_a_glitch_in_a_neighbours_padding_is_blanked_there(tmp_path, capsys, glitch, why):
    """File 4 is filtered padded with file 3's last seconds (per file: 16 Hz from 32 Hz).
    Those rows obey the rule of file 3 itself: the channel is NaN in them, as in the run with
    the channel NaN throughout file 3 (there and here the padded channel cannot be bridged:
    block 4, files 4 and 5, is built on its own from its raw files).

    Main read the padding raw: the 1e6 spike rang into file 4's channel (block 4's modes
    differed from the run with the channel NaN, 3.0992 -> 3.1015 Hz); an infinite value made
    file 4's filtered channel NaN, which gave the same blocks by another way (kept here as
    the case the rule covers too)."""
    paths = write_voyage(tmp_path / "voyage", n_files=8)
    shutil.copytree(tmp_path / "voyage", tmp_path / "nan")
    _edit(paths[GLITCHED], glitch)
    _edit(
        tmp_path / "nan" / paths[GLITCHED].name, lambda a: a.__setitem__((slice(None), 2), np.nan)
    )
    status, out, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out", "16")
    assert status == 0, err
    assert f"{paths[GLITCHED].name}: channel acc03 blanked ({why})" in out
    assert _identify(capsys, tmp_path / "nan", tmp_path / "reference", "16")[0] == 0
    # blocks 2 and 3 hold file 3; block 4 holds file 4, padded with file 3's last seconds;
    # block 1's file 2 is padded with file 3's first seconds (real samples here, NaN there)
    later = {2, 3, 4, 5, 6}
    for kind in ("selected", "poles"):
        ours = pd.read_parquet(tmp_path / "out" / f"{kind}.parquet")
        theirs = pd.read_parquet(tmp_path / "reference" / f"{kind}.parquet")
        ours = ours[ours["block"].isin(later)].reset_index(drop=True)
        theirs = theirs[theirs["block"].isin(later)].reset_index(drop=True)
        assert set(ours["block"]) >= {4}, kind
        pd.testing.assert_frame_equal(ours, theirs, check_exact=True)
