"""Operating profile of the demo voyage and the DSHIP-like ship log it produces.

The true predictors are smooth functions of time at 1 s resolution; the log written to
disk adds sensor noise, rounding, lower rates for some columns, gaps and a faulty
air-temperature sensor.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import atomic_path

__all__ = [
    "CASE_FRACTIONS",
    "OperatingProfile",
    "operating_profile",
    "write_dship_log",
]

#: Operating cases of one profile cycle and their share of the cycle (12 h by default:
#: 2 h stationary, 3 h constant speed, 4 h alternating 0-10 kn, 3 h temperature drift).
CASE_FRACTIONS: tuple[tuple[str, float], ...] = (
    ("stationary", 2 / 12),
    ("constant_speed", 3 / 12),
    ("alternating", 4 / 12),
    ("temperature_drift", 3 / 12),
)

#: Length of one profile cycle; longer voyages repeat it. [h]
CYCLE_HOURS = 12.0
#: Period of the 0-10 kn alternation: 15 min at rest, 5 min ramp, 15 min at speed, 5 min
#: ramp. [s]
ALTERNATION_PERIOD_S = 2400.0
#: Water-temperature rise over a temperature-drift stretch. [°C]
DRIFT_WATER_RISE_C = 3.0
#: Air-temperature rise over a temperature-drift stretch. [°C]
DRIFT_AIR_RISE_C = 2.5
#: Mean speed while breaking ice, and the RMS of the ramming (the ship slows on a floe and
#: speeds up in the broken channel, about every 1.5 min). [kn]
ICE_SPEED_KN = 3.5
ICE_RAMMING_KN = 1.5


@dataclass(frozen=True)
class OperatingProfile:
    """True (noise-free) predictors at 1 s and the operating cases.

    Parameters
    ----------
    predictors : DataFrame
        Columns time (UTC), elapsed_hours, speed_kn, water_temp_c, air_temp_c,
        wind_speed_ms, wind_dir_rel_deg, latitude, longitude; one row per second.
    cases : DataFrame
        Columns case, start, end (UTC): the operating stretches.
    """

    predictors: pd.DataFrame
    cases: pd.DataFrame


def _smooth_noise(rng: np.random.Generator, n: int, correlation_s: float) -> np.ndarray:
    """Unit-variance Gaussian noise smoothed over about *correlation_s* samples (AR(1))."""
    from scipy.signal import lfilter

    coefficient = np.exp(-1.0 / correlation_s)
    drive = rng.standard_normal(n) * np.sqrt(1 - coefficient**2)
    return lfilter([1.0], [1.0, -coefficient], drive, zi=[coefficient * rng.standard_normal()])[0]


def _ramp(t: np.ndarray, start: float, stop: float) -> np.ndarray:
    return np.clip((t - start) / (stop - start), 0.0, 1.0)


def operating_profile(
    start_time: pd.Timestamp,
    hours: float,
    *,
    rng: np.random.Generator,
    ice_hours: float = 0.0,
    ice_rng: np.random.Generator | None = None,
) -> OperatingProfile:
    """Build the true predictors of a voyage of *hours* starting at *start_time*.

    With *ice_hours* > 0 the voyage ends in an ice-breaking stretch of that length (case
    ``ice``, replacing the end of the cycle's cases): speed :data:`ICE_SPEED_KN` with
    ramming of :data:`ICE_RAMMING_KN` RMS (correlation 90 s), drawn from *ice_rng*; the
    other predictors and everything before the stretch are what they are without it.

    Notes
    -----
    The voyage is split into ceil(hours / 12) cycles of equal length, each with the cases
    of :data:`CASE_FRACTIONS` in that order. Speed: ~0.2 kn drift when stationary,
    10 ± 0.3 kn at constant speed, 0 ↔ 8.5-10.5 kn alternation with period 40 min, 7 kn
    during the temperature drift. Water temperature: 2 °C ± 0.3 °C slow wander, rising by
    3 °C over each drift stretch and relaxing afterwards (time constant 1.5 h). Air
    temperature: -2 °C, diurnal ± 2 °C and ± 0.7 °C wander, +2.5 °C over a drift stretch.
    Wind: 8 ± 3 m/s, relative direction wandering. Position: heading 030° from 78° N,
    10° E.
    """
    n_seconds = int(round(hours * 3600))
    t = np.arange(n_seconds, dtype=float)
    n_cycles = max(1, int(np.ceil(hours / CYCLE_HOURS - 1e-9)))
    cycle_s = n_seconds / n_cycles
    bounds = np.cumsum([0.0] + [f for _, f in CASE_FRACTIONS])
    case_rows = []
    speed = np.zeros(n_seconds)
    drift = np.zeros(n_seconds)  # 0..1 shape of the temperature drift, with relaxation
    relax_s = 1.5 * 3600
    for cycle in range(n_cycles):
        origin = cycle * cycle_s
        for (case, _), lo, hi in zip(CASE_FRACTIONS, bounds[:-1], bounds[1:], strict=True):
            a, b = origin + lo * cycle_s, origin + hi * cycle_s
            case_rows.append((case, a, b))
            inside = (t >= a) & (t < b)
            tau = t[inside] - a
            if case == "stationary":
                speed[inside] = 0.0
            elif case == "constant_speed":
                # speed changes are smoothed over 3 min below
                speed[inside] = 10.0
            elif case == "alternating":
                phase = np.mod(tau, ALTERNATION_PERIOD_S) / ALTERNATION_PERIOD_S
                n_period = int(np.ceil((b - a) / ALTERNATION_PERIOD_S)) + 1
                level = rng.uniform(8.5, 10.5, n_period)[(tau // ALTERNATION_PERIOD_S).astype(int)]
                up = np.clip((phase - 0.375) / 0.125, 0, 1)
                down = np.clip((phase - 0.875) / 0.125, 0, 1)
                speed[inside] = level * (up - down)
            else:
                speed[inside] = 7.0
                # drift ramps 0 -> 1 over the stretch, then relaxes exponentially
                drift_end = b
                ramp = _ramp(t, a, drift_end)
                after = t >= drift_end
                contribution = ramp.copy()
                contribution[after] = np.exp(-(t[after] - drift_end) / relax_s)
                drift = np.maximum(drift, contribution)
    # gentle speed changes (about 3 min), small fluctuations at sea, slow drift at rest
    kernel = np.ones(180) / 180.0
    speed = np.convolve(np.pad(speed, (90, 89), mode="edge"), kernel, mode="valid")
    moving = np.clip(speed / 3.0, 0.0, 1.0)
    speed = speed + moving * 0.3 * _smooth_noise(rng, n_seconds, 300.0)
    speed = speed + (1 - moving) * 0.2 * np.abs(_smooth_noise(rng, n_seconds, 900.0))
    speed = np.clip(speed, 0.0, None)
    if ice_hours > 0:
        if not ice_hours < hours:
            raise ValueError(f"ice_hours={ice_hours} must be shorter than the voyage ({hours} h)")
        if ice_rng is None:
            raise ValueError("ice_hours > 0 needs ice_rng")
        ice_start = n_seconds - int(round(ice_hours * 3600))
        inside = t >= ice_start
        ramming = ICE_SPEED_KN + ICE_RAMMING_KN * _smooth_noise(ice_rng, int(inside.sum()), 90.0)
        # the speed eases into the ice over 3 min
        blend = _ramp(t[inside], ice_start, ice_start + 180.0)
        speed[inside] = (1 - blend) * speed[inside] + blend * np.clip(ramming, 0.5, None)
        kept = []
        for case, a, b in case_rows:
            if a < ice_start:
                kept.append((case, a, min(b, float(ice_start))))
        case_rows = [*kept, ("ice", float(ice_start), float(n_seconds))]

    water = 2.0 + 0.3 * _smooth_noise(rng, n_seconds, 5400.0) + DRIFT_WATER_RISE_C * drift
    day = 2 * np.pi * t / 86400.0
    air = (
        -2.0
        + 2.0 * np.sin(day + rng.uniform(0, 2 * np.pi))
        + 0.7 * _smooth_noise(rng, n_seconds, 3600.0)
        + DRIFT_AIR_RISE_C * drift
    )
    wind = np.clip(8.0 + 3.0 * _smooth_noise(rng, n_seconds, 2400.0), 0.3, None)
    wind_dir = np.mod(
        rng.uniform(0, 360) + 60.0 * np.cumsum(_smooth_noise(rng, n_seconds, 1800.0)) / 1800.0, 360
    )
    heading = np.deg2rad(30.0)
    distance_nm = np.cumsum(speed) / 3600.0
    latitude = 78.0 + distance_nm * np.cos(heading) / 60.0
    longitude = 10.0 + distance_nm * np.sin(heading) / (60.0 * np.cos(np.deg2rad(latitude)))

    times = start_time + pd.to_timedelta(t, unit="s")
    predictors = pd.DataFrame(
        {
            "time": times,
            "elapsed_hours": t / 3600.0,
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": air,
            "wind_speed_ms": wind,
            "wind_dir_rel_deg": wind_dir,
            "latitude": latitude,
            "longitude": longitude,
        }
    )
    cases = pd.DataFrame(
        {
            "case": [c for c, _, _ in case_rows],
            "start": [start_time + pd.Timedelta(seconds=round(a)) for _, a, _ in case_rows],
            "end": [start_time + pd.Timedelta(seconds=round(b)) for _, _, b in case_rows],
        }
    )
    return OperatingProfile(predictors, cases)


_HEADER = """/* DATA DESCRIPTION:
Citation:\tworkbench demo voyage, simulated ship log (seed {seed}; synthetic values)
Event(s):\tDEMO-track * LATITUDE: {lat:.5f} * LONGITUDE: {lon:.5f}
Parameter(s):\tDATE/TIME * SHORT_NAME: Date/Time * METHOD/DEVICE: ship data system (1 s rows)
\tLATITUDE * SHORT_NAME: Latitude
\tLONGITUDE * SHORT_NAME: Longitude
\tSpeed, ship * SHORT_NAME: Speed * UNIT: kn
\tTemperature, water * SHORT_NAME: Temp * UNIT: °C * COMMENT: sampled every 60 s
\tTemperature, air * SHORT_NAME: TTT * UNIT: °C * COMMENT: sampled every 60 s
\tWind speed * SHORT_NAME: ff * UNIT: m/s * COMMENT: sampled every 10 s
\tWind direction, relative * SHORT_NAME: RelWindDir * UNIT: deg * COMMENT: sampled every 10 s
{shaft}License:\tCC-BY-4.0
Size:\t{size} data points
*/
"""


def _fmt(values: np.ndarray, decimals: int) -> np.ndarray:
    text = np.char.mod(f"%.{decimals}f", np.round(values, decimals))
    return np.where(np.isfinite(values), text, "")


def write_dship_log(
    profile: OperatingProfile,
    path: str | os.PathLike,
    *,
    rng: np.random.Generator,
    seed: int,
    shaft_rpm: np.ndarray | None = None,
) -> tuple[Path, dict]:
    """Write the ship log of *profile* as a PANGAEA-like tab-separated file.

    Notes
    -----
    One row per second (``Date/Time`` ISO-8601 with seconds, UTC). Latitude, Longitude
    and Speed are logged every second, ff and RelWindDir every 10 s, Temp and TTT every
    60 s; other rows leave those cells empty. Sensor noise: speed 0.1 kn, water 0.02 °C,
    air 0.1 °C, wind 0.4 m/s, direction 4°. Defects: the data system is down for 10 min
    around 55 % of the voyage (no rows), the water-temperature sensor for 40 min around
    35 % (empty cells), wind for 20 min around 80 %; the air-temperature sensor is faulty
    over 20 % of the voyage from 60 % on: 15 % of its readings are spikes of ±(20-35) °C.
    With *shaft_rpm* (one value per second of the profile [rpm]) the log also carries
    ``Shaft speed [rpm]`` every second, rounded to 0.1 rpm.

    Returns
    -------
    path : Path
    defects : dict
        Where the defects are (UTC ISO strings), for the voyage summary.
    """
    path = Path(path)
    frame = profile.predictors
    n = len(frame)
    t = np.rint(frame["elapsed_hours"].to_numpy() * 3600.0).astype(np.int64)  # whole seconds
    total = max(float(n), 1.0)
    speed = frame["speed_kn"].to_numpy() + 0.1 * rng.standard_normal(n)
    speed = np.abs(speed)
    water = frame["water_temp_c"].to_numpy() + 0.02 * rng.standard_normal(n)
    air = frame["air_temp_c"].to_numpy() + 0.1 * rng.standard_normal(n)
    wind = np.abs(frame["wind_speed_ms"].to_numpy() + 0.4 * rng.standard_normal(n))
    wind_dir = np.mod(frame["wind_dir_rel_deg"].to_numpy() + 4.0 * rng.standard_normal(n), 360)
    every10 = np.mod(t, 10) == 0
    every60 = np.mod(t, 60) == 0
    water[~every60] = np.nan
    air[~every60] = np.nan
    wind[~every10] = np.nan
    wind_dir[~every10] = np.nan

    def stretch(fraction: float, seconds: float) -> np.ndarray:
        start = np.floor(fraction * total / 60.0) * 60.0
        return (t >= start) & (t < start + min(seconds, 0.1 * total))

    water_gap = stretch(0.35, 2400)
    wind_gap = stretch(0.80, 1200)
    row_gap = stretch(0.55, 600)
    faulty = (t >= np.floor(0.6 * total)) & (t < np.floor(0.8 * total))
    water[water_gap] = np.nan
    wind[wind_gap] = np.nan
    wind_dir[wind_gap] = np.nan
    spikes = faulty & every60 & (rng.random(n) < 0.15)
    air[spikes] += rng.choice([-1.0, 1.0], spikes.sum()) * rng.uniform(20, 35, spikes.sum())

    keep = ~row_gap
    times = frame["time"][keep].dt.strftime("%Y-%m-%dT%H:%M:%S").to_numpy()
    columns = [
        times,
        _fmt(frame["latitude"].to_numpy()[keep], 5),
        _fmt(frame["longitude"].to_numpy()[keep], 5),
        _fmt(speed[keep], 1),
        _fmt(water[keep], 2),
        _fmt(air[keep], 1),
        _fmt(wind[keep], 1),
        _fmt(wind_dir[keep], 0),
    ]
    names = [
        "Date/Time",
        "Latitude",
        "Longitude",
        "Speed [kn]",
        "Temp [°C]",
        "TTT [°C]",
        "ff [m/s]",
        "RelWindDir [deg]",
    ]
    if shaft_rpm is not None:
        columns.append(_fmt(np.abs(np.asarray(shaft_rpm, dtype=float))[keep], 1))
        names.append("Shaft speed [rpm]")
    header = "\t".join(names)
    lines = ["\t".join(row) for row in zip(*columns, strict=True)]
    first = frame.iloc[0]
    text = (
        _HEADER.format(
            seed=seed,
            lat=first["latitude"],
            lon=first["longitude"],
            size=int(keep.sum()) * (len(names) - 1),
            shaft=""
            if shaft_rpm is None
            else "\tShaft speed * SHORT_NAME: Shaft speed * UNIT: rpm\n",
        )
        + header
        + "\n"
        + "\n".join(lines)
        + "\n"
    )
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="\n") as handle:
        handle.write(text)

    def span(mask: np.ndarray) -> list[str]:
        if not mask.any():
            return []
        chosen = frame["time"][mask]
        return [chosen.iloc[0].isoformat(), (chosen.iloc[-1] + pd.Timedelta(seconds=1)).isoformat()]

    defects = {
        "rows_missing": span(row_gap),
        "water_temp_missing": span(water_gap),
        "wind_missing": span(wind_gap),
        "air_temp_faulty": span(faulty),
        "air_temp_spikes": int(spikes.sum()),
    }
    return path, defects
