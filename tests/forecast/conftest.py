"""Fixtures shared by the forecast tests."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_REGIMES = Path(__file__).resolve().parents[2] / "benchmarks" / "forecast_regimes.py"


@pytest.fixture(scope="module")
def regimes():
    """The accuracy suite's regime generators (``benchmarks/forecast_regimes.py``)."""
    spec = importlib.util.spec_from_file_location("forecast_regimes_under_test", _REGIMES)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)
