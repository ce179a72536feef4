"""What every report figure shares: the page width, one colour per tracked mode, UTC
time axes and block times."""

from __future__ import annotations

import matplotlib.dates as mdates
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

#: Width of report figures: 12 in at 100 dpi fits a 1400 px page with margins. [inch]
FIGURE_WIDTH = 12.0
_PALETTE = plt.get_cmap("tab10").colors + plt.get_cmap("Dark2").colors


def mode_colour(mode: int):
    """The colour of tracked mode *mode* in every report figure."""
    return _PALETTE[(int(mode) - 1) % len(_PALETTE)]


def time_axis(ax) -> None:
    locator = mdates.AutoDateLocator(minticks=4, maxticks=10)
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))


def naive_utc(times) -> pd.DatetimeIndex:
    """Times as naive UTC for matplotlib (labels say UTC)."""
    index = pd.DatetimeIndex(pd.to_datetime(times, utc=True))
    return index.tz_convert("UTC").tz_localize(None)


def regular_columns(times: pd.DatetimeIndex) -> tuple[np.ndarray, int, float, float]:
    """Columns of *times* (naive UTC) on a regular grid of their median step, so that gaps
    stay gaps in an image: column index per time, number of columns, and the grid's start
    and step in matplotlib date units."""
    numbers = mdates.date2num(times.to_numpy())
    step = float(np.median(np.diff(numbers))) if len(numbers) > 1 else 1.0 / 1440
    step = step if step > 0 else 1.0 / 1440
    index = np.rint((numbers - numbers[0]) / step).astype(int)
    return index, int(index.max()) + 1, float(numbers[0]), step


def block_times(frame: pd.DataFrame) -> pd.DatetimeIndex:
    """Block mid-times (start + half the length when ``block_end`` is known)."""
    start = pd.to_datetime(frame["block_start"], utc=True)
    if "block_end" in frame.columns:
        end = pd.to_datetime(frame["block_end"], utc=True)
        start = start + (end - start) / 2
    return naive_utc(start)
