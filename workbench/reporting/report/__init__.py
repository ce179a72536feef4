"""One HTML report of a run, built from its tables: ``workbench report DIR``.

:func:`find_run` locates the tables a run left in a folder (identification results, the
tracked modal table, predictors, forecasts, ...), :func:`build_report` draws the views of
:mod:`workbench.reporting.views` and renders ``templates/report.html.j2`` with jinja2:
an overview first (what ran, on which data, the modes, warnings, skipped blocks and dropped
channels), then one section per stage that ran. Internal files (the per-block store) are
never listed. Mode numbers are the tracked labels everywhere; damping is shown in percent.

Other stages add sections without touching :func:`build_report`: a function registered
with :func:`register_section` receives the run's files and the figure writer and returns a
:class:`ReportSection` (or None when its stage did not run); sections can also be passed
directly as ``extra_sections``. The template renders them after the built-in ones, with the
same tables and figures as every other section (e.g. an SSI/LSCF agreement table).

The package, by responsibility: :mod:`.run` (finding a run's files, the section type),
:mod:`.signals` (the pass over the acceleration files), :mod:`.overview` (loading the
tables, the overview), :mod:`.sections` (one section per stage), :mod:`.render` (tables,
figures and the page).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from .overview import load_run, overview_section
from .render import Figures, write_page
from .run import ReportSection, RunFiles, find_run
from .sections import (
    correlation_section,
    crosscheck_section,
    forecast_section,
    harmonics_section,
    identification_section,
    modes_section,
    regression_section,
    signals_section,
)

if TYPE_CHECKING:
    from ...stages import CorrelateResult

__all__ = ["ReportSection", "RunFiles", "build_report", "find_run", "register_section"]


#: Section builders of other stages, called in registration order (see register_section).
_SECTION_BUILDERS: list[Callable[[RunFiles, Callable[..., str]], ReportSection | None]] = []


def register_section(
    builder: Callable[[RunFiles, Callable[..., str]], ReportSection | None],
) -> Callable[[RunFiles, Callable[..., str]], ReportSection | None]:
    """Register a section of another stage (usable as a decorator).

    ``builder(run, save_figure)`` gets the :class:`RunFiles` and ``save_figure(fig, name)``
    (writes a matplotlib figure beside the report and returns its relative path) and
    returns a :class:`ReportSection`, or None when the run has nothing for it.
    """
    _SECTION_BUILDERS.append(builder)
    return builder


#: The files of a run the report reads, by their RunFiles field.
_RUN_INPUTS = {
    "tracked": "tracked modal table",
    "predictors": "predictor table",
    "dship": "ship log",
    "cases": "operating cases",
    "geometry": "sensor geometry",
    "forecast": "forecast table",
    "evaluation": "evaluation table",
    "truth": "true modal table",
}


def _check_out_is_not_an_input(out: Path, run: RunFiles) -> None:
    """Raise OptionError when the report file *out* is a file the report reads (the run's
    tracked modal table, ship log, an acceleration file): writing the page would replace it.
    """
    from ...errors import OptionError

    if not out.is_file():
        return
    named = [(getattr(run, field), label) for field, label in _RUN_INPUTS.items()]
    named += [(path, "acceleration file") for path in run.accelerations]
    for path, label in named:
        if path is not None and Path(path).is_file() and os.path.samefile(path, out):
            raise OptionError(
                f"report file {out} is the run's {label}: writing the report would replace it; "
                "choose another file"
            )


def build_report(
    root: str | os.PathLike,
    *,
    out: str | os.PathLike | None = None,
    run: RunFiles | None = None,
    title: str | None = None,
    stabilisation_blocks: Sequence[int] | None = None,
    n_stabilisation: int = 2,
    summary_lines: Sequence[str] = (),
    extra_sections: Sequence[ReportSection] = (),
    correlation: CorrelateResult | None = None,
    modal: pd.DataFrame | None = None,
    acceleration_layout=None,
    dship_mapping=None,
    dship_utc_offset: str | None = None,
    time_format: str | None = None,
    dpi: int = 100,
) -> Path:
    """Build the HTML report of the run in *root* and return its path.

    Parameters
    ----------
    root : path-like
        The run's folder (see :func:`find_run`).
    out : path-like, optional
        Report file (default ``root / "report.html"``); figures go to ``report_files/``
        beside it.
    run : RunFiles, optional
        The run's tables, if already located (default :func:`find_run` on *root*).
    stabilisation_blocks : sequence of int, optional
        Blocks whose stabilisation diagrams are drawn (default *n_stabilisation* blocks
        spread over the run).
    summary_lines : sequence of str
        Lines about the run shown first (e.g. the demo's stage timings).
    extra_sections : sequence of ReportSection
        Sections added after the built-in ones (other stages' results).
    correlation : CorrelateResult, optional
        The correlate stage's result of this run (default: the stage run on the modes
        present in at least half the blocks and the speed, temperature and wind
        predictors); the report shows its pairs of the modes present in half the blocks.
        Default: the run's own, as the correlate stage saved it (``correlation.json``),
        with the predictors it correlated; else the stage run here.
    modal : DataFrame, optional
        The run's modal table (MODAL contract) when it is not the folder's
        ``tracked_modal.*`` (e.g. another tool's table the run started from).
    acceleration_layout : AccelerationLayout or mapping, optional
        How to read the acceleration files (default: the layout identification recorded
        in its store, so the report reads them as the run did).
    dship_mapping : mapping, optional
        Ship-log column names, when the predictors are read from the DSHIP log (a run
        without a saved correlation or predictor table).
    dship_utc_offset : str, optional
        UTC offset of the ship log's times written without one (``"+02:00"``), likewise.
    time_format : str, optional
        Format of the ship log's times, likewise.
    """
    root = Path(root)
    run = run or find_run(root)
    if run.identify is None and run.tracked is None and modal is None and not run.accelerations:
        raise ValueError(
            "no run found: neither identification results (blocks.csv), a tracked modal "
            "table (tracked_modal.csv) nor acceleration files"
        )
    out = Path(out) if out is not None else root / "report.html"
    _check_out_is_not_an_input(out, run)
    figures = Figures(out, dpi)
    data = load_run(
        run,
        out,
        figures,
        correlation,
        modal=modal,
        acceleration_layout=acceleration_layout,
        dship_mapping=dship_mapping,
        dship_utc_offset=dship_utc_offset,
        time_format=time_format,
    )
    overview = overview_section(data, summary_lines)
    built = [
        signals_section(data),
        identification_section(
            data, stabilisation_blocks=stabilisation_blocks, n_stabilisation=n_stabilisation
        ),
        modes_section(data),
        harmonics_section(data),
        correlation_section(data),
        regression_section(data),
        forecast_section(data),
        crosscheck_section(run),
        *(builder(run, figures.save) for builder in _SECTION_BUILDERS),
    ]
    sections = [section for section in built if section is not None]
    sections.extend(extra_sections)
    results = [
        (path.name if path.is_file() else path.name + "/", os.path.relpath(path, out.parent))
        for path in (
            run.tracked,
            run.predictors,
            run.identify / "poles.parquet" if run.identify is not None else None,
            run.identify / "selected.parquet" if run.identify is not None else None,
            run.forecast,
            run.evaluation,
            run.fit,
        )
        if path is not None and path.exists()
    ]
    write_page(
        out,
        title=title or f"workbench report: {root.resolve().name}",
        overview=overview,
        notices=data.notices,
        results=results,
        sections=sections,
    )
    return out
