"""Pieces every command's argument parser shares: help that shows defaults, renamed
options whose old spelling still works, descriptive choices with short aliases, and the
``--verbose``/``--quiet`` switches accepted before or after the command.

Kept apart from :mod:`workbench.cli` so that the commands only declare their options.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "RENAMED",
    "HelpFormatter",
    "Namespace",
    "add_renamed",
    "add_verbosity",
    "choice",
    "stderr_is_terminal",
]


class HelpFormatter(argparse.HelpFormatter):
    """``--help`` with ``(default: X)`` after every option that has a default.

    Options whose default is ``None`` or ``False`` (computed defaults, switches) say in
    their own help text what happens when they are not given.
    """

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help
        if not text or text == argparse.SUPPRESS or "default" in text:
            return text
        default = action.default
        if default is None or default is False or default == argparse.SUPPRESS:
            return text
        if not action.option_strings:
            return text
        return f"{text} (default: %(default)s)"


#: Namespace attribute holding a command's renamed destinations (old name -> new name).
RENAMED = "renamed_destinations"


class Namespace(argparse.Namespace):
    """Parsed arguments that also answer the old names of renamed destinations, so code
    written against them (in other branches) still runs."""

    def __getattr__(self, name: str) -> Any:
        renamed = self.__dict__.get(RENAMED) or {}
        if name not in renamed:
            raise AttributeError(name)
        return getattr(self, renamed[name])


class _Deprecated(argparse.Action):
    """An old spelling of an option: hidden from ``--help``, stores into the new option's
    destination and prints a one-line deprecation note on stderr."""

    def __init__(self, option_strings, dest, *, new: str, **kwargs):
        self.new = new
        kwargs["help"] = argparse.SUPPRESS
        kwargs["default"] = argparse.SUPPRESS
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(
            f"workbench: warning: {option_string} is deprecated; use {self.new}",
            file=sys.stderr,
        )
        setattr(namespace, self.dest, values)


def add_renamed(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    flag: str,
    old_flags: Sequence[str],
    **kwargs: Any,
) -> argparse.Action:
    """Add option *flag* (with argparse's *kwargs*) and its old spellings *old_flags*."""
    action = parser.add_argument(flag, **kwargs)
    renamed = dict(parser.get_default(RENAMED) or {})  # a group shares its parser's defaults
    for old in old_flags:
        old_dest = old.lstrip("-").replace("-", "_")
        if old_dest != action.dest:
            renamed[old_dest] = action.dest
    parser.set_defaults(**{RENAMED: renamed})
    parser.add_argument(
        *old_flags,
        dest=action.dest,
        action=_Deprecated,
        new=flag,
        nargs=action.nargs,
        type=action.type,
        metavar=action.metavar,
    )
    return action


class choice:  # noqa: N801 (used like a type: ``type=choice(...)``)
    """argparse *type* for named choices with aliases: returns the value a name or alias
    stands for, refuses anything else naming the choices (aliases in brackets)."""

    def __init__(self, names: Mapping[str, Any], aliases: Mapping[str, str] | None = None):
        self.names = dict(names)
        self.aliases = dict(aliases or {})

    @property
    def metavar(self) -> str:
        return "{" + ",".join(self.names) + "}"

    def __call__(self, text: str) -> Any:
        key = self.aliases.get(str(text).strip(), str(text).strip())
        if key in self.names:
            return self.names[key]
        if key.lower() in self.names:
            return self.names[key.lower()]
        shown = ", ".join(self.names)
        if self.aliases:
            shown += " (aliases: " + ", ".join(f"{a}={n}" for a, n in self.aliases.items()) + ")"
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {shown})")

    def name_of(self, value: Any) -> str:
        """The descriptive name of *value* (for defaults shown in ``--help``)."""
        return next(name for name, v in self.names.items() if v == value)


def add_verbosity(parser: argparse.ArgumentParser, *, top_level: bool = False) -> None:
    """``-v/--verbose`` and ``-q/--quiet``. On a subcommand they default to SUPPRESS, so a
    switch given before the command is not reset by the subcommand's parser."""
    default = False if top_level else argparse.SUPPRESS
    parser.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=default,
        help="show tracebacks and debug logging",
    )
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=default,
        help="no progress bars (they are never drawn when stderr is not a terminal)",
    )


def stderr_is_terminal() -> bool:
    """Whether progress bars can be drawn: stderr is an interactive terminal."""
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # replaced or closed stream
        return False
