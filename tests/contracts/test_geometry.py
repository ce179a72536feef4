"""The sensor-geometry contract and the demo hull layout."""

import numpy as np
import pytest

from data_contracts import CONTRACTS, SENSOR_GEOMETRY, ContractError, read_table, write_table
from workbench.simulate.hull import CHANNELS, HULL_LENGTH_M, sensor_geometry


def test_demo_layout_follows_the_contract_and_round_trips(tmp_path):
    table = sensor_geometry()
    path = write_table(table, tmp_path / "geometry.csv", SENSOR_GEOMETRY)
    back = read_table(path, CONTRACTS["sensor_geometry"])
    assert list(back["channel"]) == list(CHANNELS)
    assert back["x_m"].min() == 0.0 and back["x_m"].max() == HULL_LENGTH_M
    # acc13 (tank top, midship, vertical) and acc19 (same place, transverse) share a node
    nodes = dict(zip(back["channel"], back["node"], strict=True))
    assert nodes["acc13"] == nodes["acc19"] and back["node"].nunique() == len(CHANNELS) - 1
    norms = np.linalg.norm(back[["direction_x", "direction_y", "direction_z"]], axis=1)
    np.testing.assert_allclose(norms, 1.0)


def test_every_bad_row_is_reported_at_once():
    table = sensor_geometry()
    table.loc[2, "direction_z"] = 0.5
    table.loc[5, "node"] = table.loc[0, "node"]
    with pytest.raises(ContractError) as caught:
        SENSOR_GEOMETRY.validate(table)
    text = str(caught.value)
    assert "row 2: direction" in text and "more than one position" in text


def test_duplicate_channels_are_rejected():
    table = sensor_geometry()
    table.loc[7, "channel"] = table.loc[6, "channel"]
    with pytest.raises(ContractError, match="duplicate"):
        SENSOR_GEOMETRY.validate(table)
