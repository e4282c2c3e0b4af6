"""Shift laws, 2S2P1D/Huet-Sayegh, Prony fits, Booij-Thoone and master-curve fits."""

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.rheology.kramers_kronig import booij_thoone_phase, kk_time_lag
from asphalt_nscd.rheology.laws import GeneralizedBurgers
from asphalt_nscd.rheology.master_curve import fit_master_curve, master_curve_table, replicate_noise
from asphalt_nscd.rheology.models import (
    fit_generalized_kelvin,
    fit_generalized_maxwell,
    generalized_maxwell_modulus,
    information_criteria,
    log_time_grid,
    two_s2p1d_modulus,
)
from asphalt_nscd.rheology.shift import arrhenius_log_shift, wlf_log_shift


def test_wlf_values():
    assert wlf_log_shift(15.0, 15.0, 30.0, 200.0) == 0.0
    assert wlf_log_shift(-10.0, 15.0, 30.0, 200.0) == pytest.approx(30 * 25 / 175)
    T = np.array([-10.0, 0.0, 10.0, 20.0, 30.0])
    a = wlf_log_shift(T, 15.0, 30.0, 200.0)
    # the WLF law inverted by hand: T = T_ref - a C2 / (C1 + a)
    assert 15.0 - a * 200.0 / (30.0 + a) == pytest.approx(T)
    with pytest.raises(ValueError):
        wlf_log_shift(-300.0, 15.0, 30.0, 200.0)


def test_arrhenius_values():
    T = np.array([-10.0, 4.0, 21.0, 37.0])
    a = arrhenius_log_shift(T, 21.0, 180e3)
    assert a[2] == 0.0 and a[0] > 0 > a[3]
    # log10 aT is linear in 1/T with slope Ea / (R ln 10)
    x = 1.0 / (T + 273.15) - 1.0 / (21.0 + 273.15)
    assert a == pytest.approx(180e3 / (8.314462618 * np.log(10.0)) * x, rel=1e-6)


def test_2s2p1d_limits_and_single_parabolic_element():
    w = np.array([1e-12, 1e12])
    E = two_s2p1d_modulus(w, 50.0, 40e3, 2.0, 0.2, 0.6, np.inf, 1.0)
    assert E[0].real == pytest.approx(50.0, rel=1e-2) and E[1].real == pytest.approx(40e3, rel=1e-2)
    # delta = 0, E00 = 0, no dashpot: E0 / (1 + (i w tau)^-h), exact at w tau = 1
    h = 0.5
    E1 = two_s2p1d_modulus(np.array([1.0]), 0.0, 1.0, 0.0, 0.2, h, np.inf, 1.0)[0]
    assert E1 == pytest.approx(1.0 / (1.0 + np.exp(-1j * h * np.pi / 2)))
    # beta = inf (the Huet-Sayegh model): no dashpot, the glassy-static interpolation of two
    # parabolic elements, E00 + (E0 - E00) / (1 + delta (i w tau)^-k + (i w tau)^-h)
    iwt = 1j * 3.0 * 0.1
    assert two_s2p1d_modulus(np.array([3.0]), 1.0, 10.0, 2.0, 0.2, 0.6, np.inf, 0.1)[0] == pytest.approx(
        1.0 + 9.0 / (1.0 + 2.0 * iwt**-0.2 + iwt**-0.6)
    )
    # the dashpot of 2S2P1D is a liquid: phase -> 90 deg at low frequency when E00 = 0
    low = two_s2p1d_modulus(np.array([1e-9]), 0.0, 1.0, 2.0, 0.2, 0.6, 10.0, 1.0)[0]
    assert np.degrees(np.angle(low)) > 85


def test_2s2p1d_equals_its_complex_power_definition_everywhere_it_is_defined():
    """The model computed in real arithmetic is the definition E00 + (E0 - E00) / (1 + delta (i w tau)^-k +
    (i w tau)^-h + (i w beta tau)^-1), evaluated with complex powers, over 12 decades of w tau and random
    parameters, rows of parameters broadcast against frequencies as a fit's Jacobian asks; w tau = 0,
    infinite or not a number gives no value."""
    rng = np.random.default_rng(20261129)
    m, n = 40, 60
    col = lambda a: a[:, None]  # noqa: E731
    E00, E0 = col(10 ** rng.uniform(-2, 2, m)), col(10 ** rng.uniform(3, 4.7, m))
    delta, h = col(10 ** rng.uniform(-1.5, 1.5, m)), col(rng.uniform(0.1, 0.99, m))
    k, beta = h * col(rng.uniform(0.03, 0.97, m)), col(10 ** rng.uniform(-1, 9, m))
    omega = 2 * np.pi * 10 ** rng.uniform(-2, 2, n)
    tau = 10 ** rng.uniform(-8, 8, (m, n))
    for b in (beta, np.inf):
        got = two_s2p1d_modulus(omega, E00, E0, delta, k, h, b, tau)
        iwt = 1j * omega * tau
        want = E00 + (E0 - E00) / (1.0 + delta * iwt ** (-k) + iwt ** (-h) + (1.0 / (iwt * b) if b is beta else 0.0))
        assert got.shape == (m, n)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    undefined = two_s2p1d_modulus(
        np.array([1.0, 1.0, 1.0, 1.0]), 1.0, 10.0, 2.0, 0.2, 0.6, 100.0, np.array([0.0, np.inf, np.nan, 1.0])
    )
    assert np.isnan(undefined[:3]).all() and np.isfinite(undefined[3])
    assert np.ndim(two_s2p1d_modulus(3.0, 1.0, 10.0, 2.0, 0.2, 0.6, 100.0, 0.1)) == 0  # a scalar stays one
    with pytest.raises(ValueError, match="all finite or all infinite"):
        two_s2p1d_modulus(omega[:2], 1.0, 10.0, 2.0, 0.2, 0.6, np.array([1.0, np.inf]), 0.1)


def test_generalized_kelvin_recovers_exact_law_on_its_grid():
    tau = np.array([1e-3, 1e-1])
    law = GeneralizedBurgers(Em=30e3, eta_m=5e3, Ek=(20e3, 2e3), eta_k=(20e3 * tau[0], 2e3 * tau[1]), E_inf=100.0)
    w = np.logspace(-2, 5, 50)
    fit = fit_generalized_kelvin(w, law.complex_modulus(w), np.logspace(-5, 1, 7), E_inf=100.0)
    assert fit.Em == pytest.approx(30e3, rel=1e-6) and fit.eta_m == pytest.approx(5e3, rel=1e-6)
    assert sorted(fit.Ek) == pytest.approx([2e3, 20e3], rel=1e-6)
    assert np.abs(fit.complex_modulus(w) / law.complex_modulus(w) - 1).max() < 1e-8


def test_generalized_kelvin_approximates_2s2p1d_and_maxwell_series():
    w = np.logspace(-1, 3, 40)
    E = two_s2p1d_modulus(w, 100.0, 40e3, 2.5, 0.2, 0.6, 500.0, 0.05)
    fit = fit_generalized_kelvin(w, E, log_time_grid(w.min(), w.max(), per_decade=2), E_inf=100.0)
    rel = np.abs(fit.complex_modulus(w) / E - 1)
    assert rel.max() < 0.01
    rho = np.logspace(-4, 1, 6)
    Ei = np.array([5e3, 8e3, 6e3, 3e3, 1e3, 300.0])
    target = generalized_maxwell_modulus(w, 80.0, Ei, rho)
    gm = fit_generalized_maxwell(w, target, rho)
    assert gm["E_inf"] == pytest.approx(80.0, rel=1e-5) and gm["E_i"] == pytest.approx(Ei, rel=1e-5)


def test_information_criteria():
    ic = information_criteria(10.0, 100, 3)
    assert ic["bic"] - ic["aic"] == pytest.approx(3 * np.log(100) - 6)
    with pytest.raises(ValueError):
        information_criteria(0.0, 10, 2)


def test_booij_thoone_exact_for_power_law_and_kk_time_lag():
    f = np.array([0.1, 1.0, 10.0, 25.0])
    assert booij_thoone_phase(f, 7.0 * f**0.3) == pytest.approx(np.full(4, 27.0))
    rows = []
    for T, n in ((0.0, 0.1), (20.0, 0.25), (40.0, 0.4)):
        for fr in (1.0, 3.0, 10.0, 25.0, 40.0):
            rows.append(
                {
                    "temperature_C": T,
                    "frequency_Hz": fr,
                    "E_norm_MPa": 1e3 * fr**n,
                    "phase_deg": 90 * n + 360 * fr * 0.5e-3,
                }
            )
    lag = kk_time_lag(pd.DataFrame(rows))
    assert lag["time_lag_ms"] == pytest.approx(0.5, rel=1e-6)


def _table(rng, n_spec=3, sE=0.01, sP=0.2):
    p = dict(E00=80.0, E0=38e3, delta=2.2, k=0.19, h=0.6, beta=800.0, tau=0.05, C1=28.0, C2=180.0)
    rows = []
    for s in range(n_spec):
        c = rng.normal(0, 0.04)
        for T in (-10.0, 0.0, 10.0, 20.0, 30.0):
            for f in (1.0, 3.0, 10.0, 25.0):
                tau = p["tau"] * 10 ** wlf_log_shift(T, 10.0, p["C1"], p["C2"])
                E = two_s2p1d_modulus(2 * np.pi * f, p["E00"], p["E0"], p["delta"], p["k"], p["h"], p["beta"], tau)
                rows.append(
                    {
                        "specimen": f"s{s}",
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "E_norm_MPa": abs(E) * np.exp(c + rng.normal(0, sE)),
                        "phase_deg": np.degrees(np.angle(E)) + rng.normal(0, sP),
                    }
                )
    return pd.DataFrame(rows), p


def test_master_curve_recovers_shifts_and_static_modulus():
    df, p = _table(np.random.default_rng(4))
    sE, sP = replicate_noise(df)
    assert sE == pytest.approx(0.01, rel=0.3) and sP == pytest.approx(0.2, rel=0.3)
    fit = fit_master_curve(df, T_ref_C=10.0)
    truth = wlf_log_shift(fit.temperatures, 10.0, p["C1"], p["C2"])
    assert fit.log_shift(fit.temperatures) == pytest.approx(truth, abs=0.15)
    assert fit.core()["E00_MPa"] == pytest.approx(80.0, rel=0.5)
    assert fit.rss / (fit.n_residuals - fit.n_params) == pytest.approx(1.0, abs=0.4)
    tab = master_curve_table(fit, df)
    assert set(tab["kind"]) == {"data", "model"}
    free = fit_master_curve(df, shift="free", T_ref_C=10.0)
    assert free.log_shift(free.temperatures) == pytest.approx(truth, abs=0.2)
    assert replicate_noise(df[df["specimen"] == "s0"]) == (None, None)
