"""Second-look modes need an independent estimate (either half of the block) to confirm
them, for SSI and LSCF alike (issue 32: 0 spurious modes with identify's default method,
SSI alone, and with LSCF alone); the second look's order consistency by shape finds both
modes of 1 % pairs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from workbench.sid.selection import ModeSelection, confirmed_second_look


def _selection(frequencies, shapes, second=()) -> ModeSelection:
    modes = pd.DataFrame(
        {
            "frequency_hz": np.asarray(frequencies, dtype=float),
            "damping_ratio": 0.01,
            "pole_index": np.arange(len(frequencies)) + 100,
        }
    )
    return ModeSelection(
        modes=modes,
        mode_shapes=np.asarray(shapes, dtype=complex),
        model_order=None,
        library_orders=(),
        method="cluster",
        thresholds={
            "second_look": len(second),
            "second_look_poles": tuple(100 + k for k in second),
        },
    )


def test_a_second_look_mode_stays_only_with_a_confirming_estimate():
    """Modes at 2, 3.40 (second look) and 5 Hz on 4 channels: a half with a mode 0.5 %
    from 3.40 Hz and the same shape confirms it; one at 3.40 Hz with an orthogonal shape
    (MAC 0), one 3.5 % away (beyond NEAR_MODE), or none does not; stage-3 modes are never
    judged."""
    shapes = np.array([[1, 0, 1], [1, 1, 0], [0, 1, 1], [0, 1, -1]], dtype=float)
    full = _selection([2.0, 3.40, 5.0], shapes, second=(1,))
    same = _selection([3.40 * 1.005], shapes[:, [1]])
    orthogonal_shape = np.array([[1.0], [0.0], [0.0], [0.0]])  # MAC 0 with (0, 1, 1, 1)
    other_shape = _selection([3.40], orthogonal_shape)
    farther = _selection([3.40 * 1.035], shapes[:, [1]])
    kept = confirmed_second_look(full, [other_shape, same])
    assert kept.modes["frequency_hz"].tolist() == [2.0, 3.40, 5.0]
    assert kept.thresholds["second_look_unconfirmed"] == 0
    for halves in ([other_shape], [farther], [other_shape, farther]):
        dropped = confirmed_second_look(full, halves)
        assert dropped.modes["frequency_hz"].tolist() == [2.0, 5.0]
        np.testing.assert_array_equal(dropped.mode_shapes, shapes[:, [0, 2]])
        assert dropped.thresholds["second_look"] == 0
        assert dropped.thresholds["second_look_poles"] == ()
        assert dropped.thresholds["second_look_unconfirmed"] == 1
    # nothing to judge by: unchanged
    assert confirmed_second_look(full, []) is full
    # a stage-3 mode with no partner anywhere stays
    stage3 = _selection([2.0, 3.40, 5.0], shapes)
    assert confirmed_second_look(stage3, [farther]) is stage3


def test_the_tolerance_widens_with_the_distance_to_the_nearest_mode():
    """A mode that moves inside the block reads differently in its halves. 3.40 Hz with its
    nearest mode at 2 Hz (41 % away): a half's mode 1.5 % off confirms it (tolerance
    min(0.5 x 41 %, NEAR_MODE) = 3 %). The same second-look mode 1 % from a stage-3 mode
    of another shape (a close pair): the tolerance stays 1 %, and 1.5 % does not confirm."""
    shapes = np.array([[1, 0, 1], [1, 1, 0], [0, 1, 1], [0, 1, -1]], dtype=float)
    moved = _selection([3.40 * 1.015], shapes[:, [1]])
    isolated = _selection([2.0, 3.40, 5.0], shapes, second=(1,))
    assert confirmed_second_look(isolated, [moved]).modes["frequency_hz"].tolist() == [
        2.0,
        3.40,
        5.0,
    ]
    pair = _selection([3.40 / 1.01, 3.40, 5.0], shapes[:, [0, 1, 2]], second=(1,))
    kept = confirmed_second_look(pair, [moved])
    assert kept.modes["frequency_hz"].tolist() == [3.40 / 1.01, 5.0]
    # with neighbour_share=0 the fixed 1 % pairing of before: the moved mode is lost
    fixed = confirmed_second_look(isolated, [moved], neighbour_share=0.0)
    assert fixed.thresholds["second_look_unconfirmed"] == 1


def test_a_mode_of_the_other_estimate_confirms_only_its_nearest_mode():
    """pLSCF puts a second pole 1 % beside a strong mode, with nearly its shape. A half's
    mode at the strong mode's frequency lies within 1 % and MAC 0.98 of that pole too,
    but it is nearer (frequency and shape) to the strong mode: it confirms that mode, and
    the pole goes."""
    strong = np.array([1.0, 0.5, -0.3, 0.8])
    ghost = strong + np.array([0.0, 0.1, 0.15, -0.05])  # MAC 0.982 with strong
    shapes = np.column_stack([[1.0, -1.0, 0.0, 0.0], strong, ghost])
    full = _selection([3.0, 5.89, 5.89 * 1.009], shapes, second=(2,))
    half = _selection([5.89], strong[:, None])
    kept = confirmed_second_look(full, [half])
    assert kept.modes["frequency_hz"].tolist() == [3.0, 5.89]
    assert kept.thresholds["second_look_unconfirmed"] == 1
    # alone beside nothing (the strong mode not in the block) the same half confirms it
    alone = _selection([3.0, 5.89 * 1.009], shapes[:, [0, 2]], second=(1,))
    assert confirmed_second_look(alone, [half]).thresholds["second_look_unconfirmed"] == 0


def _record(frequency, shapes, level_db, seed):
    """bench_close_weak.py's block of modes *frequency* at 1 % damping with *shapes* on 8
    channels and levels *level_db*: 20 min at 16 Hz, sensor noise 20 % of each channel's
    RMS, as the identification engine reads it (mean removed)."""
    from workbench.simulate.prescribed import prescribed_mode_record

    record = prescribed_mode_record(
        frequency,
        0.01,
        shapes,
        sampling_rate_hz=16.0,
        duration_s=1200.0,
        level_db=level_db,
        sensor_noise=0.2,
        seed=seed,
    )
    return SimpleNamespace(
        acceleration=record.acceleration - record.acceleration.mean(axis=0),
        sampling_rate_hz=record.sampling_rate_hz,
        channels=tuple(f"ch{j}" for j in range(8)),
    )


def _close_weak_block(level_db: float, seed: int):
    """bench_close_weak.py's "weak L dB" block: modes 1.1/2.3/3.4/4.6/5.9 Hz at 1 %
    damping, random shapes on 8 channels, the 2.3-Hz mode L dB down, 20 min at 16 Hz,
    sensor noise 20 % of each channel's RMS."""
    rng = np.random.default_rng(1000 + seed)
    shapes = rng.standard_normal((8, 5))
    frequency = np.array([1.1, 2.3, 3.4, 4.6, 5.9])
    return _record(frequency, shapes, np.array([0.0, -level_db, 0.0, 0.0, 0.0]), seed), frequency


def test_identify_leaves_out_the_unconfirmed_column_of_a_weak_mode_block():
    """Seed 89 of "weak 15 dB": SSI's second look found a column at 1.609 Hz (damping
    2.6 %, 12 orders; no mode within 30 %) that neither half of the block shows; identify's
    default selection now holds the five modes only, each within 0.5 % (the unconfirmed
    selection, asked for with confirm=False, still has the column)."""
    from workbench.identification.engine import _identify_method
    from workbench.identification.options import IdentifyOptions

    data, truth = _close_weak_block(15.0, 89)
    options = IdentifyOptions()
    _, unconfirmed = _identify_method("cov", data, None, options, confirm=False)
    _, selection = _identify_method("cov", data, None, options)
    assert np.any(np.abs(unconfirmed.modes["frequency_hz"] - 1.609) < 0.005)
    found = selection.modes["frequency_hz"].to_numpy()
    assert found.size == truth.size
    np.testing.assert_allclose(np.sort(found), truth, rtol=5e-3)
    assert selection.thresholds["second_look_unconfirmed"] == 1


@pytest.mark.parametrize("seed", [108])
def test_a_confirmed_weak_mode_found_by_the_second_look_stays(seed):
    """Seed 108 of "weak 20 dB": the 2.3-Hz mode, 20 dB down, is found by the second look
    and confirmed by both halves: it stays (within 0.5 %)."""
    from workbench.identification.engine import _identify_method
    from workbench.identification.options import IdentifyOptions

    data, truth = _close_weak_block(20.0, seed)
    _, selection = _identify_method("cov", data, None, IdentifyOptions())
    assert selection.thresholds["second_look"] >= 1
    assert selection.thresholds["second_look_unconfirmed"] == 0
    found = selection.modes["frequency_hz"].to_numpy()
    assert np.min(np.abs(found / 2.3 - 1)) < 5e-3


def _close_pair_block(mac_value: float, seed: int):
    """bench_close_weak.py's "close 1% MAC m" block: the five modes above at the same level
    and a sixth 1 % above 3.4 Hz whose shape has MAC *mac_value* with the 3.4-Hz mode."""
    from workbench.simulate.prescribed import shapes_with_mac

    rng = np.random.default_rng(1000 + seed)
    shapes = rng.standard_normal((8, 5))
    shapes = np.column_stack([shapes, shapes_with_mac(shapes[:, 2], mac_value, rng)])
    frequency = np.array([1.1, 2.3, 3.4, 4.6, 5.9, 3.4 * 1.01])
    return _record(frequency, shapes, np.zeros(6), seed), np.sort(frequency)


@pytest.mark.parametrize(
    "seed",
    [62, 101, 134],
    ids=[
        "gaps where the pair mixes (16 of 24 orders in the column)",
        "upper mode wandering 4x the stage-3 scatter",
        "beside a lower mode with gaps (10 shared orders of 13)",
    ],
)
def test_ssi_now_finds_both_modes_of_a_1_percent_pair(seed):
    """Close 1 % MAC 0.2, seeds 62, 101 and 134 (of the 6 + 8 blocks of seeds 60-179 whose
    3.434-Hz mode the selection missed, benchmarks/results/identification_32e.txt):
    identify's default SSI now holds all six modes, each within 0.4 % (the benchmark's
    score for a 1 % pair), and nothing else."""
    from workbench.identification.engine import _identify_method
    from workbench.identification.options import IdentifyOptions

    data, truth = _close_pair_block(0.2, seed)
    _, selection = _identify_method("cov", data, None, IdentifyOptions())
    found = np.sort(selection.modes["frequency_hz"].to_numpy())
    assert found.size == truth.size
    np.testing.assert_allclose(found, truth, rtol=4e-3)
    assert selection.thresholds["second_look"] >= 1
    assert selection.thresholds["second_look_unconfirmed"] == 0


def test_lscf_alone_leaves_out_its_second_pole_beside_a_strong_mode():
    """Close 1 % MAC 0.2, seed 86, LSCF alone: the diagram holds a column at 5.953 Hz,
    1.0 % above the 5.894-Hz mode, at the upper orders, with the mode's shape (MAC 0.974).
    Before, the second look added it and only the halves left it out (their 5.9-Hz mode
    confirms itself, not the column); now the second look does not add it (its shape lies
    within 3 x its scatter over the orders of the mode's: no shape of its own), so neither
    selection holds it. The six true modes stay within 0.4 %."""
    from workbench.identification.engine import _identify_method
    from workbench.identification.options import IdentifyOptions

    data, truth = _close_pair_block(0.2, 86)
    options = IdentifyOptions()
    result, unconfirmed = _identify_method("lscf", data, None, options, confirm=False)
    _, selection = _identify_method("lscf", data, None, options)
    column = np.abs(result.poles["frequency_hz"] - 5.953) < 0.01
    assert result.poles.loc[column, "model_order"].nunique() >= 5
    for chosen in (unconfirmed, selection):
        found = np.sort(chosen.modes["frequency_hz"].to_numpy())
        assert found.size == truth.size
        np.testing.assert_allclose(found, truth, rtol=4e-3)
