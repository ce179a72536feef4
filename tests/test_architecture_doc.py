"""``docs/architecture.md`` leads to code that exists: every file or folder it cites in
backticks (``workbench/cli/forecasting.py``, ``workbench/reporting/*_views.py``) and every
dotted name (``workbench.cli.forecasting._add_forecast``, ``wb.identify``) resolves, so a
newcomer following an option from its flag to where it is used never hits a dead end."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEXT = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
SPANS = re.findall(r"`([^`\n]+)`", TEXT)

PATHS = sorted({s for s in SPANS if " " not in s and "/" in s})
NAMES = sorted({s for s in SPANS if re.fullmatch(r"(workbench|data_contracts|wb)(\.\w+)+", s)})


def resolve(name: str):
    """The object a dotted name stands for: its longest importable module, then attributes."""
    parts = (
        name.replace("wb.", "workbench.", 1).split(".")
        if name.startswith("wb.")
        else name.split(".")
    )
    for n in range(len(parts), 0, -1):
        try:
            owner = importlib.import_module(".".join(parts[:n]))
        except ModuleNotFoundError:
            continue
        for attribute in parts[n:]:
            owner = getattr(owner, attribute)  # AttributeError: the page names nothing
        return owner
    raise ModuleNotFoundError(name)


def test_the_page_cites_paths_and_names():
    """The checks below see what the walk-throughs cite (else they would pass on nothing)."""
    assert "workbench/cli/monitoring.py" in PATHS and "workbench/defaults.py" in PATHS
    assert "workbench.cli.forecasting._add_forecast" in NAMES
    assert "workbench.monitor.readiness.settled" in NAMES
    assert len(NAMES) >= 25 and len(PATHS) >= 15


@pytest.mark.parametrize("path", PATHS)
def test_cited_path_exists(path):
    assert list(ROOT.glob(path.rstrip("/"))), f"docs/architecture.md cites {path}: not found"


@pytest.mark.parametrize("name", NAMES)
def test_cited_name_exists(name):
    if name.endswith(".__main__"):  # importing it would run the command
        assert ROOT.joinpath(*name.split(".")).with_suffix(".py").is_file(), name
    else:
        assert resolve(name) is not None


def test_a_missing_name_is_found():
    with pytest.raises(AttributeError):
        resolve("workbench.cli.forecasting._add_forecast_flags_nowhere")
    with pytest.raises(ModuleNotFoundError):
        resolve("nowhere.module")
    assert resolve("wb.identify") is resolve("workbench.stages.identify")
