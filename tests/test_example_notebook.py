"""The example notebook (examples/notebook.ipynb) executed through nbclient, as a user
runs it in Jupyter (issue 30): summaries shown as HTML, each figure once, results that
iterate and have a length, pandas out where pandas came in, a model read back that says in
one line what it cannot do, and a progress bar without the 'IProgress not found' warning.

The test skips only when no Jupyter kernel can start on this machine.
"""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _make_notebook_module():
    spec = importlib.util.spec_from_file_location("make_notebook", EXAMPLES / "make_notebook.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def kernel_available() -> None:
    """Skip when no python3 kernel starts here (the one reason to skip)."""
    from jupyter_client.manager import start_new_kernel

    try:
        manager, client = start_new_kernel(kernel_name="python3", startup_timeout=120)
    except Exception as error:  # noqa: BLE001 - any failure to start: no kernel here
        pytest.skip(f"no Jupyter kernel can start here: {type(error).__name__}: {error}")
    client.stop_channels()
    manager.shutdown_kernel(now=True)


def _outputs(cell, kind: str) -> list:
    return [o for o in cell.outputs if o.output_type == kind]


def _images(cell) -> int:
    return sum("image/png" in o.get("data", {}) for o in cell.outputs)


def test_the_committed_notebook_is_the_example_and_executed():
    module = _make_notebook_module()
    committed = nbformat.read(EXAMPLES / "notebook.ipynb", as_version=4)
    code = [c for c in committed.cells if c.cell_type == "code"]
    assert [c.source for c in code] == module.CELLS
    assert [c.execution_count for c in code] == list(range(1, len(code) + 1))
    assert all(c.outputs for c in code[1:])  # every cell after the first shows something


def test_the_example_notebook_runs_as_a_user_sees_it(kernel_available, tmp_path, monkeypatch):
    module = _make_notebook_module()
    monkeypatch.setenv("PYTHONPATH", "")  # execute() puts this checkout first
    monkeypatch.delenv("MPLBACKEND", raising=False)
    book = module.notebook()
    module.execute(book, tmp_path, timeout_s=600)  # a failing cell raises CellExecutionError
    cells = {c.source.splitlines()[-1]: c for c in book.cells if c.cell_type == "code"}

    # progress bar in the notebook: a text bar on stderr, no widget warning
    track = cells["modes.summary()"]
    stderr = "".join(o.text for o in _outputs(track, "stream") if o.name == "stderr")
    assert "track: 100%" in stderr and "IProgress" not in stderr
    # summaries: HTML in the notebook, the text view (not a quoted string) as plain text
    for last in ("modes.summary()", "fit.summary()"):
        (result,) = _outputs(cells[last], "execute_result")
        assert result.data["text/html"].startswith("<div>")
        assert not result.data["text/plain"].startswith(("'", '"'))
    fit_html = _outputs(cells["fit.summary()"], "execute_result")[0].data["text/html"]
    assert "stepwise models per mode" in fit_html and fit_html.count("<tr>") >= 3
    # results iterate and have a length
    (result,) = _outputs(
        cells["len(fit), [round(fit[mode].rsquared, 3) for mode in fit]"], "execute_result"
    )
    length, r_squared = ast.literal_eval(result.data["text/plain"])
    assert length == len(r_squared) >= 3 and all(0.0 <= r <= 1.0 for r in r_squared)
    # pandas out where pandas came in
    (result,) = _outputs(cells["fit[1].predict(ship).head()"], "execute_result")
    assert "Name: mode1_frequency_hz, dtype: float64" in result.data["text/plain"]
    # each figure once (before: the returned figure and pyplot's open figure, twice)
    assert _images(cells["fit.plot(1)"]) == 1
    assert _images(cells["forecast.plot(1)"]) == 1
    # a model read back says in one line what it cannot do
    (printed,) = _outputs(cells["    print(error)"], "stream")
    lines = printed.text.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fittedvalues of mode 1 needs")
    assert "fit.json" in lines[0]
