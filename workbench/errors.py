r"""Exceptions for user-facing problems that are not contract violations, and how a
message is made safe to print.

One rule for exit codes everywhere: :class:`OptionError` (an option that cannot work, with
this data or at all) is a usage error, exit 2, reported without an input file's name;
:class:`WorkbenchError` and contract errors are bad data or files, exit 1.

Messages quote file names, column names and cell values, which may hold terminal escape
sequences (``\x1b]0;...``) or line breaks that fake a second message: :func:`printable`
shows every control character escaped, as Python's ``repr`` would (``\x1b``, ``\n``).
"""

import re

#: Exit status of a command ended by Ctrl-C (128 + SIGINT, as the shells report it).
EXIT_INTERRUPTED = 130

#: C0 and C1 control characters, DEL, and the Unicode line separators and bidirectional
#: controls that reorder what a terminal shows.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def _escape(match: re.Match) -> str:
    character = match.group()
    return repr(character)[1:-1] if ord(character) < 0x100 else f"\\u{ord(character):04x}"


def printable(text) -> str:
    r"""*text* with every control character escaped (``\x1b``, ``\n``, ``\u202e``), so
    a message is one line that cannot drive the terminal."""
    return _CONTROL.sub(_escape, str(text))


class WorkbenchError(Exception):
    """A problem with the user's data or files that the CLI reports in one line (exit 1).

    The message names the file, column or block concerned.
    """


class OptionError(ValueError):
    """An option value that makes no sense, alone or with the data (CLI: usage error, exit 2).

    Raised before any work is done; the message names the option, its value and the
    constraint (``band_hz=(2.0, 40.0): upper edge must lie below the Nyquist frequency
    32 Hz``).
    """


class DataError(ValueError):
    """Data that cannot serve a computation as asked (too few blocks for a window): bad
    data (exit 1), said with the parameter that asked for it.

    The message speaks of the table's blocks and columns by the names the table holds; it
    does not name a file (a stage takes DataFrames): the CLI names the file and shows
    *parameter* as the flag that set it, where a library caller reads ``parameter=value``.

    Parameters
    ----------
    message : str
        What is wrong, one line.
    parameter : str, optional
        The parameter that set the size asked for (``train_blocks``), shown with *value*.
    value : optional
        Its value.
    """

    def __init__(self, message: str, *, parameter: str | None = None, value=None):
        self.message = message
        self.parameter = parameter
        self.value = value
        shown = f" ({parameter}={value!r})" if parameter is not None else ""
        super().__init__(f"{message}{shown}")

    def for_user(self, flags: dict[str, str] | None = None) -> str:
        """The message with *parameter* shown as the flag *flags* maps it to (its text
        as given, e.g. ``{"train_blocks": "--train-blocks 6"}``), or as ``name=value``."""
        if self.parameter is not None and flags and self.parameter in flags:
            return f"{self.message} ({flags[self.parameter]})"
        return str(self)


class PredictorError(DataError):
    """A :class:`DataError` of the predictor table (the ship log's values per block):
    too few blocks in a span, a column missing. The CLI names the predictor file
    (``--predictors``, or the ship log given as ``--dship``), not the modal table."""


class UnreadableInputError(WorkbenchError, ValueError):
    """An input file whose samples cannot be read: cut short, a bad checksum, not the
    format its name says.

    Bad data (exit 1) where it ends a command; a ``ValueError`` too, so a block that meets
    it is skipped like any block whose data is bad. A batch run leaves the file out: the
    blocks that need it are skipped with ``"<path>: unreadable (<detail>)"`` as the
    reason and every other block is identified as if the file were not there
    (``workbench identify`` names the file in one warning).

    Parameters
    ----------
    path : path-like
        The file, as it was given.
    detail : str
        Why it cannot be read, without the file's name (one line).
    """

    def __init__(self, path, detail: str):
        self.path = str(path)
        self.detail = detail
        super().__init__(f"{self.path}: unreadable ({detail})")

    @classmethod
    def of(cls, path, error: BaseException) -> "UnreadableInputError":
        """The error for *path* that a reader's *error* stands for: its first line, the
        file's name taken off its front (the message names the file once)."""
        detail = str(error).splitlines()[0] if str(error) else type(error).__name__
        for prefix in (f"{path}: ", f"{getattr(path, 'name', path)}: "):
            detail = detail.removeprefix(prefix)
        return cls(path, detail)


class UsageError(Exception):
    """Command-line arguments that parse but make no sense together (CLI: exit 2)."""
