"""Every option declared once: ``monitor`` takes its identification, tracking, forecast and
health options from the declarations of ``identify``, ``track``, ``forecast`` and ``health``
(flags, types, defaults, help), and ``--config`` reaches both the same way."""

from __future__ import annotations

import argparse

import pytest

from workbench.arguments import copy_flags
from workbench.cli import build_parser, identify_options, parse_arguments
from workbench.cli import monitoring as M
from workbench.config import write_config

COPIED = {
    "identify": M.MONITOR_IDENTIFY_FLAGS + ("dship_columns",),
    "track": M.MONITOR_TRACK_FLAGS,
    "forecast": M.MONITOR_FORECAST_FLAGS,
    "health": M.MONITOR_HEALTH_FLAGS,
}
#: The help texts the monitor rewords: its --mac-min serves track and forecast; its
#: --block-minutes auto and --cases say when a live block's length is decided.
REWORDED = {"mac_min", "block_minutes", "cases"}


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def _option(parser: argparse.ArgumentParser, dest: str) -> argparse.Action:
    (action,) = [a for a in parser._actions if a.dest == dest and a.option_strings]
    return action


@pytest.mark.parametrize("command", sorted(COPIED))
def test_the_monitor_takes_the_batch_commands_declarations(command):
    commands = _subparsers()
    for dest in COPIED[command]:
        batch, monitor = _option(commands[command], dest), _option(commands["monitor"], dest)
        fields = ("option_strings", "nargs", "default", "type", "choices", "metavar")
        assert [getattr(monitor, f) for f in fields] == [getattr(batch, f) for f in fields], dest
        assert type(monitor) is type(batch), dest
        if dest not in REWORDED:
            assert monitor.help == batch.help, dest


def test_the_monitor_reads_identification_as_identify_does(tmp_path):
    """No flags: the same IdentifyOptions; the same flags: the same IdentifyOptions."""
    flags = ["--method", "data", "--block-rows", "12", "--max-order", "30", "--band", "2", "12"]
    flags += ["--kurtosis-max", "8", "--lscf-max-order", "9", "--step-minutes", "10"]
    for given in ([], flags):
        identify = parse_arguments(["identify", "D", "--out", "o", *given])
        monitor = parse_arguments(["monitor", "--watch", "w", "--state", "s", *given])
        assert identify_options(monitor) == identify_options(identify)
    assert identify_options(monitor).block_rows == 12
    assert identify_options(monitor).fault_options[0] == ("kurtosis_limits", (1.3, 8.0))


def test_the_monitor_defaults_are_the_batch_defaults():
    """The values a command takes without flags, compared where the monitor shares them."""
    commands = {
        "identify": ["identify", "D", "--out", "o"],
        "track": ["track", "S", "--out", "t.csv"],
        "forecast": ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv"],
        "health": ["health", "--forecast", "f.csv", "--out", "h"],
    }
    monitor = vars(parse_arguments(["monitor", "--watch", "w", "--state", "s"]))
    for command, argv in commands.items():
        batch = vars(parse_arguments(argv))
        shared = {d: batch[d] for d in COPIED[command]}
        assert {d: monitor[d] for d in shared} == shared, command
    assert monitor["option"] == "A" and monitor["scheme"] == 2 and monitor["mac_min"] == 0.9


def test_configuration_reaches_identify_and_monitor_alike(tmp_path):
    """[identify] reference_channels was dropped on the way to identify (its destination
    was misnamed) and so to the monitor; the monitor's --mac-min is [track]'s."""
    config = write_config(
        tmp_path / "ship.toml",
        {
            "accelerations": {"inputs": ["recordings"]},
            "dship": {"file": "log.tsv", "columns": {"speed_kn": "SOG"}},
            "identify": {"reference_channels": ["a1", "a2"], "block_rows": 8, "blades": 4},
            "track": {"mac_min": 0.85},
            "forecast": {"option": "both", "scheme": 1, "mac_min": 0.7, "train_blocks": 9},
        },
    )
    identify = parse_arguments(["identify", "--config", str(config)])
    monitor = parse_arguments(["monitor", "--config", str(config), "--block-rows", "6"])
    assert identify.reference_channels == monitor.reference_channels == "a1,a2"
    assert identify_options(identify).reference_channels == ("a1", "a2")
    assert identify.block_rows == 8 and monitor.block_rows == 6  # flags win
    assert monitor.blades == 4 and monitor.mac_min == 0.85
    assert monitor.option == "AB" and monitor.scheme == 1 and monitor.train_blocks == 9
    assert monitor.watch == tmp_path / "recordings"
    assert monitor.state == tmp_path / "out" / "monitor"
    assert monitor.dship == tmp_path / "log.tsv"
    assert monitor.dship_columns == ["speed_kn=SOG"]


def test_copy_flags_names_a_missing_option():
    source = argparse.ArgumentParser(prog="source")
    source.add_argument("--rate", type=float, default=2.0, help="a rate")
    target = argparse.ArgumentParser(prog="target")
    with pytest.raises(KeyError) as error:
        copy_flags(source, target, ("rate", "block_rows"))
    assert "source has no option for block_rows" in str(error.value)
    copy_flags(source, target, ("rate",), help={"rate": "the rate"})
    assert target.parse_args([]).rate == 2.0 and target.parse_args(["--rate", "3"]).rate == 3.0
    assert _option(target, "rate").help == "the rate"
