"""One pass over a run's acceleration files for the report's signal views: channel
moments per chunk, spectra per operating case, the spectrogram of the first singular value,
and the singular values of one block's spectral matrix."""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import read_accelerations

log = logging.getLogger("workbench.reporting.report")


@dataclass
class SignalSummary:
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
    layout: dict | None = None


def segment_length(rate: float) -> int:
    return int(2 ** np.round(np.log2(max(rate * 8.0, 64.0))))


def _csd(chunk: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch cross-spectral matrix (Hann, 50 % overlap) of a chunk; NaN channels as zero."""
    from scipy.signal import get_window

    n = min(segment_length(rate), len(chunk))
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


def signal_pass(
    files: Sequence[Path],
    cases: pd.DataFrame | None,
    band_hz: tuple[float, float] | None = None,
    *,
    max_files: int = 720,
    max_chunks: int = 600,
    layout=None,
    skipped: list[str] | None = None,
) -> SignalSummary | None:
    """One pass over the acceleration files: per-chunk channel moments, the first singular
    value of each chunk's spectral matrix (spectrogram) and the mean spectral matrix of each
    operating case (its singular values).

    Long runs are read at *max_files* files spread evenly over the run; chunks are sized so
    that about *max_chunks* of them cover it (at least two spectral segments each). The
    files are read with *layout* (:class:`~data_contracts.formats.AccelerationLayout` or
    its fields), the one identification used; a file that cannot be read is skipped, its
    reason appended to *skipped* when given.
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
    skipped = [] if skipped is None else skipped
    layout = dict(layout) if layout else None
    for path in files:
        try:
            record = read_accelerations(path, layout=layout)
        except Exception as error:  # a bad file is reported by identify; skip it here
            reason = str(error).splitlines()[0] if str(error) else type(error).__name__
            log.warning("report: %s skipped (%s)", path, reason)
            skipped.append(reason)
            continue
        if rate is None:
            rate, channels = record.sampling_rate_hz, record.channels
            segment = segment_length(rate)
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
            if len(chunk) < min(per_chunk, segment_length(rate)):
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
    return SignalSummary(
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
        layout=layout,
    )


def block_singular_values(signal: SignalSummary, start: pd.Timestamp, length_s: float):
    """Singular values of the spectral matrix of one block's data (its files, cut)."""
    end = start + pd.Timedelta(seconds=length_s)
    parts = []
    for file_start, file_end, path in signal.files:
        if file_end <= start or file_start >= end:
            continue
        record = read_accelerations(path, layout=signal.layout)
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
