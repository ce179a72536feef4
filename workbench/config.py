"""A ship's set-up in one TOML file: inputs and their layouts, block grid, models, forecast.

``workbench run ship.toml`` runs the chain the file describes (identify -> track ->
correlate -> fit -> forecast -> evaluate, each where its inputs are given); ``--config
ship.toml`` on any command takes that command's settings from the file, and flags given on
the command line win. Paths in the file are relative to the file. Unknown sections and keys
are refused by name (a mistyped option must not be ignored). Example::

    [output]
    dir = "out"

    [accelerations]                     # recordings and how to read them
    inputs = ["recordings/"]
    start_time = "filename"             # relative times; start in the file names
    units = "g"

    [dship]                             # the ship's log
    file = "dship/extraction.dat"
    columns = { speed_kn = "SYS.STR.SOG" }

    [blocks]
    length_minutes = 20
    step_minutes = 5

    [identify]
    band = [2.0, 12.0]
    rate = 64
    blades = 5                          # the [dship] log's shaft speed marks the shaft
    harmonic_orders = [1, 2, 3]         # orders and blade pass, kept out of the modes

    [forecast]
    option = "both"                     # tracked-pole (A), pole-cluster (B) or both
    train_blocks = 20

A modal table from another tool replaces identification and tracking::

    [modal]
    file = "artemis_modes.csv"
    damping_unit = "percent"
    time_reference = "centre"
"""

from __future__ import annotations

import argparse
import os
import tomllib
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = [
    "SCHEMA",
    "ConfigDeprecationWarning",
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
        "length_minutes": (int, float),
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
        "figures": bool,
    },
    "evaluate": {"truth": _PATH, "phase": str},
}


#: Keys renamed with the vocabulary (README, "Glossary"): section -> old key -> new key. The
#: old keys are still read, with a warning.
RENAMED_KEYS: dict[str, dict[str, str]] = {
    "track": {
        "threshold": "mac_min",
        "frequency_tolerance": "frequency_tol",
        "reference": "reference_modes",
    },
    "forecast": {"method": "scheme", "train": "train_blocks", "shape_mac_min": "mac_min"},
}


class ConfigDeprecationWarning(UserWarning):
    """A configuration key under its old name (still read; shown to the user)."""


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
    """Read and check a TOML configuration.

    Raises
    ------
    ConfigError
        Unreadable TOML, unknown sections or keys, values of the wrong type.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ConfigError(f"{path}: cannot read: {error.strerror or error}") from None
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{path}: not valid TOML: {error}") from None
    problems = []
    sections: dict[str, dict[str, Any]] = {}
    base = path.parent
    for name, values in data.items():
        if name not in SCHEMA:
            problems.append(f"unknown section [{name}] (known: {', '.join(SCHEMA)})")
            continue
        if not isinstance(values, dict):
            problems.append(f"[{name}] must be a table")
            continue
        section = {}
        for given, value in values.items():
            key = given
            new = RENAMED_KEYS.get(name, {}).get(key)
            if new is not None:
                if new in values:
                    problems.append(f"[{name}] give {new} only ({key} is its old name)")
                    continue
                warnings.warn(
                    f"{path}: [{name}] {key} is deprecated; use {new}",
                    ConfigDeprecationWarning,
                    stacklevel=2,
                )
                key = new
            kind = SCHEMA[name].get(key)
            if kind is None:
                problems.append(
                    f"[{name}] unknown key '{given}' (known: {', '.join(SCHEMA[name])})"
                )
            elif kind == _PATH:
                if not isinstance(value, str):
                    problems.append(f"[{name}] {given} must be a path (text)")
                else:
                    section[key] = base / value
            elif kind == _PATHS:
                items = [value] if isinstance(value, str) else value
                if not isinstance(items, list) or not all(isinstance(v, str) for v in items):
                    problems.append(f"[{name}] {given} must be a path or a list of paths")
                else:
                    section[key] = [base / v for v in items]
            elif not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
                problems.append(f"[{name}] {given} = {value!r} has the wrong type")
            else:
                section[key] = value
        sections[name] = section
    if problems:
        raise ConfigError("\n".join(f"{path}: {p}" for p in problems))
    return ShipConfig(path, sections)


def _pairs(mapping: Mapping[str, Any]) -> str:
    return ",".join(f"{k}={v}" for k, v in mapping.items())


def command_defaults(command: str, config: ShipConfig) -> dict[str, Any]:
    """argparse destinations -> values of *command* taken from *config*."""
    c = config
    out = c.out_dir
    values: dict[str, Any] = {}

    def put(dest: str, section: str, key: str, convert=lambda v: v) -> None:
        if c.has(section, key):
            values[dest] = convert(c.get(section, key))

    # where the modal table and the predictors come from
    modal = c.get("modal", "file") or out / "tracked_modal.csv"
    if command in ("correlate", "fit", "forecast"):
        values["modal"] = modal
        put("dship", "dship", "file")
        put("predictors", "predictors", "file")
        put("all_predictors", "predictors", "all")
    if command in ("correlate", "fit", "forecast", "validate"):
        put("dship_columns", "dship", "columns", lambda m: [_pairs(m)])
    if command in ("correlate", "fit", "forecast", "evaluate"):
        put("damping_unit", "modal", "damping_unit")
        put("time_reference", "modal", "time_reference")
        put("time_zone", "modal", "time_zone")
        if c.has("modal") and (c.has("blocks") or c.has("modal", "grid_t0")):
            grid = [
                c.get("blocks", "length_minutes", 20.0),
                c.get("blocks", "step_minutes", 5.0),
            ]
            if c.has("modal", "grid_t0"):
                grid.append(c.get("modal", "grid_t0"))
            values["grid"] = ",".join(str(g) for g in grid)
    if command in ("identify", "validate"):
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
        put("reference", "identify", "reference_channels", lambda v: ",".join(v))
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
        for key in ("option", "train_blocks", "horizon", "min_presence", "mac_min"):
            put(key, "forecast", key)
        put("scheme", "forecast", "scheme", str)
        put("reacquire_blocks", "forecast", "reacquire_blocks")
        put("trust", "forecast", "trust", str)
        if c.get("forecast", "figures", False):
            values["figures"] = out / "forecast_figures"
        option = str(c.get("forecast", "option", "A"))
        if option in ("B", "AB", "pole-cluster", "both") and c.has("accelerations", "inputs"):
            values["poles"] = out / "identify" / "poles.parquet"
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
    """The commands ``workbench run`` runs for *config*, in order."""
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


def write_demo_config(out_dir: str | os.PathLike, voyage: str = "voyage") -> Path:
    """The demo voyage's set-up as an example configuration, ``out_dir/ship.toml``.

    ``workbench run out_dir/ship.toml`` repeats the demo's chain on the simulated files
    into ``out_dir/ship_run`` (the demo's own results are left alone).
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
            "trust": 0.65,
            "figures": True,
        },
        "evaluate": {"truth": f"{voyage}/truth_modal.csv"},
    }
    comment = (
        "The demo voyage's set-up, written by `workbench demo` as an example.\n"
        "Run it with: workbench run ship.toml   (or any command with --config ship.toml)\n"
        "Paths are relative to this file. Sections and keys: see workbench/config.py."
    )
    return write_config(Path(out_dir) / "ship.toml", sections, comment=comment)
