"""The README's notebook version of the demo runs as written (on a 3-hour voyage)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def notebook_snippet() -> str:
    section = README.read_text(encoding="utf-8").split("## In a notebook", 1)[1]
    return re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)


def test_readme_notebook_demo(tmp_path, monkeypatch):
    code = notebook_snippet()
    assert "hours=6" in code
    # a 3-hour voyage (33 blocks) keeps the test short; identify in this process
    code = code.replace("hours=6", "hours=3").replace(
        "band_hz=(2.0, 12.0))", 'band_hz=(2.0, 12.0)), scheduler="synchronous"'
    )
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    with warnings.catch_warnings():  # e.g. a despiked stretch of the simulated ship log
        warnings.simplefilter("ignore", UserWarning)
        exec(compile(code, str(README), "exec"), namespace)
    modes, fit, forecast, evaluation = (
        namespace[k] for k in ("modes", "fit", "forecast", "evaluation")
    )
    assert modes.table["mode"].nunique() >= 6
    assert set(forecast.table["option"]) == {"A", "B"}
    assert len(evaluation.mapping) >= 6  # tracked modes paired with the true ones
    assert fit.rsquared.min() > 0.5
    assert (tmp_path / "notebook" / "identify" / "selected.parquet").is_file()
