"""Correlate stage: Pearson r of every mode quantity with every predictor, per case."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from data_contracts import MODAL, PREDICTORS

from ..errors import WorkbenchError
from ..results import StageResult, read_any_table, shown_once, write_frame, write_json
from ..sid.presence import persistent_modes
from ..stats.correlation import (
    case_masks,
    correlation_table,
    effective_significance,
    joined_blocks,
    read_cases,
)

__all__ = ["CorrelateOptions", "CorrelateResult", "correlate", "read_correlation"]

#: Files beside correlation.csv that let :func:`read_correlation` rebuild the result.
BLOCKS_FILE, STATE_FILE = "correlation_blocks.parquet", "correlation.json"


@dataclass(frozen=True)
class CorrelateOptions:
    """Options of :func:`correlate`.

    Parameters
    ----------
    alpha : float
        Significance level: a pair is significant when its (adjusted) p-value is below it.
    correction : {None, "holm", "fdr_bh"}
        Multiple-comparison correction of the p-values within each case.
    quantities : sequence of str, optional
        Modal columns correlated; default frequency and damping ratio, frequency only when
        the modal table has no damping (another tool's frequency-only table).
    predictors_used : sequence of str, optional
        Predictor columns; default every numeric predictor column.
    useful_r : float
        A significant pair is *useful* when |r| is at least this.
    min_presence : float
        Only modes measured in at least this share of the blocks are correlated.
    """

    alpha: float = 0.05
    correction: Literal["holm", "fdr_bh"] | None = None
    quantities: tuple[str, ...] | None = None
    predictors_used: tuple[str, ...] | None = None
    useful_r: float = 0.5
    min_presence: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha={self.alpha} must be in (0, 1)")
        if self.correction not in (None, "holm", "fdr_bh"):
            raise ValueError(f"correction={self.correction!r} must be None, 'holm' or 'fdr_bh'")
        if not 0.0 <= self.min_presence <= 1.0:
            raise ValueError(f"min_presence={self.min_presence} must be in [0, 1]")
        if not 0.0 <= self.useful_r <= 1.0:
            raise ValueError(f"useful_r={self.useful_r} must be in [0, 1]")


@dataclass
class CorrelateResult(StageResult):
    """Correlations of the modes with the predictors.

    Attributes
    ----------
    table : DataFrame
        Tidy table, one row per pair and case: x, y, case, r, p_value, p_adjusted, n,
        significant, useful.
    joined : DataFrame
        The block table correlated (index block): predictors and ``mode<k>_<quantity>``.
    mode_columns, predictor_names : list of str
        Mode-quantity and predictor columns of *joined*.
    case_blocks : dict of str -> ndarray of bool
        Rows of *joined* per case (``"all"``: the stitched cases).
    options : CorrelateOptions
    """

    table: pd.DataFrame
    joined: pd.DataFrame
    mode_columns: list[str]
    predictor_names: list[str]
    case_blocks: dict[str, np.ndarray]
    options: CorrelateOptions
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "correlation of modes with predictors"

    @property
    def quantities(self) -> tuple[str, ...]:
        return self.options.quantities or ("frequency_hz", "damping_ratio")

    def pivot(self, value: str = "r", *, case: str = "all") -> pd.DataFrame:
        """*value* (r, p_value, p_adjusted, n) of one case as a y x x matrix."""
        part = self.table[self.table["case"] == case]
        if part.empty:
            raise KeyError(f"no case {case!r}; cases: {list(pd.unique(self.table['case']))}")
        return part.pivot(index="y", columns="x", values=value)

    @property
    def r(self) -> pd.DataFrame:
        """Pearson r of the stitched cases (rows y, columns x)."""
        return self.pivot("r")

    @property
    def pvalues(self) -> pd.DataFrame:
        """Two-sided p-values of the stitched cases (rows y, columns x)."""
        return self.pivot("p_value")

    @property
    def useful(self) -> pd.DataFrame:
        """The useful pairs (significant, |r| large enough), by case and p-value."""
        return self.table[self.table["useful"]].sort_values(["case", "p_value"], kind="stable")

    def effective(self, *, min_blocks: int = 10) -> pd.DataFrame:
        """:attr:`table` with significance that respects autocorrelated (overlapping)
        blocks: ``n_effective``, ``p_effective``, ``significant_effective`` and ``small``
        (fewer than *min_blocks* blocks or N_eff < 5), see
        :func:`workbench.stats.correlation.effective_significance`."""
        return effective_significance(
            self.table,
            self.joined,
            self.case_blocks,
            alpha=self.options.alpha,
            min_blocks=min_blocks,
        )

    @property
    def predictors(self) -> pd.DataFrame:
        """The block predictors correlated (PREDICTORS contract: block, block times and
        the predictor columns), as the run read them."""
        keep = [c for c in ("block_start", "block_end") if c in self.joined.columns]
        return self.joined[keep + list(self.predictor_names)].reset_index()

    def plot(self, quantity: str = "frequency_hz"):
        """corrplot of *quantity* of every mode and the predictors, all cases stitched."""
        from ..reporting.correlation import corrplot_of

        return shown_once(corrplot_of(self, quantity))

    def save(
        self, out_dir: str | os.PathLike, *, figures: bool = True, dpi: int = 110
    ) -> dict[str, Path]:
        """correlation.csv and, with *figures*, the corrplots, the heatmap and
        correlation.html (figures embedded) in *out_dir*; with them the blocks correlated
        and the options (correlation_blocks.parquet, correlation.json), so that
        :func:`read_correlation` (and ``workbench report``) takes this result as it is."""
        if figures:
            from ..reporting.correlation import write_correlation_report

            paths = write_correlation_report(self, out_dir, dpi=dpi)
        else:
            path = Path(out_dir) / "correlation.csv"
            paths = {"csv": write_frame(self.table, path, float_format="%.10g")}
        blocks = self.joined.reset_index()
        paths["blocks"] = write_frame(blocks, Path(out_dir) / BLOCKS_FILE)
        state = {
            "options": {
                "alpha": self.options.alpha,
                "correction": self.options.correction,
                "quantities": list(self.options.quantities or ()) or None,
                "predictors_used": list(self.options.predictors_used or ()) or None,
                "useful_r": self.options.useful_r,
                "min_presence": self.options.min_presence,
            },
            "mode_columns": list(self.mode_columns),
            "predictor_names": list(self.predictor_names),
            "cases": {
                case: [int(b) for b in self.joined.index[np.asarray(mask, dtype=bool)]]
                for case, mask in self.case_blocks.items()
            },
            "lines": list(self.lines),
            "warnings": list(self.warnings),
        }
        paths["state"] = write_json(state, Path(out_dir) / STATE_FILE)
        return paths


def read_correlation(path: str | os.PathLike) -> CorrelateResult:
    """The :class:`CorrelateResult` saved in the folder *path* by :meth:`CorrelateResult.save`
    (correlation.csv, correlation_blocks.parquet, correlation.json), as it was computed.

    Raises
    ------
    WorkbenchError
        A folder without these files, or files that do not belong together (one line
        naming the file).
    """
    import json

    folder = Path(path)
    if folder.is_file():
        folder = folder.parent
    missing = [
        n for n in ("correlation.csv", BLOCKS_FILE, STATE_FILE) if not (folder / n).is_file()
    ]
    if missing:
        raise WorkbenchError(
            f"{folder}: no saved correlation to read ({', '.join(missing)} missing; written "
            "by `workbench correlate` and CorrelateResult.save)"
        )
    try:
        state = json.loads((folder / STATE_FILE).read_text(encoding="utf-8"))
        known = state["options"]
        options = CorrelateOptions(
            alpha=known["alpha"],
            correction=known["correction"],
            quantities=tuple(known["quantities"]) if known["quantities"] else None,
            predictors_used=tuple(known["predictors_used"]) if known["predictors_used"] else None,
            useful_r=known["useful_r"],
            min_presence=known["min_presence"],
        )
        joined = pd.read_parquet(folder / BLOCKS_FILE).set_index("block")
        table = pd.read_csv(folder / "correlation.csv")
        names, mode_columns = list(state["predictor_names"]), list(state["mode_columns"])
        absent = sorted(set(names + mode_columns) - set(joined.columns))
        if absent:
            raise ValueError(f"{BLOCKS_FILE} has no column {absent[0]!r}")
        cases = {
            case: np.isin(joined.index.to_numpy(), np.asarray(blocks, dtype="int64"))
            for case, blocks in state["cases"].items()
        }
    except (OSError, KeyError, TypeError, ValueError) as error:
        raise WorkbenchError(f"{folder / STATE_FILE}: unreadable correlation ({error})") from None
    return CorrelateResult(
        table=table,
        joined=joined,
        mode_columns=mode_columns,
        predictor_names=names,
        case_blocks=cases,
        options=options,
        lines=list(state.get("lines", [])),
        warnings=list(state.get("warnings", [])),
    )


def _cases(cases):
    """A case table from a path (checked), or *cases* as given."""
    if cases is None or isinstance(cases, pd.DataFrame):
        return cases
    if isinstance(cases, str) and not os.path.exists(cases):
        return cases  # a column of the predictors
    try:
        table = read_cases(cases)
    except ValueError as error:
        raise WorkbenchError(str(error).splitlines()[0]) from None
    if (table["case"].str.lower() == "all").any():
        raise WorkbenchError(
            f"{cases}: the case name 'all' is reserved for the stitched cases; rename that case"
        )
    return table


def _voyage_span(joined: pd.DataFrame) -> str:
    """`` (blocks from START to END)`` of a block table with times, else ``""``."""
    if "block_start" not in joined.columns or not len(joined):
        return ""
    start = pd.to_datetime(joined["block_start"], utc=True).min()
    column = "block_end" if "block_end" in joined.columns else "block_start"
    end = pd.to_datetime(joined[column], utc=True).max()
    return f" (blocks from {start:%Y-%m-%dT%H:%MZ} to {end:%Y-%m-%dT%H:%MZ})"


def correlate(
    modal: pd.DataFrame | str | os.PathLike,
    predictors: pd.DataFrame | str | os.PathLike,
    *,
    cases: str | os.PathLike | pd.DataFrame | None = None,
    options: CorrelateOptions | None = None,
) -> CorrelateResult:
    """Pearson correlation and significance of the modes with the predictors.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors (PREDICTORS contract) on the modal table's blocks.
    cases : None, column name, path or DataFrame
        Operating cases (``case,start,end``; see :func:`workbench.stats.correlation.case_masks`).
        Each case is tested separately; ``"all"`` stitches them.
    options : CorrelateOptions, optional
    """
    options = options or CorrelateOptions()
    modal = read_any_table(modal, MODAL, name="modal")
    predictors = read_any_table(predictors, PREDICTORS, name="predictors")
    modal, lines = persistent_modes(modal, options.min_presence)
    if options.quantities is None:
        quantities: Sequence[str] = (
            ("frequency_hz", "damping_ratio")
            if "damping_ratio" in modal.columns and modal["damping_ratio"].notna().any()
            else ("frequency_hz",)
        )
        options = replace(options, quantities=tuple(quantities))
    cases_source = (
        str(cases) if isinstance(cases, str | os.PathLike) and os.path.isfile(cases) else None
    )
    cases = _cases(cases)
    table = correlation_table(
        modal,
        predictors,
        cases=cases,
        alpha=options.alpha,
        correction=options.correction,
        quantities=options.quantities,
        predictors_used=options.predictors_used,
        useful_r=options.useful_r,
    )
    joined, mode_columns, names = joined_blocks(
        modal, predictors, quantities=options.quantities, predictors_used=options.predictors_used
    )
    masks = dict(case_masks(joined.reset_index(), cases))
    empty = [case for case, mask in masks.items() if case != "all" and not mask.any()]
    span = _voyage_span(joined)
    if empty and len(empty) == len(masks) - 1:
        message = (
            f"no case holds a block of the voyage{span} (cases {', '.join(map(repr, empty))}); "
            "check the case times"
        )
        if cases_source is None:
            raise ValueError(message)
        raise WorkbenchError(f"{cases_source}: {message}")
    result = CorrelateResult(
        table=table,
        joined=joined,
        mode_columns=mode_columns,
        predictor_names=names,
        case_blocks=masks,
        options=options,
        lines=list(lines),
    )
    for case in empty:
        result.warnings.append(
            f"case {case!r} holds no block of the voyage{span}: its pairs have n = 0 and are "
            "not tested; check the case times"
        )
    n_useful = int(table["useful"].sum())
    result.lines.append(
        f"correlation of {len(mode_columns)} mode quantities with {len(names)} predictors over "
        f"{len(joined)} blocks, cases {', '.join(masks)}: {n_useful} useful pairs "
        f"(significant at {options.alpha:g}, |r| >= {options.useful_r:g})"
    )
    return result
