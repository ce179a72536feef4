"""The statistics on the demo voyage recover the simulator's law (issue 3, item 6).

The simulator (:mod:`workbench.simulate.hull`) lowers every frequency with speed except
mode 4 (T1, speed_mass 0.002: 0.1 % at 10 kn, below the identification scatter), leaves
mode 3 (VB2) insensitive to air temperature, and gives wind no effect at all (a term in the
wind direction's cosine may enter the stepwise models, with an effect under the
identification scatter).
"""

from __future__ import annotations

import numpy as np
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
        assert not any("wind_speed" in term for term in terms), (mode, terms)
        # the direction enters as its cosine, smooth like the slow part of the blocks'
        # (autocorrelated) identification error: the F-test lets it in by chance for mode 7
        # here (p 0.017, -0.105 % of the frequency, 0.37 of the residual scatter; main's column in
        # degrees, jumping 360 at each of the voyage's 3 crossings of the bow, let none in
        # on this seed, 2 on seed 2): a small effect, under half the scatter, no product
        assert not any("wind_dir" in t and t != "wind_dir_rel_cos" for t in terms), terms
        direction = item.fit.coefficients["estimate"].get("wind_dir_rel_cos", 0.0)
        assert abs(direction) < 0.5 * np.std(item.residuals), (mode, terms, direction)
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
