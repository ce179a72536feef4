"""Schema machinery: columns with units, table contracts, lazy validation.

A :class:`TableContract` lists its columns (name, kind, unit, bounds, nullability) and
validates a DataFrame *lazily*: every failing column is examined and all problems are
reported together in one :class:`ContractError`. Validation returns a coerced copy
(integers as ``int64``, times as ``datetime64[ns, UTC]``, ...), so every stage downstream
sees the same dtypes whichever file format the table came from.
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

__all__ = [
    "Column",
    "ColumnPattern",
    "ContractError",
    "TableContract",
    "Violation",
    "atomic_path",
]

Kind = Literal["int", "nullable_int", "float", "bool", "time", "str"]

#: pandas < 3 parses CSV floats with a fast approximate parser unless told otherwise;
#: pandas 3 reads them exactly by default (and deprecates the option).
CSV_READ_OPTIONS: dict = (
    {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
)

#: How many row labels a violation message shows before summarising the rest.
_MAX_ROWS_SHOWN = 5


@dataclass(frozen=True)
class Violation:
    """One problem found in a table: which column, which rows, and why."""

    column: str | None
    reason: str
    rows: tuple = ()
    n_rows: int = 0

    def __str__(self) -> str:
        parts = []
        if self.column is not None:
            parts.append(f"column '{self.column}'")
        if self.n_rows:
            shown = ", ".join(str(r) for r in self.rows[:_MAX_ROWS_SHOWN])
            more = self.n_rows - min(self.n_rows, _MAX_ROWS_SHOWN)
            # rows labelled by the reader itself ("line 7") need no "row" prefix
            labelled = all(isinstance(r, str) for r in self.rows)
            label = "" if labelled else ("row " if self.n_rows == 1 else "rows ")
            parts.append(f"{label}{shown}" + (f" (+{more} more)" if more else ""))
        prefix = ", ".join(parts)
        return f"{prefix}: {self.reason}" if prefix else self.reason


class ContractError(ValueError):
    """Data do not satisfy a contract.

    Attributes
    ----------
    violations : list of Violation
        Every problem found, not only the first.
    source : str or None
        File (or other origin) of the data, named in every message line.
    contract : str or None
        Name of the contract that was checked.
    """

    def __init__(
        self,
        violations: Sequence[Violation],
        *,
        source: str | os.PathLike | None = None,
        contract: str | None = None,
    ):
        self.violations = list(violations)
        self.source = None if source is None else str(source)
        self.contract = contract
        super().__init__("\n".join(self.lines()))

    def lines(self) -> list[str]:
        """One self-contained line per violation, prefixed with the source."""
        head = self.source or (f"<{self.contract}>" if self.contract else "<data>")
        return [f"{head}: {violation}" for violation in self.violations]


def _row_labels(index: pd.Index, mask: np.ndarray) -> tuple[tuple, int]:
    labels = index[np.asarray(mask, dtype=bool)]
    return tuple(labels[:_MAX_ROWS_SHOWN].tolist()), len(labels)


@dataclass(frozen=True)
class Column:
    """One column of a contract table.

    Parameters
    ----------
    name : str
        Column name; physical quantities carry their unit (``frequency_hz``).
    kind : {"int", "nullable_int", "float", "bool", "time", "str"}
        Logical type. ``time`` is a tz-aware UTC timestamp.
    description : str
        What the column holds, for the documentation.
    unit : str, optional
        Physical unit, for the documentation (already part of the name).
    required : bool
        Whether the column must be present.
    nullable : bool
        Whether missing values (NaN, NaT, <NA>) are allowed.
    minimum, maximum : float, optional
        Inclusive bounds on the values.
    exclusive_minimum : bool
        The values must lie above *minimum*, not on it (a natural frequency: > 0 Hz).
    allowed : tuple, optional
        Closed set of permitted values.
    hint : str, optional
        Extra advice appended to bound violations (e.g. a likely unit mix-up).
    """

    name: str
    kind: Kind
    description: str = ""
    unit: str | None = None
    required: bool = True
    nullable: bool = False
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    allowed: tuple | None = None
    hint: str = ""


@dataclass(frozen=True)
class ColumnPattern:
    """A family of columns matched by a regular expression (e.g. mode-shape columns)."""

    regex: str
    kind: Kind
    description: str = ""
    nullable: bool = True


def _coerce(series: pd.Series, kind: Kind) -> tuple[pd.Series, np.ndarray]:
    """Coerce *series* to *kind*; return it and a mask of values that could not be parsed."""
    missing_before = series.isna().to_numpy()
    if kind == "float":
        if pd.api.types.is_bool_dtype(series.dtype):
            out = pd.Series(np.full(len(series), np.nan), index=series.index)
            return out, ~missing_before
        out = pd.to_numeric(series, errors="coerce").astype("float64")
    elif kind in ("int", "nullable_int"):
        numeric = pd.to_numeric(series, errors="coerce")
        values = numeric.to_numpy(dtype="float64", na_value=np.nan)
        not_integral = np.isfinite(values) & (np.round(values) != values)
        out = numeric.where(~not_integral).astype("Int64") if len(series) else numeric
        out = pd.Series(out, index=series.index).astype("Int64")
        bad = (out.isna().to_numpy() & ~missing_before) | not_integral
        if kind == "int" and not out.isna().any():
            out = out.astype("int64")
        return out, bad
    elif kind == "bool":
        mapping = {"true": True, "false": False, "1": True, "0": False}
        if pd.api.types.is_bool_dtype(series.dtype):
            out = series.astype("boolean")
        else:
            text = series.astype("string").str.strip().str.lower()
            out = text.map(mapping).astype("boolean")
        bad = out.isna().to_numpy() & ~missing_before
        if not out.isna().any():
            out = out.astype(bool)
        return out, bad
    elif kind == "time":
        if isinstance(series.dtype, pd.DatetimeTZDtype):
            out = series.dt.tz_convert("UTC")
        elif pd.api.types.is_datetime64_dtype(series.dtype):
            out = series.dt.tz_localize("UTC")
        else:
            from .dship_names import complete_times

            out = pd.to_datetime(series, utc=True, errors="coerce", format="ISO8601")
            text = series.map(lambda value: isinstance(value, str)).to_numpy(bool)
            whole = complete_times(series.where(text, "2000-01-01"), "ISO8601")
            out = out.where(whole)  # T00:1 would read as 00:01
        out = out.astype("datetime64[ns, UTC]")
    elif kind == "str":
        out = series.astype("string")
    else:  # pragma: no cover - guarded by Literal
        raise TypeError(f"unknown column kind {kind!r}")
    bad = out.isna().to_numpy() & ~missing_before
    return out, bad


@dataclass(frozen=True)
class TableContract:
    """A table schema: named columns with kinds, units and checks.

    Parameters
    ----------
    name : str
        Short name used in messages and by ``workbench validate KIND``.
    description : str
        One paragraph for the documentation.
    columns : tuple of Column
        Known columns, in canonical order.
    patterns : tuple of ColumnPattern
        Families of additional columns (mode shapes).
    unique : tuple of str
        Columns whose combination identifies a row.
    allow_extra : bool
        Whether columns that are neither listed nor matched are allowed. Extra numeric
        columns are kept untouched.
    checks : tuple of callables
        Table-level checks ``check(df) -> list[Violation]`` run on the coerced frame.
    """

    name: str
    description: str
    columns: tuple[Column, ...]
    patterns: tuple[ColumnPattern, ...] = ()
    unique: tuple[str, ...] = ()
    allow_extra: bool = True
    checks: tuple[Callable[[pd.DataFrame], list[Violation]], ...] = field(default=())

    @property
    def column_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.columns)

    def column(self, name: str) -> Column:
        for column in self.columns:
            if column.name == name:
                return column
        raise KeyError(name)

    def validate(
        self, frame: pd.DataFrame, *, source: str | os.PathLike | None = None
    ) -> pd.DataFrame:
        """Check *frame* against the contract and return a coerced copy.

        Raises
        ------
        ContractError
            Listing every violation found (column, rows, reason).
        """
        if not isinstance(frame, pd.DataFrame):
            raise TypeError(f"{self.name} contract validates a pandas DataFrame, got {type(frame)}")
        problems: list[Violation] = []
        out = frame.copy()
        duplicated = out.columns[out.columns.duplicated()].unique().tolist()
        for name in duplicated:
            problems.append(Violation(str(name), "column appears more than once"))
        if duplicated:
            raise ContractError(problems, source=source, contract=self.name)
        out = out.reset_index(drop=True) if not isinstance(out.index, pd.RangeIndex) else out
        index = out.index
        for column in self.columns:
            if column.name not in out.columns:
                if column.required:
                    problems.append(
                        Violation(column.name, f"required column is missing ({column.description})")
                    )
                continue
            problems.extend(self._check_column(out, column, index))
        matched = set(self.column_names)
        for pattern in self.patterns:
            regex = re.compile(pattern.regex)
            for name in out.columns:
                if isinstance(name, str) and regex.fullmatch(name):
                    matched.add(name)
                    problems.extend(
                        self._check_column(
                            out, Column(name, pattern.kind, nullable=pattern.nullable), index
                        )
                    )
        if not self.allow_extra:
            for name in out.columns:
                if name not in matched:
                    problems.append(Violation(str(name), "column is not part of the contract"))
        present_key = [c for c in self.unique if c in out.columns]
        if present_key and len(present_key) == len(self.unique) and len(out):
            dup = out.duplicated(subset=list(self.unique), keep="first").to_numpy()
            if dup.any():
                rows, n = _row_labels(index, dup)
                key = ", ".join(self.unique)
                problems.append(Violation(key, f"duplicate ({key}) combinations", rows, n))
        if not problems:
            for check in self.checks:
                problems.extend(check(out))
        if problems:
            raise ContractError(problems, source=source, contract=self.name)
        ordered = [c.name for c in self.columns if c.name in out.columns]
        rest = [c for c in out.columns if c not in ordered]
        return out[ordered + rest]

    @staticmethod
    def _check_column(out: pd.DataFrame, column: Column, index: pd.Index) -> list[Violation]:
        problems = []
        coerced, bad = _coerce(out[column.name], column.kind)
        if bad.any():
            rows, n = _row_labels(index, bad)
            problems.append(
                Violation(column.name, f"values cannot be read as {column.kind}", rows, n)
            )
        out[column.name] = coerced
        missing = coerced.isna().to_numpy() & ~bad
        if not column.nullable and missing.any():
            rows, n = _row_labels(index, missing)
            problems.append(Violation(column.name, "missing values are not allowed", rows, n))
        if column.kind in ("int", "nullable_int", "float") and (
            column.minimum is not None or column.maximum is not None
        ):
            values = coerced.to_numpy(dtype="float64", na_value=np.nan)
            with np.errstate(invalid="ignore"):
                low = False
                if column.minimum is not None:
                    low = (
                        values <= column.minimum
                        if column.exclusive_minimum
                        else values < column.minimum
                    )
                high = values > column.maximum if column.maximum is not None else False
            outside = np.asarray(low | high, dtype=bool) & np.isfinite(values)
            infinite = np.isinf(values)
            if outside.any():
                rows, n = _row_labels(index, outside)
                opening = "(" if column.exclusive_minimum else "["
                bounds = f"{opening}{column.minimum}, {column.maximum}]"
                unit = f" {column.unit}" if column.unit else ""
                reason = f"values outside {bounds}{unit}"
                if column.hint:
                    reason += f" ({column.hint})"
                problems.append(Violation(column.name, reason, rows, n))
            if infinite.any():
                rows, n = _row_labels(index, infinite)
                problems.append(Violation(column.name, "infinite values", rows, n))
        if column.allowed is not None:
            present = coerced.notna().to_numpy()
            ok = coerced.isin(list(column.allowed)).to_numpy(dtype=bool, na_value=False)
            wrong = present & ~ok
            if wrong.any():
                rows, n = _row_labels(index, wrong)
                allowed = ", ".join(repr(a) for a in column.allowed)
                problems.append(Violation(column.name, f"values not in {{{allowed}}}", rows, n))
        return problems


@contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside *path*; move it onto *path* only on success.

    Readers never see a half-written file: the final name appears by ``os.replace``, which
    is atomic on POSIX and Windows when both names are on one file system.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{target.name}.",
        suffix=suffix if suffix is not None else ".tmp" + target.suffix,
        dir=target.parent,
    )
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp creates the file readable by its owner only; give it the usual mode
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
