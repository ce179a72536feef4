"""Tracking fed block by block, in block order, as the monitor decides blocks."""

from __future__ import annotations

import pandas as pd

from data_contracts import MODAL, shapes_from_frame

from ..errors import WorkbenchError
from ..sid.tracking import ModeTracker, TrackingOptions
from .outlook import empty_table

__all__ = ["IncrementalTracking"]


class IncrementalTracking:
    """The tracked table of the blocks decided so far, grown one block at a time.

    Blocks may be decided out of order (one waits for late data while later ones are
    ready); :class:`~workbench.sid.tracking.ModeTracker` needs them in order, so selected
    modes are held until every block before them is decided (:meth:`advance`). The
    table equals ``workbench track`` over the same selected modes.

    Parameters
    ----------
    options : TrackingOptions
    """

    def __init__(self, options: TrackingOptions) -> None:
        self.options = options
        self.tracked_through = -1  # every block up to this one is in the tracker
        self._parts: dict[int, pd.DataFrame] = {}  # selected modes waiting for their turn
        self._tracker: ModeTracker | None = None
        self._rows: list[tuple[int, int, float]] = []
        self._frame: pd.DataFrame | None = None
        self._channels: list[str] | None = None

    def add(self, block: int, selected: pd.DataFrame) -> None:
        """Hold the selected modes of a decided *block* until its turn."""
        self._parts[int(block)] = selected

    def advance(self, done: set[int]) -> bool:
        """Feed the decided blocks that follow :attr:`tracked_through` without a hole;
        True when the tracked table grew."""
        grew = False
        while self.tracked_through + 1 in done:
            block = self.tracked_through + 1
            part = self._parts.pop(block, None)
            if part is not None:
                self._track_block(block, part)
                grew = True
            self.tracked_through = block
        return grew

    def table(self, marker=None) -> pd.DataFrame:
        """The tracked table (MODAL contract) so far. *marker* (called with the selected
        modes tracked so far) adds their ``harmonic`` column, which decides only which
        labels are harmonics (never the assignment), so the marks may come late."""
        from ..sid.tracking import _tracked_table

        if self._frame is None:
            return empty_table(MODAL)
        frame = self._frame if marker is None else marker(self._frame)
        return _tracked_table(frame, list(self._rows), self._tracker, self._channels, self.options)

    def rows_of(self, labels) -> dict[int, list[int]]:
        """Rows of the selected modes tracked so far (index of the frame :meth:`table`
        passes to its *marker*) that carry each tracker label of *labels*."""
        wanted = {int(label) for label in labels}
        found: dict[int, list[int]] = {label: [] for label in wanted}
        for index, label, _ in self._rows:
            if label in wanted:
                found[label].append(index)
        return found

    def _track_block(self, block: int, part: pd.DataFrame) -> None:
        # the order `workbench identify` exports a block's modes in (then `track` reads it)
        if "model_order" in part.columns:
            part = part.sort_values("model_order", kind="stable")
        part = part.sort_values("frequency_hz", kind="stable")
        if self._tracker is None:
            channels, _ = shapes_from_frame(part.iloc[:0])
            if not channels:
                raise WorkbenchError(f"block {block}: selected modes without mode shapes")
            self._channels = channels
            self._tracker = ModeTracker(len(channels), self.options)
        offset = 0 if self._frame is None else len(self._frame)
        part = part.reset_index(drop=True)
        part.index = pd.RangeIndex(offset, offset + len(part))
        self._frame = part if self._frame is None else pd.concat([self._frame, part])
        _, shapes = shapes_from_frame(part)
        updates = self._tracker.update(
            block,
            part["frequency_hz"].to_numpy(dtype=float),
            part["damping_ratio"].to_numpy(dtype=float),
            shapes.T,
            part.index,
        )
        self._rows += [(int(part.index[i]), label, score) for i, label, score in updates]
        self._rows += self._tracker.late_assignments
        self._tracker.late_assignments = []
