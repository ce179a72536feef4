"""The README's notebook version of the demo runs as written (on a 3-hour voyage): the
five lines of the chain exactly as shown, then the block of the other two stages."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def notebook_snippets() -> list[str]:
    section = README.read_text(encoding="utf-8").split("## In a notebook", 1)[1]
    section = section.split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_the_notebook_demo_is_five_lines_one_stage_per_call():
    chain = notebook_snippets()[0].splitlines()
    assert len(chain) == 5
    assert chain[0] == "import workbench as wb"
    # every stage of the demo's chain is a visible call
    code = "\n".join(chain)
    for call in (
        "simulate_voyage(",
        "identify(",
        ".track(",
        ".predictors(",
        ".forecast(",
        ".evaluate(",
    ):
        assert call in code


def test_readme_notebook_demo(tmp_path, monkeypatch):
    chain, others = notebook_snippets()[:2]
    assert "hours=6" in chain
    # a 3-hour voyage (33 blocks) keeps the test short; identify in this process
    chain = chain.replace("hours=6", "hours=3").replace(
        "band_hz=(2.0, 12.0))", 'band_hz=(2.0, 12.0)), scheduler="synchronous"'
    )
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    with warnings.catch_warnings():  # e.g. a despiked stretch of the simulated ship log
        warnings.simplefilter("ignore", UserWarning)
        exec(compile(chain, str(README), "exec"), namespace)
        exec(compile(others, str(README), "exec"), namespace)
    modes, ship, evaluation, links, fit = (
        namespace[k] for k in ("modes", "ship", "evaluation", "links", "fit")
    )
    assert modes.table["mode"].nunique() >= 6
    assert modes.poles is not None and len(modes.poles)  # kept for option B
    assert set(evaluation.table["option"]) == {"A", "B"}
    assert len(evaluation.mapping) >= 6  # tracked modes paired with the true ones
    assert list(ship.columns[3:]) == [
        "log_coverage",
        "log_coverage_speed_kn", "log_coverage_water_temp_c", "log_coverage_air_temp_c",
        "log_coverage_wind_speed_ms", "log_coverage_wind_dir_rel_deg",
        "speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"
    ]  # fmt: skip
    assert fit.rsquared.min() > 0.5
    assert links.table["useful"].any()
    assert (tmp_path / "notebook" / "identify" / "selected.parquet").is_file()
