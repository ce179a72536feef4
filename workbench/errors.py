"""Exceptions for user-facing problems that are not contract violations."""


class WorkbenchError(Exception):
    """A problem with the user's data or files that the CLI reports in one line (exit 1).

    The message names the file, column or block concerned.
    """
