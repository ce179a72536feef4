"""One vocabulary: the README's glossary against ``--help`` and the library, defaults shown
in every ``--help``, former flags, keyword arguments and configuration keys refused,
``--verbose`` and ``--quiet`` on either side of the command, no progress bars when stderr
is no terminal.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import io
import pkgutil
import re
import warnings
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import workbench
from data_contracts import CONTRACTS, MODAL, write_table
from workbench import defaults
from workbench.arguments import HelpFormatter, choice
from workbench.cli import build_parser, main

README = Path(__file__).resolve().parents[1] / "README.md"


# --------------------------------------------------------------------------- the parser
@cache
def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


COMMANDS = sorted(_subparsers())


@cache
def _help(command: str) -> str:
    return _subparsers()[command].format_help()


def _option_help(command: str, action: argparse.Action) -> str:
    """The help text of one option as ``--help`` prints it (defaults expanded)."""
    formatter = HelpFormatter(prog="workbench")
    text = formatter._expand_help(action) if action.help else ""
    return " ".join(text.split())


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_help_exits_0(command, capsys):
    assert main([command, "--help"]) == 0
    assert f"usage: workbench {command}" in capsys.readouterr().out


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_with_a_default_shows_it(command):
    """An option with a value default shows ``(default: X)``; an option whose default is
    computed (``None``) says what happens when it is not given, or has no default."""
    for action in _subparsers()[command]._actions:
        if not action.option_strings or action.help == argparse.SUPPRESS:
            continue
        if isinstance(action, argparse._HelpAction | argparse._StoreTrueAction):
            continue
        text = _option_help(command, action)
        if action.default is not None:
            assert "default" in text, f"{command} {action.option_strings[0]}: {text!r}"
            if "%(default)" not in (action.help or "") and "(default: " in text:
                shown = re.search(r"\(default: ([^)]*)\)", text).group(1)
                assert shown == str(action.default), (command, action.option_strings)


def test_defaults_are_the_library_defaults():
    """The command line shows the library's defaults (defaults.py reads them; a copy here
    would let them drift apart silently)."""
    from workbench.forecasting.options import ForecastOptions
    from workbench.identification import IdentifyOptions
    from workbench.sid.tracking import TrackingOptions

    identify = IdentifyOptions()
    parser = _subparsers()
    get = {name: p.get_default for name, p in parser.items()}
    assert get["identify"]("block_rows") == identify.block_rows == 20
    assert get["identify"]("min_order") == min(identify.orders)
    assert get["identify"]("max_order") == max(identify.orders)
    assert get["identify"]("method") == identify.method
    assert get["track"]("mac_min") == TrackingOptions().mac_min
    assert get["track"]("frequency_tol") == TrackingOptions().frequency_tol
    assert get["forecast"]("mac_min") == ForecastOptions().mac_min
    assert get["fit"]("p_enter") == defaults.FIT_P_ENTER == 0.05
    # the model-order step is no longer hard-coded in the command
    assert defaults.IDENTIFY_ORDER_STEP == identify.orders[1] - identify.orders[0]


# --------------------------------------------------------------------------- the glossary
def _glossary() -> list[dict[str, list[str]]]:
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## Glossary\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    header = [c.strip() for c in rows[0].strip("|").split("|")]
    assert header == ["concept", "command line", "Python", "column", "former names"]
    out = []
    for line in rows[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        row = {"concept": [cells[0]]}
        for name, cell in zip(header[1:], cells[1:], strict=True):
            # a cell lists `items`, separated by commas; brackets hold values, not names
            cell = re.sub(r"\([^()]*`[^()]*\)", "", cell) if name != "Python" else cell
            row[name] = re.findall(r"`([^`]+)`", cell)
        out.append(row)
    return out


GLOSSARY = _glossary()


def test_glossary_names_each_concept_once():
    concepts = [row["concept"][0] for row in GLOSSARY]
    assert len(concepts) == len(set(concepts)) >= 20
    flags = [f for row in GLOSSARY for f in row["command line"]]
    assert len(flags) == len(set(flags)), "a flag belongs to one concept"


@pytest.mark.parametrize("row", GLOSSARY, ids=lambda r: r["concept"][0][:40])
def test_glossary_flags_are_what_help_shows(row):
    for item in row["command line"]:
        command, flag = item.split()
        assert re.search(rf"(?<![\w-]){re.escape(flag)}(?![\w-])", _help(command)), item
    for item in row["former names"]:
        if " --" not in item:
            continue
        command, flag = item.split()
        assert not re.search(rf"(?<![\w-]){re.escape(flag)}(?![\w-])", _help(command)), (
            f"former name {item} is still shown in --help"
        )
        assert flag not in _subparsers()[command]._option_string_actions, f"{item} accepted"


@cache
def _library() -> dict[str, object]:
    """Public classes and functions of every workbench and data_contracts module, by name."""
    import data_contracts

    found: dict[str, object] = {}
    packages = [
        *pkgutil.walk_packages(workbench.__path__, "workbench."),
        *pkgutil.walk_packages(data_contracts.__path__, "data_contracts."),
    ]
    for info in packages:
        if info.name.endswith("__main__"):
            continue
        try:
            module = importlib.import_module(info.name)
        except ImportError:  # optional dependencies
            continue
        for name, value in vars(module).items():
            if not name.startswith("_") and (inspect.isclass(value) or callable(value)):
                if getattr(value, "__module__", "").startswith(("workbench", "data_contracts")):
                    found.setdefault(name, value)
    return found


def _parameters(obj) -> set[str]:
    names = set(inspect.signature(obj).parameters)
    if inspect.isclass(obj) and hasattr(obj, "__dataclass_fields__"):
        names |= set(obj.__dataclass_fields__)
    return names


def _resolve(item: str):
    """``Owner.name`` or ``owner(name)`` -> (owner object, name)."""
    match = re.fullmatch(r"(\w+)(?:\.(\w+)|\((\w+)\))", item)
    assert match, f"glossary item {item!r} is neither Owner.name nor function(name)"
    owner = _library().get(match.group(1))
    assert owner is not None, f"{match.group(1)} not found in workbench"
    return owner, match.group(2) or match.group(3)


@pytest.mark.parametrize("row", GLOSSARY, ids=lambda r: r["concept"][0][:40])
def test_glossary_parameters_exist_and_former_ones_are_gone(row):
    for item in row["Python"]:
        if not re.fullmatch(r"\w+(\.\w+|\(\w+\))", item):
            continue  # a value in brackets, e.g. "tracked_pole"
        owner, name = _resolve(item)
        assert name in _parameters(owner), item
    for item in row["former names"]:
        if " --" in item:
            continue
        owner, name = _resolve(item)
        if owner.__module__.startswith("workbench.forecasting"):
            continue  # the forecast package's shims go with issue 31a; drop this line then
        assert name not in _parameters(owner), f"{item}: a former name is a parameter again"


def test_glossary_columns_are_contract_columns():
    columns = {c.name for contract in CONTRACTS.values() for c in contract.columns}
    columns |= {"mac", "model_order"}  # selected-modes and pole tables
    for row in GLOSSARY:
        for column in row["column"]:
            assert column in columns, column


# --------------------------------------------------------------------------- former names
#: Flags renamed with the vocabulary: the former spellings are refused (0.x, no shims), also
#: where a former name begins a current flag of its command (``--train`` of
#: ``--train-blocks``): abbreviations are not accepted.
FORMER_FLAGS = [
    ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv", "--train", "20"],
    ["identify", "D", "--out", "o", "--reference", "0,1"],
    ["track", "S", "--out", "o.csv", "--reference", "modes.json"],
    ["monitor", "--watch", "w", "--state", "s", "--train", "20"],
    ["track", "S", "--out", "o.csv", "--threshold", "0.8"],
    ["track", "S", "--out", "o.csv", "--frequency-tolerance", "0.1"],
    ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv", "--method", "1"],
    ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv", "--jobs", "3"],
    ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv", "--shape-mac-min", "0.5"],
    ["identify", "D", "--out", "o", "--figures", "2"],
    ["simulate", "--out", "v", "--rate", "2048"],
    ["monitor", "--watch", "w", "--state", "s", "--threshold", "0.8"],
    ["monitor", "--watch", "w", "--state", "s", "--forecast-method", "1"],
]


@pytest.mark.parametrize("argv", FORMER_FLAGS, ids=lambda argv: f"{argv[0]} {argv[-2]}")
def test_former_flags_are_refused(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2
    assert err[-1].endswith(f"unrecognized arguments: {argv[-2]} {argv[-1]}")


def test_named_choices_and_their_aliases():
    options = {"--option": ("tracked-pole", "A"), "--scheme": ("rolling", 2)}
    base = ["forecast", "--modal", "m", "--dship", "d", "--out", "f.csv"]
    parser = build_parser()
    assert parser.parse_args(base).option == "A" and parser.parse_args(base).scheme == 2
    for value, expected in [
        ("pole-cluster", "B"),
        ("B", "B"),
        ("both", "AB"),
        ("AB", "AB"),
        ("tracked-pole", "A"),
    ]:
        assert parser.parse_args([*base, "--option", value]).option == expected
    for value, expected in [("single-window", 1), ("1", 1), ("rolling", 2), ("2", 2)]:
        assert parser.parse_args([*base, "--scheme", value]).scheme == expected
    assert options  # the defaults above are the descriptive names
    scheme = choice({"single-window": 1, "rolling": 2}, {"1": "single-window"})
    with pytest.raises(argparse.ArgumentTypeError, match="single-window, rolling"):
        scheme("3")


def test_forecast_help_shows_descriptive_names_only():
    text = " ".join(_help("forecast").split())
    assert "--option {tracked-pole,pole-cluster,both}" in text
    assert "--scheme {single-window,rolling}" in text
    assert "(default: tracked-pole)" in text and "(default: rolling)" in text
    assert "--method" not in text and "--jobs" not in text and "--train " not in text


# --------------------------------------------------------------------------- verbose, quiet
@pytest.mark.parametrize(
    "argv",
    [
        ["--verbose", "validate", "poles", "{missing}"],
        ["validate", "poles", "{missing}", "--verbose"],
        ["validate", "-v", "poles", "{missing}"],
    ],
)
def test_verbose_before_or_after_the_command(argv, tmp_path):
    argv = [a.format(missing=tmp_path / "none.csv") for a in argv]
    with pytest.raises(Exception, match="file not found"):
        main(argv)


def test_quiet_before_or_after_the_command():
    parser = build_parser()
    for argv in (
        ["-q", "evaluate", "--forecast", "f", "--truth", "t"],
        ["evaluate", "--forecast", "f", "--truth", "t", "--quiet"],
    ):
        args = parser.parse_args(argv)
        assert args.quiet is True and args.verbose is False
    args = parser.parse_args(["evaluate", "--forecast", "f", "--truth", "t"])
    assert args.quiet is False


def _selected_table(path: Path) -> Path:
    """A small selected-modes table: two modes with clean shapes over 12 blocks."""
    rng = np.random.default_rng(4)
    shapes = {1: np.array([1.0, 0.8, 0.3, -0.2]), 2: np.array([0.2, -0.6, 1.0, 0.7])}
    rows = []
    t0 = pd.Timestamp("2024-03-01T00:00Z")
    for block in range(12):
        for mode, f in ((1, 2.9), (2, 6.1)):
            shape = shapes[mode] + rng.normal(0, 0.01, 4)
            row = {
                "block": block,
                "block_start": t0 + pd.Timedelta(minutes=5 * block),
                "block_end": t0 + pd.Timedelta(minutes=5 * block + 20),
                "frequency_hz": f * (1 + rng.normal(0, 1e-3)),
                "damping_ratio": 0.01,
            }
            row |= {f"shape_re_acc{c}": shape[c] for c in range(4)}
            row |= {f"shape_im_acc{c}": 0.0 for c in range(4)}
            rows.append(row)
    frame = pd.DataFrame(rows)
    frame.to_csv(path, index=False)
    return path


def test_no_progress_bar_when_stderr_is_not_a_terminal(tmp_path, capsys, monkeypatch):
    selected = _selected_table(tmp_path / "selected.csv")
    argv = ["track", str(selected), "--out", str(tmp_path / "tracked.csv")]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "it/s" not in err and "block" not in err and "%|" not in err, err

    # the same run on a terminal draws the bar (the check above can fail)
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal = Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    assert main(argv) == 0
    assert (
        "%|" in terminal.getvalue()
        or "it/s" in terminal.getvalue()
        or "12/12" in (terminal.getvalue())
    )
    # ... and --quiet hides it there
    quiet = Terminal()
    monkeypatch.setattr("sys.stderr", quiet)
    assert main([*argv, "--quiet"]) == 0
    assert "12/12" not in quiet.getvalue() and "%|" not in quiet.getvalue()
    tracked = pd.read_csv(tmp_path / "tracked.csv")
    assert sorted(tracked["mode"].unique()) == [1, 2]
    write_table(tracked, tmp_path / "again.csv", MODAL)  # a valid modal table


def test_former_configuration_keys_are_refused(tmp_path):
    """A key under its former name is an unknown key (no aliases while the version is 0.x),
    reported with the others; a file with the present names reads without a warning."""
    from workbench.config import ConfigError, load_config, write_demo_config

    path = tmp_path / "ship.toml"
    path.write_text("[track]\nthreshold = 0.8\n[forecast]\nmethod = 1\ntrain = 12\n")
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    message = str(caught.value)
    for section, key in (("track", "threshold"), ("forecast", "method"), ("forecast", "train")):
        assert f"[{section}] unknown key '{key}'" in message
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        demo = load_config(write_demo_config(tmp_path))
    assert demo.get("forecast", "scheme") == "rolling"
