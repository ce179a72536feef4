"""Option B's measurement chooser for the memory forecast: the pole cluster in the gate,
checked against the mode's shape where the poles carry shapes.

Used by :func:`~workbench.forecast.blend.memory_forecast`; the cluster search itself is in
:mod:`workbench.forecast.measurement`.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd

from .measurement import ClusterChooser, PoleIndex
from .options import MeasurementOptions

__all__ = ["option_b_chooser"]


def option_b_chooser(
    poles: pd.DataFrame,
    modal: pd.DataFrame,
    blocks: np.ndarray,
    mode_labels: np.ndarray,
    index: PoleIndex,
    measurement: MeasurementOptions,
    notes: Counter[str],
) -> ClusterChooser:
    """Chooser of each block's pole cluster per mode (MAC check when shapes are there).

    Without shape columns the note saying so is counted in *notes*.
    """
    from .pole_selection import _MIN_SHAPE_CHANNELS, _mac_on_common_channels, _PoleSelector

    selector = _PoleSelector(
        poles,
        modal,
        blocks,
        mode_labels,
        shape_mac_min=measurement.mac_min,
        reacquire_blocks=measurement.reacquire_blocks,
        reacquire_band=measurement.reacquire_band,
    )
    shape_mac = None
    if selector.uses_shapes:
        # selector rows are in the table order of its own sort; map PoleIndex positions
        table_row_to_selector = np.empty(len(poles), dtype=np.int64)
        table_row_to_selector[selector.rows] = np.arange(selector.rows.size)

        def shape_mac(i, j, positions):
            ref = int(selector.reference_row[i, j])
            if ref < 0:
                return np.full(positions.size, np.nan)
            table_rows = index.rows[positions]
            shapes = selector.shapes[selector.rows[table_row_to_selector[table_rows]]]
            return _mac_on_common_channels(selector.reference_shapes[ref], shapes)
    else:
        notes[
            "option B without mode shapes (poles or modal lack shape_re_<channel> columns "
            f"for {_MIN_SHAPE_CHANNELS}+ shared channels): consistent pole cluster in the "
            "gate, no MAC check"
        ] += 1
    return ClusterChooser(
        index,
        shape_mac,
        shape_mac_min=measurement.mac_min,
        reacquire_blocks=measurement.reacquire_blocks,
        reacquire_band=measurement.reacquire_band,
    )
