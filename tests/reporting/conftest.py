"""A short run of every stage on a simulated voyage, for the report tests."""

from __future__ import annotations

import matplotlib
import pytest

matplotlib.use("Agg")


def make_run(out, *, hours: float = 2.0):
    """Simulate *hours* of the demo voyage into ``out/voyage`` and run identify (orders up
    to 30, in this process, shaft harmonics marked from the ship log), track, predictors,
    fit and a forecast with a 6-block window into *out*, as the CLI stages would."""
    from data_contracts import CONTRACTS, PREDICTORS, read_table, write_table
    from workbench.identification import IdentifyOptions
    from workbench.predictors import canonical_predictors, load_predictors
    from workbench.sid.harmonics import HarmonicOptions
    from workbench.simulate import simulate_voyage
    from workbench.stages import ForecastOptions, evaluate, fit, forecast, identify, track

    voyage = simulate_voyage(out / "voyage", seed=3, hours=hours)
    identified = identify(
        out / "voyage",
        out / "identify",
        options=IdentifyOptions(orders=tuple(range(4, 31, 2))),
        scheduler="synchronous",
        dship=voyage.dship_log,
        harmonics=HarmonicOptions(blades=5),
    )
    tracked = track(identified.table)
    tracked.save(out / "tracked_modal.csv")
    tracked = tracked.table
    predictors = load_predictors(dship=voyage.dship_log, onto=tracked)
    write_table(predictors, out / "predictors.csv", PREDICTORS)
    predictors = canonical_predictors(predictors)
    fit(tracked, predictors).save(out / "fit")
    forecasted = forecast(
        tracked,
        predictors,
        poles=identified.poles,
        options=ForecastOptions(
            options=("A", "B"), scheme=2, train_blocks=6, horizon=2, trust=0.65
        ),
    )
    forecasted.save(out / "forecast.csv")
    truth = read_table(voyage.truth_modal, CONTRACTS["modal"])
    evaluate(forecasted.table, truth).save(out / "evaluation.csv")
    return out


@pytest.fixture(scope="session")
def short_run(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run"))
