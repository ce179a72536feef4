"""Tests for workbench.sid.stabilisation: criteria edges and the stable flags of a diagram."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.sid.ssi import ssi_cov
from workbench.sid.stabilisation import StabilityCriteria, stabilise, stability_flags

SHAPE = np.array([1.0, 0.5, -0.2], dtype=complex)


def _shape_with_mac(target_mac: float) -> np.ndarray:
    """A unit shape whose MAC with SHAPE is exactly *target_mac* (rotation in a plane)."""
    unit = SHAPE / np.linalg.norm(SHAPE)
    orthogonal = np.array([0.5, -1.0, 0.0], dtype=complex)
    orthogonal -= np.vdot(unit, orthogonal) * unit
    orthogonal /= np.linalg.norm(orthogonal)
    angle = np.arccos(np.sqrt(target_mac))
    return np.cos(angle) * unit + np.sin(angle) * orthogonal


@pytest.mark.parametrize(
    ("frequency", "damping", "target_mac", "expected"),
    [
        (10.09, 0.0204, 0.99, True),  # Δf 0.9 %, Δζ 2 %, MAC 0.99
        (10.11, 0.0200, 0.99, False),  # Δf 1.1 %
        (10.00, 0.0211, 0.99, False),  # Δζ 5.5 %
        (10.00, 0.0200, 0.97, False),  # MAC 0.97
        (10.00, 0.0209, 0.981, True),  # Δζ 4.5 %, MAC 0.981
    ],
)
def test_criteria_edges(frequency, damping, target_mac, expected):
    shapes = np.column_stack([SHAPE, _shape_with_mac(target_mac)])
    flags = stability_flags(
        np.array([2, 4]), np.array([10.0, frequency]), np.array([0.02, damping]), shapes, [2, 4]
    )
    assert flags.tolist() == [False, expected]


def test_negative_damping_lowest_order_and_gaps():
    # order 2: one pole; order 4: same pole twice, once with negative damping; order 6: no
    # pole; order 8: the pole again (its previous order, 6, is empty)
    model_order = np.array([2, 4, 4, 8])
    frequency = np.full(4, 5.0)
    damping = np.array([0.01, 0.01, -0.01, 0.01])
    shapes = np.column_stack([SHAPE] * 4)
    flags = stability_flags(model_order, frequency, damping, shapes, [2, 4, 6, 8])
    assert flags.tolist() == [False, True, False, False]


def test_criteria_validation():
    with pytest.raises(ValueError, match="frequency_tol"):
        StabilityCriteria(frequency_tol=0.0)
    with pytest.raises(ValueError, match="mac_min"):
        StabilityCriteria(mac_min=1.5)


def test_stabilise_recomputes_flags_without_touching_the_input(chain3):
    result = ssi_cov(
        chain3.acceleration, chain3.sampling_rate_hz, block_rows=10, orders=range(2, 21, 2)
    )
    loose = stabilise(result, frequency_tol=0.05, damping_tol=0.5, mac_min=0.9)
    strict = stabilise(result, frequency_tol=1e-4, damping_tol=1e-3, mac_min=0.9999)
    assert loose.criteria == StabilityCriteria(0.05, 0.5, 0.9)
    assert result.criteria == StabilityCriteria()
    n_default = int(result.poles["stable"].sum())
    assert int(loose.poles["stable"].sum()) >= n_default >= int(strict.poles["stable"].sum())
    # the defaults reproduce what ssi_cov flagged
    again = stabilise(result)
    assert again.poles["stable"].equals(result.poles["stable"])
    # each of the three modes of the chain has a stable pole at every order from 8 on
    poles = result.poles
    for true_frequency in chain3.frequency_hz:
        near = poles[
            (np.abs(poles["frequency_hz"] / true_frequency - 1) < 0.005)
            & (poles["model_order"] >= 8)
        ]
        assert near.groupby("model_order")["stable"].any().sum() == 7


def _pairwise_flags(order, frequency, damping, shapes, orders, criteria):
    """Reference: every pole against every pole of the previous order (the definition)."""
    stable = np.zeros(order.size, dtype=bool)
    levels = sorted(set(orders))
    for previous, current in zip(levels[:-1], levels[1:], strict=True):
        for a in np.flatnonzero(order == current):
            for b in np.flatnonzero(order == previous):
                phi_a, phi_b = shapes[:, a], shapes[:, b]
                mac_ab = abs(np.vdot(phi_a, phi_b)) ** 2 / (
                    np.vdot(phi_a, phi_a).real * np.vdot(phi_b, phi_b).real
                )
                if (
                    abs(frequency[a] - frequency[b]) < criteria.frequency_tol * frequency[b]
                    and abs(damping[a] - damping[b]) < criteria.damping_tol * damping[b]
                    and damping[a] > 0
                    and damping[b] > 0
                    and mac_ab > criteria.mac_min
                ):
                    stable[a] = True
    return stable


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("tolerances", [(0.01, 0.05, 0.98), (0.3, 0.5, 0.5), (1.5, 2.0, 0.0)])
def test_vectorised_flags_equal_the_pairwise_definition(seed, tolerances):
    """Random diagrams with near-duplicate poles, negative damping, unsorted rows, orders
    without poles and poles of orders outside the list."""
    rng = np.random.default_rng(seed)
    orders = [2, 4, 6, 8, 10, 14]
    n = 300
    order = rng.choice([2, 4, 6, 8, 10, 12, 14], n)  # 12 is not in the diagram
    order[order == 8] = 6  # order 8 has no poles
    frequency = rng.choice([1.0, 2.0, 5.0], n) * (1 + rng.normal(0, 0.01, n))
    frequency[::37] = -frequency[::37]
    damping = rng.choice([0.01, 0.02], n) * (1 + rng.normal(0, 0.05, n))
    damping[::11] *= -1
    base = rng.standard_normal((4, 3)) + 1j * rng.standard_normal((4, 3))
    shapes = base[:, rng.integers(0, 3, n)] + 0.1 * rng.standard_normal((4, n))
    criteria = StabilityCriteria(*tolerances)
    got = stability_flags(order, frequency, damping, shapes, orders, criteria)
    expected = _pairwise_flags(order, frequency, damping, shapes, orders, criteria)
    np.testing.assert_array_equal(got, expected)
    assert expected.sum() > 5  # the comparison is not vacuous
