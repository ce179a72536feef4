"""HDF5 acceleration files: a sample matrix (or a group of one dataset per channel), the
sampling rate, the start time and the channel names as datasets or attributes."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._core import ContractError, Violation
from ..limits import check_channel_count, check_declared_size
from . import (
    AccelerationLayout,
    convert_units,
    describe,
    layout_start,
    resolve_start,
    text_start,
    warn_if_gravity_in_g,
)
from .containers import check_dataset, container_datasets, read_dataset

__all__ = ["HDF5_SUFFIXES", "read_hdf5_accelerations"]

HDF5_SUFFIXES = (".h5", ".hdf5", ".he5")

#: Usual names, tried in order when the layout does not name the dataset or attribute.
USUAL_NAMES: dict[str, tuple[str, ...]] = {
    "acceleration": ("acceleration", "accelerations", "data", "acc", "accel", "signals", "y"),
    "sampling_rate_hz": (
        "sampling_rate_hz",
        "fs",
        "sampling_rate",
        "sample_rate",
        "samplerate",
        "srate",
        "rate",
    ),
    "start_time": ("start_time", "t0", "starttime", "start", "time0", "start_time_utc"),
    "channels": ("channels", "channel_names", "chanNames", "chan_names", "names", "labels"),
    "time": ("time", "t", "timestamps"),
    "units": ("units", "unit"),
}


def _text(value) -> str:
    array = np.asarray(value)
    if array.dtype.kind == "S":
        return (
            b"".join(array.ravel()).decode("utf-8", "replace")
            if array.ndim
            else array.item().decode()
        )
    if array.dtype.kind == "O":
        item = array.ravel()[0] if array.size else ""
        return item.decode() if isinstance(item, bytes) else str(item)
    return str(array.ravel()[0]) if array.ndim else str(array.item())


def _texts(value) -> list[str]:
    array = np.atleast_1d(np.asarray(value))
    return [v.decode() if isinstance(v, bytes) else str(v) for v in array.ravel()]


def read_hdf5_accelerations(path: str | os.PathLike, layout: AccelerationLayout):
    """Read an HDF5 acceleration file (see :class:`AccelerationLayout`).

    A file must hold its own data: external links, external storage and virtual datasets
    are refused before anything is read (:mod:`data_contracts.formats.containers`), and
    every dataset's declared size is checked against the file and the memory budget
    (:mod:`data_contracts.limits`) before it is read.
    """
    import h5py

    from ..accelerations import AccelerationRecord

    path = Path(path)
    with h5py.File(path, "r") as handle:
        # refuses anything taking data from another file, before any value is read
        datasets = container_datasets(handle, path)

        def value(node, key: str):
            """A dataset's values (checked, size-guarded) or an attribute's value."""
            if isinstance(node, h5py.Dataset):
                return read_dataset(node, path, what=f"{key} dataset {node.name}")
            return node

        listing = [
            f"{n} ({'x'.join(map(str, d.shape)) or 'scalar'} {d.dtype})"
            for n, d in datasets.items()
        ]
        attributes = sorted(handle.attrs)

        def contents() -> str:
            text = describe(listing, "datasets")
            if attributes:
                text += "; " + describe(attributes, "attributes of /")
            return text

        def fail(reason: str, column: str | None = None) -> ContractError:
            return ContractError(
                [Violation(column, f"{reason} ({contents()})")],
                source=path,
                contract="accelerations",
            )

        def lookup(key: str, places):
            """(value, where) of *key* among the datasets (at the root or beside the
            acceleration) and the attributes of *places*."""
            wanted = layout.variables.get(key)
            names = (wanted,) if wanted else USUAL_NAMES[key]
            beside = places[1].name.rstrip("/") if places else ""
            for name in names:
                clean = "/" + name.strip("/")
                for candidate in (clean, f"{beside}{clean}" if not wanted else clean):
                    if candidate in datasets:
                        return datasets[candidate], candidate
                for place in places:
                    if name in place.attrs:
                        return place.attrs[name], f"attribute {name} of {place.name}"
            if wanted:
                raise fail(f"'{wanted}' ({key}) is neither a dataset nor an attribute")
            return None, None

        # -- the sample matrix, or a group of one dataset per channel
        wanted = layout.variables.get("acceleration")
        group_channels = None
        if wanted and isinstance(handle.get("/" + wanted.strip("/")), h5py.Group):
            group = handle["/" + wanted.strip("/")]
            members = [
                k for k in group if isinstance(group.get(k), h5py.Dataset) and group[k].ndim == 1
            ]
            if layout.channels is not None:
                members = [k for k in members if k in layout.channels]
            if not members:
                raise fail(f"group '{wanted}' holds no 1-D datasets")
            nodes = [group[k] for k in members]
            for node in nodes:
                check_dataset(node, path)
            check_channel_count(len(nodes), source=path, what=f"group {wanted}")
            check_declared_size(
                (max(n.shape[0] for n in nodes), len(nodes)),
                max(n.dtype.itemsize for n in nodes),
                stored_bytes=sum(n.id.get_storage_size() for n in nodes),
                source=path,
                what=f"group {wanted}",
            )
            matrix = np.column_stack([value(n, "acceleration") for n in nodes])
            group_channels = members
            acc_node = nodes[0]
        else:
            acc_node, where = lookup("acceleration", ())
            if acc_node is None:
                numeric = [d for d in datasets.values() if d.ndim == 2 and d.dtype.kind in "fiu"]
                if len(numeric) != 1:
                    raise fail(
                        "no acceleration matrix found (looked for "
                        f"{', '.join(USUAL_NAMES['acceleration'])}); name the dataset",
                        "acceleration",
                    )
                acc_node = numeric[0]
            if not isinstance(acc_node, h5py.Dataset):
                raise fail("the acceleration is an attribute, not a dataset", "acceleration")
            if acc_node.ndim == 2:
                shape = acc_node.shape
                across = {"samples_first": shape[1], "channels_first": shape[0]}
                check_channel_count(
                    across.get(layout.orientation, min(shape)),
                    source=path,
                    what=f"dataset {acc_node.name}",
                )
            matrix = value(acc_node, "acceleration")
        places = (acc_node, acc_node.parent, handle)
        matrix = np.asarray(matrix)
        if matrix.dtype.kind == "c":
            raise fail(f"{acc_node.name} holds complex numbers, not accelerations")
        if matrix.ndim != 2:
            raise fail(f"{acc_node.name} is {matrix.ndim}-D; expected samples x channels")
        if layout.orientation == "channels_first" or (
            layout.orientation == "auto" and matrix.shape[0] < matrix.shape[1]
        ):
            matrix = matrix.T
        acceleration = matrix.astype(float)

        rate_value, _ = lookup("sampling_rate_hz", places)
        time_value, _ = lookup("time", places)
        start_value, _ = lookup("start_time", places)
        channel_value, _ = lookup("channels", places)
        unit_value, _ = lookup("units", places)
        rate = layout.sampling_rate_hz
        times = None
        if time_value is not None:
            times = np.asarray(value(time_value, "time"), dtype=float).ravel()
        if rate is None and rate_value is not None:
            rate = float(np.asarray(value(rate_value, "sampling_rate_hz")).ravel()[0])
        if rate is None and times is not None and times.size > 1:
            rate = round(1.0 / float(np.median(np.diff(times))), 9)
        if rate is None:
            raise fail(
                "sampling rate not found (looked for fs, sampling_rate, a time dataset); give it"
            )
        if layout.start_time is not None:
            start = layout_start(layout, path)
        elif start_value is not None:
            raw = np.asarray(value(start_value, "start_time"))
            start = (
                text_start(_text(raw), path, layout.time_format)
                if raw.dtype.kind in "SOU"
                else resolve_start(raw, path)
            )
        elif times is not None and times.size and times[0] > 1e8:
            start = resolve_start(times[0], path)
        else:
            raise fail("start time not found (looked for start_time, t0, start); give it")
        n = acceleration.shape[1]
        if group_channels is not None:
            channels = list(group_channels)
        elif channel_value is not None:
            raw = value(channel_value, "channels")
            channels = [c.strip() for c in _texts(raw)]
        else:
            channels = [f"acc{j + 1:02d}" for j in range(n)]
        if layout.channels is not None and group_channels is None:
            missing = [c for c in layout.channels if c not in channels]
            if missing:
                raise fail(f"channel(s) {', '.join(missing)} not among {', '.join(channels)}")
            keep = [channels.index(c) for c in layout.channels]
            acceleration = acceleration[:, keep]
            channels = list(layout.channels)
        header_units: list[str | None] = [None] * len(channels)
        if unit_value is not None:
            raw = value(unit_value, "units")
            texts: list[str | None] = list(_texts(raw))
            header_units = texts * len(channels) if len(texts) == 1 else texts
        elif group_channels is not None:
            header_units = [
                _text(handle[acc_node.parent.name][c].attrs["units"])
                if "units" in handle[acc_node.parent.name][c].attrs
                else None
                for c in channels
            ]
    acceleration = convert_units(acceleration, channels, header_units, layout, path)
    stated = layout.units is not None or any(u is not None for u in header_units)
    warn_if_gravity_in_g(acceleration, channels, stated, path)
    return AccelerationRecord(acceleration, rate, start, tuple(channels))
