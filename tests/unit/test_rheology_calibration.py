"""Burger's calibration (Eqs. 27-29), paper Table 3 loader, micro parameters (Eqs. 30-33, 8-11)."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.calibration import (
    PARAM_COLUMNS,
    burgers_curves,
    burgers_isotherm,
    fit_burgers,
    fit_table,
    load_table3,
    micro_parameters,
    refit_check,
)
from asphalt_nscd.rheology.laws import bond_scale, tangential_ratio

REPO = Path(__file__).resolve().parents[2]
TABLE3 = REPO / "data" / "paper" / "table3_burgers.csv"
UIUC = REPO / "data" / "measured" / "uiuc_fdmix1_utm" / "complex_modulus.csv"
PAPER_F = [3.0, 6.0, 10.0, 25.0, 40.0]


def test_table3_units_readings():
    pa = load_table3(TABLE3, units="Pa")
    kpa = load_table3(TABLE3, units="kPa")
    assert list(pa.columns) == ["temperature_C", *PARAM_COLUMNS]
    assert pa["temperature_C"].tolist() == [-10, 0, 10, 15, 20, 30]
    row = pa.set_index("temperature_C").loc[15]
    assert row["Em_MPa"] == pytest.approx(24.3)  # 2.43e7 Pa
    assert row["eta_k_MPa_s"] == pytest.approx(0.773)  # 7.73e5 Pa s
    np.testing.assert_allclose(kpa[list(PARAM_COLUMNS)], 1e3 * pa[list(PARAM_COLUMNS)])
    with pytest.raises(InputError, match="unit reading"):
        load_table3(TABLE3, units="MPa")


def test_isotherm_matches_closed_form_compliance():
    p = {"Em_MPa": 24.3, "eta_m_MPa_s": 3.71, "Ek_MPa": 48.4, "eta_k_MPa_s": 0.773}
    f = np.array([3.0, 40.0])
    w = 2 * np.pi * f
    Em, eta_m, Ek, eta_k = p["Em_MPa"], p["eta_m_MPa_s"], p["Ek_MPa"], p["eta_k_MPa_s"]
    D1 = 1 / Em + Ek / (Ek**2 + w**2 * eta_k**2)  # Eq. 28
    D2 = 1 / (w * eta_m) + w * eta_k / (Ek**2 + w**2 * eta_k**2)  # Eq. 29
    E, phi = burgers_isotherm(p, f)
    np.testing.assert_allclose(E, 1 / np.hypot(D1, D2), rtol=1e-12)  # Eq. 27
    np.testing.assert_allclose(phi, np.degrees(np.arctan(D2 / D1)), atol=1e-10)


@pytest.mark.parametrize("units", ["Pa", "kPa"])
def test_table3_isotherms_fitted_back_within_one_percent(units):
    check = refit_check(load_table3(TABLE3, units=units), PAPER_F)
    errors = check[[f"{c}_rel_err" for c in PARAM_COLUMNS]].to_numpy()
    assert np.abs(errors).max() < 0.01


def test_fit_with_noise_gives_standard_errors_covering_truth():
    rng = np.random.default_rng(42)
    truth = {"Em_MPa": 30000.0, "eta_m_MPa_s": 20000.0, "Ek_MPa": 40000.0, "eta_k_MPa_s": 800.0}
    f = np.repeat(np.array([0.1, 0.5, 1.0, 5.0, 10.0, 25.0]), 3)
    E, phi = burgers_isotherm(truth, f)
    E = E * np.exp(0.01 * rng.standard_normal(f.size))
    phi = phi + np.degrees(0.01 * rng.standard_normal(f.size))
    fit = fit_burgers(f, E, phi)
    assert fit["success"]
    for name, value in truth.items():
        assert fit[f"{name}_se"] > 0
        assert abs(fit[name] - value) < 4 * fit[f"{name}_se"], name
    assert fit["rmse_log_E"] == pytest.approx(0.01, rel=0.5)


def test_weights_change_the_compromise():
    from asphalt_nscd.lab.measured import load_measured

    df = load_measured(UIUC)  # the file is in degF, its sidecar says so
    g = df[df["temperature_C"] == 21.0]
    modulus_only = fit_burgers(g["frequency_Hz"], g["E_norm_MPa"], g["phase_deg"], weights={"phase_rad": 0.0})
    balanced = fit_burgers(g["frequency_Hz"], g["E_norm_MPa"], g["phase_deg"])
    assert modulus_only["rmse_log_E"] < balanced["rmse_log_E"]
    assert balanced["rmse_phase_deg"] < modulus_only["rmse_phase_deg"]
    with pytest.raises(ValueError, match="weight"):
        fit_burgers(g["frequency_Hz"], g["E_norm_MPa"], g["phase_deg"], weights={"phase": 1.0})


def test_fit_table_of_measured_mix_reports_errors_per_temperature():
    from asphalt_nscd.lab.measured import load_measured

    table = fit_table(load_measured(UIUC))
    assert table["temperature_C"].tolist() == [-10.0, 4.0, 21.0, 37.0, 54.0]
    for c in (
        *PARAM_COLUMNS,
        *(f"{c}_se" for c in PARAM_COLUMNS),
        "rmse_log_E",
        "rmse_phase_deg",
        "mre_E_pct",
        "mre_phase_pct",
    ):
        assert c in table.columns and np.all(np.isfinite(table[c]))
    # the modulus decreases with temperature; Em is the upper plateau >= measured max
    assert np.all(np.diff(table["Em_MPa"]) < 0)
    assert table["Em_MPa"].iloc[0] > 0.9 * 27472.0


def test_fit_rejects_bad_input():
    with pytest.raises(ValueError, match="2 or more distinct frequencies"):
        fit_burgers([2, 2, 2], [1, 2, 3], [10, 10, 10])
    with pytest.raises(ValueError, match=r"\(0, 90\)"):
        fit_burgers([1, 2, 3, 4], [1, 2, 3, 4], [10, 10, 0, 10])


def test_micro_parameters_follow_eqs_30_33_and_8_11():
    table = load_table3(TABLE3)
    r, l0 = np.array([1e-3, 2e-3]), np.array([2.1e-3, 4.5e-3])
    micro = micro_parameters(table, r, l0, nu=0.35, grain_mass_kg=2.86e-5)
    assert len(micro) == 12
    row = micro[(micro["temperature_C"] == 15) & (micro["bond"] == 1)].iloc[0]
    a = float(bond_scale(r[1], l0[1]))
    assert row["scale_m"] == pytest.approx(np.pi * 2e-3**2 / 4.5e-3)
    assert row["Km_N_m"] == pytest.approx(a * 24.3e6)
    assert row["Ck_N_s_m"] == pytest.approx(a * 7.73e5)
    assert row["Kk_t_N_m"] == pytest.approx(row["Kk_N_m"] * tangential_ratio(0.35))
    assert row["Cm_t_N_s_m"] == pytest.approx(row["Cm_N_s_m"] / 2.7)
    assert row["dt_e_s"] == pytest.approx(np.sqrt(2.86e-5 / row["Km_N_m"]))


def test_cli_fit_table3_curves_micro(tmp_path):
    params = tmp_path / "params.csv"
    assert main(["fit", "--measured", str(UIUC), "--model", "burgers", "-o", str(params)]) == 0
    out = pd.read_csv(params)
    assert list(out.columns[:5]) == ["temperature_C", "Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s"]
    assert len(out) == 5
    t3 = tmp_path / "t3.csv"
    assert main(["table3", str(TABLE3), "--units", "kPa", "-o", str(t3)]) == 0
    assert pd.read_csv(t3)["Em_MPa"].iloc[0] == pytest.approx(39800.0)
    curves = tmp_path / "curves.csv"
    assert main(["burgers-curves", "--parameters", str(t3), "--points", "5", "-o", str(curves)]) == 0
    assert len(pd.read_csv(curves)) == 30
    micro = tmp_path / "micro.csv"
    assert main(["micro", "--parameters", str(t3), "--r-min-mm", "1", "2", "--l0-mm", "2", "-o", str(micro)]) == 0
    assert len(pd.read_csv(micro)) == 12
    assert (
        main(
            [
                "micro",
                "--parameters",
                str(t3),
                "--r-min-mm",
                "1",
                "2",
                "--l0-mm",
                "2",
                "3",
                "4",
                "-o",
                str(tmp_path / "bad.csv"),
            ]
        )
        == 2
    )
    assert not (tmp_path / "bad.csv").exists()


def test_cli_fit_rejects_bad_measured_table(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("specimen,temperature_C,frequency_Hz,E_norm_MPa\nA,10,1,100\n")
    out = tmp_path / "params.csv"
    assert main(["fit", "--measured", str(bad), "-o", str(out)]) == 2
    assert not out.exists()


def test_burgers_curves_shape():
    curves = burgers_curves(load_table3(TABLE3), np.array([1.0, 10.0]))
    assert len(curves) == 12
    np.testing.assert_allclose(np.hypot(curves["E1_MPa"], curves["E2_MPa"]), curves["E_norm_MPa"])


def test_analytic_jacobian_of_the_fit_matches_finite_differences():
    from asphalt_nscd.rheology.calibration import _log_modulus, _log_modulus_jacobian

    x = np.log([24.3, 3.71, 48.4, 0.773])
    w = 2 * np.pi * np.array([0.1, 3.0, 40.0])
    J = _log_modulus_jacobian(x, w)
    h = 1e-6
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        fd = (_log_modulus(x + e, w) - _log_modulus(x - e, w)) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-9)
