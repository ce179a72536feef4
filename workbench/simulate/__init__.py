"""Demo voyage simulator with ground truth (``workbench simulate``).

A hull with seven global modes (2.9, 4.7, 5.2, 5.4, 7.1, 7.6, 8.3 Hz at the reference
conditions; damping 0.6-2.2 %), 19 accelerometers acc01..acc19 at 64 Hz, and a ship log.
Deterministic for a given seed.

The law of the modal parameters (:func:`true_modal_parameters`, coefficients in
:data:`MODE_LAWS`): with s = speed_kn / 10, ΔT_w = water_temp_c - 2 °C,
ΔT_a = air_temp_c + 2 °C and t = hours since the voyage start,

    m_m = 1 + a_m s - b_m t                              (added water mass; fuel burn)
    k_m = 1 + c_m ΔT_w + d_m ΔT_a + e_m s ΔT_w           (temperatures; speed x water)
    f_m = f0_m sqrt(k_m / m_m),    ζ_m = ζ0_m (1 + g_m s)

=====  =====  =====  ======  ======  =======  =======  ======  =====
mode   f0     ζ0     a       b [1/h] c [1/°C] d [1/°C] e [1/°C] g
=====  =====  =====  ======  ======  =======  =======  ======  =====
1 VB1  2.9    0.012  0.050   0.0008  -0.0040  -0.0010  0       0.25
2 HB1  4.7    0.008  0.030   0.0009  -0.0030  -0.0020  0.0030  0.20
3 VB2  5.2    0.015  0.040   0.0007  -0.0050  0        0       0.30
4 T1   5.4    0.006  0.002   0.0008  -0.0040  -0.0015  0       0.15
5 VB3  7.1    0.020  0.060   0.0010  -0.0005  -0.0020  0.0040  0.20
6 HB2  7.6    0.010  0.025   0.0006  -0.0060  -0.0010  0       0.25
7 T2   8.3    0.022  0.035   0.0008  -0.0030  -0.0025  0.0020  0.20
=====  =====  =====  ======  ======  =======  =======  ======  =====

Speed at 10 kn lowers the frequencies by 0.1 % (mode 4, nearly insensitive) to 3 %;
3 °C warmer water by 0.1-1 %; 12 h of fuel burn raise them by ~0.5 %; wind has no
effect. The TRUE (smooth) predictors drive the law; the ship log adds noise and defects.

Operating profile (per 12-h cycle, scaled to ``hours`` and repeated for longer voyages):
stationary 2 h, constant speed (10 kn) 3 h, alternating 0 ↔ ~10 kn (40-min period) 4 h,
temperature drift (7 kn, water +3 °C, air +2.5 °C) 3 h.

The shaft line (:class:`ShaftHarmonics`): order 1 of the shaft rate (0.3 Hz/kn x speed,
3 Hz at 10 kn) and the blade pass of a 5-bladed propeller sweep with speed through the
band of the modes; the ship log carries the shaft speed (``Shaft speed [rpm]``).

Entry point: :func:`simulate_voyage`. Outputs are described there.

The simulators, one module each: :mod:`.dynamics` (random vibration of the modes by
modal superposition, exact ZOH discretisation), :mod:`.voyage` (the demo voyage's
acceleration files, ship log and true tables), :mod:`.prescribed` (records of structures with
prescribed modes: close pairs, weakly excited modes), :mod:`.imitation` (the tracked
modal table and poles identification would produce, with documented imperfections), :mod:`.health_voyage` (block-level voyages with a stiffness loss, for
the health chart: :func:`simulate_health_voyage`).
"""

from typing import TYPE_CHECKING

from .._lazy import attach

#: Public names and the module defining each, imported on first use (PEP 562): the command
#: line's defaults read :mod:`.voyage` alone, not every simulation.
_EXPORTS = {
    "HealthVoyage": ".health_voyage",
    "detection_delay_hours": ".health_voyage",
    "law_forecast": ".health_voyage",
    "simulate_health_voyage": ".health_voyage",
    "CHANNELS": ".hull",
    "MODE_LAWS": ".hull",
    "REFERENCE_CONDITIONS": ".hull",
    "SENSORS": ".hull",
    "ModalParameters": ".hull",
    "ModeLaw": ".hull",
    "mode_shapes": ".hull",
    "true_modal_parameters": ".hull",
    "IdentificationImitation": ".imitation",
    "imitate_identification": ".imitation",
    "CASE_FRACTIONS": ".profile",
    "OperatingProfile": ".profile",
    "operating_profile": ".profile",
    "write_dship_log": ".profile",
    "DEFAULT_HOURS": ".voyage",
    "SAMPLING_RATE_HZ": ".voyage",
    "START_TIME": ".voyage",
    "ShaftHarmonics": ".voyage",
    "VoyageSummary": ".voyage",
    "simulate_voyage": ".voyage",
}

if TYPE_CHECKING:
    from .health_voyage import (
        HealthVoyage,
        detection_delay_hours,
        law_forecast,
        simulate_health_voyage,
    )
    from .hull import (
        CHANNELS,
        MODE_LAWS,
        REFERENCE_CONDITIONS,
        SENSORS,
        ModalParameters,
        ModeLaw,
        mode_shapes,
        true_modal_parameters,
    )
    from .imitation import IdentificationImitation, imitate_identification
    from .profile import CASE_FRACTIONS, OperatingProfile, operating_profile, write_dship_log
    from .voyage import (
        DEFAULT_HOURS,
        SAMPLING_RATE_HZ,
        START_TIME,
        ShaftHarmonics,
        VoyageSummary,
        simulate_voyage,
    )


__getattr__, __dir__ = attach(__name__, _EXPORTS, globals())


__all__ = [
    "CASE_FRACTIONS",
    "CHANNELS",
    "DEFAULT_HOURS",
    "MODE_LAWS",
    "REFERENCE_CONDITIONS",
    "SAMPLING_RATE_HZ",
    "SENSORS",
    "START_TIME",
    "ShaftHarmonics",
    "HealthVoyage",
    "IdentificationImitation",
    "ModalParameters",
    "ModeLaw",
    "OperatingProfile",
    "VoyageSummary",
    "detection_delay_hours",
    "imitate_identification",
    "law_forecast",
    "mode_shapes",
    "operating_profile",
    "simulate_health_voyage",
    "simulate_voyage",
    "true_modal_parameters",
    "write_dship_log",
]
