"""Report building blocks: spectra, moments, mode shapes on the layout, run discovery, CLI."""

from __future__ import annotations

import re
import shutil

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from data_contracts import shapes_to_frame
from workbench.cli import main
from workbench.reporting import views
from workbench.reporting.mode_views import _real_shape
from workbench.reporting.report import build_report, find_run
from workbench.reporting.report.signals import _chunk_moments, _csd


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def test_csd_of_white_noise_has_the_one_sided_level():
    # white noise of variance s² sampled at fs has the one-sided PSD 2 s² / fs
    rng = np.random.default_rng(0)
    rate, sigma = 64.0, 0.3
    frequency, csd = _csd(sigma * rng.standard_normal((64 * 600, 2)), rate)
    inside = (frequency > 1) & (frequency < 30)
    level = np.real(csd[inside, 0, 0]).mean()
    assert level == pytest.approx(2 * sigma**2 / rate, rel=0.03)
    assert np.abs(csd[inside, 0, 1]).mean() < 0.1 * level  # independent channels


def test_chunk_moments_of_known_signals():
    rng = np.random.default_rng(1)
    t = np.arange(200_000) / 100.0
    chunk = np.column_stack([2.0 * np.sin(2 * np.pi * 3.1 * t), rng.standard_normal(len(t))])
    chunk[:10, 1] = np.nan  # a dropout does not spoil the others
    (rms, skewness, kurtosis) = _chunk_moments(chunk)
    assert rms[0] == pytest.approx(2 / np.sqrt(2), rel=1e-3)
    assert kurtosis[0] == pytest.approx(1.5, rel=1e-2)  # sine: 3/2
    assert kurtosis[1] == pytest.approx(3.0, abs=0.05) and abs(skewness[1]) < 0.02


def _modal_with_shapes(shape, n_blocks=6, seed=0):
    rng = np.random.default_rng(seed)
    phases = np.exp(1j * rng.uniform(0, 2 * np.pi, n_blocks))  # arbitrary phase per block
    shapes = phases[:, None] * shape[None, :]
    frame = pd.DataFrame({"block": np.arange(n_blocks), "mode": 1, "frequency_hz": 2.0})
    channels = [f"c{j}" for j in range(len(shape))]
    return pd.concat([frame, shapes_to_frame(channels, shapes)], axis=1), channels


def test_mean_shape_undoes_block_phases():
    shape = np.array([0.2, 0.5, -1.0, 0.1])
    modal, _ = _modal_with_shapes(shape)
    modes, _, mean = views.mean_mode_shapes(modal)
    assert modes == [1]
    real = _real_shape(mean[:, 0])
    np.testing.assert_allclose(real, -shape / np.linalg.norm(shape), atol=1e-12)


def test_mode_shape_arrows_follow_the_sensor_directions():
    shape = np.array([0.25, 0.5, 1.0])
    modal, channels = _modal_with_shapes(shape)
    geometry = pd.DataFrame(
        {
            "channel": channels,
            "node": ["a", "b", "c"],
            "x_m": [0.0, 5.0, 10.0],
            "y_m": 0.0,
            "z_m": 0.0,
            "direction_x": 0.0,
            "direction_y": [0.0, 1.0, 0.0],
            "direction_z": [1.0, 0.0, 1.0],
        }
    )
    fig = views.plot_mode_shapes(modal, geometry)
    side, plan = (ax.collections[-1] for ax in fig.axes[:2])
    unit = shape / np.linalg.norm(shape)
    scale = 0.12 * 10.0 / unit.max()  # largest arrow 12 % of the 10 m layout
    np.testing.assert_allclose(side.V, [unit[0] * scale, 0.0, unit[2] * scale])  # z only
    np.testing.assert_allclose(plan.V, [0.0, unit[1] * scale, 0.0])  # y only
    np.testing.assert_allclose(side.U, 0.0)


def test_report_of_a_short_run(short_run):
    run = find_run(short_run)
    assert run.identify == short_run / "identify" and run.tracked.name == "tracked_modal.csv"
    assert run.geometry.name == "sensor_geometry.csv" and len(run.accelerations) > 0
    page = build_report(short_run, out=short_run / "other" / "page.html", dpi=50)
    text = page.read_text(encoding="utf-8")
    assert (short_run / "other" / "report_files" / "mode_shapes.png").exists()
    # the Campbell view: orders drawn against the logged shaft speed
    assert (short_run / "other" / "report_files" / "campbell.png").exists()
    assert 'id="harmonics"' in text and "of the logged shaft speed" in text
    # evaluation under the tracked labels, the truth's numbers beside
    assert "true mode" in text and "Kalman vs SSI [%]" in text
    assert "store" not in text.replace("stored", "")


def test_campbell_view_draws_orders_and_keeps_modes_and_harmonics_apart():
    import matplotlib.pyplot as plt

    from workbench.reporting.views import plot_campbell

    shaft = pd.DataFrame({"block": [0, 1], "shaft_rpm": [120.0, 180.0], "speed_kn": [6.7, 10.0]})
    shape = {"shape_re_c0": 1.0, "shape_im_c0": 0.0}
    selected = pd.DataFrame(
        [
            {"block": 0, "frequency_hz": 2.0, "harmonic": 1.0, **shape},  # 120 rpm / 60
            {"block": 1, "frequency_hz": 3.0, "harmonic": 1.0, **shape},
            {"block": 0, "frequency_hz": 2.9, "harmonic": np.nan, **shape},
            {"block": 1, "frequency_hz": 2.88, "harmonic": 1.0, **shape},  # crossed mode
        ]
    )
    modal = selected.iloc[2:].assign(mode=1)
    fig = plot_campbell(selected, shaft, modal=modal, orders=(1.0, 2.0))
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    crosses = lines["harmonic (kept out of the modes)"]
    np.testing.assert_array_equal(crosses.get_xdata(), [120.0, 180.0])
    np.testing.assert_array_equal(lines["mode 1"].get_ydata(), [2.9, 2.88])
    order_lines = [ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == "--"]
    assert len(order_lines) == 2
    rpm, frequency = order_lines[1].get_xdata(), order_lines[1].get_ydata()
    np.testing.assert_allclose(frequency, 2.0 * rpm / 60.0)
    plt.close(fig)


def test_campbell_view_draws_orders_at_the_rate_per_knot_without_a_shaft_speed():
    """A log with the speed only (identify's shaft.csv without shaft_rpm, harmonics.json's
    shaft_hz_per_kn): the abscissa is the speed the speed-following test used and each
    order is drawn as f = k x 0.3 Hz/kn x speed (main drew none)."""
    import matplotlib.pyplot as plt

    from workbench.reporting.views import plot_campbell

    shaft = pd.DataFrame(
        {
            "block": [0, 1],
            "shaft_rpm": [np.nan, np.nan],
            "speed_kn": [6.5, 10.1],
            "speed_energy_kn": [6.6, 10.0],
        }
    )
    shape = {"shape_re_c0": 1.0, "shape_im_c0": 0.0}
    selected = pd.DataFrame(
        [
            {"block": 0, "frequency_hz": 1.98, "harmonic": 0.0, **shape},  # 0.3 x 6.6
            {"block": 1, "frequency_hz": 3.0, "harmonic": 0.0, **shape},
        ]
    )
    fig = plot_campbell(selected, shaft, orders=(1.0, 2.0), shaft_hz_per_kn=0.3)
    ax = fig.axes[0]
    crosses = {line.get_label(): line for line in ax.get_lines()}[
        "harmonic (kept out of the modes)"
    ]
    np.testing.assert_array_equal(crosses.get_xdata(), [6.6, 10.0])
    order_lines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(order_lines) == 2
    speed, frequency = order_lines[1].get_xdata(), order_lines[1].get_ydata()
    np.testing.assert_allclose(frequency, 2.0 * 0.3 * speed)
    assert ax.get_xlabel() == "speed [kn] (no shaft speed logged; shaft rate 0.3000 Hz/kn)"
    # without the rate: no order drawn
    fig2 = plot_campbell(selected, shaft, orders=(1.0, 2.0))
    assert not [ln for ln in fig2.axes[0].get_lines() if ln.get_linestyle() == "--"]
    plt.close(fig)
    plt.close(fig2)


def test_cli_report_errors_are_one_line(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["report", str(tmp_path / "empty")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no run found" in err[1]
    assert main(["report", str(tmp_path / "empty"), "--blocks", "x"]) == 2


def test_registered_sections_come_after_the_built_in_ones(short_run, monkeypatch):
    from workbench.reporting import report

    monkeypatch.setattr(report, "_SECTION_BUILDERS", [])

    @report.register_section
    def agreement(run, save_figure):
        table = pd.DataFrame({"mode": [1, 2], "SSI [Hz]": [2.9, 4.7], "other [Hz]": [2.91, 4.69]})
        return report.ReportSection("agreement", "Method agreement", tables=[("by mode", table)])

    tracked_only = report.RunFiles(short_run, tracked=short_run / "tracked_modal.csv")
    page = build_report(short_run, out=short_run / "extra" / "page.html", run=tracked_only, dpi=40)
    text = page.read_text(encoding="utf-8")
    assert text.index('id="modes"') < text.index('id="agreement"')
    assert "Method agreement" in text and "4.69" in text


def test_crosscheck_section_shows_the_ssi_lscf_agreement_per_block(short_run, tmp_path):
    # two blocks: block 0 with three SSI modes, two of which LSCF finds (0.05 % and 0.2 %
    # apart), block 1 with one mode both find 0.02 % apart; identical shapes (MAC 1)
    from workbench.reporting import report
    from workbench.sid.crosscheck import cross_check

    shapes = np.eye(3, dtype=complex)
    table = pd.concat(
        [
            cross_check(
                [2.0, 3.0, 5.0],
                [0.01, 0.01, 0.02],
                shapes,
                [2.001, 3.006],
                [0.011, 0.012],
                shapes[:, :2],
                block=0,
            ),
            cross_check([4.0], [0.01], shapes[:, :1], [4.0008], [0.01], shapes[:, :1], block=1),
        ]
    )
    identify = tmp_path / "identify"
    shutil.copytree(find_run(short_run).identify, identify)
    table.to_csv(identify / "crosscheck.csv", index=False)
    run = report.RunFiles(tmp_path, identify=identify, tracked=short_run / "tracked_modal.csv")
    section = report.sections.crosscheck_section(run)
    shown = section.tables[0][1].set_index("block")
    assert shown.loc[0, "pairs"] == 2 and shown.loc[0, "SSI modes"] == 3
    assert shown.loc[0, "within 0.1 %"] == 1  # 0.05 % agrees, 0.2 % does not
    assert shown.loc[0, "max |Δf|/f [%]"] == pytest.approx(0.2)
    assert shown.loc[1, "max |Δf|/f [%]"] == pytest.approx(0.02)
    assert shown.loc[1, "lowest MAC"] == pytest.approx(1.0)
    page = build_report(tmp_path, out=tmp_path / "page.html", run=run, dpi=40)
    assert "SSI / LSCF cross-check" in page.read_text(encoding="utf-8")


def test_the_report_shows_the_correlate_stage_result(short_run, tmp_path):
    # the report draws the correlations from the correlate stage: the result it is given
    # (here with every mode, however rare) and the stage it runs itself agree on the modes
    # the report keeps (present in at least half the blocks), digit for digit
    from data_contracts import MODAL, PREDICTORS, read_table, write_table
    from workbench.predictors import canonical_predictors
    from workbench.reporting import report
    from workbench.stages import CorrelateOptions, correlate

    found = find_run(short_run)
    modal = read_table(found.tracked, MODAL)
    # a rare mode (3 blocks; the run's shaft harmonics, once such, are left out by tracking)
    rare = modal[modal["mode"] == modal["mode"].min()].head(3)
    rare = rare.assign(mode=int(modal["mode"].max()) + 1, frequency_hz=rare["frequency_hz"] * 1.3)
    modal = pd.concat([modal, rare], ignore_index=True).sort_values(["block", "mode"])
    tracked = write_table(modal.reset_index(drop=True), tmp_path / "tracked_modal.csv", MODAL)
    run = report.RunFiles(short_run, tracked=tracked, predictors=found.predictors)
    modal = read_table(tracked, MODAL)
    predictors = canonical_predictors(read_table(found.predictors, PREDICTORS))
    every_mode = correlate(modal, predictors, options=CorrelateOptions(min_presence=0.0))
    tables = {}
    for name, given in (("own", None), ("given", every_mode)):
        page = build_report(short_run, out=tmp_path / name / "page.html", run=run,
                            correlation=given, dpi=30)  # fmt: skip
        tables[name] = pd.read_csv(page.parent / "report_files" / "correlation_effective.csv")
    pd.testing.assert_frame_equal(tables["own"], tables["given"])
    presence = modal.groupby("mode")["block"].nunique() / modal["block"].nunique()
    shown = {int(y[4:].split("_")[0]) for y in tables["own"]["y"] if y.startswith("mode")}
    assert shown == {int(m) for m in presence.index[presence >= 0.5]}
    assert shown < {int(m) for m in modal["mode"]}  # the given result's rare modes left out
    assert {"n_effective", "p_effective", "significant_effective"} <= set(tables["own"])


def test_the_correlation_text_states_the_overlap_of_the_block_grid():
    from data_contracts import set_grid
    from workbench.reporting.report.sections import block_dependence

    start = pd.Timestamp("2024-01-01", tz="UTC") + pd.to_timedelta(10 * np.arange(6), unit="min")
    blocks = pd.DataFrame({"block": np.arange(6), "block_start": start})
    half = blocks.assign(block_end=start + pd.Timedelta(minutes=20))  # inferred: 10 of 20 min
    assert block_dependence(half).startswith("Blocks overlap (50 %), so")
    recorded = set_grid(half.copy(), {"t0": start[0], "length_s": 1200.0, "step_s": 600.0})
    assert block_dependence(recorded).startswith("Blocks overlap (50 %), so")
    adjacent = blocks.assign(block_end=start + pd.Timedelta(minutes=10))
    assert "overlap" not in block_dependence(adjacent)
    off_grid = set_grid(half.copy(), {"t0": start[0], "length_s": 1200.0, "step_s": 300.0})
    assert block_dependence(off_grid) == "Neighbouring blocks are not independent"


def test_a_figure_write_cut_short_leaves_the_earlier_figure_whole(short_run, monkeypatch):
    """A crash while a report writes a figure (here: half the PNG written, then an error)
    leaves the figure of the earlier report as it was and no partial file: every figure
    goes through results.save_figure (temporary file, then rename)."""
    import matplotlib.figure

    from workbench.reporting import report

    run = report.RunFiles(short_run, tracked=short_run / "tracked_modal.csv")
    out = short_run / "cut" / "page.html"
    build_report(short_run, out=out, run=run, dpi=40)
    figures = sorted(p for p in out.parent.rglob("*.png"))
    assert figures
    before = {p: p.read_bytes() for p in figures}
    page = out.read_bytes()
    real = matplotlib.figure.Figure.savefig

    def cut_short(fig, target, **kwargs):
        real(fig, target, **kwargs)
        data = open(target, "rb").read()
        with open(target, "wb") as handle:
            handle.write(data[: len(data) // 2])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", cut_short)
    with pytest.raises(OSError, match="No space left"):
        build_report(short_run, out=out, run=run, dpi=40)
    assert {p: p.read_bytes() for p in sorted(out.parent.rglob("*.png"))} == before
    assert out.read_bytes() == page
    assert not [p for p in out.parent.rglob("*") if p.is_file() and p.name.startswith(".")]


def test_a_tracked_table_of_another_run_is_named_in_the_overview(short_run, tmp_path):
    """The tracked modes and the identification shown beside them must be of one run: a
    tracked table left in the folder from an earlier identification (its poles 1 % off
    those of the identification now there) is named in the overview's warnings, as
    ``forecast --poles`` refuses it (main: the report showed both without a word)."""
    from workbench.reporting import report

    tracked = pd.read_csv(short_run / "tracked_modal.csv")
    run = report.RunFiles(
        short_run, identify=short_run / "identify", tracked=short_run / "tracked_modal.csv"
    )
    page = build_report(short_run, out=tmp_path / "same" / "page.html", run=run, dpi=40)
    assert "not of one run" not in page.read_text(encoding="utf-8")

    earlier = tracked.assign(frequency_hz=tracked["frequency_hz"] * 1.01)
    earlier.to_csv(tmp_path / "tracked_modal.csv", index=False)
    run = report.RunFiles(
        short_run, identify=short_run / "identify", tracked=tmp_path / "tracked_modal.csv"
    )
    page = build_report(short_run, out=tmp_path / "other" / "page.html", run=run, dpi=40)
    text = page.read_text(encoding="utf-8")
    n_rows = int(tracked["model_order"].notna().sum())
    assert "not of one run" in text
    assert re.search(r"only 0 of (\d+) tracked poles of tracked_modal\.csv", text)
    assert int(re.search(r"only 0 of (\d+) tracked poles", text)[1]) <= n_rows
