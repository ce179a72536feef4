"""Tracking fed block by block, in block order, as the monitor decides blocks."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import MODAL, atomic_path, shapes_from_frame

from ..errors import WorkbenchError
from ..sid.tracking import ModeTracker, TrackingOptions, tracker_for
from .outlook import empty_table

__all__ = ["LABELS_SCHEMA", "IncrementalTracking", "LabelsUnreadable"]

#: ``schema`` of ``labels.json`` (the labels shown so far; see :meth:`IncrementalTracking.
#: check_labels`).
LABELS_SCHEMA = "workbench.monitor.labels/1"


class LabelsUnreadable(WorkbenchError):
    """``labels.json`` cannot be read: the labels an earlier run gave are not known."""


class IncrementalTracking:
    """The tracked table of the blocks decided so far, grown one block at a time.

    Blocks may be decided out of order (one waits for late data while later ones are
    ready); :class:`~workbench.sid.tracking.ModeTracker` needs them in order, so selected
    modes are held until every block before them is decided (:meth:`advance`). The
    table equals ``workbench track`` over the same selected modes, labels included: the
    tracker labels a mode once, when it has been seen in ``min_blocks`` blocks, and never
    renumbers (:mod:`workbench.sid.tracking`), so a label shown at any block keeps its mode.

    Parameters
    ----------
    options : TrackingOptions
    reference_modes : DataFrame, optional
        Modal table whose modes start the library, labels kept (``workbench track
        --reference-modes``; the modes of a saved health baseline).
    """

    def __init__(
        self, options: TrackingOptions, reference_modes: pd.DataFrame | None = None
    ) -> None:
        self.options = options
        self.reference_modes = reference_modes
        self.tracked_through = -1  # every block up to this one is in the tracker
        self._parts: dict[int, pd.DataFrame] = {}  # selected modes waiting for their turn
        self._tracker: ModeTracker | None = None
        self._rows: list[tuple[int, int, float]] = []
        # _rows as arrays (_row_arrays) and each frame row's block
        self._arrays = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, float))
        self._blocks = np.empty(0, np.int64)
        self._frame: pd.DataFrame | None = None
        self._channels: list[str] | None = None
        self._written_labels: list[dict] | None = None
        # labels an earlier run gave, not yet given again by the replay: mode -> (block, Hz)
        self._expected: dict[int, tuple[int, float]] = {}
        self._labels_path: Path | None = None
        # the table :meth:`table` built last: (table, rows then, labels then, labels left
        # out as harmonics)
        self._built: tuple[pd.DataFrame, int, dict[int, int], set[int]] | None = None
        #: The last :meth:`table`'s rows of the blocks before this one are those of the
        #: table before it (None: any row may have changed).
        self.changed_from: int | None = None

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

    def table(self, marks=None) -> pd.DataFrame:
        """The tracked table (MODAL contract) so far. *marks* (called with the selected
        modes tracked so far, :attr:`frame`) gives each row's harmonic marks as an array
        (rows x 3: ``harmonic``, ``harmonic_frequency_hz``, checked by the ship log 1.0 or
        0.0; None: not marked), which decide only which labels are harmonics (never the
        assignment), so the marks may come late.

        Only the rows that may have changed since the table built last are built again
        (the blocks from :meth:`_changed_from` on) while the labels left out as
        harmonics stay the same; the labels' verdict is taken over every row each time
        (per-label counts, :func:`~workbench.sid.tracking.harmonic_verdict`)."""
        from ..sid.tracking import _empty_tracked, harmonic_verdict, tracked_rows

        self.changed_from = None
        if self._frame is None:
            return empty_table(MODAL)
        frame = self._frame
        labels = self._tracker.labels()
        since = self._changed_from(labels)
        index, serial, score = self._row_arrays()
        label = np.full(int(serial.max(initial=-1)) + 1, -1, dtype=np.int64)
        for row_serial, row_label in labels.items():
            if row_serial < len(label):
                label[row_serial] = row_label
        label = label[serial] if len(serial) else serial
        labelled = label >= 0
        index, label, score = index[labelled], label[labelled], score[labelled]
        marked = None if marks is None else marks(frame)
        harmonic: list[dict] = []
        if marked is not None and len(label):
            harmonic = harmonic_verdict(
                label,
                self._blocks[index],
                np.isfinite(marked[index, 0]),
                marked[index, 2] > 0.5,
                frame["frequency_hz"].to_numpy(float)[index],
                marked[index, 1],
                self.options,
            )
        left_out = {h["label"] for h in harmonic}
        keep = ~np.isin(label, list(left_out)) if left_out else np.ones(len(label), bool)
        if self._built is not None and since is not None and left_out != self._built[3]:
            since = None  # a line became (or stopped being) a harmonic: its rows everywhere
        if not len(label):  # no labelled mode yet: the selected modes' columns
            table = _empty_tracked(frame)
        elif since is not None:
            # the rows of the blocks from `since` on built again, the others kept: the
            # table is sorted by (block, mode), stable in the order of the rows
            head = self._built[0]
            head = head.iloc[: int(np.searchsorted(head["block"].to_numpy(), since))]
            keep &= self._blocks[index] >= since
            tail = tracked_rows(frame, index[keep], label[keep], score[keep], self._channels)
            if len(tail):
                table = pd.concat([head, tail], ignore_index=True)
            else:
                table = head.reset_index(drop=True)
        else:
            table = tracked_rows(frame, index[keep], label[keep], score[keep], self._channels)
        if len(label):  # as track's table (an empty one has no attributes)
            table.attrs["harmonic_labels"] = harmonic
        self.changed_from = since
        self._built = (table, len(self._rows), labels, left_out)
        return table

    @property
    def frame(self) -> pd.DataFrame | None:
        """The selected modes tracked so far, a row per mode (index 0, 1, ...), in the
        order they were fed."""
        return self._frame

    def _row_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:attr:`_rows` as arrays (row of the frame, serial, MACXP), extended by the rows
        tracked since the last call."""
        arrays = self._arrays
        done = len(arrays[0])
        if done < len(self._rows):
            new = self._rows[done:]
            arrays = tuple(
                np.concatenate([old, np.array([r[k] for r in new], dtype=old.dtype)])
                for k, old in enumerate(arrays)
            )
            self._arrays = arrays
        return arrays

    def _changed_from(self, labels: dict[int, int]) -> int | None:
        """First block whose table rows may differ from the table built last (None: any,
        or nothing built yet): the blocks of the rows tracked since, and of every row of
        a mode labelled since (its rows before the label join the table)."""
        if self._built is None or self._built[0].empty:
            return None
        _, n_rows, before, _ = self._built
        if any(before.get(serial, label) != label for serial, label in labels.items()):
            return None  # labels are never renumbered: not expected
        if len(before) > len(labels):
            return None
        blocks = self._blocks
        new_serials = {serial for serial in labels if serial not in before}
        changed = [int(blocks[r[0]]) for r in self._rows[n_rows:]]
        if new_serials:
            changed += [int(blocks[r[0]]) for r in self._rows if r[1] in new_serials]
        newest = int(self._built[0]["block"].iloc[-1])
        return min([*changed, newest])

    def rows_of(self, labels) -> dict[int, list[int]]:
        """Rows of the selected modes tracked so far (index of :attr:`frame`, the frame
        :meth:`table` passes to its *marks*) under each shown label of *labels* (the
        ``mode`` of the tracked table and of its ``harmonic_labels``), in the order they
        were tracked.

        The tracker's rows carry its modes' serial numbers (in order of birth), not the
        labels shown (given once a mode is seen in ``min_blocks`` blocks, in the order
        modes reach it; a mode never confirmed has none)."""
        wanted = {int(label) for label in labels}
        found: dict[int, list[int]] = {label: [] for label in wanted}
        shown = self._tracker.labels() if self._tracker is not None else {}
        index, serial, _ = self._row_arrays()
        serials = [row_serial for row_serial, label in shown.items() if label in wanted]
        for row_serial in serials:
            found[shown[row_serial]].extend(index[serial == row_serial].tolist())
        return {label: sorted(rows) for label, rows in found.items()}

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
            try:
                self._tracker = tracker_for(channels, self.options, self.reference_modes)
            except ValueError as error:
                raise WorkbenchError(f"reference modes: {error}") from None
        offset = 0 if self._frame is None else len(self._frame)
        part = part.reset_index(drop=True)
        part.index = pd.RangeIndex(offset, offset + len(part))
        self._frame = part if self._frame is None else pd.concat([self._frame, part])
        self._blocks = np.concatenate([self._blocks, part["block"].to_numpy(np.int64)])
        _, shapes = shapes_from_frame(part)
        updates = self._tracker.update(
            block,
            part["frequency_hz"].to_numpy(dtype=float),
            part["damping_ratio"].to_numpy(dtype=float),
            shapes.T,
            part.index,
        )
        self._rows += [(int(part.index[i]), serial, score) for i, serial, score in updates]
        self._rows += self._tracker.late_assignments
        self._tracker.late_assignments = []

    # ------------------------------------------------------------------ labels shown
    def shown_labels(self) -> list[dict]:
        """The labels given so far, in order (those of harmonics, which the table leaves
        out, included): ``mode``, ``labelled_block`` (the block it was given at, from which
        the table shows it; -1 for a reference mode) and ``frequency_hz`` (its frequency
        then)."""
        if self._tracker is None:
            return []
        modes = sorted(
            (m for m in self._tracker.library if m.label is not None), key=lambda m: m.label
        )
        return [
            {
                "mode": int(m.label),
                "labelled_block": int(m.labelled_block),
                "frequency_hz": float(m.labelled_frequency_hz),
            }
            for m in modes
        ]

    def write_labels(self, path: str | Path) -> None:
        """Write :meth:`shown_labels` to *path* (``labels.json``) atomically when they
        changed since the last write; labels of an earlier run that the replay has not
        reached yet (:meth:`expect_labels`) are kept in the file."""
        labels = self.shown_labels()
        given = {e["mode"] for e in labels}
        pending = [
            {"mode": mode, "labelled_block": block, "frequency_hz": frequency}
            for mode, (block, frequency) in self._expected.items()
            if mode not in given
        ]
        labels = sorted(labels + pending, key=lambda e: e["mode"])
        if labels == self._written_labels:
            return
        with atomic_path(Path(path)) as tmp:
            tmp.write_text(
                json.dumps({"schema": LABELS_SCHEMA, "labels": labels}, indent=1),
                encoding="utf-8",
            )
        self._written_labels = labels

    def expect_labels(self, path: str | Path) -> None:
        """After a restart: the labels an earlier run gave (*path*, ``labels.json``) must
        be given again, at the same blocks to the same modes, as the tracker is replayed
        from the store and fed on (:meth:`check_labels`, once it has reached each label's
        block: a block of a damaged store file is identified again first).

        Raises
        ------
        LabelsUnreadable
            *path* is unreadable (one line naming it).
        """
        path = Path(path)
        self._labels_path = path
        if not path.is_file():
            return
        try:
            found = json.loads(path.read_text(encoding="utf-8"))
            if found.get("schema") != LABELS_SCHEMA:
                raise ValueError(f"schema {found.get('schema')!r}, expected {LABELS_SCHEMA!r}")
            self._expected = {
                int(e["mode"]): (int(e["labelled_block"]), float(e["frequency_hz"]))
                for e in found["labels"]
            }
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            raise LabelsUnreadable(f"{path}: unreadable ({error})") from None

    def check_labels(self) -> None:
        """Check the expected labels (:meth:`expect_labels`) of the blocks tracked so far.

        Raises
        ------
        WorkbenchError
            One line naming the file and the first label that differs (the tracking
            options changed since the labels were given, or the state was edited).
        """
        if not self._expected or self._tracker is None:
            return
        now = {e["mode"]: e for e in self.shown_labels()}
        for mode, (block, frequency) in sorted(self._expected.items()):
            if block > self.tracked_through:
                continue
            again = now.get(mode)
            if (
                again is None
                or again["labelled_block"] != block
                or not math.isclose(again["frequency_hz"], frequency, rel_tol=1e-9)
            ):
                replayed = (
                    "no such label"
                    if again is None
                    else f"block {again['labelled_block']}, {again['frequency_hz']:.4f} Hz"
                )
                raise WorkbenchError(
                    f"{self._labels_path}: mode {mode} was shown from block {block} at "
                    f"{frequency:.4f} Hz, tracking the stored blocks again gives {replayed}: "
                    "the tracking options (--mac-min, --gate, --frequency-tol, --baseline) "
                    "differ from the first run's; use them, or another --state"
                )
            del self._expected[mode]
