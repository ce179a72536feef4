"""MATLAB acceleration files (v5 and v7.3): which variables hold what."""

from __future__ import annotations

import os
from pathlib import Path

from .._core import ContractError, Violation
from . import describe

__all__ = ["USUAL_MATLAB_NAMES", "matlab_variables"]

#: Usual variable names, tried in order when the layout does not name the variable.
USUAL_MATLAB_NAMES: dict[str, tuple[str, ...]] = {
    "acceleration": ("acceleration", "data", "acc", "accel", "Data", "y", "signals"),
    "sampling_rate_hz": (
        "sampling_rate_hz",
        "fs",
        "Fs",
        "sampling_rate",
        "sample_rate",
        "srate",
        "rate",
    ),
    "start_time": ("start_time", "t0", "starttime", "start", "time0", "StartTime"),
    "channels": (
        "channels",
        "chanNames",
        "channel_names",
        "chan_names",
        "names",
        "labels",
        "ChannelNames",
    ),
}


def _names_in(path: Path) -> tuple[list[str], list[str]]:
    """Variable names and their descriptions (``data (300000x16 double)``)."""
    with open(path, "rb") as handle:
        header = handle.read(128)
    if b"MATLAB 7.3" in header or header[:8] == b"\x89HDF\r\n\x1a\n":
        import h5py

        from .containers import container_datasets

        with h5py.File(path, "r") as mat:
            container_datasets(mat, path)  # nothing pointing outside the file, first
            names = [k for k in mat if not k.startswith("#")]
            shown = [
                f"{k} ({'x'.join(map(str, mat[k].shape[::-1])) or 'scalar'} "
                f"{mat[k].attrs.get('MATLAB_class', b'').decode() or 'group'})"
                if isinstance(mat[k], h5py.Dataset)
                else f"{k} (struct)"
                for k in names
            ]
        return names, shown
    import scipy.io

    entries = scipy.io.whosmat(path)
    return [e[0] for e in entries], [f"{n} ({'x'.join(map(str, s))} {c})" for n, s, c in entries]


def matlab_variables(path: str | os.PathLike, given: dict[str, str]) -> dict[str, str]:
    """The variable names to read: *given* ones (checked), else the usual names present.

    Raises
    ------
    ContractError
        When a variable is missing; the message lists the variables the file holds.
    """
    path = Path(path)
    names, shown = _names_in(path)
    resolved: dict[str, str] = {}
    problems = []
    for key, usual in USUAL_MATLAB_NAMES.items():
        wanted = given.get(key)
        if wanted:
            if wanted in names:
                resolved[key] = wanted
            else:
                problems.append(f"'{wanted}' ({key})")
            continue
        found = next((n for n in usual if n in names), None)
        if found is None:
            problems.append(f"{key} (tried {', '.join(usual)})")
        else:
            resolved[key] = found
    if problems:
        raise ContractError(
            [
                Violation(
                    None,
                    f"variable(s) missing: {'; '.join(problems)} ({describe(shown, 'variables')}); "
                    "name them (variables acceleration=..., sampling_rate_hz=..., ...)",
                )
            ],
            source=path,
            contract="accelerations",
        )
    return resolved
