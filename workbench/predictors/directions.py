"""Direction predictors as model inputs: an angle's cosine, never the angle as a number.

The ship log's relative wind direction is an angle on a circle (0° = from ahead, 90° = from
starboard): 359° and 1° are 2° apart. Taken as a number, a ship steaming into the wind
(the direction swinging across 0°) jumps between about 0 and 360 from block to block, and a
linear term in it, its range, its z-score and its Pearson correlation all read those jumps
as the largest changes of the voyage, and a voyage with the same wind from astern (never
crossing 0°) gives other models. The models, correlations and range checks therefore take
a direction column as its cosine::

    wind_dir_rel_cos = cos θ   (+1 wind from ahead, 0 from abeam, -1 from astern)

the head component of the direction's unit vector.

Why the cosine alone, not the cosine and the sine (the unit vector, as circular-linear
regression :math:`y = a + b\\cos\\theta + c\\sin\\theta` [1]_ takes a direction): the hull is
symmetric about its centre plane, so a wind from 30° to starboard and one from 30° to port
are mirror images of one load case, and the mirrored hull is the same hull: its natural
frequencies and damping ratios are even functions of θ, :math:`f(\\theta) = f(-\\theta)`,
and an even function of θ is a function of :math:`\\cos\\theta` alone (:math:`\\cos n\\theta`
is a polynomial in it; the search's squares give :math:`\\cos 2\\theta`, head or stern against
abeam). The sine (the cross component, port against starboard) could only carry an
asymmetry of the ship (a list, a deck cargo on one side); as a candidate it is one more
slowly varying column the stepwise F-tests, which take the blocks as independent, let in
by chance (``benchmarks/results/wind_direction_54.txt``: on the 12-h demo voyage, seeds
0-5, whose simulator gives the wind no effect, 4 chance entries with the cosine, 7 with
the cosine and the sine; the demo's forecast lost 2-3 points with both).

The cosine does not depend on where the circle is cut: a full turn leaves it as it is,
mirroring the wind (θ -> -θ, starboard into port) too, and turning every direction by
180° (a head wind into a following wind) changes its sign only, so a linear model's
predictions, its range checks and |r| stay the same. The wind speed stays a column of its
own: a mode that follows the wind speed needs no direction, and a direction missing from
the log does not take the speed with it (with the speed, the search's interaction is the
head wind :math:`V\\cos\\theta`).

Tables the user reads (the predictor table, the forecast's inputs) keep the direction in
degrees; only what a model, a correlation or a range check computes with is its cosine.

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


def component_columns(direction: str) -> tuple[str, ...]:
    """The columns a direction column enters models as: its cosine (``wind_dir_rel_deg``
    -> ``wind_dir_rel_cos``)."""
    return (direction.removesuffix("_deg") + "_cos",)


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
    """*columns* with each direction column replaced, where it stands, by its cosine (a
    column named already kept once)."""
    out: list[str] = []
    for column in columns:
        parts = component_columns(column) if column in DIRECTION_PREDICTORS else (column,)
        out.extend(part for part in parts if part not in out)
    return out


def direction_components(angle_deg) -> tuple[np.ndarray, ...]:
    """The columns of :func:`component_columns` for angles in degrees: ``(cos θ,)``, NaN
    where the angle is missing."""
    return (np.cos(np.deg2rad(np.asarray(angle_deg, dtype=float))),)


def with_direction_components(frame: pd.DataFrame) -> pd.DataFrame:
    """A copy of *frame* with each direction column replaced, where it stands, by its
    cosine; *frame* itself when it has no direction column."""
    directions = [c for c in frame.columns if c in DIRECTION_PREDICTORS]
    if not directions:
        return frame
    columns: dict[str, pd.Series | np.ndarray] = {}
    for column in frame.columns:
        if column in directions:
            values = pd.to_numeric(frame[column], errors="coerce").to_numpy(
                dtype=float, na_value=np.nan
            )
            for name, component in zip(
                component_columns(column), direction_components(values), strict=True
            ):
                columns[name] = component
        elif column not in _SOURCE or _SOURCE[column] not in directions:
            columns[column] = frame[column]
    return pd.DataFrame(columns, index=frame.index)
