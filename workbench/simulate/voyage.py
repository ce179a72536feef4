"""The demo voyage: orchestrates profile, ship log, accelerations and tables."""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import (
    MODAL,
    POLES,
    PREDICTORS,
    AccelerationRecord,
    atomic_path,
    shapes_to_frame,
    write_accelerations,
    write_table,
)

from ..blocks import BlockGrid
from .dynamics import (
    ModalState,
    draw_stationary_state,
    simulate_modal_response,
    stationary_covariance,
)
from .hull import CHANNELS, MODE_LAWS, REFERENCE_CONDITIONS, mode_shapes, true_modal_parameters
from .imitation import imitate_identification
from .profile import operating_profile, write_dship_log

__all__ = ["DEFAULT_HOURS", "ShaftHarmonics", "VoyageSummary", "simulate_voyage"]

#: Default voyage length. [h]
DEFAULT_HOURS = 12.0
#: Sampling rate of the accelerometers (default) and of the modal physics' normalisation. [Hz]
SAMPLING_RATE_HZ = 64.0
#: Generator hum written into files sampled fast enough to hold it (above the analysis
#: band; decimating to 64 Hz without an anti-alias filter would fold it to 4 Hz). [Hz]
GENERATOR_HZ = 60.0
#: Its amplitude, larger than any mode's RMS. [m/s²]
GENERATOR_AMPLITUDE_MS2 = 0.03
#: Length of one acceleration file. [s]
FILE_SECONDS = 300
#: Block grid of the truth tables: length and step. [s]
BLOCK_SECONDS = 1200
BLOCK_STEP_SECONDS = 300
#: Voyage start.
START_TIME = pd.Timestamp("2024-03-01T00:00:00Z")
#: Modal acceleration RMS of each mode at 5 kn (0.5 + 0.1 x speed_kn times this). [m/s²]
MODE_RMS_MS2 = np.array([0.020, 0.012, 0.015, 0.008, 0.012, 0.010, 0.008])
#: Sensor noise RMS. [m/s²]
SENSOR_NOISE_MS2 = 0.001
#: Shaft-harmonic amplitude at 10 kn (scales with speed²). [m/s²]
SHAFT_AMPLITUDE_MS2 = 0.008
#: Blade-pass amplitude at 10 kn (scales with speed²). [m/s²]
BLADE_PASS_AMPLITUDE_MS2 = 0.004
#: Noise of the logged shaft speed. [rpm]
SHAFT_RPM_NOISE = 0.2
#: Ice breaking (``ice_hours``): relative frequency drop of each mode at full ice load
#: (floes in contact with the hull add mass and contact stiffness; the lower, global modes
#: feel it less than the local ones). [-]
ICE_FREQUENCY_DROP = np.array([0.010, 0.012, 0.015, 0.015, 0.018, 0.020, 0.020])
#: Correlation time of the ice load (floe after floe). [s]
ICE_LOAD_CORRELATION_S = 240.0
#: Damping ratio increase at full ice load (friction of the floes), as a factor. [-]
ICE_DAMPING_RISE = 0.5
#: Modal excitation in ice over that of open water at the same speed (median), and the
#: file-to-file scatter of its logarithm (intermittent impacts). [-]
ICE_EXCITATION_GAIN = 3.0
ICE_EXCITATION_LOG_STD = 0.5


@dataclass(frozen=True)
class ShaftHarmonics:
    """The shaft line's harmonics in a simulated voyage (fixed-pitch propeller: the shaft
    rate is proportional to the ship's speed).

    Parameters
    ----------
    hz_per_kn : float
        Shaft rate per knot of speed; the shaft turns at 60 x hz_per_kn x speed_kn rpm. [Hz/kn]
    orders : tuple of int
        Shaft orders in the accelerations, each with amplitude
        :data:`SHAFT_AMPLITUDE_MS2` x (speed / 10 kn)². [-]
    blades : int
        Propeller blades: the blade-pass order (blades x shaft rate) is added with
        amplitude :data:`BLADE_PASS_AMPLITUDE_MS2` x (speed / 10 kn)²; 0 leaves it out. [-]
    log_rpm : bool
        Log the shaft speed in the ship log (``Shaft speed [rpm]``, 1 s rows, noise
        :data:`SHAFT_RPM_NOISE`).

    The orders are phase-locked to the shaft (order k has phase k x the shaft's phase)
    and share a stern-heavy shape (propeller pressure pulses and shaft-line forces enter
    at the stern).
    """

    hz_per_kn: float = 0.3
    orders: tuple[int, ...] = (1,)
    blades: int = 5
    log_rpm: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hz_per_kn) and self.hz_per_kn > 0):
            raise ValueError(f"hz_per_kn={self.hz_per_kn} must be a positive rate per knot")
        orders = tuple(int(k) for k in self.orders)
        if any(k < 1 for k in orders) or any(
            k != o for k, o in zip(orders, self.orders, strict=True)
        ):
            raise ValueError(f"orders={self.orders!r} must be whole orders of at least 1")
        object.__setattr__(self, "orders", orders)
        if int(self.blades) != self.blades or self.blades < 0:
            raise ValueError(f"blades={self.blades} must be a whole number of at least 0")

    def components(self) -> list[tuple[float, float]]:
        """(order, amplitude at 10 kn [m/s²]) of every harmonic in the accelerations."""
        out = [(float(k), SHAFT_AMPLITUDE_MS2) for k in self.orders]
        if self.blades:
            out.append((float(self.blades), BLADE_PASS_AMPLITUDE_MS2))
        return out


#: Channels with short NaN dropouts, and the channel that is dead for an hour.
DROPOUT_CHANNELS = ("acc07", "acc15")
DEAD_CHANNEL = "acc12"


@dataclass(frozen=True)
class VoyageSummary:
    """What :func:`simulate_voyage` wrote.

    Parameters
    ----------
    out_dir : Path
    seed : int
    hours : float
        Voyage length. [h]
    start_time, end_time : pandas.Timestamp
        Voyage start and end. [UTC]
    n_blocks : int
        Blocks of the 20-min / 5-min grid in the truth tables.
    acceleration_files : tuple of Path
        5-min ``.npz`` files (empty when accelerations were skipped).
    dship_log, truth_modal, tracked_modal, poles, truth_predictors, cases, summary_json : Path
    """

    out_dir: Path
    seed: int
    hours: float
    start_time: pd.Timestamp
    end_time: pd.Timestamp
    n_blocks: int
    acceleration_files: tuple[Path, ...]
    dship_log: Path
    truth_modal: Path
    tracked_modal: Path
    poles: Path
    truth_predictors: Path
    cases: Path
    summary_json: Path


def _shaft_shape() -> np.ndarray:
    from .hull import SENSORS

    stern = np.array([np.exp(-3.0 * s.position) for s in SENSORS])
    transverse = np.array([s.direction == "transverse" for s in SENSORS])
    shape = np.where(transverse, 0.3 * stern, stern)
    return shape / np.linalg.norm(shape)


def _chunk_means(values: np.ndarray, n_chunks: int, per_chunk: int) -> np.ndarray:
    return values[: n_chunks * per_chunk].reshape(n_chunks, per_chunk, *values.shape[1:]).mean(1)


def _iso(time: pd.Timestamp) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ")


def simulate_voyage(
    out_dir: str | os.PathLike,
    *,
    seed: int = 0,
    hours: float | None = None,
    accelerations: bool = True,
    progress: Callable[[int, int], None] | None = None,
    sampling_rate_hz: float = SAMPLING_RATE_HZ,
    shaft: ShaftHarmonics | None = None,
    ice_hours: float = 0.0,
) -> VoyageSummary:
    """Simulate a demo voyage and write all its files into *out_dir*.

    Parameters
    ----------
    out_dir : path
        Output folder (created).
    seed : int
        Seed; the same seed gives byte-identical files.
    hours : float, optional
        Voyage length, at least 1/3 h, rounded down to whole 5-min files. Default
        :data:`DEFAULT_HOURS` (12 h).
    accelerations : bool
        Write the acceleration files (the slow part); the tables do not depend on it.
    progress : callable, optional
        Called as ``progress(files_done, files_total)`` after each acceleration file.
    sampling_rate_hz : float
        Rate of the acceleration files (a recorder's rate, e.g. 2048), a whole multiple of
        :data:`SAMPLING_RATE_HZ` (64 Hz). [Hz] The physics is the same at every rate: the
        modal forces and the sensor noise keep their power spectral density (their
        per-sample standard deviation grows as the square root of the rate), so the band
        holding the modes looks the same and the files carry broadband content up to the
        Nyquist frequency above it. Files at 160 Hz and faster also carry a generator hum
        at :data:`GENERATOR_HZ` (60 Hz, 30 mm/s²): content above the band that the
        decimation must remove (it would alias to 4 Hz at 64 Hz). Dropout lengths are the
        same in seconds.
    shaft : ShaftHarmonics, optional
        The shaft and blade-pass orders and whether the log carries the shaft speed
        (default :class:`ShaftHarmonics`: order 1 at 0.3 Hz/kn and the blade pass of 5
        blades, shaft speed logged).
    ice_hours : float
        Length of an ice-breaking stretch at the end of the voyage (0: none). [h] Ramming
        at 3.5 ± 1.5 kn (:func:`~workbench.simulate.profile.operating_profile`); the ice
        load l(t) = |AR(1) noise| (correlation :data:`ICE_LOAD_CORRELATION_S`) lowers each
        mode's frequency by :data:`ICE_FREQUENCY_DROP` x l and raises its damping by
        :data:`ICE_DAMPING_RISE` x l; the modal excitation is :data:`ICE_EXCITATION_GAIN`
        times that of open water with a log-normal file-to-file scatter
        (:data:`ICE_EXCITATION_LOG_STD`): strong, broadband and intermittent. The voyage
        then also writes ``truth_files.csv``: the true modal frequencies and damping of
        every 5-min file (the path the identification should follow) and each file's
        excitation level. Random numbers of the ice come from their own stream, so
        ``ice_hours=0`` writes what it wrote before.

    Returns
    -------
    VoyageSummary

    Notes
    -----
    Files written:

    * ``accelerations/acc_YYYYmmddTHHMMSSZ.npz``: 5-min records, 19 channels, 64 Hz [m/s²]:
      response of the 7 modes (:mod:`workbench.simulate.dynamics`, white-noise modal forces
      scaled by 0.5 + 0.1 speed_kn, modal parameters constant within a file at the file
      mean of the law), shaft orders at k x 0.3 Hz/kn x speed (amplitude 8 mm/s² x
      (speed/10 kn)², stern-heavy shape) and the blade pass (4 mm/s² x (speed/10 kn)²;
      :class:`ShaftHarmonics`), sensor noise 1 mm/s², NaN dropouts (short runs
      of 0.5-5 s on acc07 and acc15, acc12 dead for 1 h from 40 % of the voyage).
    * ``dship.tsv``: the ship log (:func:`~workbench.simulate.profile.write_dship_log`).
    * ``truth_predictors.csv`` (PREDICTORS contract, plus ``elapsed_hours``): block means
      of the true predictors (wind direction: circular mean).
    * ``truth_modal.csv`` (MODAL contract): block means of the true modal parameters, true
      shapes.
    * ``tracked_modal.csv`` (MODAL) and ``poles.parquet`` (POLES): imitated identification
      (:func:`~workbench.simulate.imitation.imitate_identification`).
    * ``cases.csv``: case, start, end of the operating stretches.
    * ``voyage.json``: seed, hours, times, files, law coefficients, defect locations.

    Only one 5-min file of accelerations is in memory at a time.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed={seed!r} must be a non-negative integer")
    hours = DEFAULT_HOURS if hours is None else float(hours)
    shaft = ShaftHarmonics() if shaft is None else shaft
    rate = float(sampling_rate_hz)
    multiple = rate / SAMPLING_RATE_HZ
    if not (rate > 0 and multiple >= 1 and abs(multiple - round(multiple)) < 1e-9):
        raise ValueError(
            f"sampling_rate_hz={sampling_rate_hz} must be a whole multiple of "
            f"{SAMPLING_RATE_HZ:g} Hz"
        )
    n_files = int(np.floor(hours * 3600 / FILE_SECONDS + 1e-9))
    if n_files < BLOCK_SECONDS // FILE_SECONDS:
        raise ValueError(f"hours={hours} must be at least {BLOCK_SECONDS / 3600:g} (one block)")
    hours = n_files * FILE_SECONDS / 3600.0
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    streams = np.random.SeedSequence(seed).spawn(6)
    profile_rng, log_rng, force_rng, sensor_rng, tracked_rng, poles_rng = (
        np.random.default_rng(s) for s in streams
    )
    start = START_TIME
    end = start + pd.Timedelta(hours=hours)

    ice_rng = None
    if ice_hours:
        ice_hours = float(ice_hours)
        if not (math.isfinite(ice_hours) and 0 < ice_hours < hours):
            raise ValueError(f"ice_hours={ice_hours} must lie in (0, {hours:g}) h")
        ice_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(8)[7])
    profile = operating_profile(start, hours, rng=profile_rng, ice_hours=ice_hours, ice_rng=ice_rng)
    truth = profile.predictors
    shaft_rpm = None
    if shaft.log_rpm:
        # its own stream: the other log columns stay as they were without the shaft
        rpm_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(7)[6])
        true_rpm = 60.0 * shaft.hz_per_kn * truth["speed_kn"].to_numpy()
        shaft_rpm = true_rpm + SHAFT_RPM_NOISE * rpm_rng.standard_normal(len(true_rpm))
    dship_path, defects = write_dship_log(
        profile, out / "dship.tsv", rng=log_rng, seed=seed, shaft_rpm=shaft_rpm
    )

    # modal parameters: law at 1 s, averaged per 5-min file (constant within a file)
    per_second = true_modal_parameters(truth)
    second_frequency, second_damping = per_second.frequency_hz, per_second.damping_ratio
    file_gain = np.ones(n_files)
    if ice_rng is not None:
        second_frequency, second_damping, file_gain = _ice(
            second_frequency, second_damping, n_files, ice_hours, ice_rng
        )
    file_frequency = _chunk_means(second_frequency, n_files, FILE_SECONDS)
    file_damping = _chunk_means(second_damping, n_files, FILE_SECONDS)
    file_speed = _chunk_means(truth["speed_kn"].to_numpy(), n_files, FILE_SECONDS)

    # block grid and truth tables
    per_block = BLOCK_SECONDS // FILE_SECONDS
    n_blocks = n_files - per_block + 1
    block_ids = np.arange(n_blocks)
    block_start = start + pd.to_timedelta(block_ids * BLOCK_STEP_SECONDS, unit="s")
    blocks = pd.DataFrame(
        {
            "block": block_ids,
            "block_start": block_start,
            "block_end": block_start + pd.Timedelta(seconds=BLOCK_SECONDS),
        }
    )
    window = np.lib.stride_tricks.sliding_window_view
    block_frequency = window(file_frequency, per_block, axis=0).mean(-1)
    block_damping = window(file_damping, per_block, axis=0).mean(-1)
    predictors = _block_predictors(truth, blocks)
    shapes = mode_shapes()
    truth_modal = _modal_frame(blocks, block_frequency, block_damping, shapes)
    speed_seconds = truth["speed_kn"].to_numpy()
    speed_windows = np.array(
        [
            speed_seconds[b * BLOCK_STEP_SECONDS : b * BLOCK_STEP_SECONDS + BLOCK_SECONDS]
            for b in block_ids
        ]
    )
    imitation = imitate_identification(
        blocks,
        block_frequency,
        block_damping,
        shapes,
        CHANNELS,
        speed_windows.mean(axis=1),
        speed_windows.std(axis=1),
        tracked_rng=tracked_rng,
        poles_rng=poles_rng,
    )
    grid = BlockGrid(start, BLOCK_SECONDS, BLOCK_STEP_SECONDS)
    paths = {
        "truth_predictors": write_table(
            predictors, out / "truth_predictors.csv", PREDICTORS, grid=grid
        ),
        "truth_modal": write_table(truth_modal, out / "truth_modal.csv", MODAL, grid=grid),
        "tracked_modal": write_table(
            imitation.tracked, out / "tracked_modal.csv", MODAL, grid=grid
        ),
        "poles": write_table(imitation.poles, out / "poles.parquet", POLES, grid=grid),
    }
    cases = profile.cases.assign(
        start=profile.cases["start"].map(_iso), end=profile.cases["end"].map(_iso)
    )
    with atomic_path(out / "cases.csv") as tmp:
        cases.to_csv(tmp, index=False, lineterminator="\n")
    from data_contracts import SENSOR_GEOMETRY

    from .hull import sensor_geometry

    write_table(sensor_geometry(), out / "sensor_geometry.csv", SENSOR_GEOMETRY)

    dead_start_file = int(np.floor(0.4 * n_files))
    dead_files = max(1, min(12, n_files // 10))
    files: list[Path] = []
    if accelerations:
        files = _write_accelerations(
            out / "accelerations",
            start,
            truth,
            file_frequency,
            file_damping,
            file_speed,
            shapes,
            force_rng,
            sensor_rng,
            (dead_start_file, dead_start_file + dead_files),
            progress,
            rate,
            shaft,
            file_gain,
        )
    if ice_rng is not None:
        paths["truth_files"] = _write_file_truth(
            out / "truth_files.csv", start, file_frequency, file_damping, file_speed, file_gain
        )

    summary = {
        "seed": int(seed),
        "hours": hours,
        "start_time": _iso(start),
        "end_time": _iso(end),
        "sampling_rate_hz": rate,
        "channels": list(CHANNELS),
        "file_seconds": FILE_SECONDS,
        "block_seconds": BLOCK_SECONDS,
        "block_step_seconds": BLOCK_STEP_SECONDS,
        "n_blocks": int(n_blocks),
        "files": {
            "accelerations": [f"accelerations/{p.name}" for p in files],
            "dship_log": "dship.tsv",
            "truth_predictors": "truth_predictors.csv",
            "truth_modal": "truth_modal.csv",
            "tracked_modal": "tracked_modal.csv",
            "poles": "poles.parquet",
            "cases": "cases.csv",
            "sensor_geometry": "sensor_geometry.csv",
        },
        "law": {
            "reference_conditions": REFERENCE_CONDITIONS,
            "modes": [asdict(m) for m in MODE_LAWS],
            "equations": "f = f0 sqrt(k/m); m = 1 + speed_mass*speed_kn/10 - "
            "fuel_mass_per_hour*elapsed_hours; k = 1 + water_stiffness*(water_temp_c - 2) + "
            "air_stiffness*(air_temp_c + 2) + speed_water_stiffness*(speed_kn/10)*"
            "(water_temp_c - 2); zeta = zeta0 (1 + speed_damping*speed_kn/10)",
        },
        "shaft_harmonic_hz_per_kn": shaft.hz_per_kn,
        "shaft": {
            "hz_per_kn": shaft.hz_per_kn,
            "rpm_per_kn": 60.0 * shaft.hz_per_kn,
            "orders": list(shaft.orders),
            "blades": shaft.blades,
            "rpm_logged": shaft.log_rpm,
            "harmonics": [{"order": k, "amplitude_ms2_at_10kn": a} for k, a in shaft.components()],
        },
        "defects": {
            **defects,
            "dead_channel": DEAD_CHANNEL,
            "dead_channel_span": [
                _iso(start + pd.Timedelta(seconds=dead_start_file * FILE_SECONDS)),
                _iso(start + pd.Timedelta(seconds=(dead_start_file + dead_files) * FILE_SECONDS)),
            ],
            "dropout_channels": list(DROPOUT_CHANNELS),
            "mislabelled_blocks": list(imitation.mislabelled_blocks),
            "mislabelled_modes": [3, 4],
            "weak_mode": 4,
            "weak_mode_blocks": list(imitation.weak_mode_blocks),
        },
    }
    if ice_rng is not None:
        summary["ice_hours"] = ice_hours
        summary["files"]["truth_files"] = "truth_files.csv"
    summary_path = out / "voyage.json"
    with atomic_path(summary_path) as tmp:
        tmp.write_text(json.dumps(summary, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return VoyageSummary(
        out_dir=out,
        seed=int(seed),
        hours=hours,
        start_time=start,
        end_time=end,
        n_blocks=int(n_blocks),
        acceleration_files=tuple(files),
        dship_log=dship_path,
        truth_modal=paths["truth_modal"],
        tracked_modal=paths["tracked_modal"],
        poles=paths["poles"],
        truth_predictors=paths["truth_predictors"],
        cases=out / "cases.csv",
        summary_json=summary_path,
    )


def _block_predictors(truth: pd.DataFrame, blocks: pd.DataFrame) -> pd.DataFrame:
    n_blocks = len(blocks)
    window = np.lib.stride_tricks.sliding_window_view
    rows = {}
    for column in ("speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "elapsed_hours"):
        values = truth[column].to_numpy()
        rows[column] = window(values, BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
    angle = np.deg2rad(truth["wind_dir_rel_deg"].to_numpy())
    sin = window(np.sin(angle), BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
    cos = window(np.cos(angle), BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
    rows["wind_dir_rel_deg"] = np.mod(np.rad2deg(np.arctan2(sin, cos)), 360.0)
    frame = blocks.copy()
    for column in (
        "speed_kn",
        "water_temp_c",
        "air_temp_c",
        "wind_speed_ms",
        "wind_dir_rel_deg",
        "elapsed_hours",
    ):
        frame[column] = rows[column]
    return frame


def _modal_frame(blocks, frequency, damping, shapes) -> pd.DataFrame:
    n_blocks, n_modes = frequency.shape
    b = np.repeat(np.arange(n_blocks), n_modes)
    m = np.tile(np.arange(n_modes), n_blocks)
    frame = pd.DataFrame(
        {
            "block": blocks["block"].to_numpy()[b],
            "block_start": blocks["block_start"].to_numpy()[b],
            "block_end": blocks["block_end"].to_numpy()[b],
            "mode": m + 1,
            "frequency_hz": frequency[b, m],
            "damping_ratio": damping[b, m],
        }
    )
    frame["block_start"] = pd.to_datetime(frame["block_start"], utc=True)
    frame["block_end"] = pd.to_datetime(frame["block_end"], utc=True)
    return pd.concat([frame, shapes_to_frame(CHANNELS, shapes[m], index=frame.index)], axis=1)


def _write_accelerations(
    folder: Path,
    start: pd.Timestamp,
    truth: pd.DataFrame,
    file_frequency: np.ndarray,
    file_damping: np.ndarray,
    file_speed: np.ndarray,
    shapes: np.ndarray,
    force_rng: np.random.Generator,
    sensor_rng: np.random.Generator,
    dead_files: tuple[int, int],
    progress,
    rate: float = SAMPLING_RATE_HZ,
    shaft: ShaftHarmonics | None = None,
    file_gain: np.ndarray | None = None,
) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    n_files = len(file_frequency)
    n_samples = int(round(FILE_SECONDS * rate))
    # white noise keeps its spectral density at any rate: per-sample std ~ sqrt(rate)
    density_scale = np.sqrt(rate / SAMPLING_RATE_HZ)
    shaft = ShaftHarmonics() if shaft is None else shaft
    harmonics = shaft.components()
    shaft_shape = _shaft_shape()
    dropout_columns = [CHANNELS.index(c) for c in DROPOUT_CHANNELS]
    dead_column = CHANNELS.index(DEAD_CHANNEL)
    speed_seconds = truth["speed_kn"].to_numpy()
    seconds = np.arange(len(speed_seconds), dtype=float)
    # modal force std giving the target RMS at 5 kn, per unit of (0.5 + 0.1 speed)
    unit_rms = np.sqrt(
        [
            _acceleration_variance(stationary_covariance(f, z, SAMPLING_RATE_HZ)[0], f, z)
            for f, z in zip(file_frequency[0], file_damping[0], strict=True)
        ]
    )
    base_std = MODE_RMS_MS2 / unit_rms * density_scale
    state: ModalState | None = None
    shaft_phase = 0.0
    paths = []
    for k in range(n_files):
        level = 0.5 + 0.1 * file_speed[k]
        if file_gain is not None:
            level = level * file_gain[k]
        if state is None:
            state = draw_stationary_state(
                file_frequency[k],
                file_damping[k],
                rate,
                rng=force_rng,
                excitation_std=base_std * level,
            )
        result = simulate_modal_response(
            file_frequency[k],
            file_damping[k],
            shapes,
            rate,
            n_samples,
            rng=force_rng,
            excitation_std=base_std * level,
            state=state,
        )
        state = result.state
        acceleration = result.response
        # shaft orders and blade pass, phase-locked to the shaft, continuous across files
        t = k * FILE_SECONDS + np.arange(n_samples) / rate
        speed = np.interp(t, seconds, speed_seconds)
        phase = shaft_phase + 2 * np.pi * np.cumsum(shaft.hz_per_kn * speed) / rate
        shaft_phase = float(np.mod(phase[-1], 2 * np.pi))
        speed_level = (speed / 10.0) ** 2
        forced = np.zeros(n_samples)
        for order, amplitude in harmonics:
            forced += amplitude * speed_level * np.sin(order * phase)
        acceleration += forced[:, None] * shaft_shape
        if rate >= 160.0:
            hum = GENERATOR_AMPLITUDE_MS2 * np.sin(2 * np.pi * GENERATOR_HZ * t)
            acceleration += hum[:, None] * shaft_shape
        noise = SENSOR_NOISE_MS2 * density_scale
        acceleration += noise * sensor_rng.standard_normal(acceleration.shape)
        for column, rate_per_file in zip(dropout_columns, (2.0, 1.0), strict=True):
            for _ in range(sensor_rng.poisson(rate_per_file)):
                length = int(round(sensor_rng.integers(32, 321) * rate / SAMPLING_RATE_HZ))
                first = int(sensor_rng.integers(0, n_samples - length))
                acceleration[first : first + length, column] = np.nan
        if dead_files[0] <= k < dead_files[1]:
            acceleration[:, dead_column] = np.nan
        file_start = start + pd.Timedelta(seconds=k * FILE_SECONDS)
        path = folder / f"acc_{file_start.strftime('%Y%m%dT%H%M%SZ')}.npz"
        with warnings.catch_warnings():
            # a dead channel is all-NaN on purpose; the validator's nanmax warns about it
            warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)
            write_accelerations(AccelerationRecord(acceleration, rate, file_start, CHANNELS), path)
        paths.append(path)
        if progress is not None:
            progress(k + 1, n_files)
    return paths


def _ice(frequency, damping, n_files: int, ice_hours: float, rng: np.random.Generator):
    """Per-second frequencies and damping ratios with the ice load of the last *ice_hours*,
    and the excitation gain of every file (see :func:`simulate_voyage`)."""
    from .profile import _smooth_noise

    n_seconds = frequency.shape[0]
    ice_seconds = int(round(ice_hours * 3600))
    load = np.zeros(n_seconds)
    load[n_seconds - ice_seconds :] = np.abs(
        _smooth_noise(rng, ice_seconds, ICE_LOAD_CORRELATION_S)
    )
    frequency = frequency * (1.0 - ICE_FREQUENCY_DROP[None, :] * load[:, None])
    damping = damping * (1.0 + ICE_DAMPING_RISE * load[:, None])
    gain = np.ones(n_files)
    first_ice_file = (n_seconds - ice_seconds) // FILE_SECONDS
    n_ice = n_files - first_ice_file
    gain[first_ice_file:] = ICE_EXCITATION_GAIN * np.exp(
        ICE_EXCITATION_LOG_STD * rng.standard_normal(n_ice)
    )
    return frequency, damping, gain


def _write_file_truth(path: Path, start, frequency, damping, speed, gain) -> Path:
    """``truth_files.csv``: file start and end, mode, true frequency and damping ratio of
    every 5-min file, its mean speed and excitation gain."""
    n_files, n_modes = frequency.shape
    file_start = start + pd.to_timedelta(np.arange(n_files) * FILE_SECONDS, unit="s")
    f = np.repeat(np.arange(n_files), n_modes)
    m = np.tile(np.arange(n_modes), n_files)
    frame = pd.DataFrame(
        {
            "file_start": [_iso(t) for t in file_start[f]],
            "file_end": [_iso(t + pd.Timedelta(seconds=FILE_SECONDS)) for t in file_start[f]],
            "mode": m + 1,
            "frequency_hz": frequency[f, m],
            "damping_ratio": damping[f, m],
            "speed_kn": speed[f],
            "excitation_gain": gain[f],
        }
    )
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, lineterminator="\n")
    return path


def _acceleration_variance(covariance: np.ndarray, frequency_hz: float, damping: float) -> float:
    """Variance of q'' = -ω² q - 2ζω q' + f for unit force variance (see dynamics)."""
    omega = 2 * np.pi * frequency_hz
    c = np.array([-(omega**2), -2 * damping * omega])
    return float(c @ covariance @ c + 1.0)
