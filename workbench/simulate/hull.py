"""The demo hull: sensor layout, mode shapes and the law linking modal parameters to predictors.

Everything here is fixed (independent of the voyage seed): every simulated voyage is a
voyage of the same ship.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = [
    "CHANNELS",
    "MODE_LAWS",
    "REFERENCE_CONDITIONS",
    "SENSORS",
    "ModalParameters",
    "ModeLaw",
    "Sensor",
    "mode_shapes",
    "sensor_geometry",
    "true_modal_parameters",
]


@dataclass(frozen=True)
class Sensor:
    """One accelerometer on the hull.

    Parameters
    ----------
    channel : str
        Channel name.
    position : float
        Longitudinal position as a fraction of the hull length, 0 = stern, 1 = bow. [-]
    side : float
        Transverse position, +1 port, -1 starboard, 0 centre line (half-breadths). [-]
    height : float
        Height above the keel as a fraction of the depth, 1 = main deck. [-]
    direction : {"vertical", "transverse"}
        Measuring direction.
    """

    channel: str
    position: float
    side: float
    height: float
    direction: str


def _layout() -> tuple[Sensor, ...]:
    rows: list[tuple[float, float, float, str]] = []
    rows += [(x, 1.0, 1.0, "vertical") for x in (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)]  # deck, port
    rows += [(x, -1.0, 1.0, "vertical") for x in (0.1, 0.3, 0.5, 0.7, 0.9)]  # deck, stbd
    rows += [(x, 0.0, 0.1, "vertical") for x in (0.15, 0.5, 0.85)]  # tank top, centre
    rows += [(x, 1.0, 1.0, "transverse") for x in (0.05, 0.35, 0.65, 0.95)]  # deck, port
    rows += [(0.5, 0.0, 0.1, "transverse")]  # tank top, midship
    return tuple(
        Sensor(f"acc{j + 1:02d}", x, side, height, direction)
        for j, (x, side, height, direction) in enumerate(rows)
    )


#: The 19 accelerometers: deck port and starboard and tank top (vertical), deck and tank
#: top (transverse).
SENSORS: tuple[Sensor, ...] = _layout()
#: Channel names acc01 .. acc19.
CHANNELS: tuple[str, ...] = tuple(s.channel for s in SENSORS)

#: Main dimensions of the demo hull (a polar research vessel): length between
#: perpendiculars, breadth and depth. [m]
HULL_LENGTH_M, HULL_BREADTH_M, HULL_DEPTH_M = 118.0, 25.0, 13.6


def sensor_geometry() -> pd.DataFrame:
    """The demo hull's sensor layout as a SENSOR_GEOMETRY table (x forward from the aft
    perpendicular, y to port, z up from the keel; vertical sensors measure +z, transverse
    ones +y). Sensors at the same place share a node."""
    rows, nodes = [], {}
    for sensor in SENSORS:
        place = (
            round(sensor.position * HULL_LENGTH_M, 3),
            round(sensor.side * HULL_BREADTH_M / 2, 3),
            round(sensor.height * HULL_DEPTH_M, 3),
        )
        node = nodes.setdefault(place, f"N{len(nodes) + 1:02d}")
        vertical = sensor.direction == "vertical"
        deck = "main deck" if sensor.height >= 1.0 else "tank top"
        side = {1.0: "port", -1.0: "starboard", 0.0: "centre line"}[sensor.side]
        rows.append(
            {
                "channel": sensor.channel,
                "node": node,
                "x_m": place[0],
                "y_m": place[1],
                "z_m": place[2],
                "direction_x": 0.0,
                "direction_y": 0.0 if vertical else 1.0,
                "direction_z": 1.0 if vertical else 0.0,
                "description": f"{deck}, {side}, {sensor.direction}",
            }
        )
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class ModeLaw:
    """Reference modal parameters of one mode and their sensitivities to the predictors.

    See :func:`true_modal_parameters` for the law these coefficients enter.
    """

    name: str
    frequency_hz: float  #: natural frequency at the reference conditions [Hz]
    damping_ratio: float  #: damping ratio at the reference conditions [-]
    speed_mass: float  #: a_m, added mass per 10 kn [-]
    fuel_mass_per_hour: float  #: b_m, mass lost by fuel burn per hour [1/h]
    water_stiffness: float  #: c_m, stiffness change per °C of water [1/°C]
    air_stiffness: float  #: d_m, stiffness change per °C of air [1/°C]
    speed_water_stiffness: float  #: e_m, interaction, per 10 kn and °C of water [1/°C]
    speed_damping: float  #: g_m, relative damping increase per 10 kn [-]


#: The seven global modes of the demo hull (vertical bending VB, horizontal bending HB,
#: torsion T). Mode 4 (T1) is almost insensitive to speed, mode 3 (VB2) to air temperature,
#: mode 5 (VB3) to water temperature; modes 2, 5 and 7 carry the speed x water interaction.
MODE_LAWS: tuple[ModeLaw, ...] = (
    ModeLaw("VB1", 2.9, 0.012, 0.050, 0.0008, -0.0040, -0.0010, 0.0000, 0.25),
    ModeLaw("HB1", 4.7, 0.008, 0.030, 0.0009, -0.0030, -0.0020, 0.0030, 0.20),
    ModeLaw("VB2", 5.2, 0.015, 0.040, 0.0007, -0.0050, 0.0000, 0.0000, 0.30),
    ModeLaw("T1", 5.4, 0.006, 0.002, 0.0008, -0.0040, -0.0015, 0.0000, 0.15),
    ModeLaw("VB3", 7.1, 0.020, 0.060, 0.0010, -0.0005, -0.0020, 0.0040, 0.20),
    ModeLaw("HB2", 7.6, 0.010, 0.025, 0.0006, -0.0060, -0.0010, 0.0000, 0.25),
    ModeLaw("T2", 8.3, 0.022, 0.035, 0.0008, -0.0030, -0.0025, 0.0020, 0.20),
)

#: Time constant of the fuel burn: the burn rate falls as exp(-t / τ_f). [h]
FUEL_TIME_CONSTANT_H = 240.0

#: Predictor values at which the modes have their reference parameters.
REFERENCE_CONDITIONS: dict[str, float] = {
    "speed_kn": 0.0,
    "water_temp_c": 2.0,
    "air_temp_c": -2.0,
    "elapsed_hours": 0.0,
}


@dataclass(frozen=True)
class ModalParameters:
    """Natural frequencies and damping ratios, one column per mode.

    Unpacks as ``frequency_hz, damping_ratio = true_modal_parameters(...)``.

    Parameters
    ----------
    frequency_hz : ndarray, shape (n, n_modes)
        Natural frequencies. [Hz]
    damping_ratio : ndarray, shape (n, n_modes)
        Damping ratios (fractions). [-]
    """

    frequency_hz: np.ndarray
    damping_ratio: np.ndarray

    def __iter__(self):
        return iter((self.frequency_hz, self.damping_ratio))


def _column(predictors, name: str) -> np.ndarray:
    if isinstance(predictors, pd.DataFrame):
        if name not in predictors.columns:
            raise ValueError(f"predictors has no column '{name}'")
        return predictors[name].to_numpy(dtype=float)
    if isinstance(predictors, Mapping):
        if name not in predictors:
            raise ValueError(f"predictors has no entry '{name}'")
        return np.atleast_1d(np.asarray(predictors[name], dtype=float))
    raise TypeError(f"predictors must be a DataFrame or a mapping, got {type(predictors).__name__}")


def true_modal_parameters(predictors, elapsed_hours=None) -> ModalParameters:
    """Modal parameters of the demo hull under given operating conditions.

    Parameters
    ----------
    predictors : DataFrame or mapping of array_like
        ``speed_kn`` [kn], ``water_temp_c`` [°C], ``air_temp_c`` [°C] and, unless
        *elapsed_hours* is given, ``elapsed_hours`` [h].
    elapsed_hours : array_like, optional
        Time since the start of the voyage (fuel burn). [h]

    Returns
    -------
    ModalParameters
        Frequencies and damping ratios, shape (n, 7).

    Notes
    -----
    With s = speed_kn / 10, ΔT_w = water_temp_c - 2, ΔT_a = air_temp_c + 2, t = elapsed
    hours and the coefficients of :data:`MODE_LAWS` for mode m,

    .. math::

        m_m &= 1 + a_m s - b_m τ_f (1 - e^{-t/τ_f}) \\quad\\text{(speed adds water mass, fuel burn
        removes mass)}

        k_m &= 1 + c_m ΔT_w + d_m ΔT_a + e_m s ΔT_w \\quad\\text{(temperatures soften steel
        and change the water's added stiffness; interaction speed x water)}

        f_m &= f_{0,m} \\sqrt{k_m / m_m}, \\qquad ζ_m = ζ_{0,m} (1 + g_m s).

    At 10 kn the frequencies drop by 0.1-3 %; 3 °C warmer water lowers them by 0.1-1 %; 12 h
    of fuel burn raise them by about 0.5 %. Fuel burn slows as the tanks empty (time constant
    τ_f = :data:`FUEL_TIME_CONSTANT_H`, 10 days), so the mass stays positive on voyages of
    any length (at most 20-25 % is lost, frequencies rise by at most 12-15 %). Wind does not enter the law (a distractor for
    the statistics). The demo hull is invented; the magnitudes are chosen to be visible
    above an identification scatter of 0.2-0.5 %.
    """
    speed = _column(predictors, "speed_kn") / 10.0
    water = _column(predictors, "water_temp_c") - REFERENCE_CONDITIONS["water_temp_c"]
    air = _column(predictors, "air_temp_c") - REFERENCE_CONDITIONS["air_temp_c"]
    if elapsed_hours is None:
        hours = _column(predictors, "elapsed_hours")
    else:
        hours = np.broadcast_to(np.asarray(elapsed_hours, dtype=float), speed.shape)
    law = {
        field: np.array([getattr(m, field) for m in MODE_LAWS])
        for field in ModeLaw.__dataclass_fields__
        if field != "name"
    }
    s, w, a, t = (v[:, None] for v in (speed, water, air, hours))
    burned = FUEL_TIME_CONSTANT_H * (1.0 - np.exp(-t / FUEL_TIME_CONSTANT_H))
    mass = 1.0 + law["speed_mass"] * s - law["fuel_mass_per_hour"] * burned
    stiffness = (
        1.0
        + law["water_stiffness"] * w
        + law["air_stiffness"] * a
        + law["speed_water_stiffness"] * s * w
    )
    frequency = law["frequency_hz"] * np.sqrt(stiffness / mass)
    damping = law["damping_ratio"] * (1.0 + law["speed_damping"] * s)
    return ModalParameters(frequency, damping)


def _free_free_beam(position: np.ndarray, n_nodes: int) -> np.ndarray:
    """Bending mode with *n_nodes* nodes of a free-free uniform beam (Euler-Bernoulli)."""
    beta = {2: 4.730041, 3: 7.853205, 4: 10.995608}[n_nodes]
    sigma = (np.cosh(beta) - np.cos(beta)) / (np.sinh(beta) - np.sin(beta))
    x = beta * position
    return np.cosh(x) + np.cos(x) - sigma * (np.sinh(x) + np.sin(x))


def mode_shapes() -> np.ndarray:
    """Real mode shapes of the seven modes at the 19 sensors, shape (7, 19).

    Vertical bending VB1-VB3 are free-free beam shapes seen by the vertical sensors
    (slightly smaller at the tank top); horizontal bending HB1, HB2 the same seen by the
    transverse sensors; torsion T1, T2 (twist cos(πx), cos(2πx) about an axis at 30 % of
    the depth) moves port and starboard deck in opposite directions and the deck and tank
    top transversely in opposite directions, coupled with some horizontal bending.
    A fixed 3 % perturbation (not seed-dependent) stands in for local flexibility. Each
    shape has unit Euclidean norm and its largest component positive.
    """
    x = np.array([s.position for s in SENSORS])
    side = np.array([s.side for s in SENSORS])
    height = np.array([s.height for s in SENSORS])
    vertical = np.array([s.direction == "vertical" for s in SENSORS])
    transverse = ~vertical
    level = np.where(height > 0.5, 1.0, 0.9)

    def bending_vertical(n_nodes):
        return np.where(vertical, level * _free_free_beam(x, n_nodes), 0.0)

    def bending_horizontal(n_nodes):
        return np.where(transverse, _free_free_beam(x, n_nodes), 0.0)

    def torsion(n_half_waves, coupling):
        twist = np.cos(n_half_waves * np.pi * x)
        lever = np.where(vertical, side, -(height - 0.3))
        return lever * twist + coupling * bending_horizontal(n_half_waves + 1)

    shapes = np.array(
        [
            bending_vertical(2),
            bending_horizontal(2),
            bending_vertical(3),
            torsion(1, 0.3),
            bending_vertical(4),
            bending_horizontal(3),
            torsion(2, 0.2),
        ]
    )
    perturbation = np.random.default_rng(20240301).standard_normal(shapes.shape)
    shapes = shapes + 0.03 * np.abs(shapes).max(axis=1, keepdims=True) * perturbation
    shapes /= np.linalg.norm(shapes, axis=1, keepdims=True)
    sign = np.sign(shapes[np.arange(len(shapes)), np.argmax(np.abs(shapes), axis=1)])
    return shapes * sign[:, None]
