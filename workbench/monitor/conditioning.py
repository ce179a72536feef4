"""Files conditioned once for all the blocks holding them (the monitor's per-file path)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from ..identification.engine import conditioning_options
from ..signals.file_conditioning import FileConditioner

__all__ = ["SharedConditioner", "block_conditioner", "forget_conditioned"]


class SharedConditioner(FileConditioner):
    """A :class:`FileConditioner` over a few files that takes conditioned files from a
    cache shared by the monitor's blocks, so each file is conditioned once.

    A conditioned file depends on the file and on the raw edges of its contiguous
    neighbours; the cache key names all three, so a file conditioned before its next
    neighbour landed is conditioned again once it has (the monitor avoids that by waiting
    for the neighbour, see ``late_s``).

    Parameters
    ----------
    *args, **kwargs
        As :class:`~workbench.signals.file_conditioning.FileConditioner`.
    shared : dict
        The cache, kept by the monitor across blocks.
    counter : list of int
        ``counter[0]`` counts the files conditioned (not taken from the cache).
    """

    def __init__(self, *args, shared: dict, counter: list, **kwargs):
        super().__init__(*args, **kwargs)
        self._shared = shared
        self._counter = counter

    def _key(self, index: int):
        before = self.files[index - 1].path if self._contiguous(index - 1, index) else None
        after = self.files[index + 1].path if self._contiguous(index, index + 1) else None
        # and the cuts its step sums are split at (a drifting record's blocks' edges,
        # which move as the record's clock line is refitted from the files landed)
        first = int(round(self._offset(index)))
        inside = self._cuts[
            (self._cuts > first) & (self._cuts < first + self.files[index].n_samples)
        ]
        return (self.files[index].path, before, after, tuple(inside.tolist()))

    def _conditioned(self, index: int):
        key = self._key(index)
        hit = self._shared.get(key)
        if hit is not None:
            self._cache[index] = hit
            return hit
        result = super()._conditioned(index)
        self._shared[key] = result
        self._counter[0] += 1
        return result


def block_conditioner(
    infos: Sequence,
    position: Callable[[Path], int | None],
    planned,
    grid,
    channels,
    options,
    *,
    shared: dict,
    counter: list,
    cuts: Sequence[int] = (),
) -> SharedConditioner:
    """The conditioner of one planned block: its files and one neighbour on each side
    (whose raw edges pad the conditioning exactly as in a batch run).

    Parameters
    ----------
    infos : sequence of FileInfo
        Headers of every file taken so far, in time order.
    position : callable
        A file's index in *infos* by its path (None for a file not among them); the
        monitor keeps them (:meth:`~workbench.monitor.taken.TakenFiles.placed_index`).
    planned : PlannedBlock
        The block (its ``files``).
    grid, channels, options
        The voyage's block grid, channels and resolved :class:`IdentifyOptions`.
    shared, counter
        See :class:`SharedConditioner`.
    cuts : sequence of int
        As :class:`~workbench.signals.file_conditioning.FileConditioner`'s.
    """
    used = [i for i in (position(Path(p)) for p in planned.files) if i is not None]
    if used:
        lo, hi = max(min(used) - 1, 0), min(max(used) + 2, len(infos))
    else:
        lo, hi = 0, len(infos)
    return SharedConditioner(
        list(infos[lo:hi]),
        grid,
        channels,
        options=conditioning_options(options),
        shared=shared,
        counter=counter,
        cuts=cuts,
    )


def forget_conditioned(
    shared: dict, waiting_starts: Sequence[pd.Timestamp], file_ends: dict
) -> None:
    """Drop from *shared* the conditioned files no block still to come needs: those that
    end before the first waiting block starts (all of them when none waits).

    Parameters
    ----------
    shared : dict
        The cache of :class:`SharedConditioner` (keys start with the file's path).
    waiting_starts : sequence of Timestamp
        Starts of the planned blocks not yet decided.
    file_ends : dict
        End time of each taken file, by path.
    """
    if not shared:
        return
    horizon = min(waiting_starts) if len(waiting_starts) else None
    for key in list(shared):
        end = file_ends.get(key[0])
        if end is None or horizon is None or end <= horizon:
            del shared[key]
