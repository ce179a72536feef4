"""Block-level voyage regimes for the forecast accuracy suite (``bench_forecast_accuracy.py``).

Each regime is a ship's operating profile at 1-minute resolution (speed, water and air
temperature, wind), turned into block-level tables the forecast stage reads: the block
predictors (20-minute blocks, a new one every 5 minutes), the true modal frequencies, a
tracked modal table (option A's measurements) and a pole table (stabilisation diagrams,
option B's measurements), with or without mode shapes.

The frequencies follow the demo hull's law (:func:`workbench.simulate.hull.true_modal_parameters`:
added mass of water with speed, temperature-dependent stiffness, speed x water interaction,
fuel burn) for four of its modes. What SSI "measures" is built to behave like real SSI
errors rather than white noise:

* *excitation weighting*: a block's identified frequency is the frequency averaged with the
  block's excitation power (which grows with speed squared; impulsive in ice), not the time
  average that is the block's truth, so a block in which the speed changes is biased
  towards its faster part;
* *correlated errors*: 75 %-overlapping blocks share most of their data, so the
  identification error is correlated from block to block, with a size that varies from
  block to block (log-normal, larger when the speed changes inside the block, 2.5x larger
  and heavy-tailed, Student t with 3 degrees of freedom, in ice). Two generators
  (*error_model*): ``"ar1"`` (the suite's original, used for every record before issue 27's
  second round) draws it AR(1) with lag-1 correlation 0.65, so it still correlates beyond
  the overlap (0.65^4 = 0.18 at lag 4); ``"segments"`` follows the physics of overlapping
  blocks: a 20-minute block with a new block every 5 minutes is made of four 5-minute
  segments with independent errors, and its error is their mean (to first order), an MA(3)
  with correlations 3/4, 2/4, 1/4 and exactly zero from lag 4;
* *stabilisation diagrams*: each mode is a column of poles over the model orders 10-60,
  scattered about the block's identified value by an amount that follows the block's error
  size (imperfectly); noise poles at random orders; a propeller blade-rate harmonic that
  sweeps through the band with speed (very lightly damped, stable over many orders); in
  ice, extra short stable columns from ice impacts;
* *tracking errors*: the tracked pole is one pole of the column (a random order of the
  upper half), occasionally (1.5 %, 4 % in ice) a noise pole near the mode instead;
  estimates missing at random (12 %) and in runs (blocks where the mode is not excited;
  long runs of 10-40 blocks in ice).

Nothing here knows the forecast method; the regimes were written before the method was
changed (see the issue-11 report for the before/after table).

*Halves* (optional, ``make_regime(..., halves=True)``): SSI on each half of the block, as
identify records it (``half_difference_hz``), for the forecast's SSI guard: each half's
frequency is the excitation-weighted truth over its 10 minutes plus an error with twice the
block's variance whose mean over the halves is the block's error (``"segments"``: each half's
own two segments; ``"ar1"``: the block's error ± an independent term of its size).

Unrecorded changes (issue 27, :data:`UNRECORDED`): the same tables with a disturbance of the
true frequencies that no predictor records (fuel without soundings, ballast, ice on deck):
a slow rise, a held step, an AR(1) wander at two time constants and two sizes, and a model
trained in open water and carried into ice (ice SSI errors, an unrecorded added-mass offset
and a wander with ice concentration). Each comes with an *oracle*: a Kalman filter that
knows the hull's law exactly (a perfect model of the recorded part), the identification
error's model (AR(1), its per-block size, the tracking scatter, which tracked poles are
mislabelled) and the disturbance's statistics, but not its realisation (AR(1) wander with
its true time constant and size; a rise or step as a random walk with the same mean-square
change over the voyage; the ice offset as an unknown constant from the known entry time).
What it reaches is the distance to the reachable that the suite prints beside each case.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from data_contracts import shapes_to_frame
from workbench.simulate.hull import CHANNELS, mode_shapes, true_modal_parameters

REGIMES = ("alternating_speed", "slow_speed", "stationary", "temperature_drift", "ice_breaking")
#: Regimes with an unrecorded change (issue 27): name -> (base profile, disturbance kind,
#: size, time constant [min]). Sizes: relative change of the frequency for "rise" (per
#: 12 h) and "step"; multiples of the identification error's standard deviation for
#: "wander".
UNRECORDED = {
    "rise_0.8pct_12h": ("slow_speed", "rise", 0.008, None),
    "step_-0.6pct": ("slow_speed", "step", -0.006, None),
    "wander_40min_2x": ("slow_speed", "wander", 2.0, 40.0),
    "wander_40min_1x": ("slow_speed", "wander", 1.0, 40.0),
    "wander_160min_2x": ("slow_speed", "wander", 2.0, 160.0),
    "wander_160min_1x": ("slow_speed", "wander", 1.0, 160.0),
    "open_water_into_ice": ("open_water_into_ice", "ice", 0.005, 60.0),
}
ALL_REGIMES = (*REGIMES, *UNRECORDED)
#: Modes of the demo hull used (0-based indices into MODE_LAWS): VB1, HB1, T1, VB3.
MODE_INDEX = (0, 1, 3, 4)
#: Relative standard deviation of the identification error of each of the hull's seven
#: modes (VB1, HB1, VB2, T1, VB3, HB2, T2). [-]
RELATIVE_ERROR_ALL = np.array([0.003, 0.004, 0.003, 0.003, 0.004, 0.004, 0.004])
LAG1 = 0.65
#: Identification-error generators (module docstring).
ERROR_MODELS = ("ar1", "segments")
STEP_MIN = 5
BLOCK_MIN = 20
ORDERS = np.arange(10, 61, 2)
BLADE_HZ_PER_KN = 0.33  # 4 blades x shaft rate, shaft rate ~ speed


@dataclass(frozen=True)
class RegimeData:
    name: str
    seed: int
    predictors: pd.DataFrame
    truth: pd.DataFrame
    tracked: pd.DataFrame
    poles: pd.DataFrame
    oracle: pd.DataFrame | None = None


def _smooth(rng, n, correlation_min):
    """Unit-variance noise smoothed over *correlation_min* minutes (AR(1))."""
    a = np.exp(-1.0 / correlation_min)
    e = rng.standard_normal(n) * np.sqrt(1 - a * a)
    out = np.empty(n)
    acc = rng.standard_normal()
    for i in range(n):
        acc = a * acc + e[i]
        out[i] = acc
    return out


def _ramp_towards(target, max_rate):
    """Follow *target* with at most *max_rate* change per minute (ship acceleration)."""
    out = np.empty_like(target)
    out[0] = target[0]
    for i in range(1, target.size):
        out[i] = out[i - 1] + np.clip(target[i] - out[i - 1], -max_rate, max_rate)
    return out


def _profile(name: str, rng, n_min: int):
    t_h = np.arange(n_min) / 60.0
    water = 3.0 + 0.3 * _smooth(rng, n_min, 240)
    air = (
        -2.0
        + 3.0 * np.sin(2 * np.pi * (t_h - rng.uniform(0, 24)) / 24)
        + 0.8 * _smooth(rng, n_min, 60)
    )
    wind = np.clip(8.0 + 3.0 * _smooth(rng, n_min, 90), 0, None)
    wind_dir = np.mod(rng.uniform(0, 360) + 40 * np.cumsum(_smooth(rng, n_min, 30)) / 60, 360)
    excitation_spikes = np.ones(n_min)
    if name == "alternating_speed":
        target = np.empty(n_min)
        i, high = 0, bool(rng.integers(2))
        while i < n_min:
            length = int(rng.uniform(90, 240))
            target[i : i + length] = rng.uniform(10, 15) if high else rng.uniform(2, 6)
            i += length
            high = not high
        speed = _ramp_towards(target, 0.5) + 0.3 * _smooth(rng, n_min, 10)
    elif name == "slow_speed":
        period = rng.uniform(8, 14)
        speed = 9 + 4 * np.sin(2 * np.pi * t_h / period + rng.uniform(0, 6.3))
        speed = speed + 0.8 * _smooth(rng, n_min, 120) + 0.2 * _smooth(rng, n_min, 10)
    elif name == "stationary":
        speed = np.abs(0.3 + 0.2 * _smooth(rng, n_min, 30))
    elif name == "temperature_drift":
        speed = 11 + 0.7 * _smooth(rng, n_min, 60)
        centre, width = rng.uniform(0.3, 0.7) * t_h[-1], rng.uniform(2, 6)
        front = 1 / (1 + np.exp(-(t_h - centre) / (width / 4)))
        water = 7.0 - 8.5 * front + 0.2 * _smooth(rng, n_min, 120)
        air = air + 6.0 - 15.0 * front
    elif name == "ice_breaking":
        # ramming: accelerate to 5-7 kn, stop in the ridge, back off; or steady breaking
        target = np.empty(n_min)
        i = 0
        while i < n_min:
            if rng.random() < 0.5:
                cycle = int(rng.uniform(8, 20))
                peak = rng.uniform(5, 7)
                shape = np.concatenate(
                    [np.linspace(0, peak, cycle // 2), np.linspace(peak, -1, cycle - cycle // 2)]
                )
                target[i : i + cycle] = shape[: max(0, min(cycle, n_min - i))]
                i += cycle
            else:
                length = int(rng.uniform(30, 120))
                target[i : i + length] = rng.uniform(2.5, 4.5)
                i += length
        speed = _ramp_towards(target, 1.0) + 0.2 * _smooth(rng, n_min, 5)
        water = -1.6 + 0.1 * _smooth(rng, n_min, 240)
        air = air - 13.0
        # ice impacts: impulsive excitation, heavy-tailed in power
        excitation_spikes = np.exp(1.5 * rng.standard_normal(n_min))
    elif name == "open_water_into_ice":
        # alternating speed in open water, then ice breaking from the middle of the voyage
        _, v_open, w_open, a_open, *_ = _profile("alternating_speed", rng, n_min)
        _, v_ice, w_ice, a_ice, _, _, spikes_ice = _profile("ice_breaking", rng, n_min)
        entry = n_min // 2
        into = np.clip((np.arange(n_min) - entry) / 30.0, 0.0, 1.0)  # 30 min transition
        speed = np.where(np.arange(n_min) < entry, v_open, v_ice)
        water = (1 - into) * w_open + into * w_ice
        air = (1 - into) * a_open + into * a_ice
        excitation_spikes = np.where(np.arange(n_min) < entry, 1.0, spikes_ice)
    else:
        raise ValueError(f"unknown regime {name!r}")
    return t_h, speed, water, air, wind, wind_dir, excitation_spikes


def make_regime(
    name: str,
    seed: int,
    *,
    n_blocks: int = 432,
    shapes: bool = True,
    mode_index: tuple[int, ...] = MODE_INDEX,
    first_label: int = 1,
    error_model: str = "ar1",
    halves: bool = False,
) -> RegimeData:
    """Block-level tables of one regime and seed (see the module docstring).

    *halves* adds the tracked table's ``half_difference_hz`` (module docstring, *halves*),
    drawn from a random stream of its own: every other draw is the same with and without.

    *mode_index* picks the hull's modes (0-based indices into its seven), labelled
    *first_label*, *first_label* + 1, ... in the tables. *error_model* picks the
    identification error's generator (:data:`ERROR_MODELS`); every other draw is the same
    for both, so the two differ only in the error's correlation.
    """
    if error_model not in ERROR_MODELS:
        raise ValueError(f"error_model={error_model!r} must be one of {ERROR_MODELS}")
    mode_index = tuple(int(m) for m in mode_index)
    relative_error = RELATIVE_ERROR_ALL[list(mode_index)]
    if name in REGIMES:
        number, profile, disturbance = REGIMES.index(name), name, None
    elif name in UNRECORDED:
        number = len(REGIMES) + list(UNRECORDED).index(name)
        profile, disturbance = UNRECORDED[name][0], UNRECORDED[name]
    else:
        raise ValueError(f"unknown regime {name!r}")
    rng = np.random.default_rng([number, seed])
    n_min = (n_blocks - 1) * STEP_MIN + BLOCK_MIN
    t_h, speed, water, air, wind, wind_dir, spikes = _profile(profile, rng, n_min)
    minute = {
        "speed_kn": speed,
        "water_temp_c": water,
        "air_temp_c": air,
        "elapsed_hours": t_h,
    }
    freq_min = true_modal_parameters(minute).frequency_hz[:, mode_index]
    freq0_min = freq_min.copy()  # what the predictors explain
    oracle_spec = None
    if disturbance is not None:  # the unrecorded change, from its own random stream
        freq_min, oracle_spec = _disturb(
            freq0_min, t_h, disturbance, (number, seed), relative_error
        )
    damp_min = true_modal_parameters(minute).damping_ratio[:, mode_index]
    n_modes = len(mode_index)
    starts = np.arange(n_blocks) * STEP_MIN
    index = starts[:, None] + np.arange(BLOCK_MIN)[None, :]
    weights = (0.2 + (np.abs(speed) / 10.0) ** 2) * spikes
    w = weights[index]
    w = w / w.sum(axis=1, keepdims=True)
    truth_f = freq_min[index].mean(axis=1)  # (n_blocks, n_modes): time average
    seen_f = np.einsum("bm,bmj->bj", w, freq_min[index])  # excitation-weighted
    truth0_f = freq0_min[index].mean(axis=1)  # without the unrecorded change
    seen0_f = np.einsum("bm,bmj->bj", w, freq0_min[index])
    damping = damp_min[index].mean(axis=1)
    speed_change = np.ptp(speed[index], axis=1)

    if profile == "open_water_into_ice":
        ice_block = starts >= n_min // 2
    else:
        ice_block = np.full(n_blocks, profile == "ice_breaking")
    ice = bool(ice_block.any())
    size = (
        relative_error[None, :] * truth_f * np.exp(0.35 * rng.standard_normal((n_blocks, n_modes)))
    )
    size *= 1.0 + 0.15 * speed_change[:, None]
    if ice_block.all():
        size *= 2.5
        shocks = rng.standard_t(3, (n_blocks, n_modes)) / np.sqrt(3.0)
    elif not ice:
        shocks = rng.standard_normal((n_blocks, n_modes))
    else:
        size *= np.where(ice_block, 2.5, 1.0)[:, None]
        heavy = rng.standard_t(3, (n_blocks, n_modes)) / np.sqrt(3.0)
        shocks = np.where(ice_block[:, None], heavy, rng.standard_normal((n_blocks, n_modes)))
    n_segments = BLOCK_MIN // STEP_MIN  # blocks sharing data with a block (4)
    extra = None
    if error_model == "segments":  # the voyage's last blocks end in segments of their own
        extra_rng = np.random.default_rng([number, seed, n_segments])
        shape = (n_segments - 1, n_modes)
        if ice_block[-1]:  # heavy-tailed like the ice blocks' shocks
            extra = extra_rng.standard_t(3, shape) / np.sqrt(3.0)
        else:
            extra = extra_rng.standard_normal(shape)
    error, segment_size = identification_error(size, shocks, extra, n_segments)
    centre = seen_f + error  # the column's centre in the block's stabilisation diagram
    half_difference = (
        _half_differences(freq_min, w, index, error, size, shocks, extra, ice_block, (number, seed))
        if halves
        else None
    )

    # presence: missing at random and in runs
    present = rng.random((n_blocks, n_modes)) > 0.12
    n_runs, run_len = (4, (10, 40)) if ice else (2, (4, 15))
    for j in range(n_modes):
        for _ in range(n_runs):
            length = int(rng.integers(*run_len))
            s = int(rng.integers(0, n_blocks - length))
            present[s : s + length, j] = False

    block_start = pd.Timestamp("2025-01-10T00:00:00Z") + pd.to_timedelta(starts, unit="min")
    block_end = block_start + pd.Timedelta(minutes=BLOCK_MIN)
    blocks = np.arange(n_blocks)
    predictors = pd.DataFrame(
        {
            "block": blocks,
            "block_start": block_start,
            "block_end": block_end,
            "speed_kn": speed[index].mean(axis=1),
            "water_temp_c": water[index].mean(axis=1),
            "air_temp_c": air[index].mean(axis=1),
            "wind_speed_ms": wind[index].mean(axis=1),
            "wind_dir_rel_deg": wind_dir[index].mean(axis=1),
        }
    )
    labels = np.arange(first_label, first_label + n_modes)
    truth = pd.DataFrame(
        {
            "block": np.repeat(blocks, n_modes),
            "mode": np.tile(labels, n_blocks),
            "frequency_hz": truth_f.ravel(),
            "damping_ratio": damping.ravel(),
        }
    )

    # ---- stabilisation diagrams
    ref_shapes = mode_shapes()[list(mode_index)].astype(complex)
    n_ch = len(CHANNELS)
    blade_shape = np.exp(-3.0 * np.linspace(0, 1, n_ch)).astype(complex)
    blade_shape /= np.linalg.norm(blade_shape)
    rows_block, rows_order, rows_f, rows_d, rows_stable, rows_shape = [], [], [], [], [], []
    tracked_rows = []
    order_scatter = 0.4 * size * np.exp(0.3 * rng.standard_normal((n_blocks, n_modes)))
    mislabelled = np.zeros((n_blocks, n_modes), dtype=bool)

    def add(b, orders, freqs, damps, stable, shape_rows):
        rows_block.append(np.full(orders.size, b))
        rows_order.append(orders)
        rows_f.append(freqs)
        rows_d.append(damps)
        rows_stable.append(stable)
        rows_shape.append(shape_rows)

    def noisy_shapes(base, n, level):
        noise = rng.standard_normal((n, n_ch)) + 1j * rng.standard_normal((n, n_ch))
        return base[None, :] + level * noise / np.sqrt(2 * n_ch)

    for b in range(n_blocks):
        ice = bool(ice_block[b])
        mislabel = 0.04 if ice else 0.015
        for j in range(n_modes):
            if not present[b, j]:
                continue
            onset = int(rng.integers(12, 26)) // 2 * 2
            orders = ORDERS[ORDERS >= onset]
            f = centre[b, j] + order_scatter[b, j] * rng.standard_normal(orders.size)
            d = (
                damping[b, j]
                * np.exp(0.2 * rng.standard_normal())
                * np.exp(0.05 * rng.standard_normal(orders.size))
            )
            stable = rng.random(orders.size) > 0.15
            stable[0] = False
            shp = noisy_shapes(ref_shapes[j], orders.size, 0.12 * (2 if ice else 1))
            add(b, orders, f, d, stable, shp)
            upper = np.flatnonzero(orders >= 30)
            pick = int(rng.choice(upper)) if upper.size else orders.size - 1
            f_tracked, d_tracked, s_tracked = f[pick], d[pick], shp[pick]
            if rng.random() < mislabel:
                mislabelled[b, j] = True
                f_tracked = centre[b, j] * (1 + rng.choice([-1, 1]) * rng.uniform(0.01, 0.03))
                d_tracked = rng.uniform(0.005, 0.05)
                s_tracked = noisy_shapes(ref_shapes[j], 1, 0.6)[0]
                add(
                    b,
                    np.array([int(rng.choice(ORDERS))]),
                    np.array([f_tracked]),
                    np.array([d_tracked]),
                    np.array([False]),
                    s_tracked[None, :],
                )
            tracked_rows.append((b, labels[j], f_tracked, d_tracked, s_tracked))
        # noise poles
        n_noise = int(rng.poisson(25 * (1.6 if ice else 1.0)))
        add(
            b,
            rng.choice(ORDERS, n_noise),
            rng.uniform(2.5, 8.5, n_noise),
            np.exp(rng.uniform(np.log(0.004), np.log(0.1), n_noise)),
            rng.random(n_noise) < 0.2,
            noisy_shapes(np.zeros(n_ch, dtype=complex), n_noise, 1.0),
        )
        # blade-rate harmonic (lightly damped, stable over many orders)
        v = predictors["speed_kn"].iat[b]
        if v > 2.0:
            orders = ORDERS[ORDERS >= 20]
            add(
                b,
                orders,
                BLADE_HZ_PER_KN * v * (1 + 2e-4 * rng.standard_normal(orders.size)),
                np.full(orders.size, 0.002) * np.exp(0.1 * rng.standard_normal(orders.size)),
                np.ones(orders.size, dtype=bool),
                noisy_shapes(blade_shape, orders.size, 0.05),
            )
        if ice:  # short stable columns from ice impacts
            for _ in range(int(rng.poisson(2))):
                n = int(rng.integers(3, 7))
                start = int(rng.integers(0, ORDERS.size - n))
                f0 = rng.uniform(2.5, 8.5)
                add(
                    b,
                    ORDERS[start : start + n],
                    f0 * (1 + 1e-3 * rng.standard_normal(n)),
                    np.full(n, rng.uniform(0.01, 0.06)) * np.exp(0.1 * rng.standard_normal(n)),
                    np.ones(n, dtype=bool),
                    noisy_shapes(np.zeros(n_ch, dtype=complex), n, 1.0),
                )
    poles = pd.DataFrame(
        {
            "block": np.concatenate(rows_block).astype(np.int64),
            "model_order": np.concatenate(rows_order).astype(np.int64),
            "frequency_hz": np.concatenate(rows_f),
            "damping_ratio": np.concatenate(rows_d),
            "stable": np.concatenate(rows_stable).astype(bool),
        }
    )
    tb, tm, tf, td, ts = zip(*tracked_rows, strict=True)
    tracked = pd.DataFrame(
        {
            "block": np.asarray(tb, dtype=np.int64),
            "mode": np.asarray(tm, dtype=np.int64),
            "frequency_hz": np.asarray(tf),
            "damping_ratio": np.asarray(td),
        }
    )
    tracked.insert(1, "block_start", block_start[tracked["block"].to_numpy()])
    if half_difference is not None:
        # a mislabelled tracked pole keeps its mode's halves: the guard then sees a usual
        # yardstick beside a large distance from SSI, its hardest case
        tracked["half_difference_hz"] = half_difference[
            tracked["block"].to_numpy(), tracked["mode"].to_numpy() - first_label
        ]
    if shapes:
        pole_shapes = np.concatenate(rows_shape)
        poles = pd.concat([poles, shapes_to_frame(CHANNELS, pole_shapes)], axis=1)
        tracked = pd.concat([tracked, shapes_to_frame(CHANNELS, np.asarray(ts))], axis=1)
    poles = poles.sort_values(["block", "model_order"], kind="stable").reset_index(drop=True)
    oracle = None
    if oracle_spec is not None:
        measured = np.full((n_blocks, n_modes), np.nan)
        measured[np.asarray(tb), np.asarray(tm) - first_label] = np.asarray(tf)
        measured[mislabelled] = np.nan  # the oracle knows which poles are mislabelled
        if segment_size is None:
            estimate = _oracle_filter(
                measured, seen0_f, truth0_f, size, order_scatter, oracle_spec, starts, n_min
            )
        else:
            estimate = _oracle_filter_segments(
                measured, seen0_f, truth0_f, segment_size, order_scatter, oracle_spec, starts
            )
        oracle = pd.DataFrame(
            {
                "block": np.repeat(blocks, n_modes),
                "mode": np.tile(labels, n_blocks),
                "frequency_hz": estimate.ravel(),
            }
        )
    return RegimeData(name, seed, predictors, truth, tracked, poles, oracle)


def _half_differences(freq_min, w, index, error, size, shocks, extra, ice_block, stream):
    """f₁ - f₂ of SSI on the two halves of every block (module docstring, *halves*)."""
    n_blocks, n_modes = error.shape
    half = BLOCK_MIN // 2
    seen = []
    for part in (slice(0, half), slice(half, None)):
        wh = w[:, part] / w[:, part].sum(axis=1, keepdims=True)
        seen.append(np.einsum("bm,bmj->bj", wh, freq_min[index[:, part]]))
    n_segments = BLOCK_MIN // STEP_MIN
    if extra is not None:  # "segments": each half is the mean of its own segments' errors
        segment_size = np.concatenate([size, np.repeat(size[-1:], n_segments - 1, axis=0)])
        segment = segment_size * np.concatenate([shocks, extra]) / np.sqrt(n_segments)
        k = np.arange(n_blocks)[:, None]
        first = segment[k + np.arange(n_segments // 2)].sum(axis=1)
        second = segment[k + np.arange(n_segments // 2, n_segments)].sum(axis=1)
        errors = (2 * first, 2 * second)
    else:  # "ar1": halves about the block's error, each with twice its variance
        rng = np.random.default_rng([*stream, 2])
        u = np.where(
            ice_block[:, None],
            rng.standard_t(3, (n_blocks, n_modes)) / np.sqrt(3.0),
            rng.standard_normal((n_blocks, n_modes)),
        )
        errors = (error + size * u, error - size * u)
    return (seen[0] + errors[0]) - (seen[1] + errors[1])


def identification_error(size, shocks, extra=None, n_segments=BLOCK_MIN // STEP_MIN):
    """Identification error of every block (module docstring, *correlated errors*).

    Parameters
    ----------
    size : ndarray (n_blocks, n_modes)
        Standard deviation of each block's error. [Hz]
    shocks : ndarray (n_blocks, n_modes)
        Unit-variance shocks, one per block.
    extra : ndarray (n_segments - 1, n_modes), optional
        None: the ``"ar1"`` generator, e_k = ρ e_{k-1} + sqrt(1 - ρ²) size_k shock_k with
        ρ = :data:`LAG1`. Given: the ``"segments"`` generator; block k spans the segments
        k .. k + n_segments - 1, segment i has the shock ``shocks[i]`` (``extra`` for the
        segments after the last block's first) and the size of the block it starts (the
        last block's for the final ones), and e_k = Σ_i size_i shock_i / sqrt(n_segments):
        variance size² for a constant size, correlation (n_segments - h) / n_segments at
        lag h < n_segments and zero from lag n_segments.

    Returns
    -------
    error (n_blocks, n_modes) [Hz], and the segments' sizes (n_blocks + n_segments - 1,
    n_modes) [Hz] (None for ``"ar1"``).
    """
    n_blocks = size.shape[0]
    if extra is None:
        error = np.empty_like(size)
        error[0] = size[0] * shocks[0]
        for k in range(1, n_blocks):
            error[k] = LAG1 * error[k - 1] + np.sqrt(1 - LAG1**2) * size[k] * shocks[k]
        return error, None
    segment_size = np.concatenate([size, np.repeat(size[-1:], n_segments - 1, axis=0)])
    segment = segment_size * np.concatenate([shocks, extra]) / np.sqrt(n_segments)
    error = np.stack([segment[k : k + n_segments].sum(axis=0) for k in range(n_blocks)])
    return error, segment_size


def _disturb(freq0_min, t_h, disturbance, stream, relative_error):
    """True frequencies with the unrecorded change, and what the oracle knows of it.

    Returns the disturbed minute frequencies [Hz] and a dict of the oracle's block-level
    disturbance model per mode: random-walk variance per block ``q_level`` [Hz²], a jump
    of the level's variance ``jump`` [Hz²] at minute ``jump_min``, and an AR(1) wander with
    time constant ``tau_min`` [min] and variance ``wander`` [Hz²] from minute ``wander_min``.
    """
    _, kind, size, tau = disturbance
    drng = np.random.default_rng([*stream, 27])
    n_min, n_modes = freq0_min.shape
    level = freq0_min.mean(axis=0)  # [Hz]
    gain = drng.uniform(0.5, 1.5, n_modes)  # each mode feels the change differently
    n_blocks = (n_min - BLOCK_MIN) // STEP_MIN + 1
    spec = {
        "q_level": np.zeros(n_modes),
        "jump": np.zeros(n_modes),
        "jump_min": 0,
        "tau_min": 1.0,
        "wander": np.zeros(n_modes),
        "wander_min": 0,
    }
    relative = np.zeros((n_min, n_modes))
    if kind == "rise":
        relative = size * (t_h / 12.0)[:, None] * gain[None, :]
        spec["q_level"] = (size * t_h[-1] / 12.0 * gain * level) ** 2 / n_blocks
    elif kind == "step":
        at = int(drng.uniform(0.25, 0.6) * n_min)
        relative[at:] = size * gain[None, :]
        spec["q_level"] = (size * gain * level) ** 2 / n_blocks
    elif kind == "wander":
        std = size * relative_error
        relative = np.column_stack([std[j] * _smooth(drng, n_min, tau) for j in range(n_modes)])
        spec.update(tau_min=tau, wander=(std * level) ** 2)
    elif kind == "ice":
        entry = n_min // 2
        into = np.clip((np.arange(n_min) - entry) / 30.0, 0.0, 1.0)[:, None]
        std = relative_error
        wander = np.column_stack([std[j] * _smooth(drng, n_min, tau) for j in range(n_modes)])
        relative = into * (-size * gain[None, :] + wander)
        spec.update(
            jump=(size * gain * level) ** 2,
            jump_min=entry,
            tau_min=tau,
            wander=(std * level) ** 2,
            wander_min=entry,
        )
    else:
        raise ValueError(f"unknown disturbance {kind!r}")
    return freq0_min * (1.0 + relative), spec


def _oracle_filter(measured, seen0, truth0, size, order_scatter, spec, starts, n_min):
    """Kalman filter that knows the law, the identification error and the disturbance model.

    State per mode [a, w, e]: the disturbance's level a (random walk), its AR(1) wander w
    and the identification error e (AR(1), lag-1 correlation :data:`LAG1`, the block's
    size); z_k - seen0_k = a + w + e + v, v the tracking scatter. Estimate truth0 + a + w.
    """
    n_blocks, n_modes = measured.shape
    phi_w = np.exp(-STEP_MIN / spec["tau_min"])
    estimate = np.full((n_blocks, n_modes), np.nan)
    for j in range(n_modes):
        x = np.zeros(3)
        P = np.diag([0.0, 0.0, size[0, j] ** 2])
        for k in range(n_blocks):
            wander_on = starts[k] >= spec["wander_min"] and spec["wander"][j] > 0
            if k > 0:
                F = np.diag([1.0, phi_w, LAG1])
                x = F @ x  # x = Fx
                P = F @ P @ F.T  # P = FPF' + Q
                P[0, 0] += spec["q_level"][j]
                P[1, 1] += spec["wander"][j] * (1 - phi_w**2) if wander_on else 0.0
                P[2, 2] += (1 - LAG1**2) * size[k, j] ** 2
            if spec["jump"][j] > 0 and starts[k] >= spec["jump_min"] > starts[max(k - 1, 0)]:
                P[0, 0] += spec["jump"][j]
            if wander_on and (k == 0 or starts[k - 1] < spec["wander_min"]):
                P[1, 1] += spec["wander"][j]
            if np.isfinite(measured[k, j]):
                H = np.ones(3)
                y = measured[k, j] - seen0[k, j] - H @ x  # y = z - Hx
                S = H @ P @ H + order_scatter[k, j] ** 2  # S = HPH' + R
                K = P @ H / S  # K = PH'S^-1
                x = x + K * y
                A = np.eye(3) - np.outer(K, H)
                P = A @ P @ A.T + order_scatter[k, j] ** 2 * np.outer(K, K)  # Joseph form
            # before the change begins the disturbance's states have no variance: the
            # estimate would be truth0 by construction (the filter knows the law exactly), not
            # a reachable; no estimate there (_oracle_known)
            estimate[k, j] = truth0[k, j] + x[0] + x[1] if _oracle_known(P) else np.nan
    return estimate


def _oracle_known(P) -> bool:
    """Whether the knowing filter's disturbance states (a, w: the first two) have any
    variance, i.e. the unrecorded change has begun (module docstring: before it, e.g. in
    open water before the ice, the knowing filter is the truth itself: a perfect model of
    the recorded part and a disturbance known to be zero)."""
    return bool(P[0, 0] + P[1, 1] > 0.0)


def _oracle_filter_segments(measured, seen0, truth0, segment_size, order_scatter, spec, starts):
    """The knowing filter for the ``"segments"`` identification error.

    As :func:`_oracle_filter`, with the identification error of block k the sum of its L
    segment terms g_i = size_i u_i / sqrt(L), i = k .. k + L - 1 (u_i independent, unit
    variance; the oracle knows every segment's size): state [a, w, g_k, ..., g_{k+L-1}];
    from block to block the segment terms shift by one and the newest one is new.
    """
    n_blocks, n_modes = measured.shape
    L = segment_size.shape[0] - n_blocks + 1
    n_state = 2 + L
    phi_w = np.exp(-STEP_MIN / spec["tau_min"])
    F = np.zeros((n_state, n_state))
    F[0, 0], F[1, 1] = 1.0, phi_w
    F[2 : 2 + L - 1, 3 : 2 + L] = np.eye(L - 1)  # g_{k+1..k+L-1} carry over
    H = np.ones(n_state)
    estimate = np.full((n_blocks, n_modes), np.nan)
    for j in range(n_modes):
        x = np.zeros(n_state)
        P = np.zeros((n_state, n_state))
        P[2:, 2:] = np.diag(segment_size[:L, j] ** 2 / L)
        for k in range(n_blocks):
            wander_on = starts[k] >= spec["wander_min"] and spec["wander"][j] > 0
            if k > 0:
                x = F @ x  # x = Fx
                P = F @ P @ F.T  # P = FPF' + Q
                P[0, 0] += spec["q_level"][j]
                P[1, 1] += spec["wander"][j] * (1 - phi_w**2) if wander_on else 0.0
                P[-1, -1] += segment_size[k + L - 1, j] ** 2 / L
            if spec["jump"][j] > 0 and starts[k] >= spec["jump_min"] > starts[max(k - 1, 0)]:
                P[0, 0] += spec["jump"][j]
            if wander_on and (k == 0 or starts[k - 1] < spec["wander_min"]):
                P[1, 1] += spec["wander"][j]
            if np.isfinite(measured[k, j]):
                R = order_scatter[k, j] ** 2
                y = measured[k, j] - seen0[k, j] - H @ x  # y = z - Hx
                S = H @ P @ H + R  # S = HPH' + R
                K = P @ H / S  # K = PH'S^-1
                x = x + K * y
                A = np.eye(n_state) - np.outer(K, H)
                P = A @ P @ A.T + R * np.outer(K, K)  # Joseph form
            estimate[k, j] = truth0[k, j] + x[0] + x[1] if _oracle_known(P) else np.nan
    return estimate
