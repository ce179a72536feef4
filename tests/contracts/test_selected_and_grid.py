"""The selected-modes contract, the block grid recorded with block tables, validate_file and
the one reader of the canonical .npz header."""

from __future__ import annotations

import json
import warnings
import zipfile

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from data_contracts import (
    CONTRACTS,
    MODAL,
    SELECTED,
    AccelerationRecord,
    ContractError,
    read_accelerations,
    read_table,
    shapes_to_frame,
    validate_file,
    write_accelerations,
    write_table,
)
from data_contracts.grid import GRID_METADATA_KEY, grid_sidecar
from data_contracts.npz import read_sample_header, read_sample_rows
from workbench.blocks import BlockGrid, block_grid_of
from workbench.errors import WorkbenchError

# a grid no inference from one block can find: 50 % overlap, t0 not on a round time
GRID = BlockGrid(pd.Timestamp("2026-03-01T00:02:10.5Z"), length_s=1200.0, step_s=600.0)


def selected_frame(blocks=(3, 4, 7)) -> pd.DataFrame:
    rows = []
    for block in blocks:
        for j, frequency in enumerate((2.9, 4.7)):
            rows.append(
                {
                    "block": block,
                    "block_start": GRID.start(block),
                    "block_end": GRID.end(block),
                    "frequency_hz": frequency + 0.001 * block,
                    "damping_ratio": 0.012,
                    "model_order": 40,
                    "mpc": 0.99,
                    "stable": True,
                    "pole_index": 10 * j,
                    "n_poles": 12,
                }
            )
    frame = pd.DataFrame(rows)
    # bending-like and torsion-like shapes at four sensors, one row per (block, mode)
    modes = np.array([[1.0, 0.6, 0.3 + 0.02j, 0.1], [0.2, -0.5, 1.0, -0.7 + 0.05j]])
    shapes = modes[np.arange(len(frame)) % 2]
    return pd.concat([frame, shapes_to_frame(["a1", "a2", "a3", "a4"], shapes)], axis=1)


def modal_frame(blocks=(3,)) -> pd.DataFrame:
    frame = GRID.frame(blocks)
    frame["mode"] = 1
    frame["frequency_hz"] = 2.9
    frame["damping_ratio"] = 0.012
    return frame


# --------------------------------------------------------------------------- selected
def test_selected_is_a_registered_contract_and_accepts_what_identify_writes():
    assert CONTRACTS["selected"] is SELECTED
    table = SELECTED.validate(selected_frame())
    assert table["model_order"].dtype == np.int64 and table["stable"].dtype == bool
    assert list(table.columns[:6]) == [
        "block",
        "block_start",
        "block_end",
        "frequency_hz",
        "damping_ratio",
        "model_order",
    ]


def test_selected_reports_every_violation():
    bad = selected_frame().drop(columns="frequency_hz")
    bad.loc[1, "damping_ratio"] = 1.5  # a percentage, not a fraction
    bad.loc[2, "block_end"] = bad.loc[2, "block_start"]
    with pytest.raises(ContractError) as caught:
        SELECTED.validate(bad, source="selected.parquet")
    message = str(caught.value)
    assert "'frequency_hz'" in message and "'damping_ratio', row 1" in message
    # table-level checks (end after start) run once the columns are right
    with pytest.raises(ContractError, match="block_end must be after block_start"):
        SELECTED.validate(selected_frame().assign(block_end=lambda f: f["block_start"]))


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_validate_file_selected_and_cli(tmp_path, suffix, capsys):
    from workbench.cli import main

    path = write_table(selected_frame(), tmp_path / f"selected.{suffix}", SELECTED, grid=GRID)
    checked = validate_file("selected", path)
    assert checked.summary == "6 rows" and checked.data.attrs["block_grid"]["step_s"] == 600.0
    assert main(["validate", "selected", str(path)]) == 0
    assert "valid selected file (6 rows)" in capsys.readouterr().out
    with pytest.raises(ValueError, match="kind='tracked'"):
        validate_file("tracked", path)


def test_demo_folder_validation_includes_selected_modes(tmp_path):
    from workbench.demo import validate_folder

    write_table(selected_frame(), tmp_path / "identify" / "selected.parquet", SELECTED)
    assert validate_folder(tmp_path) == 1
    broken = selected_frame().drop(columns="frequency_hz")
    broken.to_parquet(tmp_path / "identify" / "selected.parquet", index=False)
    with pytest.raises(ContractError, match="frequency_hz"):
        validate_folder(tmp_path)


# --------------------------------------------------------------------------- block grid
@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_grid_round_trips_through_csv_and_parquet(tmp_path, suffix):
    path = write_table(modal_frame(), tmp_path / f"modal.{suffix}", MODAL, grid=GRID)
    table = read_table(path, MODAL)
    assert table.attrs["block_grid"] == {
        "t0": "2026-03-01T00:02:10.500000+00:00",
        "length_s": 1200.0,
        "step_s": 600.0,
    }
    # one block: the recorded step is used, not the 75 % overlap inference would assume
    assert block_grid_of(table) == (GRID.t0, 1200.0, 600.0)
    # written again from the frame, the grid travels with it
    again = write_table(table, tmp_path / f"again.{suffix}", MODAL)
    assert read_table(again, MODAL).attrs["block_grid"] == table.attrs["block_grid"]


def test_grid_is_stored_where_other_tools_find_it(tmp_path):
    parquet = write_table(modal_frame(), tmp_path / "modal.parquet", MODAL, grid=GRID)
    stored = json.loads(pq.read_schema(parquet).metadata[GRID_METADATA_KEY])
    assert stored["step_s"] == 600.0 and stored["length_s"] == 1200.0
    csv = write_table(modal_frame(), tmp_path / "modal.csv", MODAL, grid=GRID)
    assert grid_sidecar(csv).name == "modal.csv.grid.json"
    assert json.loads(grid_sidecar(csv).read_text())["t0"].startswith("2026-03-01T00:02:10.5")
    # the CSV itself stays a plain table
    assert list(pd.read_csv(csv).columns[:3]) == ["block", "block_start", "block_end"]
    # written again without a grid, the stale sidecar goes
    write_table(modal_frame().assign(mode=2), csv, MODAL)
    assert not grid_sidecar(csv).exists()


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_files_without_a_grid_read_as_before(tmp_path, suffix):
    path = tmp_path / f"modal.{suffix}"
    several = modal_frame(blocks=(3, 4, 5))
    write_table(several, path, MODAL)
    table = read_table(path, MODAL)
    assert "block_grid" not in table.attrs
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # several blocks: inferred without a warning
        assert block_grid_of(table) == (GRID.t0, 1200.0, 600.0)
    write_table(modal_frame(), path, MODAL)
    with pytest.warns(UserWarning, match="quarter of the block length"):
        assert block_grid_of(read_table(path, MODAL))[2] == 300.0  # ambiguous: warned


def test_a_grid_contradicting_the_blocks_is_refused_or_ignored(tmp_path):
    wrong = BlockGrid(GRID.t0, 1200.0, 300.0)
    with pytest.raises(ContractError, match="block 3: block_start .* not on the recorded grid"):
        write_table(modal_frame(), tmp_path / "modal.csv", MODAL, grid=wrong)
    # a sidecar left beside a CSV another tool rewrote
    path = write_table(modal_frame(), tmp_path / "modal.csv", MODAL, grid=GRID)
    shifted = modal_frame().assign(
        block_start=lambda f: f["block_start"] + pd.Timedelta("1min"),
        block_end=lambda f: f["block_end"] + pd.Timedelta("1min"),
    )
    shifted.to_csv(path, index=False)
    with pytest.warns(UserWarning, match="recorded block grid ignored"):
        table = read_table(path, MODAL)
    assert "block_grid" not in table.attrs
    grid_sidecar(path).write_text("{not json")
    with pytest.warns(UserWarning, match="recorded block grid ignored"):
        read_table(path, MODAL)
    # a frame whose recorded grid no longer fits its blocks is not trusted either
    moved = read_table(write_table(modal_frame(), tmp_path / "m.parquet", MODAL, grid=GRID), MODAL)
    moved["block_start"] += pd.Timedelta("7s")
    with pytest.raises(WorkbenchError, match="block 3"):
        block_grid_of(moved)


def test_track_carries_the_grid_from_selected_to_tracked(tmp_path):
    from workbench.stages import track

    frame = selected_frame(blocks=range(2, 10))
    selected = write_table(frame, tmp_path / "selected.parquet", SELECTED, grid=GRID)
    result = track(selected)
    result.save(tmp_path / "tracked.csv")
    tracked = read_table(tmp_path / "tracked.csv", MODAL)
    assert tracked.attrs["block_grid"]["step_s"] == 600.0
    assert tracked["mode"].nunique() == 2 and tracked["block"].nunique() == 8
    assert result.table.attrs["block_grid"] == tracked.attrs["block_grid"]


# --------------------------------------------------------------------------- .npz header
def test_npz_header_and_rows_in_place(tmp_path):
    rng = np.random.default_rng(0)
    acceleration = rng.standard_normal((500, 3))
    record = AccelerationRecord(acceleration, 64.0, "2026-03-01T00:00:00Z", ("a", "b", "c"))
    path = write_accelerations(record, tmp_path / "acc.npz")
    header = read_sample_header(path)
    assert header.shape == (500, 3) and header.dtype == np.float64
    assert header.member_size == header.claimed_bytes and header.data_offset is not None
    np.testing.assert_array_equal(read_sample_rows(path, 100, 140), acceleration[100:140])
    # a compressed archive: header still read, rows not in place (the caller reads all)
    packed = tmp_path / "packed.npz"
    with np.load(path) as data:
        np.savez_compressed(packed, **{k: data[k] for k in data.files})
    assert read_sample_header(packed).data_offset is None
    assert read_sample_rows(packed, 0, 10) is None
    np.testing.assert_array_equal(read_accelerations(packed).acceleration, acceleration)
    with zipfile.ZipFile(tmp_path / "empty.npz", "w"):
        pass
    assert read_sample_rows(tmp_path / "empty.npz", 0, 1) is None
    with pytest.raises(KeyError):
        read_sample_header(tmp_path / "empty.npz")
