"""The monitor's health options are checked before any block, and every option's error
names its flag.

Before: ``monitor --ewma-lambda 2`` (or ``--false-alarms-per-day -1``) started and ran
for hours; when the health chart was due to start it did not, and the state said only
"health: ewma_lambda=2.0 must be in (0, 1]" (exit 0 with ``--once``), where ``workbench
health --ewma-lambda 2`` is a usage error at once. The usage errors of the timing and
health options named the library's parameters (``poll_s=0.0 must be positive``) instead
of the flags.
"""

from __future__ import annotations

import pytest

from workbench.cli import main

from .voyage import write_voyage


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--ewma-lambda", "2", "--ewma-lambda 2.0 must be in (0, 1]"),
        ("--false-alarms-per-day", "-1", "--false-alarms-per-day -1.0 must be finite and > 0"),
        ("--poll", "0", "--poll 0.0 must be positive"),
        ("--settle", "-1", "--settle -1.0 must be a non-negative number of seconds"),
        ("--flush-after", "nan", "--flush-after nan must be a non-negative number of seconds"),
        ("--on-alarm-timeout", "0", "--on-alarm-timeout 0.0 must be a positive number of seconds"),
        ("--reference-hours", "0", "--reference-hours 0.0 must be positive"),
    ],
)
def test_a_bad_option_is_a_usage_error_naming_its_flag_before_any_work(
    tmp_path, capsys, flag, value, message
):
    watch, state = tmp_path / "watch", tmp_path / "state"
    write_voyage(watch, n_files=3)
    argv = ["monitor", "--watch", str(watch), "--state", str(state), "--once", "--quiet"]
    assert main([*argv, flag, value]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [f"workbench: error: {message}"]
    assert not state.exists()
