"""Model-form and simulation causes: held-out broad_spectrum, deterministic effects."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.diagnosis import causes, synthetic
from asphalt_nscd.rheology.calibration import burgers_isotherm, fit_table
from asphalt_nscd.rheology.master_curve import fit_master_curve


def _burgers_table(seed: int) -> pd.DataFrame:
    """3 replicates of per-isotherm Burger's laws (a liquid with one retardation time)."""
    rng = np.random.default_rng(seed)
    rows = []
    for T, scale in ((0.0, 1.0), (15.0, 0.3), (30.0, 0.08)):
        p = {
            "Em_MPa": 25000.0 * scale**0.3,
            "eta_m_MPa_s": 3e4 * scale,
            "Ek_MPa": 30000.0 * scale**0.5,
            "eta_k_MPa_s": 800.0 * scale,
        }
        f = np.array([25.0, 10.0, 5.0, 1.0, 0.5, 0.1])
        E, phi = burgers_isotherm(p, f)
        for s in range(3):
            c = rng.normal(0, 0.02)
            for fi, Ei, pi in zip(f, E, phi):
                rows.append(
                    {
                        "specimen": f"S{s}",
                        "temperature_C": T,
                        "frequency_Hz": fi,
                        "E_norm_MPa": Ei * np.exp(c + rng.normal(0, 0.01)),
                        "phase_deg": pi + rng.normal(0, 0.2),
                    }
                )
    return pd.DataFrame(rows)


def test_lofo_prediction_does_not_see_its_held_out_frequency():
    """docs/validation.md: change a held-out value by a large factor, the fold's prediction must
    not move (while the predictions of the other folds, which train on it, do)."""
    table, _ = synthetic.generate(3, [], schedule="aashto_t342", n_specimens=2)
    base = causes.lofo_predictions(table)
    f_k = 1.0
    moved = table.copy()
    moved.loc[np.isclose(moved["frequency_Hz"], f_k), "E_norm_MPa"] *= 10.0
    after = causes.lofo_predictions(moved)
    at = np.isclose(base["frequency_Hz"], f_k)
    for col in ("E_burgers_MPa", "phase_burgers_deg", "E_master_MPa", "phase_master_deg"):
        np.testing.assert_allclose(after.loc[at, col], base.loc[at, col], rtol=1e-9)
        assert not np.allclose(after.loc[~at, col], base.loc[~at, col], rtol=1e-3)
    assert (after.loc[at, "E_norm_MPa"] / base.loc[at, "E_norm_MPa"]).round(9).eq(10.0).all()


def test_broad_spectrum_named_on_a_2s2p1d_mix_not_on_a_burgers_material():
    mix, _ = synthetic.generate(8, [], schedule="aashto_t342", n_specimens=3)
    master = fit_master_curve(mix)
    e = causes.broad_spectrum(mix, master, fit_table(mix))
    assert e["testable"] and e["detected"] and e["p_value"] is None
    est = e["estimate"]
    assert est["held_out_difference_phase_points"] > est["threshold_phase_points"]
    liquid = _burgers_table(1)
    e = causes.broad_spectrum(liquid, fit_master_curve(liquid), fit_table(liquid))
    assert e["testable"] and not e["detected"], e["evidence"]
    # per-isotherm Burger's laws predict their own held-out frequencies to within the noise
    assert e["estimate"]["burgers_mre_phase_pct_held_out"] < 3.0


def test_broad_spectrum_not_testable_with_two_frequencies_left():
    mix, _ = synthetic.generate(8, [], schedule="aashto_t342", n_specimens=2)
    two = mix[mix["frequency_Hz"].isin([10.0, 1.0])]
    e = causes.broad_spectrum(two, fit_master_curve(two), fit_table(two))
    assert not e["testable"] and e["evidence"].startswith("not testable: ")


def _macro():
    return pd.DataFrame(
        {
            "temperature_C": [10.0, 20.0],
            "Em_MPa": 30e3,
            "eta_m_MPa_s": [3e4, 5e3],
            "Ek_MPa": 40e3,
            "eta_k_MPa_s": [100.0, 30.0],
        }
    )


@pytest.mark.parametrize(
    "factors,detected",
    [
        ([1.02, 1.02, 1.02, 1.02], True),  # 2 % exactly: effect 2 %, uncertainty 0
        ([1.008, 1.008, 1.008, 1.008], False),  # below the 1 % tolerance
        ([0.99, 1.03, 1.01, 1.01], False),  # 1 % effect, 2 % row-to-row spread
        ([1.05, 1.06, 1.04, 1.05], True),  # 5 % +- 1 %
    ],
)
def test_network_factor_is_an_effect_against_its_tolerance(factors, detected):
    macro = _macro()
    grid = pd.DataFrame({"temperature_C": [10.0, 10.0, 20.0, 20.0], "frequency_Hz": [3.0, 30.0, 3.0, 30.0]})
    E = causes.burgers_predict(macro, grid["temperature_C"], grid["frequency_Hz"])
    sample = grid.assign(E_norm_MPa=np.abs(E) * np.array(factors), phase_deg=np.degrees(np.angle(E)))
    e = causes.network_factor(sample, macro, "harmonic", tolerance=0.01)
    nf = np.exp(np.mean(np.log(factors)))
    assert e["p_value"] is None and e["testable"] and e["detected"] is detected
    assert e["estimate"]["network_factor"] == pytest.approx(nf, rel=1e-9)
    assert e["estimate"]["network_factor_uncertainty"] == pytest.approx(
        np.max(np.abs(np.array(factors) / nf - 1)) * nf, rel=1e-9
    )


def test_time_integration_is_an_effect_against_its_tolerance():
    f = np.array([3.0, 10.0, 40.0, 40.0])
    dt = np.array([5e-5, 5e-5, 5e-5, 2e-5])
    x = 360 * f * dt
    exact = pd.DataFrame({"frequency_Hz": f, "dt_s": dt, "phase_error_deg": 0.5 * x})
    e = causes.time_integration(exact, tolerance_deg=0.1)
    assert e["detected"] and e["estimate"]["phase_error_deg_at_max_f_dt"] == pytest.approx(0.5 * x.max())
    assert e["estimate"]["uncertainty_deg"] == pytest.approx(0.0, abs=1e-12) and e["p_value"] is None
    small = exact.assign(phase_error_deg=0.05 * x)  # 0.036 deg at the largest f dt
    assert not causes.time_integration(small, tolerance_deg=0.1)["detected"]
    scattered = exact.assign(phase_error_deg=0.5 * x + np.array([0.0, 0.0, 0.6, -0.6]))
    e = causes.time_integration(scattered, tolerance_deg=0.1)
    # the rows depart from the proportional law by more than the effect at the largest f dt
    assert e["estimate"]["uncertainty_deg"] > e["estimate"]["phase_error_deg_at_max_f_dt"] and not e["detected"]
