"""The files the monitor has taken, in time order, placed as identify places them.

The monitor takes files one at a time, for weeks; a restart takes a whole expedition's
folder again. :class:`TakenFiles` keeps them so that taking a file, placing it
(:func:`~workbench.signals.block_plan.place_files`: re-timed for clock jitter and drift)
and finding a placed header cost the same at day 51 as at day 1: a file landing after all
the others (the usual case) is appended and placed on from the placement of the files
before it (:class:`~workbench.signals.block_plan.FilePlacement`); only a file landing
among them (late) makes the placement start again, from the first file, when next asked
for - as identify places the same files.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..signals.block_plan import FileInfo, FilePlacement
from .watcher import LandedFile

__all__ = ["TakenFiles"]


def _order(item: LandedFile) -> tuple:
    """Where a file goes among the taken: by its start stamp, then its path."""
    return (item.info.start_time, str(item.path))


class _Int64Column:
    """A growing int64 array (appends amortised O(1)); :meth:`values` is a view."""

    def __init__(self) -> None:
        self._data = np.empty(256, dtype=np.int64)
        self._size = 0

    def append(self, value: int) -> None:
        if self._size == len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self._size] = value
        self._size += 1

    def values(self) -> np.ndarray:
        return self._data[: self._size]


class TakenFiles(Sequence[LandedFile]):
    """The files taken, ordered by (start stamp, path), and their placement.

    As a sequence: the files as taken (their headers as stamped). :meth:`placed` and the
    lookups give them as :func:`~workbench.signals.block_plan.place_files` of all of them
    places them.
    """

    def __init__(self) -> None:
        self._files: list[LandedFile] = []
        self._orders: list[tuple] = []
        self._by_path: dict[Path, LandedFile] = {}
        self._forget_placement()

    def _forget_placement(self) -> None:
        self._placement = FilePlacement()
        self._placed: list[LandedFile] = []
        self._placed_infos: list[FileInfo] = []
        self._placed_by_path: dict[Path, int] = {}
        self._starts = _Int64Column()
        self._ends = _Int64Column()

    # -- the files as taken ---------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._files)

    def __getitem__(self, index):
        return self._files[index]

    def __iter__(self) -> Iterator[LandedFile]:
        return iter(self._files)

    def add(self, item: LandedFile) -> None:
        """Take *item* (a path not taken): after the files it follows in time order."""
        order = _order(item)
        if not self._orders or order > self._orders[-1]:
            self._files.append(item)
            self._orders.append(order)
        else:  # landed late: among the files, which are placed again from the first
            index = bisect.bisect_right(self._orders, order)
            self._files.insert(index, item)
            self._orders.insert(index, order)
            if index < len(self._placed):
                self._forget_placement()
        self._by_path[item.path] = item

    def clear(self) -> list[LandedFile]:
        """Forget every file taken; the files, in order."""
        files = self._files
        self._files, self._orders, self._by_path = [], [], {}
        self._forget_placement()
        return files

    def get(self, path: Path) -> LandedFile | None:
        """The file taken at *path* (as stamped), or None."""
        return self._by_path.get(path)

    # -- the files as placed --------------------------------------------------------------
    def _place(self) -> None:
        """Place the files taken since the last call, on from the placement so far."""
        for item in self._files[len(self._placed) :]:
            info = self._placement.add(item.info)  # raises before changing anything
            self._placed_by_path[info.path] = len(self._placed)
            self._placed.append(replace(item, info=info))
            self._placed_infos.append(info)
            self._starts.append(info.start_time.value)
            self._ends.append(info.end_time.value)

    def placed(self) -> list[LandedFile]:
        """The files, each with its header as placed (not to be changed by the caller)."""
        self._place()
        return self._placed

    def placed_infos(self) -> list[FileInfo]:
        """The placed headers, in time order (not to be changed by the caller)."""
        self._place()
        return self._placed_infos

    def placement(self) -> FilePlacement:
        """The placement of all the files (the last run's start and clock); not to be
        changed by the caller (:meth:`FilePlacement.place` leaves it as it is)."""
        self._place()
        return self._placement

    def placed_file(self, path: Path) -> LandedFile | None:
        """The file at *path* with its header as placed, or None when not taken."""
        self._place()
        index = self._placed_by_path.get(path)
        return None if index is None else self._placed[index]

    def placed_index(self, path: Path) -> int | None:
        """The position of *path* among :meth:`placed`, or None when not taken."""
        self._place()
        return self._placed_by_path.get(path)

    def coverage(self) -> tuple[np.ndarray, np.ndarray]:
        """Start and end of every placed file [ns since the epoch], in time order (views:
        not to be changed by the caller)."""
        self._place()
        return self._starts.values(), self._ends.values()
