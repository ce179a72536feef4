"""``workbench fit --cases`` reads its case file as ``correlate`` does.

Before: a case named "all" (the name of the stitched model) replaced the stitched model
with its own: on a 4-h voyage the "stitched" model of mode 1 came from that case's 18
blocks instead of every case's 38, and ``coefficients.csv`` and ``fit_summary.txt`` said
nothing (exit 0; ``correlate`` refuses the name). A case file that did not read was
blamed on the modal table too: "error: tracked_modal.csv: cases.csv: line 2: ...".
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main
from workbench.stats.cases import fit_cases


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("fit_cases") / "sim"
    simulate_voyage(folder, seed=0, hours=4, accelerations=False)
    return folder


def _fit(sim: Path, cases: Path, out: Path, capsys) -> tuple[int, list[str]]:
    argv = ["fit", "--modal", sim / "tracked_modal.csv", "--predictors"]
    argv += [sim / "truth_predictors.csv", "--cases", cases, "--out", out, "--quiet"]
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, [line for line in err.splitlines() if line.startswith("error:")]


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (
            ["all,2024-03-01T00:00:00Z,2024-03-01T02:00:00Z", "ice,2024-03-01T02:00:00Z,"],
            "the case name 'all' is reserved for the stitched cases; rename that case",
        ),
        (
            ["transit,2024-03-01T02:00:00Z,2024-03-01T01:00:00Z"],
            "line 2: end 2024-03-01T01:00:00Z is not after start 2024-03-01T02:00:00Z",
        ),
        ([], "no cases (the file has a header only)"),
    ],
    ids=["named all", "end before start", "header only"],
)
def test_a_bad_case_file_is_named_alone_and_nothing_written(sim, tmp_path, capsys, rows, message):
    if rows and rows[-1].endswith(","):
        rows[-1] += "2024-03-01T04:00:00Z"
    cases = tmp_path / "cases.csv"
    cases.write_text("\n".join(["case,start,end", *rows]) + "\n", encoding="utf-8")
    status, errors = _fit(sim, cases, tmp_path / "fit", capsys)
    assert status == 1
    assert errors == [f"error: {cases}: {message}"]
    assert not (tmp_path / "fit").exists()


def test_the_library_refuses_a_case_named_all_from_a_table(sim):
    modal = pd.read_csv(sim / "tracked_modal.csv")
    predictors = pd.read_csv(sim / "truth_predictors.csv")
    table = pd.DataFrame(
        {
            "case": ["all", "ice"],
            "start": pd.to_datetime(["2024-03-01T00:00:00Z", "2024-03-01T02:00:00Z"]),
            "end": pd.to_datetime(["2024-03-01T02:00:00Z", "2024-03-01T04:00:00Z"]),
        }
    )
    with pytest.raises(ValueError, match="the case name 'all' is reserved"):
        fit_cases(modal, predictors, table)


def test_a_good_case_file_fits_as_before(sim, tmp_path, capsys):
    status, errors = _fit(sim, sim / "cases.csv", tmp_path / "fit", capsys)
    assert status == 0 and errors == []
    models = pd.read_csv(tmp_path / "fit" / "case_models.csv")
    stitched = models[(models["case"] == "all") & (models["mode"] == 1)]
    assert stitched["n_obs"].item() > 30  # every case's blocks
