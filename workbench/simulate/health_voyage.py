"""Block-level voyages for the structural-health chart: physics, SSI-like errors, damage.

:func:`simulate_health_voyage` builds a voyage at the block level (no accelerations): the
demo hull's modal law (:func:`workbench.simulate.true_modal_parameters`) driven by the
demo operating profile, a stiffness loss on one mode from a chosen time, and identification
errors with the correlation that 75 %-overlapping blocks give. It returns a tracked modal
table and block predictors that :func:`workbench.forecasting.sliding_forecast` takes as they
are, so the health chart can be tested on the real forecast's residuals in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .hull import FUEL_TIME_CONSTANT_H, true_modal_parameters
from .imitation import FREQUENCY_SCATTER
from .profile import operating_profile
from .voyage import START_TIME

__all__ = [
    "HealthVoyage",
    "detection_delay_hours",
    "law_forecast",
    "simulate_health_voyage",
]

#: Block length and step of the demo grid (20 min, 75 % overlap). [s]
BLOCK_SECONDS = 1200
BLOCK_STEP_SECONDS = 300
#: Block length in steps: a block's identification error is the mean of this many
#: independent 5-min segment errors, so errors of blocks k and k+l correlate as 1 - l/4.
SEGMENTS_PER_BLOCK = BLOCK_SECONDS // BLOCK_STEP_SECONDS
#: Fuel burn rate at departure; it falls as exp(-t / τ_f) like the hull law's mass. [t/h]
FUEL_RATE_T_PER_H = 1.2
#: Fuel on board at departure (more than the law's τ_f x rate = 288 t can burn). [t]
FUEL_AT_DEPARTURE_T = 400.0
#: Regime after :func:`simulate_health_voyage`'s ``regime_change_after_hours``: transit
#: towards the ice edge at 11.5-13 kn, water cooling to -1.7 °C (sea-water freezing point)
#: with a 2-h time constant, air cooling by 10 °C with a 4-h time constant. [kn, °C, °C]
TRANSIT_SPEED_KN = 12.25
ICE_WATER_TEMP_C = -1.7
ICE_AIR_COOLING_C = 10.0


@dataclass(frozen=True)
class HealthVoyage:
    """A block-level voyage with ground truth.

    Parameters
    ----------
    modal : DataFrame
        MODAL contract (block, block_start, block_end, mode, frequency_hz, damping_ratio).
    predictors : DataFrame
        PREDICTORS contract (wind block-averaged from the profile, noise-free; the hull
        law ignores wind) with ``fuel_on_board_t`` (tank soundings), plus
        ``elapsed_hours``, as logged (with sensor noise).
    true_frequency_hz : ndarray, shape (n_blocks, n_modes)
        Block-averaged true frequencies, damage included. [Hz]
    damage_time : Timestamp or None
        When the stiffness loss starts (None: no damage).
    damaged_mode : int or None
        Mode (1-based) whose stiffness drops.
    stiffness_loss : float
        Fraction of that mode's stiffness lost (0.015: 1.5 %). [-]
    """

    modal: pd.DataFrame
    predictors: pd.DataFrame
    true_frequency_hz: np.ndarray
    damage_time: pd.Timestamp | None
    damaged_mode: int | None
    stiffness_loss: float


def simulate_health_voyage(
    hours: float,
    *,
    seed: int = 0,
    damaged_mode: int | None = None,
    stiffness_loss: float = 0.0,
    damage_after_hours: float | None = None,
    missing_fraction: float = 0.10,
    outlier_fraction: float = 0.005,
    modes: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7),
    regime_change_after_hours: float | None = None,
    damage_ramp_hours: float = 0.0,
) -> HealthVoyage:
    """Simulate a block-level voyage, optionally with a stiffness loss part-way.

    Parameters
    ----------
    hours : float
        Voyage length. [h]
    seed : int
        Seed of every random draw.
    damaged_mode : int, optional
        Mode (1-based) that loses stiffness.
    stiffness_loss : float
        Fraction of the mode's stiffness lost; its frequency drops by the factor
        sqrt(1 - loss) (about loss / 2). [-]
    damage_after_hours : float, optional
        When the loss appears (a step), hours after the start. [h]
    missing_fraction : float
        Share of (block, mode) estimates missing at random.
    outlier_fraction : float
        Share of estimates replaced by a wrong pole (±2-5 % off).
    modes : tuple of int
        Modes kept in the tables.
    regime_change_after_hours : float, optional
        From this time on the ship leaves its 12-h operating cycle for a transit into
        colder water (:data:`TRANSIT_SPEED_KN`, :data:`ICE_WATER_TEMP_C`,
        :data:`ICE_AIR_COOLING_C`): speed, water and air temperature leave the range seen
        before, and the hull's law follows them (ice loads on the hull are not modelled).
        [h]
    damage_ramp_hours : float
        0: the loss is a step at the onset; otherwise it grows linearly from the onset to
        its full size over this time (a crack that grows). [h]

    Notes
    -----
    Identification error of mode m in block k: e = f_m (u_k + ... + u_{k+3}) / 4 with u
    independent N(0, (2 s_m)²) per 5-min segment and s_m the demo's relative scatter
    (:data:`~workbench.simulate.imitation.FREQUENCY_SCATTER`, 0.2-0.5 %), so each
    block has relative scatter s_m and neighbouring blocks, sharing 15 of their 20 minutes,
    correlate 0.75, 0.50, 0.25 at lags 1, 2, 3 blocks. A block partly after the damage
    sees the block average of the step. Logged predictors add white noise (speed 0.1 kn,
    temperatures 0.05 °C, fuel 0.3 % of the fuel burned + 0.05 t). ``fuel_on_board_t`` is
    :data:`FUEL_AT_DEPARTURE_T` minus the fuel burned, :data:`FUEL_RATE_T_PER_H` τ_f
    (1 - e^{-t/τ_f}), the mass loss the hull law sees; ``elapsed_hours`` is kept for models
    that use time as the fuel proxy.
    """
    if damaged_mode is not None and damaged_mode not in modes:
        raise ValueError(f"damaged_mode={damaged_mode} is not one of modes={modes}")
    if not 0.0 <= stiffness_loss < 1.0:
        raise ValueError(f"stiffness_loss={stiffness_loss!r} must be in [0, 1)")
    rng = np.random.default_rng(seed)
    profile = operating_profile(START_TIME, hours, rng=rng).predictors
    if regime_change_after_hours is not None:
        profile = _regime_change(profile, regime_change_after_hours * 3600.0, rng)
    n_seconds = len(profile)
    n_blocks = (n_seconds - BLOCK_SECONDS) // BLOCK_STEP_SECONDS + 1
    starts = np.arange(n_blocks) * BLOCK_STEP_SECONDS
    columns = ("speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "elapsed_hours")
    window = np.lib.stride_tricks.sliding_window_view
    truth = {
        c: window(profile[c].to_numpy(), BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
        for c in columns
    }
    direction = np.radians(profile["wind_dir_rel_deg"].to_numpy())
    wind_sin, wind_cos = (
        window(f(direction), BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
        for f in (np.sin, np.cos)
    )
    frequency = true_modal_parameters(truth).frequency_hz[:, [m - 1 for m in modes]]
    damping = true_modal_parameters(truth).damping_ratio[:, [m - 1 for m in modes]]
    damage_time = None
    if damaged_mode is not None and stiffness_loss > 0 and damage_after_hours is not None:
        onset_s = damage_after_hours * 3600.0
        damage_time = START_TIME + pd.Timedelta(seconds=onset_s)
        if damage_ramp_hours > 0:  # block mean of the ramp, from its 1-s values
            seconds = np.arange(n_seconds, dtype=float)
            ramp = np.clip((seconds - onset_s) / (3600.0 * damage_ramp_hours), 0.0, 1.0)
            share_after = window(ramp, BLOCK_SECONDS)[::BLOCK_STEP_SECONDS][:n_blocks].mean(-1)
        else:  # the share of the block after the step
            share_after = np.clip((starts + BLOCK_SECONDS - onset_s) / BLOCK_SECONDS, 0.0, 1.0)
        factor = 1.0 - share_after * (1.0 - np.sqrt(1.0 - stiffness_loss))
        frequency[:, modes.index(damaged_mode)] *= factor
    scatter = FREQUENCY_SCATTER[[m - 1 for m in modes]]
    segments = rng.standard_normal((n_blocks + SEGMENTS_PER_BLOCK - 1, len(modes)))
    segments *= 2.0 * scatter
    relative_error = window(segments, SEGMENTS_PER_BLOCK, axis=0).mean(-1)
    measured = frequency * (1.0 + relative_error)
    wrong = rng.random(measured.shape) < outlier_fraction
    offset = rng.uniform(0.02, 0.05, measured.shape) * rng.choice([-1.0, 1.0], measured.shape)
    measured = np.where(wrong, frequency * (1.0 + offset), measured)
    missing = rng.random(measured.shape) < missing_fraction

    tau = FUEL_TIME_CONSTANT_H
    fuel = FUEL_RATE_T_PER_H * tau * (1.0 - np.exp(-truth["elapsed_hours"] / tau))
    block_start = START_TIME + pd.to_timedelta(starts, unit="s")
    block_end = block_start + pd.Timedelta(seconds=BLOCK_SECONDS)
    predictors = pd.DataFrame(
        {
            "block": np.arange(n_blocks),
            "block_start": block_start,
            "block_end": block_end,
            "speed_kn": np.clip(truth["speed_kn"] + 0.1 * rng.standard_normal(n_blocks), 0, None),
            "water_temp_c": truth["water_temp_c"] + 0.05 * rng.standard_normal(n_blocks),
            "air_temp_c": truth["air_temp_c"] + 0.05 * rng.standard_normal(n_blocks),
            "wind_speed_ms": truth["wind_speed_ms"],
            "wind_dir_rel_deg": np.mod(np.degrees(np.arctan2(wind_sin, wind_cos)), 360.0),
            "elapsed_hours": truth["elapsed_hours"],
            "fuel_on_board_t": FUEL_AT_DEPARTURE_T
            - fuel * (1.0 + 0.003 * rng.standard_normal(n_blocks))
            - 0.05 * rng.standard_normal(n_blocks),
        }
    )
    rows, cols = np.nonzero(~missing)
    modal = pd.DataFrame(
        {
            "block": rows,
            "block_start": block_start[rows],
            "block_end": block_end[rows],
            "mode": np.asarray(modes)[cols],
            "frequency_hz": measured[rows, cols],
            "damping_ratio": damping[rows, cols],
        }
    )
    return HealthVoyage(
        modal=modal,
        predictors=predictors,
        true_frequency_hz=frequency,
        damage_time=damage_time,
        damaged_mode=damaged_mode if damage_time is not None else None,
        stiffness_loss=float(stiffness_loss) if damage_time is not None else 0.0,
    )


def _regime_change(profile: pd.DataFrame, onset_s: float, rng: np.random.Generator) -> pd.DataFrame:
    """The 1-s profile with the transit regime from *onset_s* on (see the constants)."""
    from .profile import _smooth_noise

    t = profile["elapsed_hours"].to_numpy() * 3600.0
    after = np.clip(t - onset_s, 0.0, None)
    ramp = np.clip(after / 1800.0, 0.0, 1.0)  # 30 min to reach transit speed
    transit = TRANSIT_SPEED_KN + 0.5 * _smooth_noise(rng, len(t), 1800.0)
    out = profile.copy()
    out["speed_kn"] = (1 - ramp) * profile["speed_kn"] + ramp * transit
    water0 = float(np.interp(onset_s, t, profile["water_temp_c"]))
    cool = 1.0 - np.exp(-after / 7200.0)
    out["water_temp_c"] = np.where(
        t >= onset_s, water0 + (ICE_WATER_TEMP_C - water0) * cool, profile["water_temp_c"]
    )
    out["air_temp_c"] = profile["air_temp_c"] - ICE_AIR_COOLING_C * (1.0 - np.exp(-after / 14400.0))
    return out


def detection_delay_hours(voyage: HealthVoyage, health: pd.DataFrame) -> float:
    """Hours from the damage onset to the end of the first alarming block at or after it.

    The end of the block (start + 20 min) is when its data were complete, so this is the
    delay a monitor fed in real time would show. ``inf`` when no alarm follows the onset.
    """
    if voyage.damage_time is None:
        raise ValueError("voyage has no damage")
    block_end = health["block_start"] + pd.Timedelta(seconds=BLOCK_SECONDS)
    after = health["alarm"].to_numpy(dtype=bool) & (block_end > voyage.damage_time).to_numpy()
    if not after.any():
        return math.inf
    first = block_end[after].iloc[0]
    return (first - voyage.damage_time).total_seconds() / 3600.0


def law_forecast(voyage: HealthVoyage) -> pd.DataFrame:
    """FORECAST table whose model is the hull's own law evaluated at the logged predictors.

    The operational/environmental model is then as good as a model can be: its error comes
    only from the log's noise. The 95 % bounds are ±1.96 s_m f with s_m the identification
    scatter of :data:`~workbench.simulate.imitation.FREQUENCY_SCATTER`. This separates
    what the chart does from how well a regression model extrapolates
    (:func:`workbench.shm.frozen_forecast`).
    """
    modes = tuple(sorted(voyage.modal["mode"].unique().tolist()))
    columns = [m - 1 for m in modes]
    law = true_modal_parameters(voyage.predictors).frequency_hz[:, columns]
    half = 1.959964 * FREQUENCY_SCATTER[columns] * law
    n_blocks, n_modes = law.shape
    measured = np.full((n_blocks, n_modes), np.nan)
    row = voyage.modal["block"].to_numpy()
    col = np.searchsorted(modes, voyage.modal["mode"].to_numpy())
    measured[row, col] = voyage.modal["frequency_hz"].to_numpy()
    block = np.repeat(np.arange(n_blocks), n_modes)
    return pd.DataFrame(
        {
            "block": block,
            "block_start": voyage.predictors["block_start"].to_numpy()[block],
            "mode": np.tile(modes, n_blocks),
            "phase": "forecast",
            "ssi_frequency_hz": measured.ravel(),
            "model_frequency_hz": law.ravel(),
            "model_lower_hz": (law - half).ravel(),
            "model_upper_hz": (law + half).ravel(),
            "kalman_frequency_hz": law.ravel(),
            "kalman_std_hz": (half / 1.959964).ravel(),
            "option": "A",
            "window_start_block": 0,
            "window_end_block": 0,
        }
    )
