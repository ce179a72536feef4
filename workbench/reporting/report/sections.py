"""The report's sections after the overview, one function per stage that ran: each takes
the run's tables (:class:`~.overview.RunData`) and returns a :class:`~.run.ReportSection`,
or None when its stage did not run."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pandas as pd

from data_contracts import FORECAST, MODAL, atomic_path, read_table

from .. import views
from ..model_views import _short
from .overview import RunData
from .render import read_csv_times, warning_counts
from .run import ReportSection, RunFiles
from .signals import block_singular_values, segment_length


def signals_section(data: RunData) -> ReportSection | None:
    """Spectra, spectrograms and channel moments (from the acceleration files, else from
    identify's channel statistics)."""
    run, figures, band, cases, signal, faults, mode_frequencies = (
        data.run,
        data.figures,
        data.band,
        data.cases,
        data.signal,
        data.faults,
        data.mode_frequencies,
    )
    if signal is not None:
        section = ReportSection("signals", "Signals")
        section.paragraphs.append(
            "Singular values of the cross-spectral matrix (Welch, Hann windows of "
            f"{segment_length(signal.sampling_rate_hz) / signal.sampling_rate_hz:g} s) per operating case; "
            "beside each, the first singular value over time. Dotted lines: the tracked modes' mean frequencies."
        )
        ranges = {"all": (signal.start, signal.end)}
        if cases is not None:
            for case, part in cases.groupby("case", sort=False):
                ranges[case] = (part["start"].min(), part["end"].max())
        fig = views.plot_spectra_by_case(
            signal.spectra,
            signal.spectrogram,
            ranges,
            band_hz=band,
            mode_frequencies=mode_frequencies,
        )
        section.figures.append(
            ("Spectra and spectrograms per operating case", figures.save(fig, "spectra"))
        )
        dropped_cells = None
        if faults is not None and len(faults):
            dropped_cells = faults.rename(columns={"block_start": "time"})[["time", "channel"]]
        fig = views.plot_channel_moments(signal.moments, dropped=dropped_cells)
        section.figures.append(
            (
                "RMS, skewness and kurtosis of every channel over time (red x: channel dropped in the block starting then)",
                figures.save(fig, "moments"),
            )
        )
        return section
    elif run.identify is not None and (run.identify / "channels.csv").exists():
        section = ReportSection("signals", "Signals")
        section.paragraphs.append(
            "Acceleration files not found: channel statistics per block from the identification."
        )
        stats_table = read_csv_times(run.identify / "channels.csv", ["block_start"]).rename(
            columns={"block_start": "time"}
        )
        dropped_cells = (
            faults.rename(columns={"block_start": "time"})[["time", "channel"]]
            if faults is not None and len(faults)
            else None
        )
        fig = views.plot_channel_moments(stats_table, dropped=dropped_cells)
        section.figures.append(
            (
                "RMS and kurtosis of every channel per block (red x: dropped)",
                figures.save(fig, "moments"),
            )
        )
        return section

    return None


def identification_section(
    data: RunData, *, stabilisation_blocks=None, n_stabilisation: int = 2
) -> ReportSection | None:
    """Stabilisation diagrams of *stabilisation_blocks* (default *n_stabilisation* blocks
    spread over the run) with the block's tracked modes."""
    run, figures, parameters, band, modal, signal, blocks = (
        data.run,
        data.figures,
        data.parameters,
        data.band,
        data.modal,
        data.signal,
        data.blocks,
    )
    poles_path = run.identify / "poles.parquet" if run.identify is not None else None
    if poles_path is not None and poles_path.exists() and blocks is not None:
        section = ReportSection("identification", "Identification")
        ok = blocks[blocks["status"] == "ok"]
        if stabilisation_blocks is None:
            picks = (
                np.unique(np.linspace(0, len(ok) - 1, max(n_stabilisation, 1)).round().astype(int))
                if len(ok)
                else []
            )
            chosen = [int(ok["block"].iloc[k]) for k in picks]
        else:
            chosen = [int(b) for b in stabilisation_blocks]
        import pyarrow.parquet as pq

        columns = ["block", "model_order", "frequency_hz", "damping_ratio", "stable"]
        pole_table = (
            pq.read_table(
                poles_path, columns=columns, filters=[("block", "in", chosen)]
            ).to_pandas()
            if chosen
            else None
        )
        section.paragraphs.append(
            "Stabilisation diagrams of chosen blocks (grey: unstable poles; blue: stable in frequency, damping and shape); "
            "dashed lines: the block's tracked modes, labelled with their mode numbers"
            + (
                "; beneath: singular values of the block's spectral matrix."
                if signal is not None
                else "."
            )
        )
        for block in chosen:
            part = pole_table[pole_table["block"] == block]
            if part.empty:
                continue
            start = blocks.loc[blocks["block"] == block, "block_start"].iloc[0]
            tracked = modal[modal["block"] == block] if modal is not None else None
            sv = None
            if signal is not None:
                sv = block_singular_values(signal, start, float(parameters.get("length_s", 1200.0)))
            fig = views.plot_stabilisation_block(
                part, tracked=tracked, singular_values=sv, band_hz=band,
                title=f"block {block}, {start:%Y-%m-%d %H:%M} UTC",
            )  # fmt: skip
            section.figures.append(
                (f"Block {block}", figures.save(fig, f"stabilisation_block{block}"))
            )
        return section

    return None


def modes_section(data: RunData) -> ReportSection | None:
    """Tracked modes against time, AutoMAC and mode shapes."""
    figures, modal, predictors, geometry, mode_frequencies = (
        data.figures,
        data.modal,
        data.predictors,
        data.geometry,
        data.mode_frequencies,
    )
    if modal is not None:
        section = ReportSection("modes", "Tracked modes")
        section.paragraphs.append(
            "Frequency and damping ratio (in % of critical) of every tracked mode against time, "
            "the ship's speed and temperatures beneath on the same time axis."
        )
        fig = views.plot_tracked_modes(modal, predictors)
        section.figures.append(
            ("Tracked modes and operating conditions", figures.save(fig, "tracked_modes"))
        )
        has_shapes = any(str(c).startswith("shape_re_") for c in modal.columns)
        if has_shapes:
            fig = views.plot_automac(modal)
            section.figures.append(
                ("AutoMAC of the tracked modes' mean shapes", figures.save(fig, "automac"))
            )
            if geometry is not None:
                fig = views.plot_mode_shapes(modal, geometry, frequencies=mode_frequencies)
                section.figures.append(
                    (
                        "Mean mode shapes on the sensor layout (arrows along each sensor's direction; red circles: no value)",
                        figures.save(fig, "mode_shapes"),
                    )
                )
        return section

    return None


def harmonics_section(data: RunData) -> ReportSection | None:
    """Campbell view of the identification: frequency against shaft speed, the shaft and
    blade-pass orders drawn, the harmonics marked, the tracked modes in their colours."""
    import json

    folder = data.run.identify
    if folder is None or not (folder / "shaft.csv").is_file():
        return None
    if not (folder / "selected.parquet").is_file():
        return None
    selected = pd.read_parquet(folder / "selected.parquet")
    shaft = pd.read_csv(folder / "shaft.csv")
    summary = {}
    if (folder / "harmonics.json").is_file():
        summary = json.loads((folder / "harmonics.json").read_text(encoding="utf-8"))
    section = ReportSection("harmonics", "Shaft harmonics (Campbell view)")
    section.paragraphs += list(summary.get("lines", []))
    section.paragraphs.append(
        "Every selected mode of every block at the block's shaft speed, weighted by rpm⁴ "
        "where the harmonics' energy is (or at its speed, when the shaft speed is not logged): a structural mode keeps its frequency whatever the "
        "shaft speed, a shaft order follows its line f = k × rpm / 60 (dashed; without a logged shaft speed "
        "f = k × the shaft rate per knot found × speed). Red crosses: "
        "harmonics, kept out of the tracked modes, forecasts and health charts; grey: "
        "selected modes tracked as nothing."
    )
    fig = views.plot_campbell(
        selected,
        shaft,
        modal=data.modal,
        orders=summary.get("orders", ()),  # without a shaft speed: at the rate per knot
        shaft_hz_per_kn=summary.get("shaft_hz_per_kn"),
    )
    section.figures.append(("Campbell view", data.figures.save(fig, "campbell")))
    return section


def correlation_section(data: RunData) -> ReportSection | None:
    """Pearson r of the modes that are present in at least half the blocks with the
    predictors, per case, with significance on the effective number of blocks."""
    out, figures, modal, predictors, mode_table = (
        data.out,
        data.figures,
        data.modal,
        data.predictors,
        data.mode_table,
    )
    if modal is not None and predictors is not None and len(predictors.columns) > 3:
        kept = (
            mode_table[mode_table["presence [%]"] >= 50]["mode"] if mode_table is not None else []
        )
        if not len(kept):
            return None  # the overview says the modes were left out
        section = ReportSection(
            "correlation", "Correlation with operating conditions", figures_first=True
        )
        table = _correlations(data, kept)
        fig = views.plot_correlation_heatmap(table)
        section.paragraphs.append(
            "Pearson r of each mode's frequency (f) and damping ratio (ζ) with each predictor, per operating case. "
            f"{block_dependence(predictors)}: the p-values use an effective "
            "number of blocks N_eff from the autocorrelation of both series (Bartlett; Bretherton et al. 1999). "
            "* significant (p < 0.05) with N_eff; ° significant only if the blocks were taken as independent. "
            "Greyed: fewer than 10 blocks or N_eff < 5, not judged."
        )
        section.figures.append(
            ("Correlation heatmap per case", figures.save(fig, "correlation_heatmap"))
        )
        modes_only = table[table["y"].str.startswith("mode")]
        top = modes_only[(modes_only["p_value"] < 0.05) | modes_only["significant_effective"]]
        top = (
            top.assign(abs_r=top["r"].abs())
            .sort_values(["small", "abs_r"], ascending=[True, False])
            .head(25)
        )
        shown = pd.DataFrame(
            {
                "predictor": top["x"],
                "mode quantity": [_short(y) for y in top["y"]],
                "case": top["case"],
                "r": top["r"],
                "n": top["n"],
                "N_eff": top["n_effective"],
                "p (naive)": top["p_value"],
                "p (N_eff)": top["p_effective"],
                "significant": top["significant_effective"],
            }
        )
        shown.attrs["row_classes"] = ["small" if s else "" for s in top["small"]]
        section.tables.append(
            (
                f"Strongest pairs significant by either test ({len(shown)} of {len(modes_only)}; greyed: too few blocks)",
                shown,
            )
        )
        csv = figures.folder / "correlation_effective.csv"
        with atomic_path(csv) as tmp:
            table.to_csv(tmp, index=False, float_format="%.6g")
        section.details.append(
            ("All pairs", f"{len(table)} rows in {csv.relative_to(out.parent).as_posix()}")
        )
        return section
    return None


def block_dependence(predictors: pd.DataFrame) -> str:
    """Why neighbouring blocks are not independent, with the overlap of the table's block
    grid (recorded with it, else inferred from the block times)."""
    from workbench.blocks import block_grid_of
    from workbench.errors import WorkbenchError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a single block: the step is assumed
            _, length_s, step_s = block_grid_of(predictors)
    except (WorkbenchError, KeyError, ValueError):
        return "Neighbouring blocks are not independent"
    overlap = 1.0 - step_s / length_s
    if overlap > 0:
        return f"Blocks overlap ({100 * overlap:.0f} %), so neighbouring blocks are not independent"
    return "Neighbouring blocks are not independent (the operating conditions change slowly)"


def _correlations(data: RunData, kept) -> pd.DataFrame:
    """The correlate stage's pairs of the *kept* modes (and of the predictors among
    themselves), with significance on the effective number of blocks: from the result the
    report was given, else from the stage run on the kept modes."""
    from workbench.stages import CorrelateOptions, correlate

    result = data.correlation
    if result is None:
        result = correlate(
            data.modal[data.modal["mode"].isin(kept)],
            data.predictors,
            cases=data.cases,
            options=CorrelateOptions(
                min_presence=0.0, quantities=("frequency_hz", "damping_ratio")
            ),
        )
    table = result.effective()
    kept = {int(mode) for mode in kept}
    left_out = [c for c in result.mode_columns if int(c[4:].split("_", 1)[0]) not in kept]
    return table[~table["y"].isin(left_out) & ~table["x"].isin(left_out)].reset_index(drop=True)


def regression_section(data: RunData) -> ReportSection | None:
    """The stepwise models per mode and their residual diagnostics."""
    run, out = data.run, data.out
    if run.fit is not None:
        section = ReportSection("regression", "Stepwise regression")
        stats_table = pd.read_csv(run.fit / "fit_statistics.csv")
        keep = [
            c
            for c in (
                "mode",
                "formula",
                "n_obs",
                "rmse",
                "r_squared",
                "adj_r_squared",
                "durbin_watson",
                "normality_p_value",
            )
            if c in stats_table
        ]
        shown = stats_table[keep].rename(
            columns={
                "n_obs": "n",
                "rmse": "RMSE [Hz]",
                "r_squared": "R²",
                "adj_r_squared": "adj. R²",
                "durbin_watson": "DW",
                "normality_p_value": "normality p",
            }
        )
        if "formula" in shown:
            shown["formula"] = shown["formula"].str.replace(r"^mode\d+_", "", regex=True)
        section.tables.append(("Fitted models per mode (frequency; DW: Durbin-Watson)", shown))
        for png in sorted(
            run.fit.glob("diagnostics_mode*.png"),
            key=lambda p: int("".join(ch for ch in p.stem if ch.isdigit()) or 0),
        ):
            section.figures.append(
                (
                    png.stem.replace("diagnostics_mode", "residual diagnostics, mode "),
                    os.path.relpath(png, out.parent),
                )
            )
        summary = run.fit / "fit_summary.txt"
        if summary.exists():
            section.details.append(("Full regression output", summary.read_text(encoding="utf-8")))
        return section

    return None


def forecast_section(data: RunData) -> ReportSection | None:
    """Forecasts per option, observed against predicted, errors against the truth."""
    run, figures, modal, notices = data.run, data.figures, data.modal, data.notices
    truth = read_table(run.truth, MODAL) if run.truth is not None else None
    mapping = {}
    if truth is not None and modal is not None:
        from workbench.sid.tracking import label_agreement

        _, mapping = label_agreement(modal, truth)
    if run.forecast is not None:
        forecast = read_table(run.forecast, FORECAST)
        section = ReportSection("forecast", "Forecast")
        section.paragraphs.append(
            "Sliding model forecasts (grey band: 95 % prediction interval) blended with the SSI estimates by a Kalman "
            "filter; option A measures the tracked pole, option B the stabilisation-diagram pole nearest the prediction."
        )
        relabelled_truth = None
        if truth is not None and mapping:
            inverse = {true: label for label, true in mapping.items()}
            relabelled_truth = truth[truth["mode"].isin(inverse)].assign(
                mode=lambda t: t["mode"].map(inverse)
            )
        for option in sorted(forecast["option"].unique()):
            fig = views.plot_forecast_overview(forecast, option=option, truth=relabelled_truth)
            section.figures.append((f"Option {option}", figures.save(fig, f"forecast_{option}")))
        fig = views.plot_observed_vs_predicted(forecast)
        section.figures.append(
            (
                "Observed (SSI) against predicted (model), forecast phase",
                figures.save(fig, "observed_vs_predicted"),
            )
        )
        if "warning" in forecast.columns:
            notices += [f"forecast: {line}" for line in warning_counts(forecast["warning"])]
        if run.evaluation is not None and mapping:
            evaluation = pd.read_csv(run.evaluation)
            inverse = {true: label for label, true in mapping.items()}
            evaluation = evaluation[evaluation["mode"].isin(inverse)]
            shown = pd.DataFrame(
                {
                    "option": evaluation["option"],
                    "mode": evaluation["mode"].map(inverse).astype(int),
                    "true mode": evaluation["mode"],
                    "blocks": evaluation["n_ssi"],
                    "SSI error [Hz]": evaluation["ssi_cumulative_error_hz"],
                    "model error [Hz]": evaluation["model_cumulative_error_hz"],
                    "Kalman error [Hz]": evaluation["kalman_cumulative_error_hz"],
                    "Kalman vs SSI [%]": evaluation["improvement_vs_ssi_pct"],
                }
            ).sort_values(["option", "mode"])
            section.tables.append(
                (
                    "Against the true frequencies (forecast phase): cumulative |error| per mode; mode = tracked label",
                    shown,
                )
            )
        return section
    return None


def crosscheck_section(run: RunFiles) -> ReportSection | None:
    """SSI/LSCF agreement per block from identify's ``crosscheck.csv`` (None without it)."""
    from workbench.sid.crosscheck import agreement_by_block, agreement_lines

    path = run.identify / "crosscheck.csv" if run.identify is not None else None
    if path is None or not path.is_file():
        return None
    table = pd.read_csv(path)
    if table.empty:
        return None
    by_block = agreement_by_block(table)
    shown = pd.DataFrame(
        {
            "block": by_block["block"],
            "SSI modes": by_block["ssi_modes"],
            "LSCF modes": by_block["lscf_modes"],
            "pairs": by_block["pairs"],
            "within 0.1 %": by_block["agreeing"],
            "max |Δf|/f [%]": 100 * by_block["frequency_difference_max"],
            "median |Δζ|/ζ [%]": 100 * by_block["damping_difference_median"],
            "lowest MAC": by_block["mac_min"],
        }
    )
    return ReportSection(
        "crosscheck",
        "SSI / LSCF cross-check",
        paragraphs=[
            "The selected modes of the same blocks identified by SSI and by poly-reference "
            "LSCF, paired one-to-one (within 1 % in frequency and MAC >= 0.8).",
            *agreement_lines(table),
        ],
        tables=[("Agreement per block", shown)],
    )
