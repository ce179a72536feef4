"""Exceptions for user-facing problems that are not contract violations.

One rule for exit codes everywhere: :class:`OptionError` (an option that cannot work, with
this data or at all) is a usage error, exit 2, reported without an input file's name;
:class:`WorkbenchError` and contract errors are bad data or files, exit 1.
"""


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


class UsageError(Exception):
    """Command-line arguments that parse but make no sense together (CLI: exit 2)."""
