"""The command line: exit codes 0/1/2, one line per problem, no tracebacks for user errors."""

from __future__ import annotations

import pandas as pd
import pytest

from data_contracts import MODAL, write_table
from workbench.cli import main


def test_help_lists_every_command(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("demo", "simulate", "validate"):
        assert command in out


def test_no_command_is_a_usage_error(capsys):
    assert main([]) == 2


def test_validate_accepts_a_valid_table(tmp_path, capsys):
    frame = pd.DataFrame(
        {
            "block": [0],
            "block_start": ["2026-01-01T00:00Z"],
            "block_end": ["2026-01-01T00:20Z"],
            "mode": [1],
            "frequency_hz": [2.9],
            "damping_ratio": [0.01],
        }
    )
    path = write_table(frame, tmp_path / "modal.csv", MODAL)
    assert main(["validate", "modal", str(path)]) == 0
    assert "valid modal file (1 rows)" in capsys.readouterr().out


def test_validate_reports_each_problem_on_one_line(tmp_path, capsys):
    path = tmp_path / "modal.csv"
    path.write_text(
        "block,block_start,mode,frequency_hz,damping_ratio\n"
        "0,2026-01-01T00:00Z,1,-2.9,0.01\n0,2026-01-01T00:00Z,2,3.1,12\n"
    )
    assert main(["validate", "modal", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"{path}: column 'block_end': required column is missing (End of the block "
        "(exclusive), UTC.)",
        f"{path}: column 'frequency_hz', row 0: values outside (0.0, 10000.0] Hz (a natural "
        "frequency lies above 0 Hz)",
        f"{path}: column 'damping_ratio', row 1: values outside [-1.0, 1.0] (damping ratios "
        "are fractions: 1.2 % is 0.012)",
    ]


def test_unreadable_file_exits_1_without_traceback(tmp_path, capsys):
    path = tmp_path / "log.tab"
    path.write_bytes(b"\x00\x01 garbage without header")
    assert main(["validate", "dship", str(path)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(path) in err


def test_verbose_shows_the_traceback(tmp_path):
    with pytest.raises(Exception, match="file not found"):
        main(["--verbose", "validate", "poles", str(tmp_path / "none.csv")])


def test_unknown_kind_is_usage_error(capsys):
    assert main(["validate", "spectra", "x"]) == 2


@pytest.mark.parametrize("command", ["identify", "forecast", "evaluate", "track", "fit", "report"])
def test_help_shows_percent_signs_once(command, capsys):
    # argparse %-formats help strings but prints descriptions as written: '%%' there is a typo
    assert main([command, "--help"]) == 0
    shown = capsys.readouterr().out
    assert "usage: workbench" in shown and "%%" not in shown
