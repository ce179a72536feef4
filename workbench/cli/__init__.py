"""Command-line interface: ``workbench COMMAND ...``.

The CLI parses arguments, calls the library and prints; nothing else. Exit status: 0 on
success, 1 on bad data (one line per problem on stderr, naming file, column and rows),
2 on usage errors. Tracebacks only with ``--verbose``.

One module per group of commands, each declaring its commands' options (``_add_*``) and
running them (``_run_*``): :mod:`~workbench.cli.demo` (demo, run, simulate),
:mod:`~workbench.cli.identify` (identify; :func:`identify_options` reads the
identification flags for identify and monitor), :mod:`~workbench.cli.modelling` (track, correlate, fit),
:mod:`~workbench.cli.forecasting` (forecast, evaluate, health),
:mod:`~workbench.cli.files` (report, validate), :mod:`~workbench.cli.monitoring`
(dashboard, and monitor, whose identification, tracking, forecast and health options are
copied from those commands' declarations); :mod:`~workbench.cli.common` holds what they
share. This module assembles the parser, applies ``--config`` (:func:`parse_arguments`)
and runs a command (:func:`main`).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from data_contracts import ContractError

from .. import __version__
from ..arguments import HelpFormatter, add_verbosity, stderr_is_terminal
from ..errors import EXIT_INTERRUPTED, OptionError, WorkbenchError, printable
from .common import (
    EXIT_DATA,
    EXIT_OK,
    EXIT_USAGE,
    MAX_SIMULATED_HOURS,
    UsageError,
    _option_names,
    check_outputs_are_not_inputs,
    log,
)
from .demo import _add_demo, _add_run, _add_simulate
from .files import _add_report, _add_validate
from .forecasting import (
    FORECAST_OPTIONS,
    FORECAST_SCHEMES,
    _add_evaluate,
    _add_forecast,
    _add_health,
)
from .identify import _add_identify, identify_options
from .modelling import _add_correlate, _add_fit, _add_track
from .monitoring import _add_dashboard, _add_monitor

__all__ = [
    "EXIT_DATA",
    "EXIT_OK",
    "EXIT_USAGE",
    "FORECAST_OPTIONS",
    "FORECAST_SCHEMES",
    "MAX_SIMULATED_HOURS",
    "UsageError",
    "build_parser",
    "identify_options",
    "main",
    "parse_arguments",
]


#: Subcommands in the order ``--help`` lists them (``monitor`` copies options of identify,
#: track, forecast and health, so it comes after them).
COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_demo,
    _add_run,
    _add_simulate,
    _add_identify,
    _add_track,
    _add_correlate,
    _add_fit,
    _add_forecast,
    _add_evaluate,
    _add_report,
    _add_health,
    _add_dashboard,
    _add_monitor,
    _add_validate,
)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line, ``warning: ...``, without source location (unless --verbose)."""
    print(f"warning: {_plain(message)}", file=sys.stderr if file is None else file)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="workbench",
        description="Hull vibration monitoring: identify, track, model and forecast a ship's "
        "structural modes from accelerations and the ship's log.",
        formatter_class=HelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    add_verbosity(parser, top_level=True)
    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    for add in COMMANDS:
        add(commands)
    for name, sub in commands.choices.items():
        sub.formatter_class = HelpFormatter
        # a flag is its whole name: a prefix (a former ``--train`` for ``--train-blocks``)
        # is refused like any unknown flag, not read as another option
        sub.allow_abbrev = False
        add_verbosity(sub)
        if name in ("demo", "simulate", "run"):
            continue
        sub.add_argument(
            "--config",
            type=Path,
            metavar="SHIP.TOML",
            help="take this command's settings from a ship's configuration (flags win)",
        )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with *argv* (default ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
        args = parse_arguments(argv, parser)
    except SystemExit as exit_:  # argparse exits 2 on usage errors, 0 on --help
        return int(exit_.code or 0)
    if not hasattr(args, "run"):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    if not stderr_is_terminal():  # no progress bars in logs, pipes and CI
        args.quiet = True
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_PlainFormatter("%(message)s"))
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING, handlers=[handler]
    )
    log.setLevel(logging.DEBUG if args.verbose else logging.INFO)
    for noisy in ("distributed", "tornado", "bokeh", "asyncio"):  # cluster chatter
        logging.getLogger(noisy).setLevel(logging.DEBUG if args.verbose else logging.ERROR)
    # commands write figures to files and never open a window: Agg, set before matplotlib
    # is imported where no command has imported it yet (a command that draws nothing,
    # such as identify, then never pays for its import)
    if "matplotlib" in sys.modules:
        sys.modules["matplotlib"].use("Agg")
    else:
        os.environ["MPLBACKEND"] = "Agg"
    shown = warnings.showwarning
    if not args.verbose:
        warnings.showwarning = _show_warning
    try:
        return _run(args, _command_actions(parser, args))
    finally:
        warnings.showwarning = shown


def parse_arguments(
    argv: Sequence[str] | None, parser: argparse.ArgumentParser | None = None
) -> argparse.Namespace:
    """The parsed arguments of *argv*, defaults taken from ``--config FILE`` where given
    (flags win). Exits (``SystemExit``) as argparse does: 2 on usage errors, 0 on --help."""
    parser = build_parser() if parser is None else parser
    _apply_config(parser, argv)
    return parser.parse_args(argv)


def _apply_config(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> None:
    """Defaults from ``--config FILE`` (bad files: message and exit 2)."""
    from ..config import ConfigError, apply_config, load_config

    pre = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    pre.add_argument("--config", type=Path)
    known, _ = pre.parse_known_args(argv)
    if known.config is not None:
        try:
            apply_config(parser, load_config(known.config))
        except ConfigError as error:
            print(f"workbench: error: {_plain(error)}", file=sys.stderr)
            raise SystemExit(EXIT_USAGE) from None


#: NumPy >= 2 scalar reprs (``np.float64(0.5)``) inside messages built with ``!r``.
_NUMPY_REPR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool|str)\w*\(([^()]*)\)")


def _plain(message) -> str:
    """*message* with NumPy scalar reprs shown as plain values (``0.5``, not
    ``np.float64(0.5)``) and control characters escaped (:func:`~workbench.errors.printable`:
    a file name cannot drive the terminal); one rule for every message the CLI prints. A
    message that lists several problems keeps its one line per problem."""
    plain = _NUMPY_REPR.sub(r"\1", str(message))
    return "\n".join(printable(line) for line in plain.split("\n"))


class _PlainFormatter(logging.Formatter):
    """Log lines with the message's control characters escaped (tracebacks of --verbose
    keep their lines)."""

    def formatMessage(self, record: logging.LogRecord) -> str:  # noqa: N802 (logging's name)
        return printable(super().formatMessage(record))


def _os_error_line(error: OSError) -> str:
    """``path: reason`` of a file-system error (read-only folder, disk full, ...)."""
    reason = error.strerror or str(error).splitlines()[0] or type(error).__name__
    names = [n for n in (error.filename, error.filename2) if n is not None]
    return _plain(f"{' -> '.join(map(str, names))}: {reason}" if names else reason)


def _command_actions(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> list[argparse.Action]:
    """The arguments of the command *args* were parsed for (none if not found)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                if sub.get_default("run") is args.run:
                    return list(sub._actions)
    return []


def _run(args: argparse.Namespace, actions: Sequence[argparse.Action] = ()) -> int:
    """Run the chosen command; user errors become messages and exit statuses."""
    try:
        check_outputs_are_not_inputs(args, actions)
        return int(args.run(args) or EXIT_OK)
    except ContractError as error:
        if args.verbose:
            raise
        for line in error.lines():
            print(_plain(line), file=sys.stderr)
        return EXIT_DATA
    except WorkbenchError as error:
        if args.verbose:
            raise
        print(f"error: {_plain(error)}", file=sys.stderr)
        return EXIT_DATA
    except (UsageError, OptionError) as error:
        print(f"workbench: error: {_plain(_option_names(str(error)))}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as error:  # file-system errors on output: one line, exit 1
        if args.verbose:
            raise
        print(f"error: {_os_error_line(error)}", file=sys.stderr)
        return EXIT_DATA
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
