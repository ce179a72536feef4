"""Correlation figures in the manner of MATLAB ``corrplot`` and a self-contained HTML report.

:func:`corrplot` draws a matrix of panels for a handful of variables: histograms on the
diagonal, scatter plots with least-squares lines below it and the correlation coefficients
above it, significant correlations in red. :func:`write_correlation_report` writes the
result of :func:`workbench.stages.correlate` as ``correlation.csv``, the figures and
``correlation.html`` (figures embedded as base64, so the page is one file).
"""

from __future__ import annotations

import base64
import html
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.patches import Rectangle
from matplotlib.ticker import MaxNLocator

from data_contracts import atomic_path
from workbench.stats.correlation import adjust_p_values, pairwise_pearson

from ..results import save_figure

__all__ = [
    "corrplot",
    "corrplot_of",
    "correlation_heatmaps",
    "variable_label",
    "write_correlation_report",
]

_SIGNIFICANT = "#c0392b"
_PLAIN = "0.35"
_MODE_COLUMN = re.compile(r"^mode(\d+)_(frequency_hz|damping_ratio)$")


def variable_label(name: str) -> str:
    """Short axis label: ``mode3_frequency_hz`` → ``f3 [Hz]``, damping ratio → ``ζ3 [%]``."""
    match = _MODE_COLUMN.match(name)
    if match is None:
        return _literal(name)
    mode, quantity = match.groups()
    return f"f{mode} [Hz]" if quantity == "frequency_hz" else f"ζ{mode} [%]"


def _literal(text: str) -> str:
    """*text* shown as is by matplotlib (``$`` would start mathtext)."""
    return str(text).replace("$", r"\$")


def _display_values(frame: pd.DataFrame, columns: Sequence[str]) -> np.ndarray:
    """Values as plotted: damping ratios in percent (reports only), the rest unchanged."""
    values = frame[list(columns)].to_numpy(dtype=float, na_value=np.nan).copy()
    for j, name in enumerate(columns):
        if name.endswith("damping_ratio"):
            values[:, j] *= 100.0
    return values


def _nice_ticks(low: float, high: float) -> np.ndarray:
    ticks = MaxNLocator(nbins=3, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
    return ticks[(ticks >= low) & (ticks <= high)]


def _tick_text(value: float) -> str:
    return f"{value:.4g}"


def corrplot(
    frame: pd.DataFrame,
    *,
    columns: Sequence[str] | None = None,
    alpha: float = 0.05,
    correction: Literal["holm", "fdr_bh"] | None = None,
    title: str | None = None,
    panel_size: float = 1.15,
    max_points: int = 2000,
):
    """Correlation matrix figure like MATLAB ``corrplot``.

    Parameters
    ----------
    frame : DataFrame
        One column per variable (e.g. mode frequencies and predictors per block); NaN is
        missing (pairs use the rows where both are finite).
    columns : sequence of str, optional
        Variables to show, in order; default every numeric column. Readable up to about
        12-14 variables.
    alpha : float
        Significance level for highlighting (two-sided t-test of r, as in
        :func:`workbench.stats.pairwise_pearson`).
    correction : {None, "holm", "fdr_bh"}
        Multiple-comparison correction over the figure's pairs.
    title : str, optional
        Figure title.
    panel_size : float
        Size of one panel. [inch]
    max_points : int
        Largest number of rows drawn in a scatter panel (an even subsample beyond; r is
        always computed on every row).

    Returns
    -------
    matplotlib.figure.Figure
        Diagonal: histograms. Below: scatter with least-squares line, r in the corner.
        Above: r on a colour scale. Significant pairs framed in red, r in bold. Damping
        ratios are shown in percent. The figure is drawn in a single axes (panels placed
        by hand) so that a large matrix renders quickly (``benchmarks/results/docstring_numbers.txt``).
    """
    if columns is None:
        columns = [
            str(c)
            for c in frame.columns
            if pd.api.types.is_numeric_dtype(frame[c]) and not pd.api.types.is_bool_dtype(frame[c])
        ]
    columns = list(columns)
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"corrplot: no column {missing[0]!r}")
    k = len(columns)
    if k < 2:
        raise ValueError(f"corrplot needs at least 2 variables, got {k}")
    values = _display_values(frame, columns)
    r, p, _ = pairwise_pearson(values, values)
    upper_i, upper_j = np.triu_indices(k, 1)
    adjusted = np.full_like(p, np.nan)
    adjusted[upper_i, upper_j] = adjust_p_values(p[upper_i, upper_j], correction)
    adjusted[upper_j, upper_i] = adjusted[upper_i, upper_j]
    significant = np.nan_to_num(adjusted, nan=1.0) < alpha
    rows = np.arange(values.shape[0])
    if rows.size > max_points:
        rows = np.linspace(0, rows.size - 1, max_points).astype(int)
    labels = [variable_label(c) for c in columns]

    # panel (i, j) occupies [j, j+1] x [i, i+1] with rows growing downwards; a value v of
    # variable c maps to c's range inside the panel with a margin
    margin = 0.07
    low = np.full(k, np.nan)
    high = np.full(k, np.nan)
    for c in range(k):
        finite = values[np.isfinite(values[:, c]), c]
        if finite.size:
            low[c], high[c] = finite.min(), finite.max()
            if high[c] <= low[c]:
                low[c], high[c] = low[c] - 0.5, high[c] + 0.5

    def across(v, c):  # x position inside column c
        return c + margin + (1 - 2 * margin) * (v - low[c]) / (high[c] - low[c])

    def down(v, c, row):  # y position inside row *row* for variable c (larger values up)
        return row + 1 - margin - (1 - 2 * margin) * (v - low[c]) / (high[c] - low[c])

    size = max(4.0, panel_size * k + 1.0)
    fig = plt.figure(figsize=(size, size))
    left = 0.8 / size + 0.01  # room for the value ticks and the rotated labels
    bottom = 0.75 / size + 0.02
    ax = fig.add_axes((left, bottom, 0.985 - left, (0.95 if title else 0.98) - bottom))
    ax.set_xlim(0, k)
    ax.set_ylim(k, 0)
    ax.set_axis_off()
    font = max(5.5, min(9.0, 95.0 / k))
    colour_map = plt.get_cmap("RdBu_r")
    for i in range(k):
        for j in range(k):
            edge = _SIGNIFICANT if significant[i, j] and i != j else "0.6"
            width = 1.4 if significant[i, j] and i != j else 0.6
            face = "white"
            if i < j and np.isfinite(r[i, j]):
                face = colour_map(0.5 + 0.35 * r[i, j])
            ax.add_patch(
                Rectangle(
                    (j + 0.02, i + 0.02), 0.96, 0.96, facecolor=face, edgecolor=edge, lw=width
                )
            )
            if not (np.isfinite(low[i]) and np.isfinite(low[j])):
                continue
            if i == j:  # histogram
                finite = values[np.isfinite(values[:, j]), j]
                counts, edges = np.histogram(
                    finite, bins=min(20, max(5, finite.size // 5)), range=(low[j], high[j])
                )
                height = (1 - 2 * margin) * counts / max(counts.max(), 1)
                x = across(edges, j)
                ax.fill_between(
                    x,
                    i + 1 - margin,
                    i + 1 - margin - np.append(height, height[-1]),
                    step="post",
                    color="0.6",
                    lw=0,
                )
            elif i > j:  # scatter with least-squares line
                both = np.isfinite(values[:, j]) & np.isfinite(values[:, i])
                shown = rows[both[rows]]
                ax.plot(
                    across(values[shown, j], j),
                    down(values[shown, i], i, i),
                    ".",
                    ms=1.6,
                    color="0.4",
                    rasterized=True,
                )
                x, y = values[both, j], values[both, i]
                if x.size >= 2 and np.ptp(x) > 0:
                    slope, intercept = np.polyfit(x, y, 1)
                    ends = np.array([x.min(), x.max()])
                    fitted = np.clip(intercept + slope * ends, low[i], high[i])
                    ax.plot(
                        across(ends, j),
                        down(fitted, i, i),
                        "-",
                        lw=1.0,
                        color=_SIGNIFICANT if significant[i, j] else "0.2",
                    )
                if np.isfinite(r[i, j]):
                    ax.text(
                        j + 0.06,
                        i + 0.06,
                        f"{r[i, j]:.2f}",
                        ha="left",
                        va="top",
                        fontsize=font,
                        color=_SIGNIFICANT if significant[i, j] else "0.25",
                        fontweight="bold" if significant[i, j] else "normal",
                        bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 0.5},
                    )
            else:  # r on a colour scale
                ax.text(
                    j + 0.5,
                    i + 0.5,
                    "—" if not np.isfinite(r[i, j]) else f"{r[i, j]:.2f}",
                    ha="center",
                    va="center",
                    fontsize=font + 1.5,
                    color="black" if significant[i, j] else "0.4",
                    fontweight="bold" if significant[i, j] else "normal",
                )
    # labels and value ticks along the left and bottom edges
    for c in range(k):
        ax.text(c + 0.5, k + 0.25, labels[c], ha="center", va="top", fontsize=font + 0.5)
        ax.text(
            -0.42, c + 0.5, labels[c], ha="center", va="center", fontsize=font + 0.5, rotation=90
        )
        if not np.isfinite(low[c]):
            continue
        for tick in _nice_ticks(low[c], high[c]):
            x = across(tick, c)
            ax.plot([x, x], [k, k + 0.05], "-", color="0.3", lw=0.6, clip_on=False)
            ax.text(x, k + 0.07, _tick_text(tick), ha="center", va="top", fontsize=font - 1.5)
            if c > 0:  # the first row holds a histogram, no value axis
                y = down(tick, c, c)
                ax.plot([-0.05, 0], [y, y], "-", color="0.3", lw=0.6, clip_on=False)
                ax.text(-0.07, y, _tick_text(tick), ha="right", va="center", fontsize=font - 1.5)
    if title:
        fig.suptitle(title, fontsize=font + 3)
    note = f"significant (p < {alpha:g}{', ' + correction if correction else ''}) framed in red"
    fig.text(0.99, 0.005, note, ha="right", va="bottom", fontsize=font, color=_SIGNIFICANT)
    return fig


def correlation_heatmaps(table: pd.DataFrame, *, cases: Sequence[str] | None = None):
    """One panel per case: r of every mode quantity (rows) with every predictor (columns).

    Significant cells are marked with their r in bold; others show r in grey.

    Parameters
    ----------
    table : DataFrame
        Output of :func:`workbench.stats.correlation_table`.
    cases : sequence of str, optional
        Cases to draw, in order; default every case of *table*.
    """
    cases = list(pd.unique(table["case"])) if cases is None else list(cases)
    modes = table[table["y"].str.match(_MODE_COLUMN.pattern)]
    if modes.empty:
        raise ValueError("the correlation table has no mode-quantity rows")
    rows = list(pd.unique(modes["y"]))
    columns = list(pd.unique(modes["x"]))
    width = max(3.5, 0.62 * len(columns) + 1.3)
    height = max(2.8, 0.3 * len(rows) + 1.3)
    n_columns = min(3, len(cases))
    n_rows = -(-len(cases) // n_columns)
    fig, axes = plt.subplots(
        n_rows,
        n_columns,
        figsize=(width * n_columns + 1.0, height * n_rows),
        squeeze=False,
        layout="constrained",
    )
    for ax in axes.ravel()[len(cases) :]:
        ax.set_visible(False)
    image = None
    for ax, case in zip(axes.ravel(), cases, strict=False):
        part = modes[modes["case"] == case].set_index(["y", "x"])
        r = np.full((len(rows), len(columns)), np.nan)
        significant = np.zeros_like(r, dtype=bool)
        for a, y in enumerate(rows):
            for b, x in enumerate(columns):
                if (y, x) in part.index:
                    r[a, b] = part.loc[(y, x), "r"]
                    significant[a, b] = bool(part.loc[(y, x), "significant"])
        image = ax.imshow(r, cmap="RdBu_r", vmin=-1, vmax=1, aspect="auto")
        for a in range(len(rows)):
            for b in range(len(columns)):
                if np.isfinite(r[a, b]):
                    ax.text(
                        b,
                        a,
                        f"{r[a, b]:.2f}",
                        ha="center",
                        va="center",
                        fontsize=7,
                        color="black" if significant[a, b] else "0.45",
                        fontweight="bold" if significant[a, b] else "normal",
                    )
        ax.set_xticks(
            range(len(columns)), [_literal(c) for c in columns], rotation=40, ha="right", fontsize=7
        )
        ax.set_yticks(range(len(rows)), [variable_label(y) for y in rows], fontsize=7)
        n = int(part["n"].max()) if len(part) else 0
        ax.set_title(f"{_literal(case)} (n ≤ {n})", fontsize=9)
    if image is not None:
        fig.colorbar(image, ax=axes.ravel().tolist(), shrink=0.6, label="Pearson r")
    return fig


# --------------------------------------------------------------------------- report
def _slug(text: str) -> str:
    slug = re.sub(r"[^0-9A-Za-z]+", "_", text).strip("_").lower()
    return slug or "case"


def _embedded(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (
        f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{html.escape(alt)}</figcaption></figure>"
    )


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.5em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0; }
td, th { border: 1px solid #ddd; padding: 2px 7px; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
td.text { text-align: left; }
figure { margin: 1em 0; } img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; } .muted { color: #777; }
"""


def _html_table(frame: pd.DataFrame) -> str:
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in frame.columns)
    body = []
    for row in frame.itertuples(index=False):
        cells = []
        for value in row:
            if isinstance(value, (bool, np.bool_)):
                cells.append(f"<td>{'yes' if value else ''}</td>")
            elif isinstance(value, (float, np.floating)):
                text = "" if not np.isfinite(value) else f"{value:.3g}"
                cells.append(f"<td>{text}</td>")
            elif isinstance(value, (int, np.integer)):
                cells.append(f"<td>{int(value)}</td>")
            else:
                cells.append(f'<td class="text">{html.escape(str(value))}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def corrplot_of(result, quantity: str = "frequency_hz"):
    """:func:`corrplot` of *quantity* of every mode and the predictors of a correlation
    result (:class:`workbench.stages.CorrelateResult`), all cases stitched."""
    options = result.options
    stitched = result.joined[result.case_blocks["all"]]
    if quantity not in result.quantities:
        raise ValueError(
            f"quantity={quantity!r} was not correlated; give one of {result.quantities}"
        )
    columns = [c for c in result.mode_columns if c.endswith("_" + quantity)]
    return corrplot(
        stitched,
        columns=columns + result.predictor_names,
        alpha=options.alpha,
        correction=options.correction,
        title=f"{quantity} and predictors, all cases ({len(stitched)} blocks)",
    )


def write_correlation_report(
    result,
    out_dir: str | os.PathLike,
    *,
    title: str = "Correlation of modal parameters with operating conditions",
    dpi: int = 110,
) -> dict[str, Path]:
    """Correlation table, corrplot figures and a self-contained HTML report.

    Parameters
    ----------
    result : CorrelateResult
        Output of :func:`workbench.stages.correlate`.
    out_dir : path-like
        Folder written into (created).
    title : str
        Title of the HTML page.
    dpi : int
        Resolution of the PNG figures.

    Returns
    -------
    dict of str -> Path
        ``"csv"`` (correlation.csv, the tidy table), ``"html"`` (correlation.html), and one
        entry per figure: ``"corrplot_<quantity>"`` (mode quantity and predictors, all
        cases stitched) and ``"heatmap"`` (r per case).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    table = result.table
    options = result.options
    alpha, correction, useful_r = options.alpha, options.correction, options.useful_r
    paths: dict[str, Path] = {}
    csv_path = out / "correlation.csv"
    with atomic_path(csv_path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.10g")
    paths["csv"] = csv_path

    joined, mode_columns, names = result.joined, result.mode_columns, result.predictor_names
    masks = result.case_blocks
    figures: list[tuple[str, Path, str]] = []
    for quantity in result.quantities:
        name = f"corrplot_{_slug(quantity)}"
        fig = corrplot_of(result, quantity)
        paths[name] = save_figure(fig, out / f"{name}.png", dpi=dpi)
        figures.append((name, paths[name], f"{quantity}: modes and predictors, all cases"))
    fig = correlation_heatmaps(table)
    paths["heatmap"] = save_figure(fig, out / "correlation_heatmap.png", dpi=dpi)
    figures.append(("heatmap", paths["heatmap"], "Pearson r of mode quantities per case"))

    useful = table[table["useful"]].sort_values(["case", "p_value"], kind="stable")
    case_names = list(pd.unique(table["case"]))
    blocks = {case: int(mask.sum()) for case, mask in masks.items()}
    summary = [
        f"{len(joined)} blocks, {len(mode_columns)} mode quantities, {len(names)} predictors "
        f"({', '.join(names)}).",
        "Cases: " + ", ".join(f"{c} ({blocks.get(c, 0)} blocks)" for c in case_names) + ".",
        f"Pearson r with two-sided t-test; significant: p{'_adjusted' if correction else ''}"
        f" < {alpha:g}{' (' + correction + ' within each case)' if correction else ''}; "
        f"useful: significant and |r| ≥ {useful_r:g}. Missing values pairwise.",
    ]
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        "".join(f"<p>{html.escape(line)}</p>" for line in summary),
        "<h2>Figures</h2>",
        *(_embedded(path, caption) for _, path, caption in figures),
        f"<h2>Useful correlations ({len(useful)})</h2>",
        _html_table(useful) if len(useful) else "<p class='muted'>none</p>",
        "<p class='muted'>p-values here take overlapping blocks as independent; the run "
        "report (<code>workbench report</code>) gives them beside p-values from the "
        "effective number of blocks.</p>",
        "<h2>All pairs</h2><details><summary>show the full table "
        f"({len(table)} rows; also in correlation.csv)</summary>",
        _html_table(table),
        "</details></body></html>",
    ]
    html_path = out / "correlation.html"
    with atomic_path(html_path) as tmp:
        tmp.write_text("".join(parts), encoding="utf-8")
    paths["html"] = html_path
    return paths
