"""Sensor geometry: where each channel sits on the structure and which way it measures.

One row per channel: the node it is mounted on, the node's coordinates in the structure's
frame and the unit vector of the measuring direction. Reports draw mode shapes on this
layout (each channel's shape component as a displacement along its direction).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ._core import Column, TableContract, Violation

__all__ = ["SENSOR_GEOMETRY", "geometry_directions"]

_DIRECTIONS = ("direction_x", "direction_y", "direction_z")


def _unit_directions(frame: pd.DataFrame) -> list[Violation]:
    vectors = frame[list(_DIRECTIONS)].to_numpy(dtype=float)
    norm = np.linalg.norm(vectors, axis=1)
    bad = ~(np.abs(norm - 1.0) <= 1e-3)
    if not bad.any():
        return []
    rows = tuple(frame.index[bad][:5].tolist())
    return [
        Violation(
            "direction_x",
            "direction (direction_x, direction_y, direction_z) is not a unit vector",
            rows,
            int(bad.sum()),
        )
    ]


def _one_place_per_node(frame: pd.DataFrame) -> list[Violation]:
    spread = frame.groupby("node")[["x_m", "y_m", "z_m"]].agg(lambda v: np.ptp(v.to_numpy()))
    nodes = spread.index[(spread.to_numpy() > 1e-6).any(axis=1)]
    if not len(nodes):
        return []
    bad = frame["node"].isin(nodes).to_numpy()
    rows = tuple(frame.index[bad][:5].tolist())
    return [
        Violation("node", f"node {nodes[0]!r} has more than one position", rows, int(bad.sum()))
    ]


SENSOR_GEOMETRY = TableContract(
    name="sensor_geometry",
    description="Where each channel is mounted and which way it measures: one row per "
    "channel. Coordinates in the structure's own right-handed frame (for a hull: x forward "
    "from the aft perpendicular, y to port, z up from the keel). Channels on one node share "
    "its coordinates.",
    columns=(
        Column("channel", "str", "Channel name, as in the acceleration files."),
        Column("node", "str", "Measurement point (several channels may share one)."),
        Column("x_m", "float", "Node coordinate x.", unit="m"),
        Column("y_m", "float", "Node coordinate y.", unit="m"),
        Column("z_m", "float", "Node coordinate z.", unit="m"),
        Column(
            "direction_x",
            "float",
            "Measuring direction, x component (unit vector).",
            minimum=-1.0,
            maximum=1.0,
        ),
        Column(
            "direction_y",
            "float",
            "Measuring direction, y component (unit vector).",
            minimum=-1.0,
            maximum=1.0,
        ),
        Column(
            "direction_z",
            "float",
            "Measuring direction, z component (unit vector).",
            minimum=-1.0,
            maximum=1.0,
        ),
        Column(
            "description",
            "str",
            "Free text (e.g. 'main deck, port').",
            required=False,
            nullable=True,
        ),
    ),
    unique=("channel",),
    checks=(_unit_directions, _one_place_per_node),
)


def geometry_directions(geometry: pd.DataFrame) -> np.ndarray:
    """The measuring directions of a SENSOR_GEOMETRY table as an (n_channels, 3) array."""
    return geometry[list(_DIRECTIONS)].to_numpy(dtype=float)
