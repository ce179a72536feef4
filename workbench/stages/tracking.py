"""Track stage: the modes selected block by block -> the tracked modal table."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from data_contracts import MODAL, SELECTED, recorded_grid, set_grid

from ..errors import WorkbenchError
from ..results import StageResult, read_any_table, shown_once, table_path, write_frame
from ..sid.tracking import TrackingOptions, track_modes

__all__ = ["TrackResult", "track"]


@dataclass
class TrackResult(StageResult):
    """The tracked modal table (MODAL contract) and what tracking found.

    Attributes
    ----------
    table : DataFrame
        One row per block and tracked mode (MODAL contract).
    n_blocks : int
        Blocks of the selected-modes table.
    poles : DataFrame, optional
        Poles of every model order and block (POLES contract) when tracked from an
        identification (:meth:`IdentifyResult.track`): what :meth:`forecast`
        measures with ``option B``.

    The next stages run on the tracked table: :meth:`predictors` (the ship log onto its
    blocks), :meth:`correlate`, :meth:`fit`, :meth:`forecast`.
    """

    table: pd.DataFrame
    n_blocks: int
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    poles: pd.DataFrame | None = field(default=None, repr=False)
    title = "tracked modes"

    def predictors(
        self,
        dship: str | os.PathLike,
        *,
        dship_mapping: dict[str, str] | None = None,
        all_predictors: bool = False,
    ) -> pd.DataFrame:
        """The ship log *dship* averaged onto the tracked blocks (PREDICTORS contract):
        speed, water and air temperature, wind speed and relative wind direction, or
        every numeric column with *all_predictors* (as ``--dship`` of the commands)."""
        from ..predictors import load_predictors

        return load_predictors(
            dship=dship,
            onto=self.table,
            dship_mapping=dship_mapping,
            all_predictors=all_predictors,
        )

    def correlate(self, predictors: pd.DataFrame, *, cases=None, options=None):
        """:func:`~workbench.stages.correlate` of the tracked modes with *predictors*."""
        from .correlation import correlate

        return correlate(self.table, predictors, cases=cases, options=options)

    def fit(self, predictors: pd.DataFrame, *, cases=None, options=None):
        """:func:`~workbench.stages.fit`: a stepwise model of each tracked mode."""
        from .fitting import fit

        return fit(self.table, predictors, cases=cases, options=options)

    def forecast(
        self, predictors: pd.DataFrame, *, poles=None, cases=None, options=None, progress=False
    ):
        """:func:`~workbench.stages.forecast` of the tracked modes; *poles* default to
        those of the identification they were tracked from."""
        from .forecasting import forecast

        return forecast(
            self.table,
            predictors,
            poles=self.poles if poles is None else poles,
            cases=cases,
            options=options,
            progress=progress,
        )

    @property
    def modes(self) -> pd.DataFrame:
        """Per tracked mode: blocks it was seen in and its median frequency [Hz]."""
        return self.table.groupby("mode").agg(
            blocks=("block", "size"), frequency_hz=("frequency_hz", "median")
        )

    def save(self, out: str | os.PathLike) -> dict[str, Path]:
        """Write the table (``out`` a .csv/.parquet file, or a folder: tracked_modal.csv)."""
        return {"tracked": write_frame(self.table, table_path(out, "tracked_modal.csv"), MODAL)}

    def plot(self, ax=None):
        """Frequency of each tracked mode over the blocks; returns the figure."""
        import matplotlib.pyplot as plt

        drawn_here = ax is None
        if ax is None:
            _, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
        for mode, part in self.table.groupby("mode"):
            ax.plot(part["block"], part["frequency_hz"], ".", ms=3, label=f"mode {mode}")
        ax.set_xlabel("block")
        ax.set_ylabel("frequency [Hz]")
        ax.legend(fontsize=7, ncols=2, loc="best")
        return shown_once(ax.figure) if drawn_here else ax.figure


def track(
    selected: pd.DataFrame | str | os.PathLike,
    *,
    reference_modes: pd.DataFrame | str | os.PathLike | None = None,
    options: TrackingOptions | None = None,
    progress: bool = False,
) -> TrackResult:
    """Follow the modes selected block by block through the voyage.

    Parameters
    ----------
    selected : DataFrame or path
        Selected modes per block (``selected.parquet`` of :func:`identify`).
    reference_modes : DataFrame or path, optional
        A modal table whose modes start the library (their labels are kept), or a health
        baseline file (``.json``, ``workbench health --save-model``): its modes.
    options : TrackingOptions, optional
        Gate, threshold, frequency tolerance... (:class:`~workbench.sid.tracking.TrackingOptions`).
    progress : bool
        Progress bar on stderr.

    Raises
    ------
    WorkbenchError
        When no mode could be tracked.
    """
    source = selected
    selected = read_any_table(selected, SELECTED, name="selected")
    if isinstance(reference_modes, str | os.PathLike) and str(reference_modes).endswith(".json"):
        from ..shm import BaselineError, HealthBaseline

        try:
            baseline = HealthBaseline.load(reference_modes)
            channels = [c[9:] for c in selected.columns if str(c).startswith("shape_re_")]
            baseline.check_channels(channels, str(source))
        except BaselineError as error:
            raise WorkbenchError(str(error)) from None
        reference_modes = baseline.modes
    elif reference_modes is not None:
        reference_modes = read_any_table(reference_modes, MODAL, name="reference modes")
    tracked = track_modes(
        selected,
        options=options or TrackingOptions(),
        reference_modes=reference_modes,
        progress=progress,
    )
    if tracked.empty:
        where = source if not isinstance(source, pd.DataFrame) else "selected modes"
        raise WorkbenchError(f"{where}: no mode could be tracked")
    set_grid(tracked, recorded_grid(selected))
    result = TrackResult(table=tracked, n_blocks=int(selected["block"].nunique()))
    result.lines.append(
        f"{result.modes.shape[0]} modes tracked over {result.n_blocks} blocks: "
        + ", ".join(
            f"{m}: {r.frequency_hz:.3f} Hz ({int(r.blocks)} blocks)"
            for m, r in result.modes.iterrows()
        )
    )
    labels = tracked.attrs.get("harmonic_labels", [])
    harmonic_labels = [h for h in labels if not h.get("unverified")]
    unverified = [h for h in labels if h.get("unverified")]
    if unverified:
        result.lines.append(
            f"{len(unverified)} tracked label(s) seen only where the ship log could not tell "
            "harmonics from modes were left out: "
            + ", ".join(f"{h['frequency_hz']:.3f} Hz ({h['blocks']} blocks)" for h in unverified)
        )
    if harmonic_labels:
        result.lines.append(
            f"{len(harmonic_labels)} tracked label(s) were shaft or blade-pass harmonics, not "
            "modes, and were left out: "
            + ", ".join(
                f"{h['frequency_hz']:.3f} Hz ({h['blocks']} blocks, {100 * h['share']:.0f} % "
                "marked)"
                for h in harmonic_labels
            )
        )
    return result
