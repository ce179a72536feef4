"""The report's overview: what ran, on which data, the modes found, skipped blocks and
dropped channels; it also loads the tables the later sections share."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from data_contracts import PREDICTORS, SENSOR_GEOMETRY, read_table

from .render import read_csv_times
from .run import ReportSection, RunFiles
from .signals import SignalSummary, signal_pass

if TYPE_CHECKING:
    from ...stages import CorrelateResult
    from .render import Figures


@dataclass
class RunData:
    """A run's tables as the report's sections read them (None where a stage did not run)."""

    run: RunFiles
    out: Path
    figures: Figures
    parameters: dict
    band: tuple[float, float] | None
    modal: pd.DataFrame | None
    predictors: pd.DataFrame | None
    cases: pd.DataFrame | None
    geometry: pd.DataFrame | None
    signal: SignalSummary | None
    correlation: CorrelateResult | None = None
    blocks: pd.DataFrame | None = None
    faults: pd.DataFrame | None = None
    mode_table: pd.DataFrame | None = None
    mode_frequencies: dict = field(default_factory=dict)
    notices: list[str] = field(default_factory=list)


def load_run(
    run: RunFiles,
    out: Path,
    figures: Figures,
    correlation: CorrelateResult | None = None,
    *,
    modal: pd.DataFrame | None = None,
    acceleration_layout=None,
    dship_mapping=None,
    dship_utc_offset: str | None = None,
    time_format: str | None = None,
) -> RunData:
    """Read the run's tables once: identification parameters, tracked modes, the
    correlate stage's result (as saved, :func:`~workbench.stages.read_correlation`) and
    its predictors (else a predictor table, else the DSHIP log onto the modal blocks, read
    with *dship_mapping*, *dship_utc_offset* and *time_format*), cases, sensor geometry and the pass over the
    acceleration files (read with *acceleration_layout*, else the layout identification
    recorded)."""
    from workbench.predictors import canonical_predictors, load_predictors
    from workbench.stages import read_correlation
    from workbench.stats.correlation import read_cases

    parameters = {}
    if run.identify is not None and (run.identify / "store" / "store.json").exists():
        parameters = json.loads((run.identify / "store" / "store.json").read_text())
    band = tuple(parameters["band_hz"]) if parameters.get("band_hz") else None
    acceleration_layout = _reading_layout(
        acceleration_layout, parameters.get("acceleration_layout") or None, run.accelerations
    )

    if modal is None and run.tracked is not None:
        # as forecast reads it: rows without a frequency (an outage) dropped, with a warning
        from data_contracts.modal_layout import read_modal_table

        modal = read_modal_table(run.tracked)
    if correlation is None and run.correlation is not None:
        correlation = read_correlation(run.correlation)  # the run's own, not recomputed
    predictors = None
    if correlation is not None:
        predictors = correlation.predictors  # as the run read them: no second reading
    elif run.predictors is not None:
        predictors = canonical_predictors(read_table(run.predictors, PREDICTORS))
    elif run.dship is not None and modal is not None:
        predictors = load_predictors(
            dship=run.dship,
            onto=modal,
            dship_mapping=dship_mapping,
            dship_utc_offset=dship_utc_offset,
            time_format=time_format,
        )
    cases = read_cases(run.cases) if run.cases is not None else None
    geometry = read_table(run.geometry, SENSOR_GEOMETRY) if run.geometry is not None else None
    if geometry is not None and modal is not None:
        from data_contracts import shapes_from_frame

        from ..mode_views import check_geometry_channels

        # before any figure is drawn: one line naming both sides, not a failure mid-report
        if any(str(c).startswith("shape_re_") for c in modal.columns):
            channels, _ = shapes_from_frame(modal)
            check_geometry_channels(channels, geometry, geometry_name=str(run.geometry))
    skipped: list[str] = []
    signal = (
        signal_pass(run.accelerations, cases, band, layout=acceleration_layout, skipped=skipped)
        if run.accelerations
        else None
    )
    notices = []
    if run.tracked is not None and run.identify is not None and modal is not None:
        mismatch = _tracked_against_poles(run, modal)
        if mismatch:
            notices.append(mismatch)
    if skipped:  # said in the report, not only in a log
        notices.append(
            f"{len(skipped)} of {len(run.accelerations)} acceleration file(s) could not be "
            f"read for the signal views; the first: {skipped[0]}"
        )
    return RunData(
        run=run,
        out=out,
        figures=figures,
        parameters=parameters,
        band=band,
        modal=modal,
        predictors=predictors,
        cases=cases,
        geometry=geometry,
        signal=signal,
        correlation=correlation,
        notices=notices,
    )


#: Tracked blocks, spread over the run, whose poles are looked up in ``poles.parquet``. [-]
MATCH_BLOCKS = 20


def _tracked_against_poles(run: RunFiles, modal: pd.DataFrame) -> str | None:
    """A notice when the tracked table's poles are not those of the identification shown
    beside it (tables of two runs in one folder: an identification run again over other
    data or settings, the tracked table left from before), as ``forecast --poles`` checks
    them (:func:`~workbench.joins.check_poles_match`); None when they match. Only the
    poles of :data:`MATCH_BLOCKS` tracked blocks are read."""
    import numpy as np
    import pyarrow.parquet as pq

    from workbench.errors import WorkbenchError
    from workbench.joins import check_poles_match

    poles_path = run.identify / "poles.parquet"
    if not poles_path.exists() or modal.empty or "model_order" not in modal.columns:
        return None
    blocks = np.unique(modal["block"].to_numpy())
    picks = np.unique(np.linspace(0, len(blocks) - 1, min(MATCH_BLOCKS, len(blocks))).round())
    sample = [int(b) for b in blocks[picks.astype(int)]]
    try:
        poles = pq.read_table(
            poles_path,
            columns=["block", "model_order", "frequency_hz"],
            filters=[("block", "in", sample)],
        ).to_pandas()
        check_poles_match(modal[modal["block"].isin(sample)], run.tracked.name, poles, poles_path)
    except WorkbenchError as error:
        return (
            f"{error}: the tracked modes ({run.tracked}) and the identification shown "
            f"({run.identify}) are not of one run"
        )
    except (OSError, ValueError, KeyError):
        return None  # an unreadable pole table: the identification section says so
    return None


def _reading_layout(given, recorded, files) -> dict | None:
    """How the report reads the acceleration files: as identification read them (the
    layout it recorded, with each file's start) unless *given* says otherwise; a start
    time given for several files is resolved per file as identify resolves it."""
    if given is None:
        return recorded
    given = dict(given)
    if recorded is not None and given == {k: v for k, v in recorded.items() if k != "file_starts"}:
        return recorded  # the same settings: identification's resolved starts
    start = given.get("start_time")
    if len(files) > 1 and start not in (None, "filename") and not given.get("file_starts"):
        from workbench.identification import IdentifyOptions
        from workbench.identification.planning import follow_on_starts

        resolved = follow_on_starts(files, IdentifyOptions(acceleration_layout=given))
        return dict(resolved.acceleration_layout or given)
    return given


def overview_section(data: RunData, summary_lines=()) -> ReportSection:
    """The overview section; sets the run's blocks, faults, mode table and mode
    frequencies on *data* and adds its notices."""
    run, parameters, band, signal = data.run, data.parameters, data.band, data.signal
    modal, predictors, notices = data.modal, data.predictors, data.notices
    overview = ReportSection("overview", "Overview", paragraphs=list(summary_lines))
    # ---- overview: what ran, on which data
    ran = [
        name
        for name, present in (
            ("identification", run.identify),
            ("tracking", run.tracked),
            ("predictors", predictors is not None),
            ("correlation", modal is not None and predictors is not None),
            ("stepwise regression", run.fit),
            ("forecast", run.forecast),
            ("evaluation against the truth", run.evaluation),
        )
        if present is not None and present is not False
    ]
    facts = [("stages", ", ".join(ran) or "none found")]
    if signal is not None:
        facts += [
            (
                "acceleration files",
                f"{signal.n_files} ({len(signal.channels)} channels at {signal.sampling_rate_hz:g} Hz)"
                + (
                    f"; {signal.n_read} spread over the run read for the signal views"
                    if signal.n_read < signal.n_files
                    else ""
                ),
            ),
            ("time span", f"{signal.start:%Y-%m-%d %H:%M} to {signal.end:%Y-%m-%d %H:%M} UTC"),
        ]
    if parameters:
        orders = parameters.get("orders") or [0]
        facts += [
            (
                "identification",
                f"SSI-{parameters.get('method')}, block rows {parameters.get('block_rows')}, "
                f"orders {min(orders)}-{max(orders)}, blocks of {parameters.get('length_s', 0) / 60:g} min "
                f"every {parameters.get('step_s', 0) / 60:g} min"
                + (f", band {band[0]:g}-{band[1]:g} Hz" if band else "")
                + (
                    f", decimated to {parameters['target_rate_hz']:g} Hz"
                    if parameters.get("target_rate_hz")
                    else ""
                ),
            )
        ]
    blocks = None
    if run.identify is not None:
        blocks = read_csv_times(run.identify / "blocks.csv", ["block_start"])
        skipped = blocks[blocks["status"] != "ok"]
        facts.append(
            (
                "blocks",
                f"{len(blocks)} planned, {len(blocks) - len(skipped)} identified, {len(skipped)} skipped",
            )
        )
        if len(skipped):
            table = skipped[["block", "block_start", "reason"]].head(20)
            overview.tables.append((f"Skipped blocks ({len(skipped)}; first 20)", table))
            notices.append(
                f"{len(skipped)} blocks could not be identified (see the skipped blocks)"
            )
    faults = None
    if run.identify is not None and (run.identify / "faults.csv").exists():
        faults = read_csv_times(run.identify / "faults.csv", ["block_start"])
        if len(faults):
            n_blocks = len(blocks) if blocks is not None else faults["block"].nunique()
            dropped = (
                faults.groupby("channel")
                .agg(
                    blocks=("block", "nunique"),
                    first=("block_start", "min"),
                    last=("block_start", "max"),
                    reason=("reason", "first"),
                )
                .reset_index()
            )
            dropped["share [%]"] = 100.0 * dropped["blocks"] / max(n_blocks, 1)
            dropped = dropped[["channel", "blocks", "share [%]", "first", "last", "reason"]]
            overview.tables.append(("Dropped channels (blocks identified without them)", dropped))
            notices.append(
                f"{len(dropped)} channel(s) dropped in some blocks: {', '.join(dropped['channel'])}"
            )
    facts.append(
        (
            "sensor layout",
            run.geometry.name
            if run.geometry is not None
            else "none (no sensor_geometry.csv; mode shapes not drawn)",
        )
    )
    mode_table = None
    if modal is not None:
        n_blocks_total = (
            int(blocks["block"].nunique()) if blocks is not None else int(modal["block"].nunique())
        )
        grouped = modal.groupby("mode")
        mode_table = pd.DataFrame(
            {
                "mode": grouped.size().index.astype(int),
                "frequency [Hz]": grouped["frequency_hz"].mean().to_numpy(),
                "f std [Hz]": grouped["frequency_hz"].std().to_numpy(),
                "damping [%]": 100 * grouped["damping_ratio"].mean().to_numpy(),
                "ζ std [%]": 100 * grouped["damping_ratio"].std().to_numpy(),
                "blocks": grouped["block"].nunique().to_numpy(),
                "presence [%]": 100
                * grouped["block"].nunique().to_numpy()
                / max(n_blocks_total, 1),
            }
        )
        if "mac" in modal.columns:
            mode_table["mean MAC"] = grouped["mac"].mean().to_numpy()
        rare = mode_table[mode_table["presence [%]"] < 50]
        if len(rare):
            notices.append(
                "modes " + ", ".join(map(str, rare["mode"])) + " found in fewer than 50 % of the "
                "blocks: left out of the correlation, regression and forecast stages"
            )
        overview.tables.insert(
            0, ("Modes found (tracked labels; damping ratio in % of critical)", mode_table)
        )
    mode_frequencies = (
        dict(zip(mode_table["mode"], mode_table["frequency [Hz]"], strict=True))
        if mode_table is not None
        else {}
    )
    overview.tables.insert(0, ("", pd.DataFrame(facts, columns=["what", "value"])))
    data.blocks, data.faults, data.mode_table = blocks, faults, mode_table
    data.mode_frequencies = mode_frequencies
    return overview
