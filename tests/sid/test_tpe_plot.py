"""Tests for workbench.reporting.tpe_plot: TPE beside the stabilisation diagram."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from workbench.reporting.tpe_plot import (  # noqa: E402
    plot_stabilisation_with_tpe,
    write_stabilisation_tpe_figure,
)
from workbench.sid.ssi import ssi_data  # noqa: E402
from workbench.sid.tpe import total_prediction_error  # noqa: E402


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def identified(chain3):
    data = chain3.acceleration[:20_000]
    kwargs = {"block_rows": 12, "orders": range(2, 17, 2)}
    return data, ssi_data(data, 200.0, **kwargs), total_prediction_error(data, 200.0, **kwargs)


def test_tpe_panel_shares_the_order_axis(identified):
    data, result, errors = identified
    fig = plot_stabilisation_with_tpe(result, errors, data, band_hz=(0, 40))
    diagram, side = fig.axes[0], fig.axes[1]
    assert side.get_shared_y_axes().joined(diagram, side)
    line = side.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), errors.orders)
    np.testing.assert_allclose(line.get_xdata(), 100 * errors.total_prediction_error)
    assert side.get_xlabel() == "TPE [%]"


def test_written_figure_is_a_png(identified, tmp_path):
    data, result, errors = identified
    path = write_stabilisation_tpe_figure(result, errors, tmp_path / "sub" / "tpe.png", data)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(path.parent.glob("*.tmp*"))
