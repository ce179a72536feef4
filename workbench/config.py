"""A ship's set-up in one TOML file: inputs and their layouts, block grid, models, forecast.

``workbench run ship.toml`` runs the chain the file describes (identify -> track ->
correlate -> fit -> forecast -> evaluate, each where its inputs are given, then the run's
report); ``--config
ship.toml`` on any command takes that command's settings from the file, and flags given on
the command line win. Paths in the file are relative to the file.

The file is checked as a whole before anything runs (:func:`load_config`): every key's type,
range or choices, unknown sections and keys (named with the nearest known one: a mistyped
option must not be ignored) and the keys that only make sense together (``trust`` needs
``model = "window"``; a block step no longer than the block), one line per problem naming
the section and key. A file that is not UTF-8 TOML is one line. Example::

    [output]
    dir = "out"

    [times]                             # every time column and text start time
    format = "%d/%m/%Y %H:%M:%S"        # (strptime or MATLAB datestr: dd-mmm-yyyy HH:MM:SS)

    [accelerations]                     # recordings and how to read them
    inputs = ["recordings/"]
    start_time = "filename"             # relative times; start in the file names
    units = "g"

    [dship]                             # the ship's log
    file = "dship/extraction.dat"
    columns = { speed_kn = "SYS.STR.SOG" }

    [blocks]
    length_minutes = 20                 # or "auto": the length from the conditions
    step_minutes = 5

    [identify]
    band = [2.0, 12.0]
    rate = 64
    blades = 5                          # the [dship] log's shaft speed marks the shaft
    harmonic_orders = [1, 2, 3]         # orders and blade pass, kept out of the modes

    [forecast]
    option = "both"                     # tracked-pole (A), pole-cluster (B) or both
    train_blocks = 20
    model = "window"                    # memory (default) or window (the reference's)
    trust = 0.65                        # window only: steady-state weight on SSI

A modal table from another tool replaces identification and tracking::

    [modal]
    file = "artemis_modes.csv"
    damping_unit = "percent"
    time_reference = "centre"
"""

from __future__ import annotations

import argparse
import difflib
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from data_contracts.limits import MAX_MODEL_ORDER

from .blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S

__all__ = [
    "SCHEMA",
    "ShipConfig",
    "apply_config",
    "chain",
    "load_config",
    "write_config",
    "write_demo_config",
]

_PATH, _PATHS = "path", "paths"

#: Section -> key -> type (``path``: relative to the file; ``paths``: list of them).
SCHEMA: dict[str, dict[str, Any]] = {
    "output": {"dir": _PATH},
    "times": {"format": str},
    "accelerations": {
        "inputs": _PATHS,
        "time_column": str,
        "time_format": str,
        "separator": str,
        "decimal": str,
        "start_time": str,
        "sampling_rate_hz": (int, float),
        "units": (str, dict),
        "channels": list,
        "variables": dict,
    },
    "dship": {"file": _PATH, "columns": dict},
    "predictors": {"file": _PATH, "all": bool},
    "modal": {
        "file": _PATH,
        "damping_unit": str,
        "time_reference": str,
        "time_zone": str,
        "grid_t0": str,
    },
    "blocks": {
        "length_minutes": (int, float, str),
        "step_minutes": (int, float),
        "max_gap_s": (int, float),
    },
    "identify": {
        "method": str,
        "block_rows": int,
        "min_order": int,
        "max_order": int,
        "weighting": str,
        "reference_channels": list,
        "rate": (int, float),
        "band": list,
        "no_band": bool,
        "harmonic_orders": list,
        "blades": int,
    },
    "track": {
        "mac_min": (int, float),
        "gate": str,
        "frequency_tol": (int, float),
        "reference_modes": _PATH,
    },
    "correlate": {
        "alpha": (int, float),
        "correction": str,
        "min_presence": (int, float),
        "cases": _PATH,
    },
    "fit": {
        "p_enter": (int, float),
        "p_remove": (int, float),
        "upper": str,
        "min_presence": (int, float),
    },
    "forecast": {
        "option": str,
        "scheme": (str, int),
        "train_blocks": int,
        "horizon": int,
        "trust": (str, int, float),
        "min_presence": (int, float),
        "mac_min": (int, float),
        "reacquire_blocks": int,
        "model": str,
        "figures": bool,
    },
    "evaluate": {"truth": _PATH, "phase": str},
}


# ------------------------------------------------------------------------- value checks
#: Highest block rows a file may ask for: far above what any block allows, low enough that
#: nothing huge is built. Model orders share identify's one limit (``MAX_MODEL_ORDER``).
MAX_BLOCK_ROWS = 10_000


def _number(low=None, high=None, *, low_open=False, high_open=False, whole=False):
    """A check of a finite number in a range (``whole``: an integer)."""

    def check(value) -> str | None:
        if whole and not isinstance(value, int):
            return "must be a whole number"
        if not math.isfinite(value):
            return "must be a finite number"
        if low is not None and (value <= low if low_open else value < low):
            return f"must be {'above' if low_open else 'at least'} {low:g}"
        if high is not None and (value >= high if high_open else value > high):
            return f"must be {'below' if high_open else 'at most'} {high:g}"
        return None

    return check


def _one_of(*choices):
    def check(value) -> str | None:
        if value not in choices:
            near = difflib.get_close_matches(str(value), [str(c) for c in choices], n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            return f"must be one of {', '.join(repr(c) for c in choices)}{hint}"
        return None

    return check


def _texts(value) -> str | None:
    if not value or not all(isinstance(v, str) and v.strip() for v in value):
        return "must be a non-empty list of names (text)"
    return None


def _text_map(value) -> str | None:
    if not value or not all(isinstance(v, str) for v in value.values()):
        return 'must be a table of names (text), e.g. { key = "name" }'
    return None


def _band(value) -> str | None:
    numbers = [v for v in value if isinstance(v, int | float) and not isinstance(v, bool)]
    if len(value) != 2 or len(numbers) != 2 or not all(math.isfinite(v) for v in numbers):
        return "must be two finite frequencies [low, high] in Hz"
    if not 0 <= numbers[0] < numbers[1]:
        return "must be [low, high] with 0 <= low < high"
    return None


def _orders(value) -> str | None:
    numbers = [v for v in value if isinstance(v, int | float) and not isinstance(v, bool)]
    if (
        not value
        or len(numbers) != len(value)
        or not all(math.isfinite(v) and v > 0 for v in numbers)
    ):
        return "must be a non-empty list of positive shaft orders, e.g. [1, 2, 3]"
    return None


def _log_columns(value) -> str | None:
    """A ``[dship] columns`` table: names (text) of the log's canonical columns."""
    from data_contracts.dship_names import AUXILIARY_COLUMNS, SHAFT_COLUMNS
    from data_contracts.tables import CANONICAL_PREDICTORS, OPTIONAL_PREDICTORS

    wrong = _text_map(value)
    if wrong:
        return wrong
    known = sorted(
        {c.name for c in CANONICAL_PREDICTORS}
        | {c.name for c in OPTIONAL_PREDICTORS}
        | set(AUXILIARY_COLUMNS)
        | set(SHAFT_COLUMNS)
        | {"time"}
    )
    unknown = [k for k in value if k not in known]
    if unknown:
        near = difflib.get_close_matches(unknown[0], known, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        return f"has unknown column(s) {', '.join(unknown)}{hint}; known: {', '.join(known)}"
    return None


def _rate(value) -> str | None:
    if isinstance(value, str):
        return _one_of("auto", "native")(value)
    return _number(0.0, low_open=True)(value)


def _trust(value) -> str | None:
    if isinstance(value, str):
        return None if value.strip().lower() == "data" else "must be a number in (0, 1) or 'data'"
    return _number(0.0, 1.0, low_open=True, high_open=True)(value)


def _iso_time(value) -> str | None:
    import pandas as pd

    try:
        pd.Timestamp(value)
    except (ValueError, TypeError):
        return "must be an ISO-8601 time, e.g. 2024-03-01T00:00:00Z"
    return None


_SHARE = _number(0.0, 1.0)
_PROBABILITY = _number(0.0, 1.0, low_open=True, high_open=True)
_POSITIVE = _number(0.0, low_open=True)

#: Section -> key -> check of a value of the right type: None or what is wrong.
CHECKS: dict[str, dict[str, Any]] = {
    "accelerations": {
        "sampling_rate_hz": _POSITIVE,
        "units": lambda v: None if isinstance(v, str) else _text_map(v),
        "channels": _texts,
        "variables": _text_map,
    },
    "dship": {"columns": _log_columns},
    "modal": {
        "damping_unit": _one_of("percent", "fraction"),
        "time_reference": _one_of("start", "centre", "end"),
        "grid_t0": _iso_time,
    },
    "blocks": {
        # minutes, or "auto": identify's and the monitor's length from the conditions
        "length_minutes": lambda v: (
            (None if v == "auto" else 'must be minutes or "auto"')
            if isinstance(v, str)
            else _POSITIVE(v)
        ),
        "step_minutes": _POSITIVE,
        "max_gap_s": _number(0.0),
    },
    "identify": {
        "method": _one_of("cov", "data", "lscf"),
        "block_rows": _number(1, MAX_BLOCK_ROWS, whole=True),
        "min_order": _number(1, MAX_MODEL_ORDER, whole=True),
        "max_order": _number(1, MAX_MODEL_ORDER, whole=True),
        "weighting": _one_of("pc", "upc", "cva"),
        "reference_channels": _texts,
        "rate": _rate,
        "band": _band,
        "harmonic_orders": _orders,
        "blades": _number(0, whole=True),
    },
    "track": {
        "mac_min": _SHARE,
        "gate": _one_of("mac", "macxp"),
        "frequency_tol": _POSITIVE,
    },
    "correlate": {
        "alpha": _PROBABILITY,
        "correction": _one_of("none", "holm", "fdr_bh"),
        "min_presence": _SHARE,
    },
    "fit": {"p_enter": _PROBABILITY, "p_remove": _PROBABILITY, "min_presence": _SHARE},
    "forecast": {
        "option": _one_of("tracked-pole", "pole-cluster", "both", "A", "B", "AB"),
        "scheme": _one_of("single-window", "rolling", 1, 2, "1", "2"),
        "train_blocks": _number(5, whole=True),  # forecast.options.MIN_TRAIN_BLOCKS
        "horizon": _number(1, whole=True),
        "trust": _trust,
        "model": _one_of("memory", "window"),
        "min_presence": _SHARE,
        "mac_min": _SHARE,
        "reacquire_blocks": _number(1, whole=True),
    },
    "evaluate": {"phase": _one_of("forecast", "train", "all")},
}


def _together(sections: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Problems of keys that only make sense together."""
    problems = []

    def has(section: str, key: str) -> bool:
        return key in sections.get(section, {})

    def get(section: str, key: str, default=None):
        return sections.get(section, {}).get(key, default)

    if has("forecast", "trust") and get("forecast", "model") != "window":
        model = get("forecast", "model")
        which = "the default model" if model is None else f"model = {model!r}"
        problems.append(
            f'[forecast] trust = {get("forecast", "trust")!r} applies to model = "window" '
            f'only ({which} takes its noise levels from the data): add model = "window" '
            "or remove trust"
        )
    length, step = get("blocks", "length_minutes"), get("blocks", "step_minutes")
    if length not in (None, "auto") and step is not None and step > length:
        problems.append(
            f"[blocks] step_minutes = {step!r} is longer than length_minutes = {length!r}"
        )
    low, high = get("identify", "min_order"), get("identify", "max_order")
    if low is not None and high is not None and low > high:
        problems.append(f"[identify] min_order = {low!r} is above max_order = {high!r}")
    if has("identify", "band") and get("identify", "no_band"):
        problems.append("[identify] band and no_band = true contradict each other")
    enter, remove = get("fit", "p_enter"), get("fit", "p_remove")
    if enter is not None and remove is not None and not enter < remove:
        problems.append(f"[fit] p_enter = {enter!r} must be below p_remove = {remove!r}")
    return problems


def _shown(value) -> str:
    """A value as the file wrote it, cut to one short line."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:57]}..."


def _nearest(given: str, known) -> str:
    near = difflib.get_close_matches(given, list(known), n=1, cutoff=0.6)
    return f"did you mean {near[0]!r}? " if near else ""


class ConfigError(ValueError):
    """A configuration file that cannot be used (the message names file and key)."""


@dataclass(frozen=True)
class ShipConfig:
    """A parsed configuration: its sections (paths resolved) and the file it came from."""

    path: Path
    sections: dict[str, dict[str, Any]]

    def get(self, section: str, key: str, default=None):
        return self.sections.get(section, {}).get(key, default)

    def has(self, section: str, key: str | None = None) -> bool:
        if key is None:
            return section in self.sections
        return key in self.sections.get(section, {})

    @property
    def out_dir(self) -> Path:
        return self.get("output", "dir") or self.path.parent / "out"


def load_config(path: str | os.PathLike) -> ShipConfig:
    """Read and check a TOML configuration as a whole.

    Raises
    ------
    ConfigError
        A file that cannot be read or is not UTF-8 TOML (one line); else every problem at
        once, one line each naming section and key: unknown sections and keys (with the
        nearest known one), values of the wrong type, out of range or not among the
        choices, and keys that contradict each other.
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")
        data = tomllib.loads(text)
    except OSError as error:
        raise ConfigError(f"{path}: cannot read: {error.strerror or error}") from None
    except UnicodeDecodeError as error:
        raise ConfigError(
            f"{path}: not a UTF-8 text file (byte {error.start}); a configuration is TOML "
            "written in UTF-8"
        ) from None
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{path}: not valid TOML: {str(error).splitlines()[0]}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not a configuration: values nested too deeply") from None
    problems = []
    sections: dict[str, dict[str, Any]] = {}
    base = path.parent
    for name, values in data.items():
        if name not in SCHEMA:
            problems.append(
                f"unknown section [{name}] ({_nearest(name, SCHEMA)}known: {', '.join(SCHEMA)})"
            )
            continue
        if not isinstance(values, dict):
            problems.append(f"[{name}] must be a table")
            continue
        section = {}
        for key, value in values.items():
            kind = SCHEMA[name].get(key)
            if kind is None:
                problems.append(
                    f"[{name}] unknown key '{key}' ({_nearest(key, SCHEMA[name])}"
                    f"known: {', '.join(SCHEMA[name])})"
                )
            elif kind == _PATH:
                if not isinstance(value, str) or not value.strip():
                    problems.append(f"[{name}] {key} = {_shown(value)} must be a path (text)")
                else:
                    section[key] = base / value
            elif kind == _PATHS:
                items = [value] if isinstance(value, str) else value
                if (
                    not isinstance(items, list)
                    or not items
                    or not all(isinstance(v, str) and v.strip() for v in items)
                ):
                    problems.append(
                        f"[{name}] {key} = {_shown(value)} must be a path or a list of paths"
                    )
                else:
                    section[key] = [base / v for v in items]
            elif not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
                problems.append(f"[{name}] {key} = {_shown(value)} has the wrong type")
            else:
                check = CHECKS.get(name, {}).get(key)
                wrong = check(value) if check is not None else None
                if wrong:
                    problems.append(f"[{name}] {key} = {_shown(value)} {wrong}")
                else:
                    section[key] = value
        sections[name] = section
    problems += _together(sections)
    if problems:
        raise ConfigError("\n".join(f"{path}: {p}" for p in problems))
    return ShipConfig(path, sections)


def _pairs(mapping: Mapping[str, Any]) -> str:
    return ",".join(f"{k}={v}" for k, v in mapping.items())


def command_defaults(command: str, config: ShipConfig) -> dict[str, Any]:
    """argparse destinations -> values of *command* taken from *config*.

    ``monitor`` reads the sections the batch commands read (its options are theirs):
    identify's, track's and forecast's values (``mac_min`` from ``[track]``), the watched
    folder from ``[accelerations] inputs`` and the state folder ``OUTPUT/monitor``.
    """
    if command == "monitor":
        forecast = command_defaults("forecast", config)
        forecast.pop("mac_min", None)  # the monitor's one --mac-min is track's
        identify = command_defaults("identify", config)
        values = {**forecast, **identify, **command_defaults("track", config)}
        if identify.get("inputs"):
            values["watch"] = Path(identify["inputs"][0])
        values["state"] = config.out_dir / "monitor"
        return values
    c = config
    out = c.out_dir
    values: dict[str, Any] = {}

    def put(dest: str, section: str, key: str, convert=lambda v: v) -> None:
        if c.has(section, key):
            values[dest] = convert(c.get(section, key))

    # one time format for every time column and text start time a command reads
    put("time_format", "times", "format")
    # where the modal table and the predictors come from
    modal = c.get("modal", "file") or out / "tracked_modal.csv"
    if command in ("correlate", "fit", "forecast"):
        values["modal"] = modal
        put("dship", "dship", "file")
        put("predictors", "predictors", "file")
        put("all_predictors", "predictors", "all")
    if command in ("correlate", "fit", "forecast", "validate"):
        put("dship_columns", "dship", "columns", lambda m: [_pairs(m)])
    if command == "report" and c.has("modal", "file"):
        values["modal"] = modal
    if command in ("correlate", "fit", "forecast", "evaluate", "report"):
        put("damping_unit", "modal", "damping_unit")
        put("time_reference", "modal", "time_reference")
        put("time_zone", "modal", "time_zone")
        # a grid of one length (blocks of varying length: the table's own grid record)
        if (
            c.has("modal")
            and (c.has("blocks") or c.has("modal", "grid_t0"))
            and c.get("blocks", "length_minutes") != "auto"
        ):
            grid = [
                c.get("blocks", "length_minutes", DEFAULT_BLOCK_LENGTH_S / 60.0),
                c.get("blocks", "step_minutes", DEFAULT_BLOCK_STEP_S / 60.0),
            ]
            if c.has("modal", "grid_t0"):
                grid.append(c.get("modal", "grid_t0"))
            values["grid"] = ",".join(str(g) for g in grid)
    if command in ("identify", "validate", "report"):
        put("time_column", "accelerations", "time_column")
        put("time_format", "accelerations", "time_format")
        put("separator", "accelerations", "separator")
        put("decimal", "accelerations", "decimal")
        put("start_time", "accelerations", "start_time")
        put("sampling_rate", "accelerations", "sampling_rate_hz")
        put("units", "accelerations", "units", lambda u: u if isinstance(u, str) else _pairs(u))
        put("channels", "accelerations", "channels", lambda v: ",".join(v))
        put("variables", "accelerations", "variables", _pairs)
    if command == "identify":
        put("inputs", "accelerations", "inputs")
        values["out"] = out / "identify"
        for key in (
            "method",
            "block_rows",
            "min_order",
            "max_order",
            "weighting",
            "rate",
            "no_band",
        ):
            put(key, "identify", key)
        put("band", "identify", "band", tuple)
        put("reference_channels", "identify", "reference_channels", lambda v: ",".join(v))
        # the ship log's shaft speed (or speed) marks the shaft harmonics
        put("dship", "dship", "file")
        put("dship_columns", "dship", "columns", lambda m: [_pairs(m)])
        put("harmonic_orders", "identify", "harmonic_orders", lambda v: ",".join(map(str, v)))
        put("blades", "identify", "blades")
        put("block_minutes", "blocks", "length_minutes")
        put("step_minutes", "blocks", "step_minutes")
        put("max_gap", "blocks", "max_gap_s")
    elif command == "track":
        values["selected"] = out / "identify" / "selected.parquet"
        values["out"] = out / "tracked_modal.csv"
        for key in ("mac_min", "gate", "frequency_tol", "reference_modes"):
            put(key, "track", key)
    elif command == "correlate":
        values["out"] = out / "correlation"
        for key in ("alpha", "correction", "min_presence", "cases"):
            put(key, "correlate", key)
    elif command == "fit":
        values["out"] = out / "fit"
        for key in ("p_enter", "p_remove", "upper", "min_presence"):
            put(key, "fit", key)
    elif command == "forecast":
        values["out"] = out / "forecast.csv"
        for key in ("option", "train_blocks", "horizon", "min_presence", "mac_min", "model"):
            put(key, "forecast", key)
        put("scheme", "forecast", "scheme", str)
        put("reacquire_blocks", "forecast", "reacquire_blocks")
        put("trust", "forecast", "trust", str)
        if c.get("forecast", "figures", False):
            values["figures"] = out / "forecast_figures"
        option = str(c.get("forecast", "option", "A"))
        if option in ("B", "AB", "pole-cluster", "both") and c.has("accelerations", "inputs"):
            values["poles"] = out / "identify" / "poles.parquet"
    elif command == "report":
        # the run's own folder, files and reading settings (its results are taken as
        # the stages left them: see workbench.reporting.report)
        values["dir"] = out
        put("accelerations", "accelerations", "inputs")
        put("dship", "dship", "file")
        put("dship_columns", "dship", "columns", lambda m: [_pairs(m)])
        put("cases", "correlate", "cases")
    elif command == "evaluate":
        values["forecast"] = out / "forecast.csv"
        put("truth", "evaluate", "truth")
        put("phase", "evaluate", "phase")
        values["out"] = out / "evaluation.csv"
    return values


def apply_config(parser: argparse.ArgumentParser, config: ShipConfig) -> None:
    """Take every subcommand's defaults from *config*; options it supplies stop being
    required (flags on the command line still win)."""
    subparsers = next(
        a
        for a in parser._actions
        if isinstance(a, argparse._SubParsersAction)  # noqa: SLF001
    )
    for command, sub in subparsers.choices.items():
        defaults = command_defaults(command, config)
        known = {a.dest for a in sub._actions}  # noqa: SLF001
        defaults = {k: v for k, v in defaults.items() if k in known}
        if not defaults:
            continue
        sub.set_defaults(**defaults)
        for action in sub._actions:  # noqa: SLF001
            if action.dest in defaults:
                action.required = False
                if not action.option_strings and action.nargs == "+":
                    action.nargs = "*"
                if not action.option_strings and action.nargs is None:
                    action.nargs = "?"
        for group in sub._mutually_exclusive_groups:  # noqa: SLF001
            if any(a.dest in defaults for a in group._group_actions):  # noqa: SLF001
                group.required = False


def chain(config: ShipConfig) -> list[list[str]]:
    """The commands ``workbench run`` runs for *config*, in order; the last builds the
    run's report."""
    flag = ["--config", str(config.path)]
    steps: list[list[str]] = []
    if config.has("accelerations", "inputs"):
        steps.append(["identify", *flag])
        if not config.has("modal", "file"):
            steps.append(["track", *flag])
    elif not config.has("modal", "file"):
        raise ConfigError(
            f"{config.path}: nothing to run: give [accelerations] inputs or a [modal] file"
        )
    if config.has("dship", "file") or config.has("predictors", "file"):
        steps += [["correlate", *flag], ["fit", *flag], ["forecast", *flag]]
        if config.has("evaluate", "truth"):
            steps.append(["evaluate", *flag])
    steps.append(["report", *flag])  # the run's report, from the results above
    return steps


def write_config(
    path: str | os.PathLike, sections: Mapping[str, Mapping[str, Any]], *, comment: str = ""
) -> Path:
    """Write *sections* as a TOML configuration (atomically); paths as given."""
    from data_contracts import atomic_path

    def value(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int | float):
            return repr(v)
        if isinstance(v, list | tuple):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, Mapping):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        text = str(v).replace("\\", "\\\\").replace('"', '\\"')
        return f'"{text}"'

    lines = [f"# {line}" for line in comment.splitlines()] + ([""] if comment else [])
    for name, entries in sections.items():
        lines.append(f"[{name}]")
        lines += [f"{k} = {value(v)}" for k, v in entries.items()]
        lines.append("")
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_text("\n".join(lines), encoding="utf-8")
    load_config(path)  # what we write must read back
    return path


def write_demo_config(
    out_dir: str | os.PathLike,
    voyage: str = "voyage",
    *,
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
) -> Path:
    """The demo voyage's set-up as an example configuration, ``out_dir/ship.toml``.

    ``workbench run out_dir/ship.toml`` (and ``workbench monitor --config``) repeats the
    demo's chain on the simulated files into ``out_dir/ship_run`` (the demo's own results
    are left alone). *overrides* replace keys of sections (e.g. a smaller model order for
    a short voyage); the file is checked like any other (:func:`load_config`).
    """
    sections = {
        "output": {"dir": "ship_run"},
        "accelerations": {"inputs": [f"{voyage}/accelerations"]},
        "dship": {"file": f"{voyage}/dship.tsv"},
        "blocks": {"length_minutes": 20, "step_minutes": 5},
        "identify": {"method": "cov", "band": [2.0, 12.0], "max_order": 60, "blades": 5},
        "track": {"mac_min": 0.9, "gate": "mac"},
        "correlate": {"alpha": 0.05, "cases": f"{voyage}/cases.csv"},
        "fit": {"p_enter": 0.05, "p_remove": 0.10},
        "forecast": {
            "option": "both",
            "scheme": "rolling",
            "train_blocks": 20,
            "model": "memory",  # the demo's (and the default) model; no trust: see comment
            "figures": True,
        },
        "evaluate": {"truth": f"{voyage}/truth_modal.csv"},
    }
    for name, entries in (overrides or {}).items():
        sections[name] = {**sections.get(name, {}), **entries}
    comment = (
        "The demo voyage's set-up, written by `workbench demo` as an example.\n"
        "Run it with: workbench run ship.toml   (or any command with --config ship.toml)\n"
        "Paths are relative to this file. Sections and keys: see workbench/config.py.\n"
        '[forecast] model = "window" (the reference configuration) takes a hand-set\n'
        "trust = 0.65 (steady-state weight on SSI); the memory model takes its noise from the data."
    )
    return write_config(Path(out_dir) / "ship.toml", sections, comment=comment)
