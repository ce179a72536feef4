"""Issue 28: ``workbench fit`` on a 1.5-h simulated voyage never returned.

The ship log's air temperature is despiked to NaN in two blocks; for mode 3 the stepwise
search added air_temp_c, added speed_kn, removed air_temp_c, removed speed_kn and repeated
forever. The fit now ends, with the cycle named in a warning, the step log and the summary
(the search itself: tests/stats/test_stepwise_termination.py). The fit stage runs here the
way ``workbench fit --modal voy/tracked_modal.csv --dship voy/dship.tsv`` runs it, without
the diagnostic figures (which take most of the command's time).
"""

from __future__ import annotations

import json
import warnings

from data_contracts.modal_layout import read_modal_table
from workbench.predictors import canonical_predictors, load_predictors
from workbench.stages import fit
from workbench.stats.stepwise import StepwiseWarning


def test_fit_on_the_issue_voyage_ends_with_the_cycle_named(tmp_path):
    from workbench.simulate import simulate_voyage

    voyage = tmp_path / "voy"
    simulate_voyage(voyage, seed=0, hours=1.5, accelerations=False)
    modal = read_modal_table(voyage / "tracked_modal.csv")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        predictors = canonical_predictors(load_predictors(dship=voyage / "dship.tsv", onto=modal))
        result = fit(modal, predictors)
        result.save(tmp_path / "F", figures=False)
    assert predictors["air_temp_c"].isna().sum() == 2  # the despiked blocks
    cycled = [str(w.message) for w in caught if w.category is StepwiseWarning]
    assert len(cycled) == 1 and cycled[0].startswith("mode3_frequency_hz: stepwise search cycled")
    assert "1 -> 1 + air_temp_c -> 1 + speed_kn + air_temp_c -> 1 + speed_kn -> 1" in cycled[0]
    assert sorted(result.models) == [1, 2, 3, 4, 5, 6, 7]
    summary = (tmp_path / "F" / "fit_summary.txt").read_text(encoding="utf-8")
    assert "Warning: mode3_frequency_hz: stepwise search cycled" in summary
    assert "5. Stopping: the search cycled; kept mode3_frequency_hz ~ 1 + speed_kn" in summary
    payload = json.loads((tmp_path / "F" / "fit.json").read_text(encoding="utf-8"))
    mode3 = next(item for item in payload["modes"] if item["mode"] == 3)["model"]
    assert mode3["terms"] == ["speed_kn"] and len(mode3["warnings"]) == 1
    assert [step["action"] for step in mode3["steps"]] == ["add", "add", "remove", "remove", "stop"]
    # the other modes ended by the search's rules
    others = [item["model"] for item in payload["modes"] if item["mode"] != 3]
    assert all(model["warnings"] == [] for model in others)
