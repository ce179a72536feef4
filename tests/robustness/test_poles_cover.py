"""A pole table lacking some blocks of the modal table is said to, naming them.

Before: ``forecast --option pole-cluster --poles FILE`` with a pole table of part of the
voyage (here blocks 25-34 missing) left option B without a measurement in those blocks -
no SSI estimate, the Kalman estimate the model's alone - with exit 0 and not a word, where
option A measures them. Now one warning names how many blocks, which, and when.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("poles_cover") / "sim"
    simulate_voyage(folder, seed=0, hours=4, accelerations=False)
    return folder


def _forecast(sim: Path, poles: Path, out: Path, capsys) -> list[str]:
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--predictors"]
    argv += [sim / "truth_predictors.csv", "--option", "B", "--poles", poles, "--out", out]
    assert main([str(a) for a in [*argv, "--quiet"]]) == 0
    return [line for line in capsys.readouterr().err.splitlines() if "no pole" in line]


def test_blocks_without_poles_are_named(sim, tmp_path, capsys):
    poles = pd.read_parquet(sim / "poles.parquet")
    part = tmp_path / "poles.parquet"
    poles[~poles["block"].between(25, 34)].to_parquet(part)
    warned = _forecast(sim, part, tmp_path / "forecast.csv", capsys)
    assert warned == [
        f"warning: {part}: no pole in 10 of 45 blocks of the modal table (blocks 25 to 34, "
        "2024-03-01T02:05:00Z to 2024-03-01T02:50:00Z): option B has no measurement there"
    ]
    forecast = pd.read_csv(tmp_path / "forecast.csv")
    assert forecast.loc[forecast["block"].between(25, 34), "ssi_frequency_hz"].isna().all()


def test_the_voyages_own_poles_say_nothing(sim, tmp_path, capsys):
    assert _forecast(sim, sim / "poles.parquet", tmp_path / "forecast.csv", capsys) == []
