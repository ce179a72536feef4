"""`workbench identify --method lscf` and the SSI/LSCF cross-check on a short simulated voyage.

The demo hull's modes (workbench.simulate.hull) lie between 2.9 and 8.3 Hz; the voyage is
30 minutes (three 20-minute blocks, 5-minute step), identified in-process.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import POLES, read_table
from workbench.cli import main
from workbench.identification import (
    IdentifyOptions,
    cross_check_blocks,
    identify_voyage,
    write_tpe_figures,
)
from workbench.sid.crosscheck import CROSS_CHECK_COLUMNS


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    from workbench.simulate import simulate_voyage

    return simulate_voyage(tmp_path_factory.mktemp("voyage"), seed=7, hours=0.5)


def test_lscf_identify_with_cross_check(voyage, tmp_path):
    options = IdentifyOptions(
        method="lscf",
        block_rows=10,
        orders=tuple(range(4, 41, 2)),
        lscf_orders=tuple(range(1, 11)),
        cross_check=True,
    )
    result = identify_voyage([voyage.out_dir], tmp_path, options=options, scheduler="synchronous")
    assert result.run.processed == voyage.n_blocks
    poles = read_table(tmp_path / "poles.parquet", POLES)
    assert set(poles["block"]) == set(range(voyage.n_blocks))
    selected = pd.read_parquet(tmp_path / "selected.parquet")
    # the library's result is the identify stage's: the tables it wrote, its summary
    assert len(result.table) == result.n_selected == len(selected)
    pd.testing.assert_frame_equal(result.poles, poles)
    assert str(result.summary()).splitlines()[0] == str(result.run).splitlines()[0]
    assert selected.groupby("block").size().min() >= 5  # of the seven hull modes
    # the combined modal model: LSCF's own estimate (the block's method, the reference of
    # the combination) with the uncertainty of both methods' scatter and agreement
    np.testing.assert_array_equal(selected["combined_frequency_hz"], selected["frequency_hz"])
    both = selected[selected["combined_methods"] == 2]
    assert len(both) >= 4 * voyage.n_blocks
    assert (both["combined_frequency_std_hz"] > 0).all()
    assert (both["combined_frequency_std_hz"] < 0.01 * both["frequency_hz"]).all()
    # the tracked modal table carries them (optional MODAL columns)
    from workbench.sid.tracking import track_modes

    tracked = track_modes(selected)
    assert {"combined_frequency_hz", "combined_frequency_std_hz"} <= set(tracked.columns)
    assert tracked["combined_frequency_std_hz"].notna().all()
    alone = selected[selected["combined_methods"] == 1]
    np.testing.assert_allclose(
        alone["combined_frequency_std_hz"],
        np.maximum(alone["frequency_std_hz"], 1e-4 * alone["frequency_hz"]),
    )
    table = pd.read_csv(tmp_path / "crosscheck.csv")
    assert list(table.columns[:1]) == ["block"]
    assert set(CROSS_CHECK_COLUMNS) <= set(table.columns)
    paired = table[table["paired"]]
    assert len(paired) >= 4 * voyage.n_blocks
    # the two methods agree on the modes they share: 1 % is the pairing window, the
    # median is far inside it
    assert np.median(paired["frequency_difference"].abs()) < 0.002
    assert (paired["mac"] > 0.95).all()
    lines = result.lines
    assert any(line.startswith("SSI/LSCF cross-check over 3 block(s)") for line in lines)


def test_options_record_lscf_settings_only_when_used():
    assert "lscf_orders" not in IdentifyOptions().parameters()
    assert "cross_check" not in IdentifyOptions().parameters()
    assert IdentifyOptions(method="lscf").parameters()["lscf_orders"] == list(range(1, 16))
    assert IdentifyOptions(cross_check=True).parameters()["cross_check"] is True
    with pytest.raises(ValueError, match="method"):
        IdentifyOptions(method="fdd")
    with pytest.raises(ValueError, match="lscf_orders"):
        IdentifyOptions(lscf_orders=(0, 1))


def test_cli_method_lscf(voyage, tmp_path, capsys):
    code = main(
        [
            "identify",
            str(voyage.out_dir),
            "--out",
            str(tmp_path),
            "--method",
            "lscf",
            "--lscf-max-order",
            "8",
            "--tpe-figures",
            "1",
            "--min-order",
            "4",
            "--max-order",
            "24",
            "--block-rows",
            "10",
            "--scheduler",
            "synchronous",
            "--quiet",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert "3 block(s) processed" in out
    assert not (tmp_path / "crosscheck.csv").exists()
    tpe_figures = list((tmp_path / "figures").glob("tpe_block*.png"))
    assert len(tpe_figures) == 1 and f"figure: {tpe_figures[0]}" in out
    orders = set(read_table(tmp_path / "poles.parquet", POLES)["model_order"])
    n_channels = 19 - 1  # acc12 is dead in this voyage (see faults.csv)
    assert orders <= {p * n_channels for p in range(1, 9)} | {p * 19 for p in range(1, 9)}


def test_cli_rejects_bad_lscf_order(voyage, tmp_path, capsys):
    code = main(["identify", str(voyage.out_dir), "--out", str(tmp_path), "--lscf-max-order", "0"])
    assert code == 2
    assert "--lscf-max-order" in capsys.readouterr().err


def test_cross_check_blocks_writes_the_table_and_per_block_summary(voyage, tmp_path):
    from workbench.sid.crosscheck import agreement_by_block

    options = IdentifyOptions(block_rows=10, orders=tuple(range(4, 41, 2)))
    table = cross_check_blocks([voyage.out_dir], tmp_path, options=options, n_blocks=2)
    assert sorted(table["block"].unique()) == [0, voyage.n_blocks - 1]
    written = pd.read_csv(tmp_path / "crosscheck.csv")
    assert len(written) == len(table)
    per_block = agreement_by_block(table)
    assert per_block["block"].tolist() == [0, voyage.n_blocks - 1]
    assert (per_block["pairs"] >= 4).all()
    assert (per_block["pairs"] <= per_block[["ssi_modes", "lscf_modes"]].min(axis=1)).all()
    assert (per_block["mac_min"] > 0.95).all()


def test_tpe_figures(voyage, tmp_path):
    options = IdentifyOptions(block_rows=10, orders=tuple(range(4, 41, 4)))
    paths = write_tpe_figures([voyage.out_dir], tmp_path, options=options, blocks=[1])
    assert [p.name for p in paths] == ["tpe_block000001.png"]
    assert paths[0].read_bytes()[:4] == b"\x89PNG"


def test_a_failing_cross_check_leaves_the_block_identified(voyage, tmp_path):
    # more lags than the block has samples: LSCF refuses, SSI-cov still identifies
    options = IdentifyOptions(
        block_rows=10, orders=tuple(range(4, 25, 2)), cross_check=True, lscf_lags=10**8
    )
    result = identify_voyage(
        [voyage.out_dir], tmp_path, options=options, scheduler="synchronous", blocks=[0]
    )
    assert result.run.processed == 1 and result.run.skipped == 0
    assert result.n_selected >= 5
    assert "crosscheck" not in result.files


def test_a_mode_the_combined_model_leaves_out_has_no_combined_values():
    """An own second-look mode the other method does not confirm is not in the combined
    model (workbench.sid.combined): its combined columns are missing, the others filled."""
    from workbench.identification.engine import _with_combined
    from workbench.sid.selection import ModeSelection

    shapes = np.eye(3, dtype=complex)[:, :2]
    modes = pd.DataFrame(
        {
            "frequency_hz": [2.0, 3.0],
            "damping_ratio": [0.01, 0.014],
            "frequency_std_hz": [0.001, 0.003],
            "damping_std": [0.001, 0.004],
            "pole_index": [10, 20],
        }
    )
    own = ModeSelection(modes, shapes, None, (), "cluster", {"second_look_poles": (20,)})
    other = ModeSelection(modes.iloc[:1].copy(), shapes[:, :1], None, (), "cluster")
    table = _with_combined(modes, own, other, "cov")
    assert str(table["combined_methods"].dtype) == "Int64"
    assert table["combined_methods"].iat[0] == 2
    assert table["combined_methods"].isna().tolist() == [False, True]
    assert np.isnan(table["combined_frequency_hz"].iat[1])
    assert table["combined_frequency_hz"].iat[0] == 2.0
