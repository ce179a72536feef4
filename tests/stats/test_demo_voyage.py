"""The statistics on the demo voyage recover the simulator's law (issue 3, item 6).

The simulator (:mod:`workbench.simulate.hull`) lowers every frequency with speed except
mode 4 (T1, speed_mass 0.002: 0.1 % at 10 kn, below the identification scatter), leaves
mode 3 (VB2) insensitive to air temperature, and gives wind no effect at all.
"""

from __future__ import annotations

import pytest

from data_contracts import MODAL, PREDICTORS, read_table
from workbench.simulate import simulate_voyage
from workbench.stats import correlation_table, fit_modes


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    folder = tmp_path_factory.mktemp("voyage")
    simulate_voyage(folder, seed=0, hours=12, accelerations=False)
    modal = read_table(folder / "tracked_modal.csv", MODAL)
    predictors = read_table(folder / "truth_predictors.csv", PREDICTORS)
    return modal, predictors, folder / "cases.csv"


def test_stepwise_models_recover_the_speed_law(voyage):
    modal, predictors, _ = voyage
    fits = fit_modes(modal, predictors)
    assert list(fits) == [1, 2, 3, 4, 5, 6, 7]
    for mode, item in fits.items():
        terms = item.fit.terms
        assert ("speed_kn" in terms) == (mode != 4), (mode, terms)
        assert not any("wind" in term for term in terms), (mode, terms)
        if "speed_kn" in terms:  # frequencies fall with speed (added water mass)
            assert item.fit.coefficients.loc["speed_kn", "estimate"] < 0
    assert "air_temp_c" not in fits[3].fit.terms


def test_correlation_report_table_on_the_demo_cases(voyage):
    modal, predictors, cases = voyage
    table = correlation_table(modal, predictors, cases=cases, correction="holm")
    assert table["case"].unique().tolist() == [
        "all",
        "stationary",
        "constant_speed",
        "alternating",
        "temperature_drift",
    ]
    speed = table[(table["x"] == "speed_kn") & (table["case"] == "all")].set_index("y")
    assert speed.loc["mode1_frequency_hz", "r"] < -0.9
    assert speed.loc["mode1_frequency_hz", "useful"]
    assert not speed.loc["mode4_frequency_hz", "useful"]
    wind = table[(table["x"] == "wind_speed_ms") & table["y"].str.endswith("frequency_hz")]
    assert not wind[wind["case"] == "all"]["useful"].any()
