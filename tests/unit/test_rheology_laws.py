"""Closed-form checks of the shared viscoelastic laws (Eqs. 27-33, 8-11)."""

import numpy as np
import pytest

from asphalt_nscd.rheology.laws import GeneralizedBurgers, bond_scale, tangential_ratio

# Paper's Table 3 at 15 degC read literally (Pa, Pa s)
T15 = dict(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)


def test_burgers_matches_eqs_28_29():
    law = GeneralizedBurgers.burgers(**T15)
    w = 2 * np.pi * np.array([3.0, 6.0, 10.0, 25.0, 40.0])
    Em, eta_m, Ek, eta_k = T15.values()
    d1 = 1 / Em + Ek / (Ek**2 + w**2 * eta_k**2)  # Eq. 28
    d2 = 1 / (w * eta_m) + w * eta_k / (Ek**2 + w**2 * eta_k**2)  # Eq. 29
    norm, phase = law.norm_and_phase(w)
    np.testing.assert_allclose(norm, 1 / np.hypot(d1, d2), rtol=1e-12)  # Eq. 27
    np.testing.assert_allclose(phase, np.degrees(np.arctan(d2 / d1)), rtol=1e-12)


def test_limits_glassy_and_liquid():
    law = GeneralizedBurgers.burgers(**T15)
    assert law.complex_modulus(1e9).real == pytest.approx(T15["Em"], rel=1e-3)
    # a Burger's model is a liquid: |E*| -> 0 and phase -> 90 deg at low frequency
    norm, phase = law.norm_and_phase(1e-9)
    assert norm < 1e-3 * T15["Em"] and phase == pytest.approx(90.0, abs=1e-3)


def test_static_spring_makes_a_solid_with_phase_peak():
    law = GeneralizedBurgers(Em=1e9, eta_m=1e7, Ek=(2e9,), eta_k=(1e7,), E_inf=5e7)
    w = np.logspace(-6, 6, 400)
    norm, phase = law.norm_and_phase(w)
    assert norm[0] == pytest.approx(5e7, rel=1e-3)
    assert 0 < np.argmax(phase) < len(w) - 1  # phase peaks and falls


def test_creep_compliance_closed_form_and_consistency():
    law = GeneralizedBurgers(Em=1e8, eta_m=1e7, Ek=(2e8, 5e8), eta_k=(1e6, 1e5))
    t = np.array([0.0, 1e-3, 0.1, 2.0])
    expected = 1 / 1e8 + t / 1e7 + (1 - np.exp(-2e8 * t / 1e6)) / 2e8 + (1 - np.exp(-5e8 * t / 1e5)) / 5e8
    np.testing.assert_allclose(law.creep_compliance(t), expected, rtol=1e-12)
    # compliance at high frequency equals the instantaneous creep compliance
    assert 1 / law.complex_modulus(1e12).real == pytest.approx(law.creep_compliance(0.0), rel=1e-6)


def test_micro_scaling_eqs_30_33_and_8_11():
    r_min, l0 = 1e-3, 3e-3
    a = bond_scale(r_min, l0)
    assert a == pytest.approx(np.pi * 1e-6 / 3e-3)
    micro = GeneralizedBurgers.burgers(**T15).scaled(a)
    assert micro.Em == pytest.approx(np.pi * r_min**2 * T15["Em"] / l0)  # Eq. 30
    assert micro.eta_k[0] == pytest.approx(np.pi * r_min**2 * T15["eta_k"] / l0)  # Eq. 33
    assert tangential_ratio(0.35) == pytest.approx(1 / 2.7)  # Eqs. 8-11


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(Em=-1, eta_m=1, Ek=1, eta_k=1),
        dict(Em=1, eta_m=1, Ek=(1, 2), eta_k=(1,)),
        dict(Em=1, eta_m=1, Ek=1, eta_k=1, E_inf=-2),
    ],
)
def test_invalid_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        GeneralizedBurgers(**kwargs)


def test_invalid_geometry_raises():
    with pytest.raises(ValueError):
        bond_scale([1e-3, 0.0], [1e-3, 1e-3])
    with pytest.raises(ValueError):
        tangential_ratio(0.6)
