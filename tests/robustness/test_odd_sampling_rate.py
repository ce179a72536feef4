"""A file at another sampling rate than the voyage's is named as the odd one, also when it
is the first file.

Before: the first file's rate was the voyage's, so a first file at another rate made
identify name the second, good file ("acc_001.npz: sampling rate 32 Hz differs from 64 Hz of
acc_000.npz"): the user was sent to a file with nothing wrong. Now the rate most files have
is the voyage's (ties: the earliest file's, as before)."""

from __future__ import annotations

import numpy as np
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage


def _at_twice_the_rate(path) -> None:
    """The file as a recorder set to twice the rate writes it (each sample repeated)."""
    record = read_accelerations(path)
    twice = AccelerationRecord(
        np.repeat(record.acceleration, 2, axis=0),
        2 * record.sampling_rate_hz,
        record.start_time,
        record.channels,
    )
    write_accelerations(twice, path)


@pytest.mark.parametrize("odd", [0, 3], ids=["first file", "later file"])
def test_the_file_at_another_rate_is_named_with_the_rate_of_the_others(tmp_path, capsys, odd):
    """The odd file is named also when it is the first (before: the second, good file was
    named as differing from the first)."""
    files = write_voyage(tmp_path / "acc", n_files=5)
    _at_twice_the_rate(files[odd])
    code = main(["identify", str(tmp_path / "acc"), "--out", str(tmp_path / "out"), *IDENTIFY_ARGS])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert err == [
        f"error: {files[odd]}: sampling rate 64 Hz differs from 32 Hz of 4 of the 5 files"
    ]
