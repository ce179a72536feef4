"""Acceleration records: the canonical ``.npz`` file and readers for MATLAB and CSV files.

A record is one file of the acquisition system (typically 5 minutes): a sample matrix
``acceleration`` (n_samples x n_channels) in m/s², NaN marking dropouts, the sampling rate,
the UTC time of the first sample and the channel names.
"""

from __future__ import annotations

import numbers
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ._core import ContractError, Violation, atomic_path
from .dship_names import cut_iso_time
from .limits import check_channel_count, check_declared_size

__all__ = [
    "MAX_PLAUSIBLE_ACCELERATION_MS2",
    "AccelerationRecord",
    "read_accelerations",
    "validate_accelerations",
    "write_accelerations",
]

#: Largest absolute acceleration accepted as plausible for hull vibration. [m/s²]
#: Values above it usually mean a unit mix-up (e.g. mm/s² or raw counts).
MAX_PLAUSIBLE_ACCELERATION_MS2 = 500.0


@dataclass(frozen=True)
class AccelerationRecord:
    """One acceleration file.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Accelerations, NaN where a channel dropped out. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    start_time : pandas.Timestamp
        Time of the first sample. [UTC]
    channels : tuple of str
        Channel names, one per column of *acceleration*.
    blanked : tuple of (str, str)
        Channels the reader set to NaN for the whole file and why, e.g.
        ``("acc03", "infinite values")`` (``glitches="blank"`` of
        :func:`validate_accelerations`); empty otherwise.
    """

    acceleration: np.ndarray
    sampling_rate_hz: float
    start_time: pd.Timestamp
    channels: tuple[str, ...]
    blanked: tuple[tuple[str, str], ...] = ()

    @property
    def n_samples(self) -> int:
        return int(self.acceleration.shape[0])

    @property
    def duration(self) -> pd.Timedelta:
        """Time covered by the samples (n_samples / sampling rate)."""
        return pd.Timedelta(seconds=self.n_samples / self.sampling_rate_hz)

    @property
    def end_time(self) -> pd.Timestamp:
        """Time just after the last sample. [UTC]"""
        return self.start_time + self.duration


def validate_accelerations(
    record: AccelerationRecord,
    *,
    source: str | os.PathLike | None = None,
    glitches: str = "refuse",
) -> AccelerationRecord:
    """Check a record and return it with canonical types (float64 array, UTC timestamp).

    Parameters
    ----------
    record : AccelerationRecord
    source : path-like, optional
        The file, named in the errors.
    glitches : {"refuse", "blank"}
        What infinite values or values above :data:`MAX_PLAUSIBLE_ACCELERATION_MS2` in
        some of the channels are: ``"refuse"`` (a check, ``workbench validate``) lists
        them as violations; ``"blank"`` (the analyses) takes them as faults of those
        channels (an ADC overflow, a loose connector), sets those channels to NaN for the
        whole record and names them in ``blanked``. A record in which every channel with
        a finite sample holds such values (wrong units) is refused either way.

    Raises
    ------
    ContractError
        Listing every problem (array shape, sampling rate, channel names, time, units).
    """
    if glitches not in ("refuse", "blank"):
        raise ValueError(f"glitches={glitches!r} must be 'refuse' or 'blank'")
    problems: list[Violation] = []
    blanked: tuple[tuple[str, str], ...] = ()
    if np.iscomplexobj(record.acceleration):
        acceleration = None
        problems.append(
            Violation("acceleration", "complex values: accelerations must be real numbers")
        )
    elif np.asarray(record.acceleration).dtype.kind == "b":
        acceleration = None
        problems.append(
            Violation(
                "acceleration",
                "boolean values (True/False, e.g. a mask or a trigger channel): "
                "accelerations must be real numbers",
            )
        )
    else:
        try:
            acceleration = np.asarray(record.acceleration, dtype=float)
        except (TypeError, ValueError):
            acceleration = None
            problems.append(Violation("acceleration", "values are not numeric"))
    if acceleration is not None and acceleration.ndim != 2:
        problems.append(
            Violation(
                "acceleration", f"must be 2-D (n_samples x n_channels), got {acceleration.ndim}-D"
            )
        )
        acceleration = None
    channels = tuple(str(c) for c in np.atleast_1d(np.asarray(record.channels, dtype=object)))
    if acceleration is not None:
        if acceleration.shape[1] != len(channels):
            problems.append(
                Violation(
                    "channels",
                    f"{len(channels)} names for {acceleration.shape[1]} columns of acceleration",
                )
            )
        if acceleration.shape[0] < 2:
            problems.append(
                Violation("acceleration", f"needs at least 2 samples, got {acceleration.shape[0]}")
            )
        peak = _column_peaks(acceleration)  # one pass: infinite and implausible values
        if glitches == "blank" and acceleration.shape[1] == len(channels):
            acceleration, peak, blanked = _blank_glitches(acceleration, peak, channels)
        if np.isinf(peak).any():
            cols = sorted(
                {
                    channels[j] if j < len(channels) else str(j)
                    for j in np.flatnonzero(np.isinf(peak))
                }
            )
            problems.append(
                Violation("acceleration", f"infinite values in channel(s) {', '.join(cols)}")
            )
        implausible = np.nonzero(np.isfinite(peak) & (peak > MAX_PLAUSIBLE_ACCELERATION_MS2))[0]
        if len(implausible):
            cols = ", ".join(channels[j] if j < len(channels) else str(j) for j in implausible)
            problems.append(
                Violation(
                    "acceleration",
                    f"|a| above {MAX_PLAUSIBLE_ACCELERATION_MS2:g} m/s² in channel(s) "
                    f"{cols}: accelerations must be in m/s² (not mm/s² or counts)",
                )
            )
    if len(set(channels)) != len(channels):
        problems.append(Violation("channels", "channel names must be unique"))
    try:
        rate = float(np.asarray(record.sampling_rate_hz).reshape(()))
    except (TypeError, ValueError):
        rate = float("nan")
    if not np.isfinite(rate) or rate <= 0:
        problems.append(
            Violation(
                "sampling_rate_hz", f"must be a positive number, got {record.sampling_rate_hz!r}"
            )
        )
    start = _start_time(record.start_time)
    if start is None:
        problems.append(Violation("start_time", _not_a_time(record.start_time)))
    if problems:
        raise ContractError(problems, source=source, contract="accelerations")
    return AccelerationRecord(acceleration, rate, start, channels, blanked)


def _blank_glitches(
    acceleration: np.ndarray, peak: np.ndarray, channels: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray, tuple[tuple[str, str], ...]]:
    """*acceleration* with the channels holding infinite or implausible values set to NaN,
    their peaks set to 0, and those channels with why; unchanged when no channel holds
    such values or when every channel with a finite sample does (wrong units: refused)."""
    infinite = np.isinf(peak)
    bad = infinite | (peak > MAX_PLAUSIBLE_ACCELERATION_MS2)
    sound = ~bad & (peak > 0)  # a dead (all-NaN) or flat channel says nothing of the units
    if not bad.any() or not sound.any():
        return acceleration, peak, ()
    acceleration = acceleration.copy()
    acceleration[:, bad] = np.nan
    peak = np.where(bad, 0.0, peak)
    return (
        acceleration,
        peak,
        tuple(
            (
                channels[j],
                "infinite values"
                if infinite[j]
                else f"|a| above {MAX_PLAUSIBLE_ACCELERATION_MS2:g} m/s²",
            )
            for j in np.flatnonzero(bad)
        ),
    )


#: Values per chunk of :func:`_column_peaks` (256 KB of float64: stays in the CPU cache).
_PEAK_CHUNK_VALUES = 32768
#: Values per row of the wide view in which :func:`_column_peaks` reduces a C-ordered
#: array (a whole number of its rows). [-]
_PEAK_ROW_VALUES = 1024


def _column_peaks(acceleration: np.ndarray) -> np.ndarray:
    """Largest absolute value of each column of a 2-D float array, NaN ignored.

    An all-NaN (dead) column gives 0, a column holding an infinite value gives ``inf``.
    One pass over the samples without full-size temporaries, so validating a 2048-Hz file
    costs a fraction of reading it: a C-ordered array is reduced as a view of wide rows,
    k of its rows side by side (largest and smallest value, a reduction the CPU
    vectorises over the wide rows; then over the k copies of each column); other layouts
    in cache-sized row chunks of absolute values. Either way the peak is one of the
    samples' magnitudes, exactly.
    """
    n_rows, n_columns = acceleration.shape
    peak = np.zeros(n_columns)
    if acceleration.flags.c_contiguous and n_columns:
        k = max(1, _PEAK_ROW_VALUES // n_columns)
        whole = n_rows - n_rows % k
        with np.errstate(invalid="ignore"):
            for part, width in ((acceleration[:whole], k), (acceleration[whole:], 1)):
                if not len(part):
                    continue
                wide = part.reshape(-1, width * n_columns)  # a view: rows side by side
                high = np.fmax.reduce(np.fmax.reduce(wide, axis=0).reshape(width, -1), axis=0)
                low = np.fmin.reduce(np.fmin.reduce(wide, axis=0).reshape(width, -1), axis=0)
                np.fmax(peak, np.fmax(high, -low), out=peak)  # fmax skips NaN
        return peak
    rows = max(1, _PEAK_CHUNK_VALUES // max(n_columns, 1))
    buffer = np.empty((min(rows, n_rows), n_columns))
    for first in range(0, n_rows, rows):
        chunk = acceleration[first : first + rows]
        magnitude = buffer[: chunk.shape[0]]
        np.abs(chunk, out=magnitude)
        np.fmax(peak, np.fmax.reduce(magnitude, axis=0), out=peak)  # fmax skips NaN
    return peak


#: An ISO-8601 date (with optional time) at the start of a text: YYYY-MM-DD.
_ISO_DATE = re.compile(r"^\s*[+-]?\d{4}-\d{2}-\d{2}")


def _start_time(value) -> pd.Timestamp | None:
    """*value* as a UTC Timestamp if it is a time (datetime or ISO-8601 text), else None.

    Numbers are refused: a number of seconds or days since some epoch is ambiguous (pandas
    would read it as nanoseconds since 1970).
    """
    if isinstance(value, (bool, numbers.Number, np.number)):
        return None
    if isinstance(value, (str, np.str_, bytes)):
        text = value.decode(errors="replace") if isinstance(value, bytes) else str(value)
        if not _ISO_DATE.match(text) or cut_iso_time(text):
            return None
        value = text
    try:
        start = pd.Timestamp(value)
        if pd.isna(start):
            return None
        return start.tz_localize("UTC") if start.tzinfo is None else start.tz_convert("UTC")
    except (TypeError, ValueError, OverflowError):
        return None


def _not_a_time(value) -> str:
    if isinstance(value, (bool, numbers.Number, np.number)):
        return f"must be an ISO-8601 time such as 2026-03-01T00:00:00Z, got the number {value}"
    text = str(value)
    shown = text if len(text) <= 40 else text[:37] + "..."
    return f"not an ISO-8601 time: {shown!r}"


def write_accelerations(record: AccelerationRecord, path: str | os.PathLike) -> Path:
    """Write *record* as the canonical ``.npz`` file (validated, atomic)."""
    record = validate_accelerations(record)
    path = Path(path)
    with atomic_path(path, suffix=".tmp.npz") as tmp:
        np.savez(
            tmp,
            acceleration=record.acceleration,
            sampling_rate_hz=np.float64(record.sampling_rate_hz),
            start_time=np.str_(record.start_time.strftime("%Y-%m-%dT%H:%M:%S.%fZ")),
            channels=np.array(record.channels, dtype=np.str_),
        )
    return path


def _scalar(value):
    array = np.asarray(value)
    if array.dtype.kind in "US" or array.dtype == object:
        flat = array.ravel()
        return str(flat[0]) if flat.size else ""
    return array.reshape(-1)[0] if array.size else np.nan


#: The one line for an ``.npz`` file that is not an acceleration archive (whatever NumPy
#: says: its messages suggest loading pickles, which are never loaded).
_NOT_NPZ = (
    "not a valid .npz acceleration file (a NumPy archive of the numeric arrays acceleration, "
    "sampling_rate_hz, start_time and channels)"
)

_NPZ_ARRAYS = ("acceleration", "sampling_rate_hz", "start_time", "channels")


def _read_npz(path: Path) -> AccelerationRecord:
    from .npz import check_sample_header, read_sample_headers, read_stored_samples

    def not_npz() -> ContractError:
        return ContractError([Violation(None, _NOT_NPZ)], source=path, contract="accelerations")

    try:
        with zipfile.ZipFile(path) as archive:
            members = set(archive.namelist())
        missing = [k for k in _NPZ_ARRAYS if f"{k}.npy" not in members]
        if missing:
            raise ContractError(
                [Violation(k, "array missing from the .npz file") for k in missing],
                source=path,
                contract="accelerations",
            )
        found = read_sample_headers(path, tuple(f"{k}.npy" for k in _NPZ_ARRAYS))
        headers = {k: found[f"{k}.npy"] for k in _NPZ_ARRAYS}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        if isinstance(error, ContractError):
            raise
        raise not_npz() from None
    for key, header in headers.items():
        if header.dtype.hasobject:  # pickled Python objects: never loaded
            raise not_npz()
        check_sample_header(header, path, f"array {key}")
    shape = headers["acceleration"].shape
    if len(shape) == 2:
        check_channel_count(shape[1], source=path, what="array acceleration")
    try:
        samples = read_stored_samples(path, headers["acceleration"])
        with np.load(path, allow_pickle=False) as data:
            return AccelerationRecord(
                data["acceleration"] if samples is None else samples,
                _scalar(data["sampling_rate_hz"]),
                _scalar(data["start_time"]),
                tuple(str(c) for c in data["channels"].ravel()),
            )
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        raise not_npz() from None


def _mat_text(value) -> str:
    array = np.asarray(value)
    if array.dtype.kind in "US":
        return (
            "".join(str(x) for x in array.ravel())
            if array.ndim and array.dtype.itemsize <= 4
            else str(array.ravel()[0])
        )
    if array.dtype.kind in "ui" and array.ndim >= 1:  # HDF5 MATLAB char arrays are uint16
        return "".join(chr(int(c)) for c in array.ravel())
    return str(_scalar(array))


def _mat_channels(value, n_channels: int) -> tuple[str, ...]:
    array = np.asarray(value, dtype=object)
    names: list[str] = []
    for item in array.ravel():
        names.append(_mat_text(item).strip())
    if len(names) == 1 and n_channels > 1:
        return tuple(f"ch{j + 1:02d}" for j in range(n_channels))
    return tuple(names)


def _check_mat5_sizes(path: Path, names: set[str]) -> None:
    """Declared sizes of the MATLAB v5 variables *names* against the file and the budget
    (:func:`data_contracts.limits.check_declared_size`), from the headers alone."""
    import scipy.io

    size = path.stat().st_size
    for name, shape, kind in scipy.io.whosmat(path):
        if name not in names:
            continue
        itemsize = 16 if kind == "cell" else 8  # at most a double per element
        check_declared_size(
            shape, itemsize, stored_bytes=size, source=path, what=f"variable {name}"
        )


def _read_mat(path: Path, variables: dict[str, str], orientation: str) -> AccelerationRecord:
    import scipy.io

    with open(path, "rb") as handle:
        header = handle.read(128)
    is_hdf5 = b"MATLAB 7.3" in header or header[:8] == b"\x89HDF\r\n\x1a\n"
    contents: dict[str, object] = {}
    if is_hdf5:
        import h5py

        from .formats.containers import container_datasets, read_dataset

        with h5py.File(path, "r") as mat:
            # refuses data in other files before any value is read (one rule for HDF5 and
            # MATLAB v7.3); every read below checks the dataset and its declared size again
            container_datasets(mat, path)
            for key, name in variables.items():
                if name not in mat:
                    continue
                node = mat[name]
                what = f"variable {name}"
                if key == "acceleration" and isinstance(node, h5py.Dataset) and node.ndim == 2:
                    check_channel_count(min(node.shape), source=path, what=what)
                values = read_dataset(node, path, what=what)
                if node.dtype == h5py.ref_dtype:
                    contents[key] = [
                        read_dataset(mat[ref], path, what=f"{what} (cell)")
                        for ref in values.ravel()
                    ]
                else:
                    contents[key] = values
        # HDF5 stores MATLAB arrays column-major: transpose the 2-D matrix back.
        if "acceleration" in contents:
            contents["acceleration"] = np.asarray(contents["acceleration"]).T
    else:
        _check_mat5_sizes(path, set(variables.values()))
        raw = scipy.io.loadmat(
            path, squeeze_me=False, chars_as_strings=True, variable_names=list(variables.values())
        )
        for key, name in variables.items():
            if name in raw:
                contents[key] = raw[name]
    missing = [f"{variables[k]} ({k})" for k in variables if k not in contents]
    if missing:
        raise ContractError(
            [Violation(m, "variable missing from the MATLAB file") for m in missing],
            source=path,
            contract="accelerations",
        )
    acceleration = np.asarray(contents["acceleration"], dtype=float)
    if orientation == "channels_first" or (
        orientation == "auto"
        and acceleration.ndim == 2
        and acceleration.shape[0] < acceleration.shape[1]
    ):
        acceleration = acceleration.T
    channels = contents["channels"]
    if isinstance(channels, list):
        names = tuple(_mat_text(c).strip() for c in channels)
    else:
        names = _mat_channels(channels, acceleration.shape[1] if acceleration.ndim == 2 else 0)
    return AccelerationRecord(
        acceleration,
        float(_scalar(contents["sampling_rate_hz"])),
        _mat_text(contents["start_time"]).strip(),
        names,
    )


def read_accelerations(
    path: str | os.PathLike,
    *,
    mat_variables: dict[str, str] | None = None,
    mat_orientation: str = "auto",
    csv_time_column: str | None = None,
    csv_sampling_rate_hz: float | None = None,
    layout=None,
    glitches: str = "refuse",
) -> AccelerationRecord:
    """Read an acceleration file: canonical ``.npz``, MATLAB ``.mat``, CSV/TSV, HDF5 or UFF.

    Parameters
    ----------
    path : path-like
        The file. The format is chosen by suffix.
    mat_variables : dict, optional
        MATLAB variable names for ``acceleration``, ``sampling_rate_hz``, ``start_time``
        and ``channels`` (default: the usual names present, e.g. ``data``, ``fs``, ``t0``,
        ``chanNames``). Both v5 and v7.3 (HDF5) files work.
    mat_orientation : {"auto", "samples_first", "channels_first"}
        Layout of the MATLAB matrix; ``auto`` takes the longer dimension as samples.
    csv_time_column : str, optional
        CSV column with the sample times (default: ``time``, ``Timestamp``, ...).
    csv_sampling_rate_hz : float, optional
        Sampling rate for CSV files; default: from the median time step. [Hz]
    layout : AccelerationLayout or mapping, optional
        Everything else a file's headers may not say (time format, separator, decimal
        mark, relative time and start, units, channels, HDF5 names); see
        :class:`data_contracts.formats.AccelerationLayout`. The keyword arguments above
        take precedence over its fields.
    glitches : {"refuse", "blank"}
        Infinite or implausible values in some channels: violations, or those channels
        set to NaN and named in ``blanked`` (see :func:`validate_accelerations`).

    Raises
    ------
    ContractError
        When the file is missing, unreadable or not a valid record; messages name the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise ContractError(
            [Violation(None, "file not found")], source=path, contract="accelerations"
        )
    from . import formats

    try:
        layout = formats.as_layout(
            layout,
            time_column=csv_time_column,
            sampling_rate_hz=csv_sampling_rate_hz,
            orientation=None if mat_orientation == "auto" else mat_orientation,
        )
        if mat_variables:
            layout = formats.as_layout(layout, variables={**layout.variables, **mat_variables})
    except ValueError as error:
        raise ContractError(
            [Violation(None, f"reading options: {error}")], source=path, contract="accelerations"
        ) from None
    try:
        if suffix == ".npz":
            record = _read_npz(path)
        elif suffix == ".mat":
            variables = formats.matlab.matlab_variables(path, layout.variables)
            record = _read_mat(path, variables, layout.orientation)
            record = formats.matlab_record(record, layout, path)
        elif suffix in formats.text.TEXT_SUFFIXES:
            record = formats.text.read_text_accelerations(path, layout)
        elif suffix in formats.hdf5.HDF5_SUFFIXES:
            record = formats.hdf5.read_hdf5_accelerations(path, layout)
        elif suffix in formats.uff.UFF_SUFFIXES:
            record = formats.uff.read_uff_accelerations(path, layout)
        else:
            raise ContractError(
                [
                    Violation(
                        None,
                        f"unknown acceleration format '{suffix}' (use "
                        f"{', '.join(formats.ACCELERATION_SUFFIXES)})",
                    )
                ],
                source=path,
                contract="accelerations",
            )
    except ContractError:
        raise
    except Exception as error:  # corrupt archives raise zipfile/OSError/ValueError/...
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ContractError(
            [Violation(None, f"cannot read file: {message}")], source=path, contract="accelerations"
        ) from None
    return validate_accelerations(record, source=path, glitches=glitches)


def channel_names(n_channels: int, prefix: str = "acc") -> tuple[str, ...]:
    """Default channel names ``acc01``, ``acc02``, ..."""
    return tuple(f"{prefix}{j + 1:02d}" for j in range(n_channels))


__all__ += ["channel_names"]
