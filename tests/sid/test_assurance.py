"""Tests for workbench.sid.assurance: MAC and MACXP invariants and closed-form values."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from workbench.sid.assurance import continuous_pole, mac, macxp

finite = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)


@st.composite
def complex_shapes(draw, n_channels=4, n_modes=3):
    real = draw(arrays(float, (n_channels, n_modes), elements=finite))
    imag = draw(arrays(float, (n_channels, n_modes), elements=finite))
    shapes = real + 1j * imag
    # keep away from zero vectors (MAC undefined there, NaN by design)
    shapes[0] += 1.0
    return shapes


@st.composite
def poles(draw, n_modes=3):
    frequency = draw(arrays(float, n_modes, elements=st.floats(0.1, 50.0)))
    damping = draw(arrays(float, n_modes, elements=st.floats(1e-4, 0.9)))
    return continuous_pole(frequency, damping)


def test_continuous_pole_closed_form():
    lam = continuous_pole(2.0, 0.05)
    omega = 4 * np.pi
    assert lam == pytest.approx(-0.05 * omega + 1j * omega * np.sqrt(1 - 0.05**2))
    # |λ| = ω and ζ = -Re λ / |λ|
    assert abs(lam) == pytest.approx(omega)
    assert -lam.real / abs(lam) == pytest.approx(0.05)
    assert continuous_pole([1.0, 2.0], [0.01, 0.02]).shape == (2,)


def test_mac_closed_form_and_shapes():
    a = np.array([1.0, 0.0, 0.0])
    b = np.array([1.0, 1.0, 0.0])
    # |a.b|^2 / (|a|^2 |b|^2) = 1 / 2
    assert float(mac(a, b)) == pytest.approx(0.5)
    assert np.ndim(mac(a, b)) == 0
    two = np.column_stack([a, b])
    three = np.column_stack([a, b, a + 1j * b])
    assert mac(two, three).shape == (2, 3)
    assert mac(a, three).shape == (3,)
    assert mac(two, a).shape == (2,)
    # orthogonal real vectors
    assert float(mac(a, np.array([0.0, 0.0, 2.0]))) == 0.0


def test_macxp_equals_one_for_identical_mode_and_reduces_with_pole_distance():
    shape = np.array([1.0, 0.5 + 0.1j, -0.3])
    lam = continuous_pole(3.0, 0.02)
    assert float(macxp(shape, lam, shape, lam)) == pytest.approx(1.0, abs=1e-12)
    # real shape, poles 10 % apart in frequency: φ^H φ = φ^T φ, so MACXP reduces to the
    # pole terms alone, (1/|λa*+λb| + 1/|λa+λb|)^2 / Π (1/(2|Re λ|) + 1/(2|λ|))
    real = np.array([1.0, 0.5, -0.3])
    far = continuous_pole(3.3, 0.02)
    expected = (1 / abs(lam.conjugate() + far) + 1 / abs(lam + far)) ** 2 / (
        (1 / (2 * abs(lam.real)) + 1 / (2 * abs(lam)))
        * (1 / (2 * abs(far.real)) + 1 / (2 * abs(far)))
    )
    assert float(macxp(real, lam, real, far)) == pytest.approx(expected, rel=1e-12)
    assert expected < 0.2  # the pole weighting separates them although MAC = 1
    # a close pole (0.05 % apart) keeps MACXP close to 1
    near = continuous_pole(3.0 * 1.0005, 0.02)
    assert float(macxp(shape, lam, shape, near)) > 0.99


def test_macxp_real_modes_light_damping_limit():
    """For real shapes and equal poles MACXP tends to MAC as damping -> 0.

    With equal lightly damped poles the |φ^H φ|/(2|Re λ|) terms dominate the
    |φ^T φ|/(2|λ|) terms by a factor 1/ζ, so MACXP -> |φ_a^T φ_b|^2/(|φ_a|^2|φ_b|^2).
    """
    a = np.array([1.0, 0.4, -0.2])
    b = np.array([0.9, 0.6, 0.1])
    lam = continuous_pole(5.0, 1e-6)
    assert float(macxp(a, lam, b, lam)) == pytest.approx(float(mac(a, b)), rel=1e-5)


@settings(max_examples=60, deadline=None)
@given(complex_shapes(), poles(), complex_shapes(n_modes=2), poles(n_modes=2))
def test_mac_and_macxp_range_symmetry(shapes_a, poles_a, shapes_b, poles_b):
    for criterion in (mac(shapes_a, shapes_b), macxp(shapes_a, poles_a, shapes_b, poles_b)):
        assert criterion.shape == (3, 2)
        assert np.all((criterion >= 0.0) & (criterion <= 1.0))
    np.testing.assert_allclose(mac(shapes_a, shapes_b), mac(shapes_b, shapes_a).T, atol=1e-12)
    np.testing.assert_allclose(
        macxp(shapes_a, poles_a, shapes_b, poles_b),
        macxp(shapes_b, poles_b, shapes_a, poles_a).T,
        atol=1e-12,
    )


@settings(max_examples=60, deadline=None)
@given(
    complex_shapes(),
    poles(),
    st.complex_numbers(
        min_magnitude=1e-3, max_magnitude=1e3, allow_nan=False, allow_infinity=False
    ),
)
def test_self_criteria_one_and_scale_invariance(shapes, lam, scale):
    np.testing.assert_allclose(np.diag(mac(shapes, shapes)), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.diag(macxp(shapes, lam, shapes, lam)), 1.0, atol=1e-9)
    np.testing.assert_allclose(mac(shapes, scale * shapes), mac(shapes, shapes), atol=1e-9)
    np.testing.assert_allclose(
        macxp(shapes, lam, scale * shapes, lam), macxp(shapes, lam, shapes, lam), atol=1e-9
    )


def test_zero_shape_gives_nan_and_bad_inputs_raise():
    a = np.zeros(3)
    b = np.ones(3)
    assert np.isnan(mac(a, b))
    with pytest.raises(ValueError, match="channels"):
        mac(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="poles_a"):
        macxp(np.ones((3, 2)), [continuous_pole(1.0, 0.01)], np.ones(3), continuous_pole(1, 0.01))
    with pytest.raises(ValueError, match="poles_b"):
        macxp(np.ones(3), continuous_pole(1.0, 0.01), np.ones(3), 1.0 + 0j)


def test_package_functions_are_not_shadowed_by_modules():
    import importlib

    import workbench.sid as sid

    for name in ("assurance", "plscf", "modal", "threads", "ssi", "tracking"):
        importlib.import_module(f"workbench.sid.{name}")
    # importing every submodule leaves the package's functions in place
    assert callable(sid.mac) and sid.mac.__module__ == "workbench.sid.assurance"
    assert callable(sid.lscf) and sid.lscf.__module__ == "workbench.sid.plscf"
