"""The index page of a report folder: every table, figure and report, linked and grouped."""

from __future__ import annotations

import html
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from data_contracts import atomic_path

__all__ = ["write_index"]

_KIND_ORDER = (".html", ".png", ".csv", ".parquet", ".json", ".txt", ".tab", ".npz")
_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.5em 0; }
td, th { border: 1px solid #ddd; padding: 3px 8px; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
.figures { display: flex; flex-wrap: wrap; gap: 10px; }
.figures a { display: block; width: 260px; font-size: 0.8em; }
.figures img { width: 260px; border: 1px solid #ddd; }
ul { columns: 2; } .muted { color: #777; }
"""


def _size(path: Path) -> str:
    size = path.stat().st_size
    for unit in ("B", "kB", "MB", "GB"):
        if size < 1024 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return ""  # pragma: no cover


def write_index(
    root: str | os.PathLike,
    *,
    title: str = "workbench report",
    summary: Sequence[str] = (),
    tables: Mapping[str, pd.DataFrame] | None = None,
    max_files_per_folder: int = 40,
) -> Path:
    """Write ``root/index.html`` linking every file below *root*, grouped by folder.

    Parameters
    ----------
    root : path-like
        Report folder.
    title : str
        Page title.
    summary : sequence of str
        Lines shown at the top (what was run, key numbers).
    tables : mapping of str -> DataFrame, optional
        Small tables shown in full (e.g. the evaluation against ground truth).
    max_files_per_folder : int
        Folders with more files (e.g. thousands of acceleration files) are summarised.
    """
    root = Path(root)
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
        f"</title><style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>"
    ]
    if summary:
        parts.append(
            "<ul style='columns:1'>"
            + "".join(f"<li>{html.escape(line)}</li>" for line in summary)
            + "</ul>"
        )
    for name, frame in (tables or {}).items():
        parts.append(f"<h2>{html.escape(name)}</h2>")
        parts.append(
            frame.to_html(index=False, float_format=lambda v: f"{v:.4g}", border=0, na_rep="–")
        )
    folders: dict[Path, list[Path]] = {}
    for path in sorted(root.rglob("*")):
        if path.is_file() and path.name != "index.html" and not path.name.startswith("."):
            folders.setdefault(path.parent, []).append(path)
    for folder, files in sorted(folders.items(), key=lambda kv: (len(kv[0].parts), kv[0])):
        label = folder.relative_to(root).as_posix() if folder != root else "."
        parts.append(f"<h2>{html.escape(label)}/</h2>")
        if len(files) > max_files_per_folder:
            total = sum(f.stat().st_size for f in files) / 1024**2
            parts.append(
                f"<p class='muted'>{len(files)} files ({total:.1f} MB), from "
                f"{html.escape(files[0].name)} to {html.escape(files[-1].name)}</p>"
            )
            continue
        figures = [f for f in files if f.suffix.lower() == ".png"]
        others = sorted(
            (f for f in files if f.suffix.lower() != ".png"),
            key=lambda f: (
                _KIND_ORDER.index(f.suffix.lower()) if f.suffix.lower() in _KIND_ORDER else 99,
                f.name,
            ),
        )
        if others:
            parts.append(
                "<ul>"
                + "".join(
                    f"<li><a href='{html.escape(f.relative_to(root).as_posix())}'>"
                    f"{html.escape(f.name)}</a> <span class='muted'>{_size(f)}</span></li>"
                    for f in others
                )
                + "</ul>"
            )
        if figures:
            parts.append(
                "<div class='figures'>"
                + "".join(
                    f"<a href='{html.escape(f.relative_to(root).as_posix())}'><img loading='lazy' "
                    f"src='{html.escape(f.relative_to(root).as_posix())}' alt=''>"
                    f"{html.escape(f.name)}</a>"
                    for f in figures
                )
                + "</div>"
            )
    parts.append("</body></html>")
    target = root / "index.html"
    with atomic_path(target) as tmp:
        tmp.write_text("\n".join(parts), encoding="utf-8")
    return target
