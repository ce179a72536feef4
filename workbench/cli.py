"""Command-line interface: ``workbench COMMAND ...``.

The CLI parses arguments, calls the library and prints; nothing else. Exit status: 0 on
success, 1 on bad data (one line per problem on stderr, naming file, column and rows),
2 on usage errors. Tracebacks only with ``--verbose``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from data_contracts import ContractError

from . import __version__
from .errors import WorkbenchError

EXIT_OK, EXIT_DATA, EXIT_USAGE = 0, 1, 2

log = logging.getLogger("workbench")


class UsageError(Exception):
    """Arguments that parse but make no sense together (exit status 2)."""


def _add_validate(commands: argparse._SubParsersAction) -> None:
    from data_contracts import CONTRACTS

    kinds = ["accelerations", "dship", *CONTRACTS]
    parser = commands.add_parser(
        "validate",
        help="check a file against a data contract",
        description="Check FILE against the contract KIND and report every problem.",
    )
    parser.add_argument("kind", choices=kinds, metavar="KIND", help=f"one of: {', '.join(kinds)}")
    parser.add_argument("file", type=Path, metavar="FILE")
    parser.set_defaults(run=_run_validate)


def _run_validate(args: argparse.Namespace) -> int:
    from data_contracts import CONTRACTS, read_accelerations, read_dship, read_table

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.kind == "accelerations":
            record = read_accelerations(args.file)
            summary = (
                f"{record.n_samples} samples x {len(record.channels)} channels at "
                f"{record.sampling_rate_hz:g} Hz from {record.start_time.isoformat()}"
            )
        elif args.kind == "dship":
            table = read_dship(args.file)
            summary = f"{len(table)} records, columns {', '.join(table.columns[1:])}"
        else:
            table = read_table(args.file, CONTRACTS[args.kind])
            summary = f"{len(table)} rows"
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    print(f"{args.file}: valid {args.kind} file ({summary})")
    return EXIT_OK


def _add_simulate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "simulate",
        help="simulate a demo voyage with known modal parameters",
        description="Write a simulated voyage: 5-minute acceleration files, the DSHIP log, "
        "ground-truth and noisy tracked modal tables, and pole tables.",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--hours",
        type=float,
        default=None,
        help="voyage length [h] (default: the demo length, 12 h)",
    )
    parser.add_argument(
        "--no-accelerations", action="store_true", help="skip the acceleration files (tables only)"
    )
    parser.set_defaults(run=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    from .simulate import simulate_voyage

    if args.hours is not None and args.hours <= 0:
        raise UsageError(f"--hours must be positive, got {args.hours}")
    from .demo import describe_voyage

    try:
        voyage = simulate_voyage(
            args.out, seed=args.seed, hours=args.hours, accelerations=not args.no_accelerations
        )
    except ValueError as error:  # e.g. a voyage shorter than one block
        raise UsageError(str(error)) from None
    print(f"simulated voyage written to {args.out}: {describe_voyage(voyage)}")
    return EXIT_OK


def _add_demo(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "demo",
        help="run the whole chain on the built-in demo voyage",
        description="Simulate the demo voyage into reports/demo/ and run every stage on it.",
    )
    parser.add_argument("--out", type=Path, default=Path("reports") / "demo", metavar="DIR")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hours", type=float, default=None)
    parser.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    summary = run_demo(args.out, seed=args.seed, hours=args.hours)
    print(summary)
    return EXIT_OK


#: Subcommands in the order ``--help`` lists them.
COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_demo,
    _add_simulate,
    _add_validate,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="workbench",
        description="Hull vibration monitoring: identify, track, model and forecast a ship's "
        "structural modes from accelerations and the ship's log.",
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks and debug logging"
    )
    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    for add in COMMANDS:
        add(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with *argv* (default ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # argparse exits 2 on usage errors, 0 on --help
        return int(exit_.code or 0)
    if not hasattr(args, "run"):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(message)s",
        stream=sys.stderr,
    )
    try:
        return int(args.run(args) or EXIT_OK)
    except ContractError as error:
        if args.verbose:
            raise
        for line in error.lines():
            print(line, file=sys.stderr)
        return EXIT_DATA
    except WorkbenchError as error:
        if args.verbose:
            raise
        print(f"error: {error}", file=sys.stderr)
        return EXIT_DATA
    except UsageError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
