"""Direction predictors as model inputs: an angle's cosine and sine, never the angle.

The ship log's relative wind direction is an angle on a circle (0° = from ahead, 90° = from
starboard): 359° and 1° are 2° apart. Taken as a number, a ship steaming into the wind
(the direction swinging across 0°) jumps between 0 and 360 from block to block, and a
linear term in it, its range, its z-score and its Pearson correlation all read those jumps
as the largest changes of the voyage. The models, correlations and range checks therefore
take each direction column as two columns::

    wind_dir_rel_cos = cos θ   (+1 wind from ahead, -1 from astern: the head component)
    wind_dir_rel_sin = sin θ   (+1 wind from starboard, -1 from port: the cross component)

the unit vector of the direction. A linear model in both is the circular-linear
regression :math:`y = a + b\\cos\\theta + c\\sin\\theta` [1]_ (a response peaking at
:math:`\\operatorname{atan2}(c, b)`), and its fit does not depend on where the circle is cut:
rotating every direction by 180° (a head wind into a following wind) or mirroring it
(starboard into port) changes the signs of the columns, not the model's predictions. A
stepwise search can enter the head component alone (a response symmetric about the bow,
as a symmetric hull's is) or the cross component alone. The wind speed stays a column of its
own: a mode that follows the wind speed needs no direction, and a direction missing from
the log does not take the speed with it (with the speed, the products the search's
interactions form are the head and cross wind, :math:`V\\cos\\theta` and :math:`V\\sin\\theta`).

Tables the user reads (the predictor table, the forecast's inputs) keep the direction in
degrees; only what a model, a correlation or a range check computes with is turned into
components.

References
----------
.. [1] K. V. Mardia, P. E. Jupp, *Directional Statistics*, Wiley 2000, §11.3 (regression
   of a linear response on a circular regressor). doi:10.1002/9780470316979
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from data_contracts import DIRECTION_PREDICTORS

__all__ = [
    "component_columns",
    "direction_components",
    "direction_source",
    "model_columns",
    "with_direction_components",
]

#: Suffixes of a direction's two components: the cosine (head), the sine (cross).
_SUFFIXES = ("_cos", "_sin")


def component_columns(direction: str) -> tuple[str, str]:
    """The cosine and sine columns of a direction column (``wind_dir_rel_deg`` ->
    ``wind_dir_rel_cos``, ``wind_dir_rel_sin``)."""
    stem = direction.removesuffix("_deg")
    return stem + _SUFFIXES[0], stem + _SUFFIXES[1]


#: Each component column's direction column.
_SOURCE = {
    component: direction
    for direction in DIRECTION_PREDICTORS
    for component in component_columns(direction)
}


def direction_source(column: str) -> str:
    """The direction column a component column is computed from (*column* itself when it
    is none): its log coverage, its reading in the tables."""
    return _SOURCE.get(column, column)


def model_columns(columns: Sequence[str]) -> list[str]:
    """*columns* with each direction column replaced, where it stands, by its cosine and
    sine columns (a component named already kept once)."""
    out: list[str] = []
    for column in columns:
        parts = component_columns(column) if column in DIRECTION_PREDICTORS else (column,)
        out.extend(part for part in parts if part not in out)
    return out


def direction_components(angle_deg) -> tuple[np.ndarray, np.ndarray]:
    """``(cos θ, sin θ)`` of angles in degrees, NaN where the angle is missing."""
    radians = np.deg2rad(np.asarray(angle_deg, dtype=float))
    return np.cos(radians), np.sin(radians)


def with_direction_components(frame: pd.DataFrame) -> pd.DataFrame:
    """A copy of *frame* with each direction column replaced, where it stands, by its
    cosine and sine columns; *frame* itself when it has no direction column."""
    directions = [c for c in frame.columns if c in DIRECTION_PREDICTORS]
    if not directions:
        return frame
    columns: dict[str, pd.Series | np.ndarray] = {}
    for column in frame.columns:
        if column in directions:
            values = pd.to_numeric(frame[column], errors="coerce").to_numpy(
                dtype=float, na_value=np.nan
            )
            cos, sin = direction_components(values)
            head, cross = component_columns(column)
            columns[head], columns[cross] = cos, sin
        elif column not in _SOURCE or _SOURCE[column] not in directions:
            columns[column] = frame[column]
    return pd.DataFrame(columns, index=frame.index)
