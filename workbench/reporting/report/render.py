"""Turning sections into the page: figures written beside the report, tables as strings,
the jinja2 template rendered and written atomically."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import atomic_path

from ...results import save_figure
from .run import ReportSection

_FIGURE_DIR = "report_files"


class Figures:
    def __init__(self, report_path: Path, dpi: int):
        self.folder = report_path.parent / _FIGURE_DIR
        self.folder.mkdir(parents=True, exist_ok=True)
        self.report_dir = report_path.parent
        self.dpi = dpi

    def save(self, fig, name: str) -> str:
        path = save_figure(fig, self.folder / f"{name}.png", dpi=self.dpi)
        return path.relative_to(self.report_dir).as_posix()


def format_table(frame: pd.DataFrame, digits: int = 4) -> dict:
    """Header and rows of strings for the template (numbers to *digits* significant)."""

    def text(value) -> str:
        if value is None or (isinstance(value, float) and np.isnan(value)):
            return "–"
        if isinstance(value, bool | np.bool_):
            return "yes" if value else "no"
        if isinstance(value, float | np.floating):
            return f"{value:.{digits}g}"
        if isinstance(value, pd.Timestamp):
            return value.strftime("%Y-%m-%d %H:%M")
        return str(value)

    numeric = [
        pd.api.types.is_numeric_dtype(frame[c]) and not pd.api.types.is_bool_dtype(frame[c])
        for c in frame.columns
    ]
    rows = [
        [(text(v), "" if is_number else "text") for v, is_number in zip(row, numeric, strict=True)]
        for row in frame.itertuples(index=False)
    ]
    classes = list(frame.attrs.get("row_classes", [""] * len(frame)))
    return {
        "columns": [
            (str(c), "" if n else "text") for c, n in zip(frame.columns, numeric, strict=True)
        ],
        "rows": list(zip(classes, rows, strict=True)),
    }


def warning_counts(warnings_column: pd.Series) -> list[str]:
    """Row warnings (``"a: detail; b: detail"``) as one line per kind with its row count,
    e.g. ``"track re-acquired (47 rows), e.g. track re-acquired: pole at 2.8621 Hz ..."``."""
    counts: dict[str, list] = {}
    for text in warnings_column.dropna().astype(str):
        for part in (p.strip() for p in text.split(";")):
            if not part:
                continue
            kind = part.split(":", 1)[0].strip()
            entry = counts.setdefault(kind, [0, part])
            entry[0] += 1
    return [
        f"{kind} ({n} rows)" + (f", e.g. {example}" if example != kind else "")
        for kind, (n, example) in counts.items()
    ]


def read_csv_times(path: Path, columns: Sequence[str]) -> pd.DataFrame:
    frame = pd.read_csv(path)
    for column in columns:
        if column in frame.columns:
            frame[column] = pd.to_datetime(frame[column], utc=True, format="ISO8601")
    return frame


def _render_section(section: ReportSection) -> dict:
    return {
        "id": section.id,
        "title": section.title,
        "paragraphs": section.paragraphs,
        "tables": [(caption, format_table(frame)) for caption, frame in section.tables],
        "figures": section.figures,
        "details": section.details,
        "figures_first": section.figures_first,
        "grid": section.id in ("identification", "regression") and len(section.figures) > 1,
    }


def write_page(
    out: Path,
    *,
    title: str,
    overview: ReportSection,
    notices: Sequence[str],
    results: Sequence[tuple[str, str]],
    sections: Sequence[ReportSection],
) -> None:
    """Render ``templates/report.html.j2`` and write it to *out* atomically."""
    import jinja2

    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("workbench.reporting", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    template = environment.get_template("report.html.j2")
    page = template.render(
        title=title,
        generated=pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ"),
        overview=_render_section(overview),
        warnings=list(notices),
        results=list(results),
        sections=[_render_section(s) for s in sections],
    )
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
