"""Operating cases: label blocks, fit one model per case beside the stitched model.

Relationships between modes and the ship's log need not hold across operating profiles
(a frequency may follow speed under way and not at all at rest, or change its slope in
ice), so models are fitted per operating case as well as on all cases together
("stitched"). Cases come from a table of time ranges (``case,start,end``, as
:func:`~workbench.stats.correlation.read_cases` reads), from a column of the block table,
or are derived from the predictors by a documented rule (:class:`CaseRule`,
:func:`derive_cases`).

* :func:`case_labels` - one case label per block (None outside every case).
* :func:`fit_cases` - :func:`~workbench.stats.fit_modes` per case and stitched, as
  :class:`CaseFits` (``table()`` compares the models, ``summary()`` prints them).
* :func:`case_training_mask` - the hook the sliding forecast calls: the training rows
  of the current case, so that the forecast uses the model of the case it is in.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import PredictorError
from ..predictors.directions import model_columns, with_direction_components
from .correlation import case_masks
from .mode_fits import ModeFit, StatsWarning, coefficient_table, fit_modes

__all__ = [
    "STITCHED",
    "CaseFits",
    "CaseRule",
    "case_labels",
    "case_training_mask",
    "derive_cases",
    "fit_cases",
]

#: Name of the model fitted on every case's blocks together.
STITCHED = "all"


@dataclass(frozen=True)
class CaseRule:
    """Rule that derives operating cases from block predictors (:func:`derive_cases`).

    Parameters
    ----------
    stationary_below_kn : float
        A block with speed below this is ``"stationary"`` (at anchor, on station, drifting
        in ice). [kn]
    speed_bands_kn : tuple of float
        Further speed edges that split the blocks under way into bands, e.g. ``(6.0,)``
        gives ``"open_water_1-6kn"`` and ``"open_water_6+kn"``; empty (default): one case
        ``"open_water"``. [kn]
    ice_water_temp_c : float or None
        A block with water temperature at or below this is ``"ice"``: in ice-covered water
        the surface layer stays within a few tenths of a degree of its freezing point,
        about -1.8 °C for sea water of salinity 33-35 (open polar water is usually warmer
        than -1.5 °C). ``None``: not used. [°C]
    ice_column : str
        Name of an ice-concentration column (fraction 0-1, or percent 0-100); when present
        it decides "ice" instead of the water temperature.
    ice_concentration_min : float
        Concentration from which a block is "ice" (0.15, the WMO ice-edge convention). [-]
    """

    stationary_below_kn: float = 1.0
    speed_bands_kn: tuple[float, ...] = ()
    ice_water_temp_c: float | None = -1.5
    ice_column: str = "ice_concentration"
    ice_concentration_min: float = 0.15

    def __post_init__(self) -> None:
        if not self.stationary_below_kn >= 0:
            raise ValueError(f"stationary_below_kn={self.stationary_below_kn!r} must be >= 0")
        edges = tuple(float(edge) for edge in self.speed_bands_kn)
        if any(e <= self.stationary_below_kn for e in edges) or list(edges) != sorted(set(edges)):
            raise ValueError(
                f"speed_bands_kn={self.speed_bands_kn!r} must increase and lie above "
                f"stationary_below_kn={self.stationary_below_kn:g}"
            )


def _band_name(lower: float, upper: float | None) -> str:
    def text(value: float) -> str:
        return f"{value:g}"

    if upper is None:
        return f"open_water_{text(lower)}+kn"
    return f"open_water_{text(lower)}-{text(upper)}kn"


def derive_cases(predictors: pd.DataFrame, rule: CaseRule | None = None) -> pd.Series:
    """Operating case of each block by *rule* (see :class:`CaseRule`).

    In order: "ice" (ice concentration, or water temperature at or below the ice
    threshold), "stationary" (speed below the threshold), then "open_water" or its speed
    bands. A block whose speed is NaN (and not ice) gets no case (None).

    Parameters
    ----------
    predictors : DataFrame
        Block predictors with ``speed_kn`` (and ``water_temp_c`` or the ice column).

    Returns
    -------
    Series of object
        Case labels on the index of *predictors*, named ``case``.
    """
    rule = rule or CaseRule()
    if "speed_kn" not in predictors.columns:
        raise PredictorError(
            "the predictor table has no column 'speed_kn', which deriving operating cases needs"
        )
    speed = pd.to_numeric(predictors["speed_kn"], errors="coerce").to_numpy(dtype=float)
    labels = np.full(len(predictors), None, dtype=object)
    under_way = speed >= rule.stationary_below_kn
    edges = [rule.stationary_below_kn, *rule.speed_bands_kn]
    if len(edges) == 1:
        labels[under_way] = "open_water"
    else:
        for k, lower in enumerate(edges):
            upper = edges[k + 1] if k + 1 < len(edges) else None
            inside = speed >= lower
            if upper is not None:
                inside &= speed < upper
            labels[inside] = _band_name(lower, upper)
    labels[speed < rule.stationary_below_kn] = "stationary"
    ice = np.zeros(len(predictors), dtype=bool)
    if rule.ice_column in predictors.columns:
        concentration = pd.to_numeric(predictors[rule.ice_column], errors="coerce").to_numpy(
            dtype=float
        )
        finite = concentration[np.isfinite(concentration)]
        if finite.size and finite.max() > 1.0:  # percent
            concentration = concentration / 100.0
        ice = concentration >= rule.ice_concentration_min
    elif rule.ice_water_temp_c is not None and "water_temp_c" in predictors.columns:
        water = pd.to_numeric(predictors["water_temp_c"], errors="coerce").to_numpy(dtype=float)
        ice = water <= rule.ice_water_temp_c
    labels[ice] = "ice"
    return pd.Series(labels, index=predictors.index, name="case", dtype=object)


def case_labels(
    frame: pd.DataFrame,
    cases: str | os.PathLike | pd.DataFrame | CaseRule | None,
) -> pd.Series:
    """One case label per row of the block table *frame* (None outside every case).

    Parameters
    ----------
    frame : DataFrame
        Block table: ``block_start``/``block_end`` for time-range cases, the predictors for
        a derived rule.
    cases : None, "derive", CaseRule, column name, path or DataFrame
        ``None``: every block is in case "all". ``"derive"`` or a :class:`CaseRule`: by
        the rule (:func:`derive_cases`). Otherwise as for
        :func:`~workbench.stats.case_masks`: a column of *frame*, a ``case,start,end`` CSV
        or table (a block belongs to a case when it lies inside one of its ranges; a block
        in two cases takes the first).
    """
    if isinstance(cases, CaseRule) or (isinstance(cases, str) and cases == "derive"):
        rule = cases if isinstance(cases, CaseRule) else None
        return derive_cases(frame, rule)
    labels = np.full(len(frame), None, dtype=object)
    for name, mask in case_masks(frame, cases)[(0 if cases is None else 1) :]:
        free = mask & pd.isna(labels)
        labels[free] = name
    return pd.Series(labels, index=frame.index, name="case", dtype=object)


@dataclass(frozen=True)
class CaseFits:
    """Per-mode stepwise models per operating case and stitched (:func:`fit_cases`).

    Parameters
    ----------
    fits : dict of str -> dict of int -> ModeFit
        ``fits["all"]`` is the stitched model (every case's blocks), then one entry per
        case in order of appearance.
    labels : Series
        Case label of each predictor block (index: block number).
    left_out : dict of str -> str
        Cases (or case/mode pairs) that could not be fitted, with the reason.
    """

    fits: dict[str, dict[int, ModeFit]]
    labels: pd.Series
    left_out: dict[str, str] = field(default_factory=dict)

    @property
    def cases(self) -> list[str]:
        """Case names, the stitched model first."""
        return list(self.fits)

    def table(self) -> pd.DataFrame:
        """One row per (case, mode): formula, n_obs, R², adjusted R², RMSE, F-test p-value,
        Durbin-Watson (within contiguous runs) and the blocks' share of the case."""
        rows = []
        for case, fits in self.fits.items():
            for mode, item in fits.items():
                fit = item.fit
                rows.append(
                    {
                        "case": case,
                        "mode": int(mode),
                        "formula": fit.formula,
                        "n_obs": fit.n_obs,
                        "r_squared": fit.r_squared,
                        "adj_r_squared": fit.adj_r_squared,
                        "rmse": fit.rmse,
                        "f_p_value": fit.f_p_value,
                        "durbin_watson": item.diagnostics.durbin_watson,
                    }
                )
        columns = [
            "case",
            "mode",
            "formula",
            "n_obs",
            "r_squared",
            "adj_r_squared",
            "rmse",
            "f_p_value",
            "durbin_watson",
        ]
        return pd.DataFrame(rows, columns=columns).set_index(["case", "mode"])

    def coefficients(self) -> pd.DataFrame:
        """Coefficients per (case, mode), 0 where a model leaves a term out."""
        tables = {case: coefficient_table(fits) for case, fits in self.fits.items() if fits}
        if not tables:
            return pd.DataFrame()
        return pd.concat(tables, names=["case", "mode"]).fillna(0.0)

    def summary(self) -> str:
        """Per mode, the stitched model beside each case's model (formula, n, R², RMSE)."""
        modes = sorted({m for fits in self.fits.values() for m in fits})
        counts = self.labels.value_counts(dropna=True)
        lines = [
            "Models per operating case (the stitched model uses every case's blocks)",
            "Cases: "
            + ", ".join(f"{case} ({int(counts.get(case, 0))} blocks)" for case in self.cases[1:]),
        ]
        width = max(len(f"{STITCHED} (stitched)"), *(len(c) for c in self.cases))
        for mode in modes:
            lines.append(f"Mode {mode}:")
            for case, fits in self.fits.items():
                name = f"{case} (stitched)" if case == STITCHED else case
                item = fits.get(mode)
                if item is None:
                    reason = self.left_out.get(f"{case}/mode {mode}", "not fitted")
                    lines.append(f"  {name:<{width}}  -- {reason}")
                    continue
                fit = item.fit
                lines.append(
                    f"  {name:<{width}}  n={fit.n_obs:<4d} R²={_fmt(fit.r_squared)} "
                    f"RMSE={fit.rmse:.3g}  {fit.formula}"
                )
        for key, reason in self.left_out.items():
            if "/" not in key:
                lines.append(f"Case {key} left out: {reason}")
        return "\n".join(lines)


def _fmt(value: float) -> str:
    return "  nan" if not math.isfinite(value) else f"{value:.3f}"


def _case_predictors(
    predictors: pd.DataFrame, names: Sequence[str] | None, case: str
) -> tuple[list[str] | None, list[str]]:
    """Predictors usable within one case: constant or all-NaN ones are left out there
    (speed is constant at rest) with a note."""
    if names is None:
        return None, []
    inputs = with_direction_components(predictors)  # a direction as its cosine
    kept, dropped = [], []
    for name in model_columns(names):
        if name not in inputs.columns:  # named in the error of the fit
            kept.append(name)
            continue
        values = pd.to_numeric(inputs[name], errors="coerce").to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if values.size == 0 or np.ptp(values) <= 1e-12 * max(1.0, float(np.abs(values).max())):
            dropped.append(name)
        else:
            kept.append(name)
    return kept, [f"case {case}: predictor {name!r} constant or missing" for name in dropped]


def fit_cases(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    cases,
    *,
    quantity: str = "frequency_hz",
    predictors_used: Sequence[str] | None = None,
    modes: Sequence[int] | None = None,
    min_blocks: int = 10,
    **options,
) -> CaseFits:
    """Fit :func:`~workbench.stats.fit_modes` on every operating case and stitched.

    Parameters
    ----------
    modal, predictors, quantity, predictors_used, modes
        As for :func:`~workbench.stats.fit_modes`.
    cases : "derive", CaseRule, column name, path or DataFrame
        Operating cases (see :func:`case_labels`).
    min_blocks : int
        A case with fewer blocks is reported but not fitted.
    **options
        Passed to :func:`~workbench.stats.fit_modes` and on to the stepwise search.

    Returns
    -------
    CaseFits
        ``fits["all"]``: the stitched models on the union of the cases' blocks; then one
        entry per case. Modes or cases without enough data are left out with a
        :class:`~workbench.stats.StatsWarning` and listed in ``left_out``.
    """
    if cases is None:
        raise ValueError("fit_cases needs cases: 'derive', a rule, a column, a file or a table")
    labels = case_labels(predictors, cases)
    labels.index = predictors["block"].to_numpy()
    present = labels.notna()
    if not present.any():
        raise ValueError("no predictor block falls in any operating case")
    names = [str(c) for c in pd.unique(labels[present])]
    if STITCHED in names:  # its models would replace the stitched ones
        raise ValueError(
            f"the case name {STITCHED!r} is reserved for the stitched cases; rename that case"
        )
    fits: dict[str, dict[int, ModeFit]] = {}
    left_out: dict[str, str] = {}
    options.setdefault("errors", "warn")
    groups = [(STITCHED, present.to_numpy())]
    groups += [(name, (labels == name).to_numpy()) for name in names]
    for case, mask in groups:
        blocks = labels.index[mask]
        if mask.sum() < min_blocks:
            left_out[case] = f"{int(mask.sum())} blocks < min_blocks={min_blocks}"
            warnings.warn(f"case {case}: {left_out[case]}; not fitted", StatsWarning, stacklevel=2)
            continue
        case_predictors = predictors[predictors["block"].isin(blocks)]
        case_modal = modal[modal["block"].isin(blocks)]
        used, notes = _case_predictors(case_predictors, predictors_used, case)
        for note in notes:
            warnings.warn(f"{note}; left out of this case's models", StatsWarning, stacklevel=2)
        if used is not None and not used:
            left_out[case] = "no predictor varies within the case"
            continue
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", StatsWarning)
            try:
                case_fits = fit_modes(
                    case_modal,
                    case_predictors,
                    quantity=quantity,
                    predictors_used=used,
                    modes=modes,
                    **options,
                )
            except ValueError as error:
                case_fits = {}
                left_out[case] = str(error)
        for item in caught:
            message = str(item.message)
            if message.startswith("mode ") and "left out" in message:
                mode = message.split(":")[0]
                left_out[f"{case}/{mode}"] = message.split(": ", 1)[-1].removesuffix(
                    "; mode left out"
                )
            warnings.warn(f"case {case}: {message}", StatsWarning, stacklevel=2)
        fits[case] = case_fits
    if STITCHED not in fits:
        raise ValueError(f"the cases hold too few blocks for a stitched model: {left_out}")
    return CaseFits(fits, labels, left_out)


def case_training_mask(
    labels: Sequence | np.ndarray | None,
    train_rows: slice,
    forecast_row: int,
    min_rows: int,
    valid: np.ndarray | None = None,
) -> np.ndarray | None:
    """Training rows of the current operating case (the sliding forecast's case hook).

    The forecast of a window uses the model of the case its first forecast block is in:
    the window's training rows of that case. When the case has fewer than *min_rows*
    usable rows in the window (a case just entered), the stitched model of the whole
    window is used instead.

    Parameters
    ----------
    labels : sequence or None
        Case label of every row of the forecast grid (None/NaN: no case); None disables
        per-case models.
    train_rows : slice
        The window's training rows ``[w0, w1)``.
    forecast_row : int
        First forecast row; its label is the current case.
    min_rows : int
        Fewest usable training rows for a case model.
    valid : ndarray of bool, optional
        Usable training rows (finite target) within the window.

    Returns
    -------
    ndarray of bool or None
        Mask over the window's training rows, or None for the stitched model (all rows).
    """
    if labels is None:
        return None
    labels = np.asarray(labels, dtype=object)
    current = labels[min(forecast_row, len(labels) - 1)]
    if current is None or (isinstance(current, float) and math.isnan(current)):
        return None
    mask = labels[train_rows] == current
    usable = mask if valid is None else mask & valid
    if int(usable.sum()) < min_rows or mask.all():
        return None
    return mask
