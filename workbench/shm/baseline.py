"""A ship's health baseline: the operational model and chart limits of an earlier voyage.

The monitor's own chart needs 12 h to fit the operational model and 6 h more for the
chart's reference before it charts a block (:mod:`workbench.monitor.structural_health`).
A ship that has sailed before has both: ``workbench health --modal --predictors
--train-hours H --save-model FILE`` writes them, with the tracked modes they are about, to
a JSON file (never pickle); ``workbench health --baseline FILE`` and ``workbench monitor
--baseline FILE`` chart every block of a new voyage with them, from the first.

The file (``schema`` :data:`SCHEMA`, ``version`` :data:`VERSION`)::

    {"schema": "workbench.shm.baseline", "version": 1, "created": ISO UTC,
     "source": {"modal": str, "predictors": str, "first_block_start": ISO UTC,
                "last_block_start": ISO UTC},
     "grid": {"step_s": float, "length_s": float|null},
     "channels": [str, ...],
     "modes": [{"mode": int, "frequency_hz": float, "damping_ratio": float,
                "shape_re": [float per channel], "shape_im": [...]}, ...],
     "model": {"terms": [str], "modes": [int], "centre": {column: float},
               "spread": {column: float}, "coefficients": [[float]] (modes x 1+terms),
               "covariance": [[[float]]] (modes x 1+terms x 1+terms),
               "residual_std": [float], "n_used": [int], "train_start_block": int,
               "train_end_block": int, "reference_design": [float] (1+terms)},
     "chart": {"options": {HealthOptions fields}, "reference": {HealthReference fields}}}

``modes`` start the tracker's library (labels kept, :func:`~workbench.sid.tracking.
tracker_for`), so a new voyage's labels mean the earlier voyage's modes; the new voyage's
channels, ship-log columns and tracked modes are checked against the file (a baseline of
another ship is refused with one line naming the file and what differs).

Limitation: the chart's level is the earlier voyage's. Without ``fuel_on_board_t`` in the
log the model has no fuel term; the chart's following baseline (``baseline_hours``)
starts from the earlier reference's level, so a voyage starting with a different fuel
load starts with that offset in its residuals.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_contracts import MODAL, atomic_path, shape_columns, shapes_from_frame, shapes_to_frame

from .chart import HealthReference, HealthResult, health_chart
from .model import OperationalModel, _parse
from .monitor import reference_from_state, reference_state
from .options import HealthOptions

__all__ = ["SCHEMA", "VERSION", "BaselineError", "HealthBaseline"]

SCHEMA = "workbench.shm.baseline"
VERSION = 1
#: Largest relative difference between a mode's median frequency in the baseline and in
#: a new voyage's tracked table for the label to be the same mode (the tracker's
#: ``frequency_tol``). [-]
FREQUENCY_TOL = 0.05


class BaselineError(ValueError):
    """A baseline file that cannot be read or does not fit the data (one line, naming the
    file and the field)."""


@dataclass(frozen=True)
class HealthBaseline:
    """Operational model, chart reference and tracked modes of an earlier voyage.

    Attributes
    ----------
    model : OperationalModel
    reference_design : ndarray, shape (1 + n_terms,)
        Mean design row over the earlier voyage's reference period (x̄_ref of
        :meth:`~workbench.shm.OperationalModel.forecast`).
    options : HealthOptions
        The chart options the reference and limits were learned with.
    reference : HealthReference
    channels : tuple of str
    modes : DataFrame
        One row per tracked mode: ``mode``, ``frequency_hz`` (median), ``damping_ratio``
        (median) and the shape columns of *channels*.
    step_s : float
        Block step of the earlier voyage. [s]
    length_s : float or None
        Block length. [s]
    source : dict
        Where it came from (files, first and last block start).
    created : str
        UTC ISO-8601.
    """

    model: OperationalModel
    reference_design: np.ndarray
    options: HealthOptions
    reference: HealthReference
    channels: tuple[str, ...]
    modes: pd.DataFrame
    step_s: float
    length_s: float | None
    source: dict
    created: str

    # ------------------------------------------------------------------ build
    @classmethod
    def from_chart(
        cls,
        modal: pd.DataFrame,
        predictors: pd.DataFrame,
        model: OperationalModel,
        chart: HealthResult,
        *,
        step_s: float,
        length_s: float | None = None,
        source: dict | None = None,
    ) -> HealthBaseline:
        """The baseline of a fitted *model* and the *chart* learned on its residuals
        (its reference period's predictors give x̄_ref)."""
        modal = MODAL.validate(modal)
        ref = chart.reference
        design = model.reference_design(
            predictors.sort_values("block").reset_index(drop=True),
            ref.start_block,
            ref.end_block - ref.start_block + 1,
        )
        channels, shapes = shapes_from_frame(modal)
        modal = modal.reset_index(drop=True)
        rows = []
        for mode, part in modal.groupby("mode", sort=True):
            # the shape of the block that matched its library mode best
            mac = part["mac"] if "mac" in part.columns else pd.Series(1.0, index=part.index)
            best = int(np.argmax(mac.fillna(0.0).to_numpy(dtype=float)))
            rows.append(
                {
                    "mode": int(mode),
                    "frequency_hz": float(part["frequency_hz"].median()),
                    "damping_ratio": float(part["damping_ratio"].median()),
                    "shape": shapes[part.index[best]],
                }
            )
        modes = _modes_frame(channels, rows)
        source = dict(source or {})
        source.setdefault("first_block_start", _iso(modal["block_start"].min()))
        source.setdefault("last_block_start", _iso(modal["block_start"].max()))
        return cls(
            model=model,
            reference_design=np.asarray(design, dtype=float),
            options=chart.options,
            reference=ref,
            channels=tuple(channels),
            modes=modes,
            step_s=float(step_s),
            length_s=None if length_s is None else float(length_s),
            source=source,
            created=_iso(pd.Timestamp.now(tz="UTC")),
        )

    # ------------------------------------------------------------------ use
    def forecast(self, modal: pd.DataFrame, predictors: pd.DataFrame) -> pd.DataFrame:
        """FORECAST table of the saved model on a new voyage's blocks (every row in the
        'forecast' phase; ``model_shift_std`` about the earlier reference)."""
        return self.model.forecast(
            modal, predictors, reference_design=self.reference_design, same_voyage=False
        )

    def chart(self, forecast: pd.DataFrame) -> HealthResult:
        """The health chart of *forecast* with the saved reference and limits, charting
        from its first block."""
        return health_chart(forecast, self.options, reference=self.reference)

    def check_channels(self, channels, where: str) -> None:
        """Refuse a voyage whose channels are not the baseline's (or a baseline without
        mode shapes, whose modes cannot start a tracker)."""
        if not self.channels:
            raise BaselineError(
                f"{self.path_name}: no mode shapes (saved from a modal table without "
                "shape columns), so its modes cannot be tracked in a new voyage"
            )
        if set(channels) != set(self.channels):
            missing = sorted(set(self.channels) - set(channels))
            extra = sorted(set(channels) - set(self.channels))
            raise BaselineError(
                f"{self.path_name}: channels differ from {where}'s (baseline only: "
                f"{','.join(missing) or '-'}; {where} only: {','.join(extra) or '-'}): a "
                "baseline of another ship or sensor layout"
            )

    def check_predictors(self, predictors: pd.DataFrame, where: str) -> None:
        """Refuse predictors without a column the model's terms need."""
        for term in self.model.terms:
            for column in _parse(term):
                if column not in predictors.columns or not predictors[column].notna().any():
                    raise BaselineError(
                        f"{self.path_name}: model term {term!r} needs column {column!r}, "
                        f"which {where} does not have"
                    )

    def check_modes(self, modal: pd.DataFrame, where: str, *, min_blocks: int = 3) -> None:
        """Refuse a tracked table whose labels are not the baseline's modes: each model
        mode seen in at least *min_blocks* blocks must have its median frequency within
        :data:`FREQUENCY_TOL` of the baseline's, and one of them must be seen."""
        known = self.modes.set_index("mode")["frequency_hz"]
        counts = modal["mode"].value_counts()
        medians = modal.groupby("mode")["frequency_hz"].median()
        seen = [m for m in self.model.modes if counts.get(m, 0) >= min_blocks]
        for mode in seen:
            if abs(medians[mode] / known[mode] - 1.0) > FREQUENCY_TOL:
                raise BaselineError(
                    f"{self.path_name}: mode {mode} is {known[mode]:.3f} Hz in the baseline "
                    f"but {medians[mode]:.3f} Hz in {where}: another ship, or {where} was "
                    "not tracked from the baseline's modes (track --reference-modes / "
                    "monitor --baseline)"
                )
        if not seen and modal["block"].nunique() >= min_blocks:
            raise BaselineError(
                f"{self.path_name}: none of the baseline's modes "
                f"{', '.join(map(str, self.model.modes))} is in {where}"
            )

    @property
    def path_name(self) -> str:
        return str(self.source.get("file", "baseline"))

    # ------------------------------------------------------------------ file
    def to_json(self) -> dict[str, Any]:
        """The file's content as plain JSON types."""
        model = self.model
        _, shapes = shapes_from_frame(self.modes)
        return {
            "schema": SCHEMA,
            "version": VERSION,
            "created": self.created,
            "source": {k: v for k, v in self.source.items() if k != "file"},
            "grid": {"step_s": self.step_s, "length_s": self.length_s},
            "channels": list(self.channels),
            "modes": [
                {
                    "mode": int(row.mode),
                    "frequency_hz": float(row.frequency_hz),
                    "damping_ratio": float(row.damping_ratio),
                    "shape_re": _list(shape.real),
                    "shape_im": _list(shape.imag),
                }
                for row, shape in zip(self.modes.itertuples(), shapes, strict=True)
            ],
            "model": {
                "terms": list(model.terms),
                "modes": [int(m) for m in model.modes],
                "centre": {k: float(v) for k, v in model.centre.items()},
                "spread": {k: float(v) for k, v in model.spread.items()},
                "coefficients": np.asarray(model.coefficients, dtype=float).tolist(),
                "covariance": np.asarray(model.covariance, dtype=float).tolist(),
                "residual_std": _list(model.residual_std),
                "n_used": [int(n) for n in model.n_used],
                "train_start_block": int(model.train_start_block),
                "train_end_block": int(model.train_end_block),
                "reference_design": _list(self.reference_design),
            },
            "chart": {
                "options": dataclasses.asdict(self.options),
                "reference": reference_state(self.reference),
            },
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write the baseline to *path* (JSON), atomically."""
        path = Path(path)
        text = json.dumps(self.to_json(), indent=1, allow_nan=False)
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> HealthBaseline:
        """Read and validate a baseline file.

        Raises
        ------
        BaselineError
            One line naming the file and the first field that is missing or wrong.
        """
        path = Path(path)
        try:
            content = json.loads(path.read_text(encoding="utf-8"))
        except OSError as error:
            raise BaselineError(f"{path}: cannot read ({error.strerror or error})") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as error:
            raise BaselineError(f"{path}: not a JSON file ({error})") from None
        return _Reader(path).baseline(content)


# ---------------------------------------------------------------------- reading
class _Reader:
    """Validates a baseline file's content field by field (errors name the field)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, field: str, problem: str) -> BaselineError:
        return BaselineError(f"{self.path}: field '{field}': {problem}")

    def get(self, obj: Any, key: str, field: str) -> Any:
        if not isinstance(obj, dict):
            raise self.fail(field.rsplit(".", 1)[0], "must be an object")
        if key not in obj:
            raise self.fail(field, "missing")
        return obj[key]

    def number(self, value: Any, field: str, *, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(field, f"must be a number, got {value!r}")
        if not math.isfinite(value) or (positive and value <= 0):
            raise self.fail(field, f"must be a {'positive' if positive else 'finite'} number")
        return float(value)

    def integer(self, value: Any, field: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(field, f"must be an integer, got {value!r}")
        return int(value)

    def array(self, value: Any, field: str, shape: tuple[int, ...], *, nan=False) -> np.ndarray:
        try:
            array = np.array(
                value if not nan else _nan_list(value), dtype=float
            )  # ragged lists raise
        except (TypeError, ValueError):
            raise self.fail(field, "must be an array of numbers") from None
        if array.shape != shape:
            raise self.fail(field, f"shape {array.shape}, expected {shape}")
        if not nan and not np.all(np.isfinite(array)):
            raise self.fail(field, "must be finite numbers")
        return array

    def baseline(self, content: Any) -> HealthBaseline:
        get = self.get
        schema = get(content, "schema", "schema")
        if schema != SCHEMA:
            raise self.fail("schema", f"{schema!r}, expected {SCHEMA!r} (not a health baseline)")
        version = get(content, "version", "version")
        if version != VERSION:
            raise self.fail("version", f"{version!r}; this workbench reads version {VERSION}")
        grid = get(content, "grid", "grid")
        step_s = self.number(get(grid, "step_s", "grid.step_s"), "grid.step_s", positive=True)
        length = get(grid, "length_s", "grid.length_s")
        length_s = None if length is None else self.number(length, "grid.length_s", positive=True)
        channels = get(content, "channels", "channels")
        if (
            not isinstance(channels, list)
            or not all(isinstance(c, str) for c in channels)
            or len(set(channels)) != len(channels)
        ):
            raise self.fail("channels", "must be a list of distinct channel names")
        modes = self.modes(get(content, "modes", "modes"), channels)
        model, design = self.model(get(content, "model", "model"), set(modes["mode"]))
        chart = get(content, "chart", "chart")
        try:
            options = HealthOptions(**get(chart, "options", "chart.options"))
        except (TypeError, ValueError) as error:
            raise self.fail("chart.options", str(error)) from None
        reference = self.reference(get(chart, "reference", "chart.reference"), model.modes)
        source = get(content, "source", "source")
        if not isinstance(source, dict):
            raise self.fail("source", "must be an object")
        created = get(content, "created", "created")
        return HealthBaseline(
            model=model,
            reference_design=design,
            options=options,
            reference=reference,
            channels=tuple(channels),
            modes=modes,
            step_s=step_s,
            length_s=length_s,
            source={**source, "file": str(self.path)},
            created=str(created),
        )

    def modes(self, items: Any, channels: list[str]) -> pd.DataFrame:
        if not isinstance(items, list) or not items:
            raise self.fail("modes", "must be a non-empty list")
        rows = []
        for k, item in enumerate(items):
            at = f"modes[{k}]"
            re = self.array(self.get(item, "shape_re", f"{at}.shape_re"), f"{at}.shape_re",
                            (len(channels),), nan=True)  # fmt: skip
            im = self.array(self.get(item, "shape_im", f"{at}.shape_im"), f"{at}.shape_im",
                            (len(channels),), nan=True)  # fmt: skip
            rows.append(
                {
                    "mode": self.integer(self.get(item, "mode", f"{at}.mode"), f"{at}.mode"),
                    "frequency_hz": self.number(
                        self.get(item, "frequency_hz", f"{at}.frequency_hz"),
                        f"{at}.frequency_hz",
                        positive=True,
                    ),
                    "damping_ratio": self.number(
                        self.get(item, "damping_ratio", f"{at}.damping_ratio"),
                        f"{at}.damping_ratio",
                    ),
                    "shape": re + 1j * im,
                }
            )
        labels = [r["mode"] for r in rows]
        if len(set(labels)) != len(labels):
            raise self.fail("modes", f"labels {labels} are not distinct")
        return _modes_frame(channels, rows)

    def model(self, item: Any, labels: set[int]) -> tuple[OperationalModel, np.ndarray]:
        get = self.get
        terms = get(item, "terms", "model.terms")
        if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
            raise self.fail("model.terms", "must be a list of terms")
        try:
            columns = sorted({c for t in terms for c in _parse(t)})
        except ValueError as error:
            raise self.fail("model.terms", str(error)) from None
        modes = get(item, "modes", "model.modes")
        if not isinstance(modes, list) or not modes:
            raise self.fail("model.modes", "must be a non-empty list of labels")
        modes = [self.integer(m, "model.modes") for m in modes]
        unknown = sorted(set(modes) - labels)
        if unknown:
            raise self.fail("model.modes", f"mode(s) {unknown} are not among 'modes'")
        centre, spread = get(item, "centre", "model.centre"), get(item, "spread", "model.spread")
        for name, values in (("centre", centre), ("spread", spread)):
            if not isinstance(values, dict) or sorted(values) != columns:
                raise self.fail(f"model.{name}", f"must have the terms' columns {columns}")
            for column, value in values.items():
                self.number(value, f"model.{name}.{column}", positive=name == "spread")
        n, k = len(modes), 1 + len(terms)
        model = OperationalModel(
            terms=tuple(terms),
            modes=tuple(modes),
            centre={c: float(v) for c, v in centre.items()},
            spread={c: float(v) for c, v in spread.items()},
            coefficients=self.array(
                get(item, "coefficients", "model.coefficients"), "model.coefficients", (n, k)
            ),
            covariance=self.array(
                get(item, "covariance", "model.covariance"), "model.covariance", (n, k, k)
            ),
            residual_std=self.array(
                get(item, "residual_std", "model.residual_std"), "model.residual_std", (n,)
            ),
            train_start_block=self.integer(
                get(item, "train_start_block", "model.train_start_block"),
                "model.train_start_block",
            ),
            train_end_block=self.integer(
                get(item, "train_end_block", "model.train_end_block"), "model.train_end_block"
            ),
            n_used=self.array(get(item, "n_used", "model.n_used"), "model.n_used", (n,)).astype(
                int
            ),
        )
        design = self.array(
            get(item, "reference_design", "model.reference_design"),
            "model.reference_design",
            (k,),
        )
        return model, design

    def reference(self, item: Any, modes: tuple[int, ...]) -> HealthReference:
        try:
            reference = reference_from_state(item)
        except KeyError as error:
            raise self.fail(f"chart.reference.{error.args[0]}", "missing") from None
        except (TypeError, ValueError, AttributeError) as error:
            raise self.fail("chart.reference", str(error)) from None
        p = len(reference.modes)
        unknown = sorted(set(reference.modes) - set(modes))
        if unknown:
            raise self.fail("chart.reference.modes", f"mode(s) {unknown} are not modelled")
        for name in ("location", "scale", "relative_median", "allowance", "mode_limits"):
            value = getattr(reference, name)
            if value is not None and value.shape != (p,):
                raise self.fail(f"chart.reference.{name}", f"{value.size} values, expected {p}")
        if not (np.all(reference.scale > 0) and math.isfinite(reference.limit)):
            raise self.fail("chart.reference", "scales must be positive and the limit finite")
        return reference


def _modes_frame(channels, rows: list[dict]) -> pd.DataFrame:
    frame = pd.DataFrame([{k: v for k, v in r.items() if k != "shape"} for r in rows])
    shapes = np.array([r["shape"] for r in rows], dtype=complex)
    frame = pd.concat([frame, shapes_to_frame(list(channels), shapes)], axis=1)
    return frame[["mode", "frequency_hz", "damping_ratio", *shape_columns(list(channels))]]


def _list(values) -> list:
    return [None if not math.isfinite(v) else float(v) for v in np.ravel(values)]


def _nan_list(values):
    if isinstance(values, list):
        return [np.nan if v is None else v for v in values]
    return values


def _iso(time) -> str:
    return pd.Timestamp(time).tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%SZ")
