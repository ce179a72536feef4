"""Container files (HDF5, and MATLAB v7.3 which is HDF5): one rule for every reader.

A container file must hold its own data. HDF5 can make a reader open other files: an
external link (``/start_time -> /etc/passwd:/x``), a dataset with external raw storage (its
bytes are those of any local file) or a virtual dataset (its values come from datasets of
other files). A crafted file would then show another file's content in an error message
(``not an ISO-8601 time: 'SECRET...'``) or write it into the result tables (as channel
names). So, before any value is read:

* :func:`container_datasets` walks the whole file once (hard links only, each object once,
  so a group linked into itself ends) and refuses external links, user-defined links,
  external storage and virtual datasets wherever they are, naming only the object;
  soft links stay inside the file and are resolved there;
* :func:`read_dataset` checks again the dataset it reads (an object reached through an
  object reference need not be linked anywhere), then its declared size against the file
  and the memory budget (:func:`data_contracts.limits.check_declared_size`), and only then
  reads it.

Attributes live in their object's header inside the file and cannot point elsewhere.
"""

from __future__ import annotations

import numpy as np

from .._core import ContractError, Violation
from ..limits import check_declared_size

__all__ = ["check_dataset", "container_datasets", "read_dataset"]


def _refuse(source, name: str, how: str) -> ContractError:
    return ContractError(
        [Violation(name, f"{how}: data stored in another file are refused for safety")],
        source=source,
        contract="accelerations",
    )


def check_dataset(node, source) -> None:
    """Raise ContractError if the HDF5 dataset *node* takes its data from another file
    (external raw storage or a virtual dataset); nothing of it is read."""
    import h5py

    if not isinstance(node, h5py.Dataset):
        raise ContractError(
            [Violation(node.name, "is a group, not a dataset")],
            source=source,
            contract="accelerations",
        )
    name = node.name or "(anonymous dataset)"
    if node.is_virtual:
        raise _refuse(source, name, "HDF5 virtual dataset")
    if node.id.get_create_plist().get_external_count() > 0:
        raise _refuse(source, name, "HDF5 external storage")


def container_datasets(handle, source) -> dict:
    """Every dataset of the open HDF5 file *handle* by path (``/group/name``), after
    refusing anything that takes data from another file (module docstring).

    Soft links are listed under their own path when their target is a dataset of the file
    (a dangling one is left out).

    Raises
    ------
    ContractError
        Naming the first object that points outside the file.
    """
    import h5py
    from h5py import h5l, h5o

    datasets: dict[str, h5py.Dataset] = {}
    soft: list[tuple[str, h5py.Group, str]] = []
    seen: set[int] = set()
    pending: list[tuple[h5py.Group, str]] = [(handle, "")]
    while pending:  # iterative: a deep or cyclic hierarchy cannot exhaust the stack
        group, prefix = pending.pop()
        for key in group:
            name = f"{prefix}/{key}"
            kind = group.id.links.get_info(key.encode()).type
            if kind == h5l.TYPE_EXTERNAL:
                raise _refuse(source, name, "HDF5 external link")
            if kind == h5l.TYPE_SOFT:
                soft.append((name, group, key))
                continue
            if kind != h5l.TYPE_HARD:
                raise _refuse(source, name, "HDF5 user-defined link")
            node = group[key]
            address = h5o.get_info(node.id).addr
            if isinstance(node, h5py.Group):
                if address not in seen:
                    seen.add(address)
                    pending.append((node, name))
            elif isinstance(node, h5py.Dataset):
                if address not in seen:
                    seen.add(address)
                    check_dataset(node, source)
                datasets[name] = node
    # every hard-linked object is checked and no link leaves the file: soft links resolve
    # inside it
    for name, group, key in soft:
        node = group.get(key)
        if isinstance(node, h5py.Dataset):
            check_dataset(node, source)
            datasets[name] = node
    return dict(sorted(datasets.items()))


def read_dataset(node, source, *, what: str | None = None) -> np.ndarray:
    """The values of the HDF5 dataset *node*, after checking that they are in the file
    (:func:`check_dataset`) and that their declared size fits the file and the memory
    budget (:func:`~data_contracts.limits.check_declared_size`).

    Raises
    ------
    ContractError
        Before anything is read, naming the dataset.
    """
    check_dataset(node, source)
    check_declared_size(
        node.shape or (),
        node.dtype.itemsize,
        stored_bytes=node.id.get_storage_size(),
        source=source,
        what=what or f"dataset {node.name}",
    )
    return np.asarray(node[()])
