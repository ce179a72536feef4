"""What the commands share: exit statuses, the usage error, option checks, reading the
modal table and the predictors of correlate/fit/forecast, printing a stage's result."""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from data_contracts import ContractError

from .. import defaults as D
from ..errors import (
    DataError,
    OptionError,
    PredictorError,
    UsageError,
    WorkbenchError,
    printable,
)
from ..inputs import (
    add_dship_columns,
    add_modal_layout,
    dship_mapping,
    dship_utc_offset,
    read_modal,
    time_format,
)

EXIT_OK, EXIT_DATA, EXIT_USAGE = 0, 1, 2


log = logging.getLogger("workbench")


#: Longest simulated voyage: a year (longer ones would write ~10^5 files per month). [h]
MAX_SIMULATED_HOURS = 24.0 * 366


def _check_hours(hours) -> None:
    import math

    if hours is not None and not (math.isfinite(hours) and 0 < hours <= MAX_SIMULATED_HOURS):
        raise UsageError(
            f"--hours must be a positive number of hours up to {MAX_SIMULATED_HOURS:g}, "
            f"got {hours:g}"
        )


def _check_seed(seed) -> None:
    """Usage error unless --seed is a non-negative integer (what NumPy's seeding takes)."""
    if seed is not None and seed < 0:
        raise UsageError(f"--seed must be a non-negative integer, got {seed}")


def _check_positive(**values) -> None:
    """Usage error unless every given integer option is at least 1 (None passes)."""
    for name, value in values.items():
        if value is not None and value < 1:
            raise UsageError(f"--{name.replace('_', '-')} must be at least 1, got {value}")


def _check_hours_flags(**values) -> None:
    """Usage error unless every given option in hours is a positive finite number (None
    passes)."""
    import math

    for name, value in values.items():
        if value is not None and not (math.isfinite(value) and value > 0):
            raise UsageError(
                f"--{name.replace('_', '-')} must be a positive number of hours, got {value:g}"
            )


def _check_share(name: str, value: float, *, low_open: bool = False) -> None:
    """Usage error unless *value* lies in [0, 1] ((0, 1] with *low_open*)."""
    import math

    ok = math.isfinite(value) and (0.0 < value if low_open else 0.0 <= value) and value <= 1.0
    if not ok:
        interval = "(0, 1]" if low_open else "[0, 1]"
        raise UsageError(f"--{name} must be in {interval}, got {value:g}")


#: Arguments that name a file the command writes; every other file argument is read.
OUTPUT_ARGUMENTS = ("out", "save_model")


def check_outputs_are_not_inputs(
    args: argparse.Namespace, actions: Sequence[argparse.Action] = ()
) -> None:
    """Usage error when a file the command writes is a file it reads (``--out`` naming the
    ``--modal`` table, by the same or another path): the output would replace the input.

    *actions* are the command's parser actions, for the flags' names in the message.
    """
    labels = {
        action.dest: action.option_strings[-1] if action.option_strings else action.metavar
        for action in actions
    }
    for output in OUTPUT_ARGUMENTS:
        target = getattr(args, output, None)
        if target is None or not Path(target).is_file():
            continue  # a new file (or a folder) replaces no input
        for dest, value in vars(args).items():
            if dest in OUTPUT_ARGUMENTS:
                continue
            for item in value if isinstance(value, list | tuple) else (value,):
                if (
                    isinstance(item, str | os.PathLike)
                    and Path(item).is_file()
                    and os.path.samefile(item, target)
                ):
                    flag = labels.get(output) or f"--{output.replace('_', '-')}"
                    given = labels.get(dest) or dest
                    raise UsageError(
                        f"{flag} {target} is also the input {given}: writing it would "
                        "replace that input; choose another file"
                    )


@contextlib.contextmanager
def _data_errors(source, *, predictors=None, flags: dict[str, str] | None = None):
    """A ValueError of the library about the data becomes a one-line error naming *source*
    (contract errors pass unchanged: they name file, column and rows themselves).

    One about the predictor table (:class:`~workbench.errors.PredictorError`) names
    *predictors* (the ``--predictors`` file or the ``--dship`` log) instead; a
    :class:`~workbench.errors.DataError` shows its parameter as the flag *flags* maps it
    to (``{"train_blocks": "--train-blocks 6"}``)."""
    try:
        yield
    except (ContractError, OptionError):
        raise
    except PredictorError as error:
        raise WorkbenchError(f"{predictors or source}: {error.for_user(flags)}") from None
    except DataError as error:
        raise WorkbenchError(f"{source}: {error.for_user(flags)}") from None
    except ValueError as error:
        raise WorkbenchError(f"{source}: {error}") from None


def _predictor_source(args: argparse.Namespace):
    """The file the predictors come from: ``--predictors``, or the ``--dship`` log."""
    return args.predictors if getattr(args, "predictors", None) is not None else args.dship


def _print_result(result, paths=None) -> None:
    """A stage result's warnings (stderr), lines and the files it wrote."""
    for line in result.warnings:
        print(f"warning: {printable(line)}", file=sys.stderr)
    for line in result.lines:
        print(printable(line))
    for name, path in dict(paths or {}).items():
        print(printable(f"{name}: {path}"))


def _add_predictor_source(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--predictors", type=Path, metavar="FILE", help="block predictor table (CSV/Parquet)"
    )
    source.add_argument(
        "--dship",
        type=Path,
        metavar="FILE",
        help="raw DSHIP log, averaged onto the modal table's blocks",
    )
    add_dship_columns(parser)
    add_modal_layout(parser)
    parser.add_argument(
        "--excitation",
        type=Path,
        metavar="FILE",
        help="with --dship: the excitation.csv of identify --block-minutes auto; the log is "
        "averaged over each block weighted by the excitation, as SSI reads the block",
    )
    parser.add_argument(
        "--all-predictors",
        action="store_true",
        help="use every numeric column of the predictors, not only speed, water/air "
        "temperature, wind speed and relative wind direction",
    )


def _add_modal_and_predictors(parser: argparse.ArgumentParser) -> None:
    """``--modal`` (required) and the predictor source: what correlate, fit and forecast read."""
    parser.add_argument(
        "--modal", type=Path, required=True, metavar="FILE", help="tracked modal table"
    )
    _add_predictor_source(parser)


def _add_min_presence(
    parser: argparse.ArgumentParser,
    help: str = "only modes measured in at least this share of the blocks",
) -> None:
    parser.add_argument(
        "--min-presence", type=float, default=D.MIN_PRESENCE, metavar="SHARE", help=help
    )


def _add_out_dir(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")


def _predictors_for(args: argparse.Namespace, modal):
    from ..predictors import load_predictors

    # the API's choice (canonical predictors unless all are asked for) in one place
    excitation = getattr(args, "excitation", None)
    if excitation is not None and args.dship is None:
        raise UsageError("--excitation weights the averaging of --dship; give --dship")
    return load_predictors(
        excitation=excitation,
        predictors=args.predictors,
        dship=args.dship,
        onto=modal,
        dship_mapping=dship_mapping(args),
        dship_utc_offset=dship_utc_offset(args),
        time_format=time_format(args),
        all_predictors=args.all_predictors,
    )


def _modal_and_predictors(args: argparse.Namespace):
    """``--modal`` and the predictors (``--predictors`` or ``--dship`` averaged onto the
    modal blocks) of correlate, fit and forecast, their block times checked against each
    other."""
    modal = _read_modal(args, args.modal)
    predictors = _predictors_for(args, modal)
    _check_joins(args, modal, predictors)
    return modal, predictors


def _add_parallel(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("parallel execution")
    group.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a running dask.distributed scheduler "
        "(tcp://host:8786), or 'synchronous' to run in this process; "
        "default: local worker processes on all cores",
    )
    group.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local worker processes (default: all cores)",
    )


#: Library parameter names and the CLI options that set them (for usage messages).
_OPTION_NAMES = {
    "length_s": "--block-minutes (in s)",
    "step_s": "--step-minutes (in s)",
    "max_gap_s": "--max-gap",
    "target_rate_hz": "--rate",
    "band_hz": "--band",
    "block_rows": "--block-rows",
    "orders": "--min-order/--max-order",
    "reference_channels": "--reference-channels",
    "batch_blocks": "--batch-blocks",
    "n_workers": "--workers",
    "scheduler": "--scheduler",
    "mac_min": "--mac-min",
    "frequency_tol": "--frequency-tol",
}


def _option_names(message: str) -> str:
    """*message* with a library parameter name at its start shown as the CLI option (the
    name followed by ``=``, ``:`` or a space: a message starting with a file's name, such
    as ``orders_2024.toml: ...``, is left as it is)."""
    for name, option in _OPTION_NAMES.items():
        if message.startswith(name) and message[len(name) : len(name) + 1] in ("=", " ", ":"):
            return option + message[len(name) :]
    return message


def _check_joins(args, modal, predictors=None, poles=None) -> None:
    """Block numbers must mean the same times in every input (one-line error, exit 1)."""
    from ..joins import (
        check_block_times,
        check_poles_cover,
        check_poles_match,
        check_predictors_overlap,
    )

    if predictors is not None:
        source = _predictor_source(args)
        check_block_times(modal, args.modal, predictors, source)
        table = getattr(args, "predictors", None) is not None
        check_predictors_overlap(modal, predictors, source, table=table)
    if poles is not None:
        check_poles_match(modal, args.modal, poles, args.poles)
        check_poles_cover(modal, poles, args.poles)


def _read_modal(args: argparse.Namespace, path: Path, contract=None):
    """A modal table in any recognised layout (or a table of *contract*) with rows, its
    block numbers on one time grid."""
    from data_contracts import read_table

    from ..joins import check_block_grid

    table = read_modal(args, path) if contract is None else read_table(path, contract)
    if table.empty:
        raise WorkbenchError(f"{path}: the table has a header but no rows")
    check_block_grid(table, path)
    return table


def _cases_argument(value: str | None):
    """--cases: None, "derive" or the path of a case,start,end CSV."""
    if value is None or value == "derive":
        return value
    return Path(value)


def _check_table_path(path: Path) -> None:
    """A usage error unless *path* names a .csv or .parquet file (not a folder)."""
    if path.suffix.lower() not in (".csv", ".parquet", ".pq"):
        raise UsageError(f"{path}: the table must end in .csv or .parquet")
    if path.is_dir():
        raise UsageError(f"{path}: is a folder; give a file name ending in .csv or .parquet")
