"""identify's check of the ship log's clock (:mod:`workbench.predictors.clock`), run live.

On the bridge the ship log is read as it grows, and a log kept in local time without a UTC
offset moves every predictor of the monitor (the harmonics' shaft speed, the forecast, the
health chart) hours off its blocks, as it moves identify's. The monitor keeps the RMS per
channel of each block it identifies (with the block's own span) and runs identify's check on
them once :data:`~workbench.predictors.clock.MIN_BLOCKS` blocks are identified, then every
:data:`CHECK_EVERY_BLOCKS` blocks until it has decided: it warned (once per run), or the log
as read follows the hull's vibration level best (:func:`~workbench.predictors.clock.
clock_agrees`; more blocks will not say otherwise), or the log has neither a speed nor a
shaft rate to check. A check reads the blocks of the newest :data:`WINDOW_H` hours only, so
that its cost stays that of a day of blocks however long the voyage (a ship at rest for
days never lets it decide).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..predictors.clock import (
    CANDIDATE_SHIFTS_H,
    MIN_BLOCKS,
    block_level,
    clock_agrees,
    clock_shift_scores,
    clock_warning,
)

__all__ = ["CHECK_EVERY_BLOCKS", "WINDOW_H", "LiveClockCheck"]

#: Blocks identified between two checks while undecided: an hour of the default 5-min
#: step. A verdict needs hours of blocks, so an hour more delays a warning little, and a
#: check's cost shared by 12 blocks is a small fraction of identifying one of them
#: (benchmarks/results/dship_clock_50.txt, section 3).
CHECK_EVERY_BLOCKS = 12
#: Span of the newest blocks a check reads (the oldest are let go). [h] identify's check
#: is right on whole voyages of up to 24 h (benchmarks/results/dship_clock_50.txt).
WINDOW_H = 24.0

_COLUMNS = ["block", "block_start", "channel", "rms"]


class LiveClockCheck:
    """The blocks' RMS per channel as the monitor identifies them, and the clock check on
    them when due.

    Parameters
    ----------
    every_blocks : int
        Blocks identified between two checks while undecided.
    """

    def __init__(self, every_blocks: int = CHECK_EVERY_BLOCKS) -> None:
        self.every_blocks = int(every_blocks)
        #: Whether the check has decided (then it neither keeps blocks nor runs again).
        self.decided = False
        #: The warning said, if any.
        self.warning: str | None = None
        #: Blocks added (this process), and the number added at each check run.
        self.n_added = 0
        self.checked_blocks: list[int] = []
        self._new: list[pd.DataFrame] = []  # the blocks' tables since the last check
        self._length_s: dict[int, float] = {}

    def add(self, channels: pd.DataFrame | None, length_s) -> None:
        """Blocks identified: their ``channels`` table (``block``, ``block_start`` of their
        own span, ``channel``, ``rms``) and their length [s] (one for all, or a Series by
        block)."""
        if self.decided or channels is None or channels.empty:
            return
        self._new.append(channels[_COLUMNS])
        self.n_added += channels["block"].nunique()
        for block in pd.unique(channels["block"]):
            block = int(block)
            own = length_s if np.isscalar(length_s) else length_s.get(block, np.nan)
            self._length_s[block] = float(own)

    @property
    def n_blocks(self) -> int:
        """Identified blocks held (those of the newest :data:`WINDOW_H` hours after a
        check)."""
        return len(self._length_s)

    def due(self) -> bool:
        """Whether to check now: undecided, with :data:`MIN_BLOCKS` blocks at least and, after
        a first check, :attr:`every_blocks` added since."""
        if self.decided or self.n_blocks < MIN_BLOCKS:
            return False
        return (
            not self.checked_blocks or self.n_added - self.checked_blocks[-1] >= self.every_blocks
        )

    def check(
        self, log: pd.DataFrame, source: str, utc_offset: pd.Timedelta | None = None
    ) -> str | None:
        """The check over the blocks held and the ship *log* read from *source* (with
        *utc_offset*): the warning, or None (:attr:`decided` says whether it decided)."""
        self.checked_blocks.append(self.n_added)
        if not {"speed_kn", "shaft_rpm"} & set(log.columns):
            self._decide()  # nothing in the log to check the clock with
            return None
        table = pd.concat(self._new, ignore_index=True) if len(self._new) > 1 else self._new[0]
        starts = pd.to_datetime(table["block_start"], utc=True)
        recent = (starts >= starts.max() - pd.Timedelta(hours=WINDOW_H)).to_numpy()
        if not recent.all():  # the older blocks let go
            table = table[recent]
            kept = set(table["block"].astype(int))
            self._length_s = {b: n for b, n in self._length_s.items() if b in kept}
        self._new = [table]
        level = block_level(table)
        length_s = pd.Series(self._length_s).reindex(level["block"]).to_numpy(float)
        keep = np.isfinite(length_s)
        level, length_s = level[keep], length_s[keep]
        # the log's rows the shifts can reach (a voyage's log is days longer than a window)
        starts = pd.DatetimeIndex(pd.to_datetime(level["block_start"], utc=True))
        low = starts.min() + pd.Timedelta(hours=float(CANDIDATE_SHIFTS_H.min()))
        high = (starts + pd.to_timedelta(length_s, unit="s")).max()
        high += pd.Timedelta(hours=float(CANDIDATE_SHIFTS_H.max()))
        log = log[[c for c in ("time", "speed_kn", "shaft_rpm") if c in log.columns]]
        log = log[((log["time"] >= low) & (log["time"] <= high)).to_numpy()]
        scores = clock_shift_scores(level, length_s, log)
        warning = clock_warning(scores, source, utc_offset)
        if warning is not None:
            self.warning = warning
            self._decide()
        elif clock_agrees(scores):
            self._decide()
        return warning

    def _decide(self) -> None:
        self.decided = True
        self._new, self._length_s = [], {}
