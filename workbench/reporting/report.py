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
"""

from __future__ import annotations

import json
import logging
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import (
    FORECAST,
    MODAL,
    PREDICTORS,
    SENSOR_GEOMETRY,
    atomic_path,
    read_accelerations,
    read_table,
)

__all__ = ["ReportSection", "RunFiles", "build_report", "find_run", "register_section"]

log = logging.getLogger(__name__)

_FIGURE_DIR = "report_files"


@dataclass
class RunFiles:
    """The tables of a run found in a folder (None where a stage did not run)."""

    root: Path
    identify: Path | None = None
    tracked: Path | None = None
    predictors: Path | None = None
    dship: Path | None = None
    cases: Path | None = None
    geometry: Path | None = None
    accelerations: list[Path] = field(default_factory=list)
    fit: Path | None = None
    forecast: Path | None = None
    evaluation: Path | None = None
    truth: Path | None = None


@dataclass
class ReportSection:
    """A section of the report: title, paragraphs (plain text), tables and figures.

    ``tables`` are ``(caption, DataFrame)`` pairs (shown with their column names);
    ``figures`` are ``(caption, path relative to the report)``.
    """

    id: str
    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)
    details: list[tuple[str, str]] = field(default_factory=list)
    figures_first: bool = False


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


def _first(root: Path, names: Sequence[str], *, depth: int = 2) -> Path | None:
    """First file named like one of *names* at depth 0, then 1, ... below *root*, outside
    the simulator's truth folder (a folder with ``voyage.json``) unless asked for."""
    for level in range(depth + 1):
        pattern = "/".join(["*"] * level)
        for name in names:
            for path in sorted(root.glob(f"{pattern}/{name}" if pattern else name)):
                if path.is_file() and "store" not in path.relative_to(root).parts[:-1]:
                    return path
    return None


def find_run(
    root: str | os.PathLike,
    *,
    accelerations: Sequence[str | os.PathLike] = (),
    dship: str | os.PathLike | None = None,
    cases: str | os.PathLike | None = None,
    geometry: str | os.PathLike | None = None,
) -> RunFiles:
    """Locate a run's tables in *root* (the folder given to the stages' ``--out``).

    Looked for (in *root*, then one and two folders down): ``blocks.csv`` next to
    ``poles.parquet``/``selected.parquet`` (identification), ``tracked_modal.*``,
    ``predictors.*``, ``fit_statistics.csv``, ``forecast.*``, ``evaluation.csv``,
    ``cases.csv``, ``sensor_geometry.csv``, a DSHIP log (``*.tsv``/``*.tab``) and an
    ``accelerations`` folder. Explicit arguments win.
    """
    from data_contracts.formats import acceleration_files

    root = Path(root)
    run = RunFiles(root)
    blocks = _first(root, ["blocks.csv"])
    run.identify = blocks.parent if blocks is not None else None
    run.tracked = _first(
        root, ["tracked_modal.csv", "tracked_modal.parquet", "tracked*.csv"], depth=1
    )
    if run.tracked is not None and (run.tracked.parent / "voyage.json").exists():
        run.tracked = None  # the simulator's imitation, not a result of this run
    run.predictors = _first(root, ["predictors.csv", "predictors.parquet"], depth=1)
    run.dship = Path(dship) if dship else _first(root, ["dship.tsv", "*.tab", "*.tsv"])
    run.cases = Path(cases) if cases else _first(root, ["cases.csv"])
    run.geometry = Path(geometry) if geometry else _first(root, ["sensor_geometry.csv"])
    fit = _first(root, ["fit_statistics.csv"])
    run.fit = fit.parent if fit is not None else None
    run.forecast = _first(root, ["forecast.csv", "forecast.parquet"], depth=1)
    run.evaluation = _first(root, ["evaluation.csv"], depth=1)
    run.truth = _first(root, ["truth_modal.csv"])
    if accelerations:
        run.accelerations = acceleration_files(accelerations)
    else:
        folder = next((p for p in sorted(root.rglob("accelerations")) if p.is_dir()), None)
        if folder is not None:
            run.accelerations = acceleration_files([folder])
    return run


# --------------------------------------------------------------------------- data passes
@dataclass
class _SignalSummary:
    sampling_rate_hz: float
    channels: tuple[str, ...]
    start: pd.Timestamp
    end: pd.Timestamp
    n_files: int
    n_read: int
    files: list[tuple[pd.Timestamp, pd.Timestamp, Path]]
    moments: pd.DataFrame
    spectra: dict[str, tuple[np.ndarray, np.ndarray]]
    spectrogram: tuple[np.ndarray, np.ndarray, np.ndarray]


def _segment_length(rate: float) -> int:
    return int(2 ** np.round(np.log2(max(rate * 8.0, 64.0))))


def _csd(chunk: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch cross-spectral matrix (Hann, 50 % overlap) of a chunk; NaN channels as zero."""
    from scipy.signal import get_window

    n = min(_segment_length(rate), len(chunk))
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        data = np.nan_to_num(chunk - np.nanmean(chunk, axis=0))
    step = n // 2
    starts = np.arange(0, len(data) - n + 1, step)
    window = get_window("hann", n)
    segments = np.stack([data[s : s + n] * window[:, None] for s in starts])
    spectra = np.fft.rfft(segments, axis=1)  # (n_seg, n_freq, n_ch)
    scale = 2.0 / (rate * np.sum(window**2))
    csd = np.einsum("sfi,sfj->fij", spectra, spectra.conj()) * scale / len(starts)
    return np.fft.rfftfreq(n, 1.0 / rate), csd


def _chunk_moments(chunk: np.ndarray) -> np.ndarray:
    """RMS about the mean [m/s²], skewness and kurtosis (not excess) of each channel:
    array of shape (3, n_channels), NaN for a channel without data."""
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.mean if np.isfinite(chunk).all() else np.nanmean
        centred = chunk - mean(chunk, axis=0)
        squared = centred * centred
        m2 = mean(squared, axis=0)
        skewness = mean(squared * centred, axis=0) / m2**1.5
        kurtosis = mean(squared * squared, axis=0) / m2**2
    return np.stack([np.sqrt(m2), skewness, kurtosis])


def _moments_frame(times: list[pd.Timestamp], values: list[np.ndarray], channels) -> pd.DataFrame:
    stacked = np.stack(values)  # (n_chunks, 3, n_channels)
    n_chunks, _, n_channels = stacked.shape
    return pd.DataFrame(
        {
            "time": np.repeat(pd.DatetimeIndex(times), n_channels),
            "channel": np.tile(np.asarray(channels, dtype=object), n_chunks),
            "rms": stacked[:, 0].ravel(),
            "skewness": stacked[:, 1].ravel(),
            "kurtosis": stacked[:, 2].ravel(),
        }
    )


def _signal_pass(
    files: Sequence[Path],
    cases: pd.DataFrame | None,
    band_hz: tuple[float, float] | None = None,
    *,
    max_files: int = 720,
    max_chunks: int = 600,
) -> _SignalSummary | None:
    """One pass over the acceleration files: per-chunk channel moments, the first singular
    value of each chunk's spectral matrix (spectrogram) and the mean spectral matrix of each
    operating case (its singular values).

    Long runs are read at *max_files* files spread evenly over the run; chunks are sized so
    that about *max_chunks* of them cover it (at least two spectral segments each).
    """
    n_files = len(files)
    if len(files) > max_files:
        picks = np.unique(np.linspace(0, len(files) - 1, max_files).round().astype(int))
        files = [files[k] for k in picks]
    case_names: list[str] = []
    case_bounds = np.empty((0, 2), dtype=np.int64)
    if cases is not None:
        case_names = list(cases["case"])
        case_bounds = np.column_stack(
            [cases["start"].to_numpy("datetime64[ns]").astype(np.int64),
             cases["end"].to_numpy("datetime64[ns]").astype(np.int64)]
        )  # fmt: skip
    sums: dict[str, np.ndarray] = {}
    counts: dict[str, int] = {}
    moments, times, first_sv = [], [], []
    frequency = shown = None
    rate = None
    per_chunk = 0
    channels: tuple[str, ...] = ()
    spans = []
    for path in files:
        try:
            record = read_accelerations(path)
        except Exception as error:  # a bad file is reported by identify; skip it here
            log.warning("report: %s skipped (%s)", path, error)
            continue
        if rate is None:
            rate, channels = record.sampling_rate_hz, record.channels
            segment = _segment_length(rate)
            total = len(files) * record.n_samples
            per_chunk = int(
                np.clip(total / max_chunks, 2 * segment, max(record.n_samples, 2 * segment))
            )
            # whole chunks per file, so that chunk times lie on a regular grid across files
            per_chunk = record.n_samples // max(1, round(record.n_samples / per_chunk))
        if record.sampling_rate_hz != rate or record.channels != channels:
            continue
        data = record.acceleration
        spans.append((record.start_time, record.start_time + record.duration, path))
        start_ns = record.start_time.value
        for start in range(0, max(record.n_samples - per_chunk // 2, 1), per_chunk):
            chunk = data[start : start + per_chunk]
            if len(chunk) < min(per_chunk, _segment_length(rate)):
                continue
            time_ns = start_ns + int(round(1e9 * start / rate))
            time = pd.Timestamp(time_ns, tz="UTC")
            moments.append(_chunk_moments(chunk))
            frequency, csd = _csd(chunk, rate)
            if shown is None:
                shown = np.ones(len(frequency), dtype=bool)
                if band_hz is not None:
                    shown = (frequency >= band_hz[0] - 0.5) & (frequency <= band_hz[1] + 0.5)
            times.append(time)
            first_sv.append(np.linalg.eigvalsh(csd[shown])[:, -1])
            inside = (case_bounds[:, 0] <= time_ns) & (time_ns < case_bounds[:, 1])
            for case in [
                "all",
                *dict.fromkeys(n for n, i in zip(case_names, inside, strict=True) if i),
            ]:
                sums[case] = sums.get(case, 0.0) + csd
                counts[case] = counts.get(case, 0) + 1
    if rate is None or not times:
        return None
    spectra = {}
    for case, total_csd in sums.items():
        values = np.linalg.eigvalsh(total_csd / counts[case])[:, ::-1][:, :3]
        spectra[case] = (frequency, np.clip(values, 0.0, None))
    order = ["all"] + [c for c in dict.fromkeys(case_names) if c in spectra]
    return _SignalSummary(
        sampling_rate_hz=float(rate),
        channels=channels,
        start=min(s for s, _, _ in spans),
        end=max(e for _, e, _ in spans),
        n_files=n_files,
        n_read=len(spans),
        files=spans,
        moments=_moments_frame(times, moments, channels),
        spectra={case: spectra[case] for case in order},
        spectrogram=(np.array(times), frequency[shown], np.array(first_sv)),
    )


def _block_singular_values(signal: _SignalSummary, start: pd.Timestamp, length_s: float):
    """Singular values of the spectral matrix of one block's data (its files, cut)."""
    end = start + pd.Timedelta(seconds=length_s)
    parts = []
    for file_start, file_end, path in signal.files:
        if file_end <= start or file_start >= end:
            continue
        record = read_accelerations(path)
        t = file_start + pd.to_timedelta(
            np.arange(record.n_samples) / record.sampling_rate_hz, unit="s"
        )
        keep = (t >= start) & (t < end)
        parts.append(record.acceleration[np.asarray(keep)])
    if not parts:
        return None
    frequency, csd = _csd(np.concatenate(parts), signal.sampling_rate_hz)
    values = np.linalg.eigvalsh(csd)[:, ::-1][:, :3]
    return frequency, np.clip(values, 0.0, None)


# --------------------------------------------------------------------------- helpers
class _Figures:
    def __init__(self, report_path: Path, dpi: int):
        self.folder = report_path.parent / _FIGURE_DIR
        self.folder.mkdir(parents=True, exist_ok=True)
        self.report_dir = report_path.parent
        self.dpi = dpi

    def save(self, fig, name: str) -> str:
        from .figures import save_figure  # matplotlib only when a report draws

        path = save_figure(fig, self.folder / f"{name}.png", dpi=self.dpi)
        return path.relative_to(self.report_dir).as_posix()


def _format_table(frame: pd.DataFrame, digits: int = 4) -> dict:
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


def _warning_counts(warnings_column: pd.Series) -> list[str]:
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


def _read_csv_times(path: Path, columns: Sequence[str]) -> pd.DataFrame:
    frame = pd.read_csv(path)
    for column in columns:
        if column in frame.columns:
            frame[column] = pd.to_datetime(frame[column], utc=True, format="ISO8601")
    return frame


# --------------------------------------------------------------------------- build
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
    """
    import jinja2

    from workbench.predictors import canonical_predictors, load_predictors
    from workbench.stats.correlation import correlation_table_effective, read_cases

    from . import views

    root = Path(root)
    run = run or find_run(root)
    if run.identify is None and run.tracked is None and not run.accelerations:
        raise ValueError(
            "no run found: neither identification results (blocks.csv), a tracked modal "
            "table (tracked_modal.csv) nor acceleration files"
        )
    out = Path(out) if out is not None else root / "report.html"
    figures = _Figures(out, dpi)
    sections: list[ReportSection] = []
    notices: list[str] = []
    overview = ReportSection("overview", "Overview", paragraphs=list(summary_lines))

    parameters = {}
    if run.identify is not None and (run.identify / "store" / "store.json").exists():
        parameters = json.loads((run.identify / "store" / "store.json").read_text())
    band = tuple(parameters["band_hz"]) if parameters.get("band_hz") else None

    modal = read_table(run.tracked, MODAL) if run.tracked is not None else None
    predictors = None
    if run.predictors is not None:
        predictors = read_table(run.predictors, PREDICTORS)
    elif run.dship is not None and modal is not None:
        predictors = load_predictors(dship=run.dship, onto=modal)
    if predictors is not None:
        predictors = canonical_predictors(predictors)
    cases = read_cases(run.cases) if run.cases is not None else None
    geometry = read_table(run.geometry, SENSOR_GEOMETRY) if run.geometry is not None else None
    signal = _signal_pass(run.accelerations, cases, band) if run.accelerations else None

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
        blocks = _read_csv_times(run.identify / "blocks.csv", ["block_start"])
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
        faults = _read_csv_times(run.identify / "faults.csv", ["block_start"])
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

    # ---- signals
    if signal is not None:
        section = ReportSection("signals", "Signals")
        section.paragraphs.append(
            "Singular values of the cross-spectral matrix (Welch, Hann windows of "
            f"{_segment_length(signal.sampling_rate_hz) / signal.sampling_rate_hz:g} s) per operating case; "
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
        sections.append(section)
    elif run.identify is not None and (run.identify / "channels.csv").exists():
        section = ReportSection("signals", "Signals")
        section.paragraphs.append(
            "Acceleration files not found: channel statistics per block from the identification."
        )
        stats_table = _read_csv_times(run.identify / "channels.csv", ["block_start"]).rename(
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
        sections.append(section)

    # ---- identification
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
                sv = _block_singular_values(
                    signal, start, float(parameters.get("length_s", 1200.0))
                )
            fig = views.plot_stabilisation_block(
                part, tracked=tracked, singular_values=sv, band_hz=band,
                title=f"block {block}, {start:%Y-%m-%d %H:%M} UTC",
            )  # fmt: skip
            section.figures.append(
                (f"Block {block}", figures.save(fig, f"stabilisation_block{block}"))
            )
        sections.append(section)

    # ---- tracked modes
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
        sections.append(section)

    # ---- correlation
    if modal is not None and predictors is not None and len(predictors.columns) > 3:
        section = ReportSection(
            "correlation", "Correlation with operating conditions", figures_first=True
        )
        kept = (
            mode_table[mode_table["presence [%]"] >= 50]["mode"] if mode_table is not None else []
        )
        table = correlation_table_effective(
            modal[modal["mode"].isin(kept)], predictors, cases=cases
        )
        fig = views.plot_correlation_heatmap(table)
        section.paragraphs.append(
            "Pearson r of each mode's frequency (f) and damping ratio (ζ) with each predictor, per operating case. "
            "Blocks overlap (75 %), so neighbouring blocks are not independent: the p-values use an effective "
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
                "mode quantity": [views._short(y) for y in top["y"]],
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
        sections.append(section)

    # ---- regression
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
        sections.append(section)

    # ---- forecast
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
            notices += [f"forecast: {line}" for line in _warning_counts(forecast["warning"])]
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
        sections.append(section)

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
    crosscheck = _crosscheck_section(run)
    if crosscheck is not None:
        sections.append(crosscheck)
    for builder in _SECTION_BUILDERS:
        extra = builder(run, figures.save)
        if extra is not None:
            sections.append(extra)
    sections.extend(extra_sections)
    overview.tables.insert(0, ("", pd.DataFrame(facts, columns=["what", "value"])))
    if not warnings:
        notices.append("none")
    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("workbench.reporting", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    template = environment.get_template("report.html.j2")
    name = title or f"workbench report: {root.resolve().name}"
    page = template.render(
        title=name,
        generated=pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%SZ"),
        overview=_render_section(overview),
        warnings=notices,
        results=results,
        sections=[_render_section(s) for s in sections],
    )
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out


def _crosscheck_section(run: RunFiles) -> ReportSection | None:
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


def _render_section(section: ReportSection) -> dict:
    return {
        "id": section.id,
        "title": section.title,
        "paragraphs": section.paragraphs,
        "tables": [(caption, _format_table(frame)) for caption, frame in section.tables],
        "figures": section.figures,
        "details": section.details,
        "figures_first": section.figures_first,
        "grid": section.id in ("identification", "regression") and len(section.figures) > 1,
    }
