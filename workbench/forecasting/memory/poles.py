"""Option B's measurement chooser for the memory forecast: the pole cluster in the gate,
checked against the mode's shape where the poles carry shapes.

Used by :func:`~workbench.forecasting.memory.forecast.memory_forecast`; the cluster search itself is in
:mod:`workbench.forecasting.measurement`, the mode's reference shape (the consensus of its
recent tracked shapes) in :mod:`workbench.forecasting.shape_reference`.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd

from ..measurement import ClusterChooser, PoleIndex
from ..options import ForecastOptions
from ..pole_selection import (
    _MIN_SHAPE_CHANNELS,
    _mac_on_common_channels,
    _shape_channels,
    _shape_matrix,
)
from ..shape_reference import consensus_references

__all__ = ["option_b_chooser"]


def option_b_chooser(
    poles: pd.DataFrame,
    modal: pd.DataFrame,
    blocks: np.ndarray,
    mode_labels: np.ndarray,
    index: PoleIndex,
    options: ForecastOptions,
    notes: Counter[str],
) -> ClusterChooser:
    """Chooser of each block's pole cluster per mode (MAC check when shapes are there).

    Without shape columns the note saying so is counted in *notes*.
    """
    channels = _shape_channels(modal, poles)
    shape_mac = None
    if len(channels) >= _MIN_SHAPE_CHANNELS:
        pole_shapes = _shape_matrix(poles, channels)  # table order
        references, reference_row = consensus_references(
            modal, blocks, mode_labels, channels, mac_min=options.mac_min
        )

        def shape_mac(i, j, positions):
            ref = int(reference_row[i, j])
            if ref < 0:
                return np.full(positions.size, np.nan)
            return _mac_on_common_channels(references[ref], pole_shapes[index.rows[positions]])
    else:
        notes[
            "option B without mode shapes (poles or modal lack shape_re_<channel> columns "
            f"for {_MIN_SHAPE_CHANNELS}+ shared channels): consistent pole cluster in the "
            "gate, no MAC check; a pick nearer to another mode's tracked pole than to "
            "the mode's own is refused and the tracked pole measured"
        ] += 1
    return ClusterChooser(
        index,
        shape_mac,
        shape_mac_min=options.mac_min,
        reacquire_blocks=options.reacquire_blocks,
        reacquire_band=options.reacquire_band,
    )
