"""The stages of the workflow as file-to-file steps, shared by the CLI and the demo.

Each function reads contract files, calls the library and writes contract files and
reports atomically; it returns what it wrote so callers can print or link it.
"""

from __future__ import annotations

import json
import os
import sys
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from data_contracts import (
    FORECAST,
    MODAL,
    POLES,
    PREDICTORS,
    atomic_path,
    read_dship,
    read_table,
    write_table,
)

from ._deprecation import renamed_parameters
from .errors import WorkbenchError

__all__ = [
    "StageResult",
    "block_grid_of",
    "canonical_predictors",
    "evaluate_forecast",
    "forecast_modes",
    "load_predictors",
    "persistent_modes",
    "run_forecast",
    "run_track",
]


@dataclass
class StageResult:
    """Files a stage wrote, headline lines to print, and warnings it raised."""

    files: list[Path] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)


def block_grid_of(table: pd.DataFrame) -> tuple[pd.Timestamp, float, float]:
    """Block grid ``(t0, length_s, step_s)`` of a table with block, block_start, block_end.

    Raises
    ------
    WorkbenchError
        If the block starts do not lie on one grid.
    """
    blocks = table[["block", "block_start", "block_end"]].drop_duplicates("block")
    blocks = blocks.sort_values("block")
    start = pd.to_datetime(blocks["block_start"], utc=True)
    length = (pd.to_datetime(blocks["block_end"], utc=True) - start).dt.total_seconds()
    if len(blocks) > 1:
        steps = start.diff().dt.total_seconds().to_numpy()[1:] / np.diff(blocks["block"])
        step = float(np.median(steps))
    else:
        step = float(length.iat[0]) / 4.0
    t0 = start.iat[0] - pd.Timedelta(seconds=step * int(blocks["block"].iat[0]))
    expected = t0 + pd.to_timedelta(blocks["block"].to_numpy() * step, unit="s")
    off = np.abs((start.to_numpy() - expected.to_numpy()) / np.timedelta64(1, "s")) > 1e-3
    if off.any():
        first = int(blocks["block"].to_numpy()[off][0])
        raise WorkbenchError(f"block {first}: block_start is off the block grid (step {step:g} s)")
    return t0, float(length.median()), step


@renamed_parameters(like="onto")
def load_predictors(
    *,
    predictors: str | os.PathLike | None = None,
    dship: str | os.PathLike | None = None,
    onto: pd.DataFrame | None = None,
    min_coverage: float = 0.5,
    dship_mapping: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Block predictors from a predictor table, or averaged from a DSHIP log.

    Parameters
    ----------
    predictors : path, optional
        A block predictor table (PREDICTORS contract).
    dship : path, optional
        A raw DSHIP log; averaged onto the block grid of *onto*.
    onto : DataFrame, optional
        A table with block, block_start, block_end (e.g. the tracked modal table) whose block
        grid the DSHIP log is averaged onto; its full block range is used.
    dship_mapping : mapping, optional
        Column mapping for :func:`~data_contracts.read_dship` (``speed_kn`` -> source name).
    """
    if (predictors is None) == (dship is None):
        raise ValueError("give exactly one of predictors and dship")
    if predictors is not None:
        return read_table(predictors, PREDICTORS)
    if onto is None:
        raise ValueError("averaging a DSHIP log needs the blocks of a modal table (onto=)")
    from .predictors import block_predictors

    log = read_dship(dship, mapping=dship_mapping)
    t0, length_s, step_s = block_grid_of(onto)
    first, last = int(onto["block"].min()), int(onto["block"].max())
    from .blocks import BlockGrid

    grid = BlockGrid(t0=t0, length_s=length_s, step_s=step_s)
    table = block_predictors(
        log, grid=grid, blocks=np.arange(first, last + 1), min_coverage=min_coverage
    )
    return PREDICTORS.validate(table)


def persistent_modes(
    modal: pd.DataFrame, min_presence: float = 0.5, *, n_blocks: int | None = None
) -> tuple[pd.DataFrame, list[str]]:
    """Rows of the modes measured in at least *min_presence* of the blocks.

    Short-lived tracks (a shaft harmonic sweeping past with the speed, spurious poles)
    would each add a column of mostly missing values to correlations and models.

    Returns
    -------
    modal : DataFrame
        The rows of the kept modes.
    lines : list of str
        A note naming the modes left out (empty when none).

    Raises
    ------
    WorkbenchError
        When no mode is left.
    """
    if not 0.0 <= min_presence <= 1.0:
        raise ValueError(f"min_presence={min_presence} must be in [0, 1]")
    n_blocks = n_blocks or modal["block"].nunique()
    presence = modal.groupby("mode")["block"].nunique() / max(n_blocks, 1)
    keep = presence.index[presence >= min_presence]
    left_out = sorted(int(m) for m in presence.index[presence < min_presence])
    if not len(keep):
        raise WorkbenchError(
            f"no mode is measured in at least {100 * min_presence:.0f} % of the blocks"
        )
    lines = []
    if left_out:
        lines.append(
            f"modes {left_out} left out: measured in fewer than {100 * min_presence:.0f} % "
            "of the blocks"
        )
    return modal[modal["mode"].isin(keep)], lines


def canonical_predictors(predictors: pd.DataFrame) -> pd.DataFrame:
    """The block columns and the canonical predictors (speed, temperatures, wind) only.

    A ship log carries more numeric columns (position, heading, depth...). They are kept in
    the predictor table, but latitude and longitude, for instance, stand in for elapsed time
    in a regression, so models and correlations use the canonical predictors unless asked.
    """
    from data_contracts import CANONICAL_PREDICTORS

    columns = ["block", "block_start", "block_end", *(c.name for c in CANONICAL_PREDICTORS)]
    return predictors[[c for c in columns if c in predictors.columns]]


# --------------------------------------------------------------------------- tracking
@renamed_parameters(reference="reference_modes")
def run_track(
    selected_path: str | os.PathLike,
    out: str | os.PathLike,
    *,
    reference_modes: str | os.PathLike | None = None,
    progress: bool = False,
    **options: Any,
) -> StageResult:
    """Track the modes selected block by block (``selected`` table) into a modal table."""
    from .sid.tracking import TrackingOptions, track_modes

    selected = _read_any(selected_path)
    ref = read_table(reference_modes, MODAL) if reference_modes is not None else None
    tracked = track_modes(
        selected, options=TrackingOptions(**options), reference_modes=ref, progress=progress
    )
    if tracked.empty:
        raise WorkbenchError(f"{selected_path}: no mode could be tracked")
    path = write_table(tracked, out, MODAL)
    result = StageResult(files=[path], tables={"tracked": tracked})
    counts = tracked.groupby("mode").agg(
        blocks=("block", "size"), frequency_hz=("frequency_hz", "median")
    )
    n_blocks = selected["block"].nunique()
    result.lines.append(
        f"{len(counts)} modes tracked over {n_blocks} blocks -> {path}: "
        + ", ".join(
            f"{m}: {r.frequency_hz:.3f} Hz ({int(r.blocks)} blocks)" for m, r in counts.iterrows()
        )
    )
    return result


def _read_any(path: str | os.PathLike) -> pd.DataFrame:
    """A table without contract (e.g. selected modes), CSV or Parquet, with UTC times."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".parquet":
            frame = pd.read_parquet(path)
        else:
            frame = pd.read_csv(path)
    except FileNotFoundError:
        raise WorkbenchError(f"{path}: no such file") from None
    except (OSError, ValueError) as error:
        raise WorkbenchError(f"{path}: unreadable ({str(error).splitlines()[0]})") from None
    for column in ("block_start", "block_end"):
        if column in frame.columns:
            frame[column] = pd.to_datetime(frame[column], utc=True)
    return frame


# --------------------------------------------------------------------------- forecast
def _forecast_part(modal, predictors, modes, kwargs):
    """One process's share of :func:`forecast_modes` (module level: picklable)."""
    from .forecast import ForecastWarning, sliding_forecast

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ForecastWarning)
        result = sliding_forecast(modal, predictors, modes=modes, **kwargs)
    messages = [str(w.message) for w in caught if issubclass(w.category, ForecastWarning)]
    return result.table, messages


@renamed_parameters(n_jobs="n_workers")
def forecast_modes(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    n_workers: int = 1,
    progress: bool = False,
    **kwargs: Any,
) -> tuple[pd.DataFrame, list[str]]:
    """:func:`~workbench.forecast.sliding_forecast` with the modes spread over processes.

    Modes are independent (one model and one Kalman filter each), so the table equals that
    of a single call, whatever *n_workers*. Returns the forecast table (sorted by block, mode)
    and the forecast warnings' messages.
    """
    modes = kwargs.pop("modes", None)
    modes = sorted(int(m) for m in (modal["mode"].unique() if modes is None else modes))
    n_workers = max(1, min(int(n_workers), len(modes)))
    from tqdm.auto import tqdm

    bar = tqdm(
        total=len(modes),
        desc="forecast",
        unit="mode",
        disable=not progress,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    with bar:
        if n_workers == 1:  # one call: the windows' normalisation is shared by all modes
            parts = [_forecast_part(modal, predictors, modes, kwargs)]
            bar.update(len(modes))
        else:
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(max_workers=n_workers) as pool:
                futures = [
                    pool.submit(
                        _forecast_part, modal[modal["mode"] == mode], predictors, [mode], kwargs
                    )
                    for mode in modes
                ]
                for _done in as_completed(futures):
                    bar.update(1)
                parts = [future.result() for future in futures]
    table = pd.concat([p[0] for p in parts], ignore_index=True)
    keys = [c for c in ("block", "mode", "option") if c in table.columns]
    table = table.sort_values(keys, kind="stable").reset_index(drop=True)
    return table, [m for p in parts for m in p[1]]


#: Descriptive names of the forecast schemes (the reference work's methods 1 and 2).
_SCHEME_NAMES = {1: "single-window", 2: "rolling"}


@renamed_parameters(method="scheme", n_jobs="n_workers")
def run_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    out: str | os.PathLike,
    *,
    poles: pd.DataFrame | None = None,
    options: Sequence[Literal["A", "B"]] = ("A",),
    scheme: Literal[1, 2, "single_window", "rolling"] = 2,
    train_blocks: int = 20,
    horizon: int | None = None,
    trust: float | None | str = "auto",
    model: str = "window",
    figures: str | os.PathLike | None = None,
    truth: pd.DataFrame | None = None,
    predictor_columns: Sequence[str] | None = None,
    stepwise_options: Mapping[str, Any] | None = None,
    n_workers: int = 1,
    progress: bool = False,
    min_presence: float = 0.5,
    option_b: Mapping[str, Any] | None = None,
    cases=None,
) -> StageResult:
    """Sliding forecasts for each option, one forecast table (CSV/Parquet) and figures.

    *cases* (None, "derive", a ``case,start,end`` file or table): each window forecasts
    with the model of the current operating case (see
    :func:`~workbench.forecast.sliding_forecast`).

    Modes measured in fewer than *min_presence* of the blocks (short-lived tracks: a shaft
    harmonic passing by, spurious poles) are not forecast; a line says which.
    """

    from .forecast.options import method_label

    result = StageResult()
    kept, note = persistent_modes(modal, min_presence, n_blocks=predictors["block"].nunique())
    modes = sorted(int(m) for m in kept["mode"].unique())
    result.lines += note
    frames = []
    for option in options:
        table, messages = forecast_modes(
            modal,
            predictors,
            n_workers=n_workers,
            progress=progress,
            modes=modes,
            poles=poles,
            option=option,
            scheme=scheme,
            train_blocks=train_blocks,
            horizon=horizon,
            trust=trust,
            model=model,
            predictor_columns=predictor_columns,
            stepwise_options=stepwise_options,
            cases=cases,
            **(dict(option_b or {}) if option == "B" else {}),
        )
        result.warnings += [f"option {option}: {m}" for m in messages]
        frames.append(table)
    table = pd.concat(frames, ignore_index=True)
    path = write_table(table, out, FORECAST)
    result.files.append(path)
    result.tables["forecast"] = table
    n_modes = table["mode"].nunique()
    result.lines.append(
        f"forecast of {n_modes} modes over {table['block'].nunique()} blocks, option(s) "
        f"{'/'.join(options)}, scheme {_SCHEME_NAMES[method_label(scheme)]}, "
        f"train {train_blocks} -> {path}"
    )
    if figures is not None:
        from .reporting.forecast_plot import write_forecast_figures

        result.files += write_forecast_figures(table, figures, truth_modal=truth)
    return result


# --------------------------------------------------------------------------- evaluation
def evaluate_forecast(
    forecast: pd.DataFrame,
    truth: pd.DataFrame,
    *,
    out: str | os.PathLike | None = None,
    phase: str | None = "forecast",
) -> StageResult:
    """Compare SSI-only, model-only and Kalman estimates with the true frequencies.

    The forecast's mode labels come from tracking; they are first paired with the true
    modes (:func:`workbench.sid.tracking.label_agreement` on the SSI estimates), so that
    extra tracked modes (e.g. a shaft harmonic) or a different numbering do not matter.
    """
    from .forecast import evaluate_against_truth
    from .sid.tracking import label_agreement

    measured = forecast.dropna(subset=["ssi_frequency_hz"])
    pseudo = (
        measured[["block", "mode", "ssi_frequency_hz"]]
        .rename(columns={"ssi_frequency_hz": "frequency_hz"})
        .drop_duplicates(["block", "mode"])
    )
    agreement, mapping = label_agreement(pseudo, truth)
    if not mapping:
        raise WorkbenchError("no forecast mode could be paired with a true mode")
    relabelled = forecast[forecast["mode"].isin(mapping)].copy()
    relabelled["mode"] = relabelled["mode"].map(mapping).astype("int64")
    table = evaluate_against_truth(relabelled, truth, phase=phase)
    result = StageResult(tables={"evaluation": table})
    for option, part in table.groupby("option"):
        total = part[
            ["ssi_cumulative_error_hz", "model_cumulative_error_hz", "kalman_cumulative_error_hz"]
        ].sum()
        ssi_error = float(total["ssi_cumulative_error_hz"])
        verdict = (
            f"{100.0 * (1.0 - total['kalman_cumulative_error_hz'] / ssi_error):+.1f} % vs SSI"
            if ssi_error > 0
            else "no gain vs SSI defined (SSI error is zero)"
        )
        result.lines.append(
            f"option {option}: cumulative |error| SSI {ssi_error:.3f} Hz,"
            f" model {total['model_cumulative_error_hz']:.3f} Hz, Kalman "
            f"{total['kalman_cumulative_error_hz']:.3f} Hz -> Kalman {verdict}"
        )
        if ssi_error == 0 and part["n_ssi"].sum() > 0:
            result.warnings.append(
                f"option {option}: the truth equals the SSI estimates on every measured block "
                "(an observed table, not an independent reference): errors measure the model "
                "and the Kalman filter against the measurements, and gains vs SSI are undefined"
            )
    result.lines.append(
        f"tracked labels paired with true modes {mapping} ({100 * agreement:.1f} % of "
        "measured rows agree)"
    )
    if out is not None:
        out = Path(out)
        with atomic_path(out) as tmp:
            if out.suffix.lower() in (".parquet", ".pq"):
                table.to_parquet(tmp, index=False)
            else:
                table.to_csv(tmp, index=False)
        result.files.append(out)
    return result


def write_json(data: Mapping[str, Any], path: str | os.PathLike) -> Path:
    """Write *data* as indented JSON, atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=_json_default), encoding="utf-8")
    return path


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    return str(value)


def read_poles(path: str | os.PathLike) -> pd.DataFrame:
    """A pole table (POLES contract)."""
    return read_table(path, POLES)
