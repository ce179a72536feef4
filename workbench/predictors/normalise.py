"""Z-score normalisation of predictors whose parameters are kept for new data."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ._common import PredictorWarning, numeric_columns

__all__ = ["Normaliser"]


def _json_number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@dataclass(frozen=True, eq=False)
class Normaliser:
    """Per-column z-scores :math:`z = (x - \\mu) / \\sigma` with stored :math:`\\mu, \\sigma`.

    Build one with :meth:`fit` on training data; :meth:`transform` then scales any frame
    (new blocks, a forecast period) with the same parameters, :meth:`inverse_transform`
    undoes it, and :meth:`to_dict` / :meth:`from_dict` keep the parameters in JSON.

    Parameters
    ----------
    columns : tuple of str
        The normalised columns.
    mean : tuple of float
        :math:`\\mu` per column (NaN for a column without data).
    std : tuple of float
        :math:`\\sigma` per column (sample standard deviation with *ddof*); 0 for a
        constant column, whose z-scores are 0 by convention.
    ddof : int
        Delta degrees of freedom used by :meth:`fit` (1: sample standard deviation, as
        MATLAB's ``zscore``).

    Examples
    --------
    >>> train = pd.DataFrame({"speed_kn": [0.0, 5.0, 10.0]})
    >>> scaler = Normaliser.fit(train)
    >>> scaler.transform(pd.DataFrame({"speed_kn": [15.0]}))["speed_kn"].item()
    2.0
    """

    columns: tuple[str, ...]
    mean: tuple[float, ...]
    std: tuple[float, ...]
    ddof: int = 1

    def __post_init__(self) -> None:
        if not len(self.columns) == len(self.mean) == len(self.std):
            raise ValueError("columns, mean and std must have the same length")
        if len(set(self.columns)) != len(self.columns):
            raise ValueError("columns must be unique")
        if any(s < 0 for s in self.std if not math.isnan(s)):
            raise ValueError("std must not be negative")

    @classmethod
    def fit(
        cls, frame: pd.DataFrame, *, columns: Sequence[str] | None = None, ddof: int = 1
    ) -> Normaliser:
        """Mean and standard deviation of each column of *frame*, ignoring NaN.

        Parameters
        ----------
        frame : DataFrame
            Training data.
        columns : sequence of str, optional
            Columns to normalise; default every numeric column except ``block``.
        ddof : int
            Delta degrees of freedom of the standard deviation.

        Warns
        -----
        PredictorWarning
            For constant columns (std 0) and columns without data (all NaN).
        """
        if columns is None:
            columns = numeric_columns(frame)
        missing = [c for c in columns if c not in frame.columns]
        if missing:
            raise ValueError(f"columns {', '.join(missing)} are not in the frame")
        values = frame[list(columns)].to_numpy(dtype=float)
        count = np.isfinite(values).sum(axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(values, axis=0) if len(values) else np.full(len(columns), np.nan)
            std = np.where(count > ddof, np.nanstd(values, axis=0, ddof=ddof), np.nan)
        constant = [c for c, s, n in zip(columns, std, count, strict=True) if n > ddof and s == 0]
        empty = [c for c, n in zip(columns, count, strict=True) if n <= ddof]
        if constant:
            warnings.warn(
                f"column(s) {', '.join(constant)} are constant (std 0); their z-scores are 0",
                PredictorWarning,
                stacklevel=2,
            )
        if empty:
            warnings.warn(
                f"column(s) {', '.join(empty)} have too few values to normalise; z-scores NaN",
                PredictorWarning,
                stacklevel=2,
            )
        return cls(
            tuple(str(c) for c in columns),
            tuple(float(m) for m in mean),
            tuple(float(s) for s in std),
            int(ddof),
        )

    def _check(self, frame: pd.DataFrame) -> None:
        missing = [c for c in self.columns if c not in frame.columns]
        if missing:
            raise ValueError(f"frame lacks normalised column(s) {', '.join(missing)}")

    def transform(self, frame: pd.DataFrame) -> pd.DataFrame:
        """A copy of *frame* with the normalised columns as z-scores (others untouched)."""
        self._check(frame)
        out = frame.copy()
        for column, mean, std in zip(self.columns, self.mean, self.std, strict=True):
            values = out[column].to_numpy(dtype=float)
            if std == 0:
                out[column] = np.where(np.isnan(values), np.nan, 0.0)
            else:
                out[column] = (values - mean) / std
        return out

    def inverse_transform(self, frame: pd.DataFrame) -> pd.DataFrame:
        """A copy of *frame* with z-scores turned back into values (:math:`x = \\mu + \\sigma z`)."""
        self._check(frame)
        out = frame.copy()
        for column, mean, std in zip(self.columns, self.mean, self.std, strict=True):
            out[column] = mean + std * out[column].to_numpy(dtype=float)
        return out

    def to_dict(self) -> dict:
        """JSON-ready parameters (NaN as ``None``)."""
        return {
            "columns": list(self.columns),
            "mean": [_json_number(m) for m in self.mean],
            "std": [_json_number(s) for s in self.std],
            "ddof": self.ddof,
        }

    @classmethod
    def from_dict(cls, data: Mapping) -> Normaliser:
        """Rebuild from :meth:`to_dict` output."""
        try:
            return cls(
                tuple(str(c) for c in data["columns"]),
                tuple(math.nan if m is None else float(m) for m in data["mean"]),
                tuple(math.nan if s is None else float(s) for s in data["std"]),
                int(data.get("ddof", 1)),
            )
        except KeyError as error:
            raise ValueError(f"normaliser parameters lack {error.args[0]!r}") from None

    def frame(self) -> pd.DataFrame:
        """Parameters as a table: column, mean, std."""
        return pd.DataFrame({"column": list(self.columns), "mean": self.mean, "std": self.std})
