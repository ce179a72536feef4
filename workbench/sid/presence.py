"""Which tracked modes are persistent enough to model: presence over the blocks."""

from __future__ import annotations

import pandas as pd

from ..errors import WorkbenchError

__all__ = ["persistent_modes"]


def persistent_modes(
    modal: pd.DataFrame, min_presence: float = 0.5
) -> tuple[pd.DataFrame, list[str]]:
    """Rows of the modes measured in at least *min_presence* of the blocks of *modal*.

    Short-lived tracks (a shaft harmonic sweeping past with the speed, spurious poles)
    would each add a column of mostly missing values to correlations and models. The share
    is of the blocks with data, those of the tracked table: a block without an
    acceleration record (a recorder off for hours), given up or skipped as faulty is no
    block a mode was absent from.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (block, mode, ...).
    min_presence : float
        Smallest share of the blocks a kept mode is measured in, in [0, 1].

    Returns
    -------
    modal : DataFrame
        The rows of the kept modes.
    lines : list of str
        A note naming the modes left out (empty when none).

    Raises
    ------
    WorkbenchError
        When no mode is left.
    """
    if not 0.0 <= min_presence <= 1.0:
        raise ValueError(f"min_presence={min_presence} must be in [0, 1]")
    presence = modal.groupby("mode")["block"].nunique() / max(modal["block"].nunique(), 1)
    keep = presence.index[presence >= min_presence]
    left_out = sorted(int(m) for m in presence.index[presence < min_presence])
    if not len(keep):
        raise WorkbenchError(
            f"no mode is measured in at least {100 * min_presence:.0f} % of the blocks"
        )
    lines = []
    if left_out:
        lines.append(
            f"modes {left_out} left out: measured in fewer than {100 * min_presence:.0f} % "
            "of the blocks"
        )
    return modal[modal["mode"].isin(keep)], lines
