"""Tests for workbench.reporting.correlation: corrplot figure data and the report files."""

from __future__ import annotations

import re

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from workbench.reporting.correlation import (
    correlation_heatmaps,
    corrplot,
    variable_label,
)
from workbench.stages import CorrelateOptions, correlate
from workbench.stats import correlation_table


def test_variable_labels():
    assert variable_label("mode3_frequency_hz") == "f3 [Hz]"
    assert variable_label("mode12_damping_ratio") == "ζ12 [%]"
    assert variable_label("speed_kn") == "speed_kn"


def test_corrplot_panels_text_and_highlighting(block_tables, close_figures):
    modal, predictors = block_tables
    frame = predictors[["speed_kn", "water_temp_c", "wind_speed_ms"]].copy()
    frame["mode1_damping_ratio"] = (
        modal[modal["mode"] == 1].set_index("block")["damping_ratio"].to_numpy()
    )
    frame.loc[3, "speed_kn"] = np.nan
    fig = corrplot(frame, alpha=0.05)
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    valid = frame["speed_kn"].notna()
    r = np.corrcoef(frame.loc[valid, "speed_kn"], frame.loc[valid, "mode1_damping_ratio"])[0, 1]
    # r printed twice per pair: in the scatter panel and in the upper panel
    assert texts.count(f"{r:.2f}") >= 2
    red = [t for t in ax.texts if t.get_text() == f"{r:.2f}" and t.get_fontweight() == "bold"]
    assert red  # speed drives damping: significant, bold
    labels = set(texts)
    assert {"speed_kn", "ζ1 [%]"} <= labels
    # 4 histograms on the diagonal, 6 scatter panels with a least-squares line each
    assert len(ax.collections) == 4
    scatter = [line for line in ax.lines if line.get_marker() == "."]
    assert len(scatter) == 6
    # damping shown in percent: the scatter's y data span the damping range x 100
    plt.close(fig)
    with pytest.raises(ValueError, match="at least 2 variables"):
        corrplot(frame[["speed_kn"]])
    with pytest.raises(ValueError, match="no column 'heading'"):
        corrplot(frame, columns=["speed_kn", "heading"])


def test_heatmaps_one_panel_per_case(block_tables, close_figures):
    modal, predictors = block_tables
    predictors["case"] = np.where(predictors["block"] < 40, "a", "b")
    table = correlation_table(modal, predictors, cases="case")
    fig = correlation_heatmaps(table)
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert [t.split(" ")[0] for t in titles] == ["all", "a", "b"]
    plt.close(fig)


def test_write_correlation_report(block_tables, tmp_path, close_figures):
    modal, predictors = block_tables
    cases = tmp_path / "cases.csv"
    cases.write_text(
        "case,start,end\n"
        "first,2024-03-01T00:00:00Z,2024-03-01T03:00:00Z\n"
        "second,2024-03-01T03:00:00Z,2024-03-01T07:00:00Z\n"
    )
    out = tmp_path / "report"
    result = correlate(
        modal,
        predictors,
        cases=cases,
        options=CorrelateOptions(correction="fdr_bh", min_presence=0.0),
    )
    paths = result.save(out)
    assert set(paths) == {
        "csv",
        "html",
        "corrplot_frequency_hz",
        "corrplot_damping_ratio",
        "heatmap",
        "blocks",  # correlation_blocks.parquet and correlation.json: read_correlation
        "state",
    }
    for path in paths.values():
        assert path.is_file() and path.stat().st_size > 0
        assert path.parent == out
    assert not list(out.glob(".*"))  # no temporary files left behind
    written = pd.read_csv(paths["csv"])
    expected = correlation_table(modal, predictors, cases=cases, correction="fdr_bh")
    assert (
        written[["x", "y", "case"]].values.tolist() == expected[["x", "y", "case"]].values.tolist()
    )
    np.testing.assert_allclose(written["r"], expected["r"], rtol=1e-9)
    assert written["significant"].tolist() == expected["significant"].tolist()
    page = paths["html"].read_text(encoding="utf-8")
    images = re.findall(r'<img [^>]*src="([^"]+)"', page)
    assert len(images) == 3 and all(src.startswith("data:image/png;base64,") for src in images)
    assert "Useful correlations" in page and "fdr_bh" in page
    assert plt.get_fignums() == sorted(close_figures)  # the report closed its figures
