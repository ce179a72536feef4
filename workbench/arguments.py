"""Pieces every command's argument parser shares: help that shows defaults, options one
command takes over from another (:func:`copy_flags`), descriptive choices with short
aliases, and the ``--verbose``/``--quiet`` switches accepted before or after the command.

Kept apart from :mod:`workbench.cli` so that the commands only declare their options.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "HelpFormatter",
    "add_verbosity",
    "choice",
    "copy_flags",
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


def copy_flags(
    source: argparse.ArgumentParser,
    target: argparse.ArgumentParser | argparse._ArgumentGroup,
    dests: Sequence[str],
    *,
    help: Mapping[str, str] | None = None,
) -> None:
    """Add to *target* the options of *source* whose destinations are *dests*: the same
    flags, type, choices, default and help (*help* replaces the text of some), in
    *source*'s order. A command that shares another's options (``monitor`` those of
    ``identify``, ``track``, ``forecast`` and ``health``) declares them this way, so that
    each option is declared once.

    Raises
    ------
    KeyError
        A destination *source* has no option for.
    """
    wanted = set(dests)
    actions = [a for a in source._actions if a.dest in wanted and a.option_strings]  # noqa: SLF001
    missing = wanted - {a.dest for a in actions}
    if missing:
        raise KeyError(f"{source.prog} has no option for {', '.join(sorted(missing))}")
    for action in actions:
        kwargs: dict[str, Any] = {
            "action": type(action),
            "dest": action.dest,
            "default": action.default,
            "help": dict(help or {}).get(action.dest, action.help),
        }
        if action.nargs != 0:  # not a switch: the value's reading and display
            kwargs.update(
                nargs=action.nargs,
                const=action.const,
                type=action.type,
                choices=action.choices,
                metavar=action.metavar,
            )
        target.add_argument(*action.option_strings, **kwargs)


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
