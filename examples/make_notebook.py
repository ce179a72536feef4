"""Write and execute ``examples/notebook.ipynb`` (the outputs kept in the file).

    python examples/make_notebook.py

The notebook runs in a temporary folder (its simulated voyage and saved models are not
kept); ``tests/test_example_notebook.py`` executes it again through nbclient.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parent
#: The checkout the kernel imports workbench from (not another installed copy).
ROOT = HERE.parent

INTRODUCTION = """\
# workbench in a notebook

A simulated 6-hour voyage without acceleration files: the simulator's noisy modal table is
tracked, the ship log averaged onto its blocks, one stepwise model fitted per mode (read
like statsmodels' results), the models saved and read back, and the modes forecast. The
notebook writes into the folder it runs in (`voyage/`, `fit/`)."""

CELLS = [
    "%matplotlib inline\nimport workbench as wb\n\n"
    'voyage = wb.simulate_voyage("voyage", hours=6, accelerations=False)',
    "modes = wb.track(voyage.tracked_modal, progress=True)\nmodes.summary()",
    "ship = modes.predictors(voyage.dship_log)\nfit = modes.fit(ship)\nfit.summary()",
    "len(fit), [round(fit[mode].rsquared, 3) for mode in fit]",
    "fit[1].predict(ship).head()",
    "fit.plot(1)",
    'fit.save("fit", figures=False)\nback = wb.read_fit("fit")\n'
    "try:\n    fitted = back[1].fittedvalues\nexcept ValueError as error:\n    print(error)",
    "forecast = modes.forecast(ship)\nforecast.plot(1)",
]


def notebook() -> nbformat.NotebookNode:
    """The example notebook, not executed."""
    cells = [nbformat.v4.new_markdown_cell(INTRODUCTION)]
    cells += [nbformat.v4.new_code_cell(source) for source in CELLS]
    book = nbformat.v4.new_notebook(cells=cells)
    book.metadata["kernelspec"] = {
        "name": "python3",
        "display_name": "Python 3",
        "language": "python",
    }
    return book


def execute(book: nbformat.NotebookNode, folder: Path, *, timeout_s: int = 600):
    """Run *book* in *folder* with the python3 kernel (its outputs stored in *book*); the
    kernel imports workbench from this checkout."""
    paths = [str(ROOT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    os.environ["PYTHONPATH"] = os.pathsep.join(os.path.abspath(p) for p in paths)
    client = NotebookClient(
        book,
        timeout=timeout_s,
        kernel_name="python3",
        resources={"metadata": {"path": str(folder)}},
    )
    return client.execute()


def main() -> int:
    book = notebook()
    with tempfile.TemporaryDirectory(prefix="workbench-notebook-") as folder:
        execute(book, Path(folder))
    for cell in book.cells:  # the temporary folder's name is not part of the example
        for output in cell.get("outputs", []):
            if "text" in output:
                output["text"] = output["text"].replace(folder, ".")
    nbformat.write(book, HERE / "notebook.ipynb")
    print(f"written: {HERE / 'notebook.ipynb'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
