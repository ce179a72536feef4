"""A short run of every stage on a simulated voyage, for the report tests."""

from __future__ import annotations

import matplotlib
import pytest

matplotlib.use("Agg")


def make_run(out, *, hours: float = 2.0):
    """Simulate *hours* of the demo voyage into ``out/voyage`` and run identify (orders up
    to 30, in this process), track, predictors, fit and a forecast with a 6-block window
    into *out*, as the CLI stages would."""
    from data_contracts import CONTRACTS, PREDICTORS, read_table, write_table
    from workbench.identify import IdentifyOptions, identify_voyage
    from workbench.pipeline import (
        canonical_predictors,
        evaluate_forecast,
        load_predictors,
        persistent_modes,
        run_forecast,
        run_track,
    )
    from workbench.reporting.diagnostics_plot import write_fit_report
    from workbench.simulate import simulate_voyage

    voyage = simulate_voyage(out / "voyage", seed=3, hours=hours)
    identify_voyage(
        [out / "voyage"],
        out / "identify",
        options=IdentifyOptions(orders=tuple(range(4, 31, 2))),
        scheduler="synchronous",
    )
    tracked = run_track(out / "identify" / "selected.parquet", out / "tracked_modal.csv")
    tracked = tracked.tables["tracked"]
    predictors = load_predictors(dship=voyage.dship_log, onto=tracked)
    write_table(predictors, out / "predictors.csv", PREDICTORS)
    predictors = canonical_predictors(predictors)
    modes, _ = persistent_modes(tracked, 0.5)
    write_fit_report(modes, predictors, out / "fit")
    forecast = run_forecast(
        tracked,
        predictors,
        out / "forecast.csv",
        poles=read_table(out / "identify" / "poles.parquet", CONTRACTS["poles"]),
        options=("A", "B"),
        scheme=2,
        train_blocks=6,
        horizon=2,
        trust=0.65,
    )
    truth = read_table(voyage.truth_modal, CONTRACTS["modal"])
    evaluate_forecast(forecast.tables["forecast"], truth, out=out / "evaluation.csv")
    return out


@pytest.fixture(scope="session")
def short_run(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run"))
