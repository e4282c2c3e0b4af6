"""EN 12697-26 2PB reduction (paper Eqs. 1-5): form factor, unit conversions, round trips."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.en12697 import (
    Specimen2PB,
    complex_modulus,
    fit_sinusoid,
    read_record,
    reduce_record,
)


def test_gamma_of_paper_trapezoid_by_hand():
    # b = 25, B = 56, e = 25, h = 250 mm:
    # 12 h^3 / (e (B-b)^3) = 187 500 000 / 744 775 = 251.75388...
    # bracket = (2 - 25/112) * 25/56 - 1.5 - ln(25/56)
    #         = 1.7767857143 * 0.4464285714 - 1.5 + 0.8064758658 = 0.0996837740
    prefactor = 187_500_000 / 744_775
    bracket = 0.7932079082 - 1.5 + 0.8064758658
    assert Specimen2PB().gamma_per_mm == pytest.approx(prefactor * bracket, rel=1e-8)
    assert Specimen2PB().gamma_per_mm == pytest.approx(25.0958, abs=1e-4)


def test_mass_factor_in_grams():
    assert Specimen2PB().mu_g == pytest.approx(0.135 * 600 + 235)  # 316 g
    assert Specimen2PB(M_kg=1.0, m_kg=0.5).mu_g == pytest.approx(635.0)


def test_complex_modulus_unit_conversions_against_si():
    spec = Specimen2PB()
    F0, z0, psi, f = 180.0, 63e-6, 20.0, 10.0
    out = complex_modulus(F0, z0, psi, f, spec)
    # SI: gamma in 1/m, stiffness in N/m, mu in kg -> E in Pa
    gamma_si = spec.gamma_per_mm * 1e3
    mu_kg = 0.135 * spec.M_kg + spec.m_kg
    w = 2 * math.pi * f
    E1 = gamma_si * (F0 / z0 * math.cos(math.radians(psi)) + mu_kg * w**2) * 1e-6
    E2 = gamma_si * (F0 / z0 * math.sin(math.radians(psi))) * 1e-6
    assert out["E1_MPa"] == pytest.approx(E1, rel=1e-12)
    assert out["E2_MPa"] == pytest.approx(E2, rel=1e-12)
    assert out["E_norm_MPa"] == pytest.approx(math.hypot(E1, E2), rel=1e-12)
    assert out["phase_deg"] == pytest.approx(math.degrees(math.atan2(E2, E1)), abs=1e-12)
    # inertia correction raises E1 and lowers Phi relative to the bare force/displacement ratio
    assert out["phase_deg"] < psi
    assert out["mu_g"] == pytest.approx(316.0)


def test_complex_modulus_rejects_nonpositive_displacement():
    with pytest.raises(ValueError):
        complex_modulus(100.0, 0.0, 10.0, 10.0)


def test_fit_sinusoid_recovers_offset_drift_and_phase_exactly():
    t = np.linspace(3.0, 4.37, 700)  # not a whole number of cycles, shifted time origin
    y = 0.2 - 0.05 * t + 1.7 * np.sin(2 * np.pi * 6.0 * t - 2.5)
    fit = fit_sinusoid(t, y, 6.0)
    assert fit["amplitude"] == pytest.approx(1.7, rel=1e-10)
    assert fit["phase_rad"] == pytest.approx(-2.5, abs=1e-10)
    assert fit["offset"] == pytest.approx(0.2, abs=1e-10)
    assert fit["drift"] == pytest.approx(-0.05, abs=1e-10)


def synthetic_record(E_MPa, phi_deg, f, spec, duration, fs, noise=0.0, seed=0, A=63e-6):
    """Head displacement and force of a 2PB test on a linear viscoelastic specimen.

    Head stiffness k* = E*/gamma (N/mm -> x1e3 N/m); the measured force lacks the inertia
    of the moving mass: F* = (k* - mu w^2) z*.  Offsets, drifts and white noise added.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / fs)
    w = 2 * np.pi * f
    E = E_MPa * np.exp(1j * np.radians(phi_deg))
    k = E / spec.gamma_per_mm * 1e3  # N/m
    mu_kg = spec.mu_g * 1e-3
    z_c = A * np.exp(1j * 0.4)
    F_c = (k - mu_kg * w**2) * z_c
    z = np.imag(z_c * np.exp(1j * w * t)) + 2e-6 + 1e-7 * t
    F = np.imag(F_c * np.exp(1j * w * t)) + 3.0 - 0.2 * t
    z = z + noise * abs(z_c) * rng.standard_normal(t.size)
    F = F + noise * abs(F_c) * rng.standard_normal(t.size)
    return t, z, F


@pytest.mark.parametrize("E_MPa, phi_deg, f", [(25000.0, 3.0, 3.0), (12000.0, 20.0, 10.0), (1500.0, 45.0, 40.0)])
def test_round_trip_lab_record_with_noise_drift_and_inertia(E_MPa, phi_deg, f):
    spec = Specimen2PB(M_kg=0.62)
    t, z, F = synthetic_record(E_MPa, phi_deg, f, spec, duration=30.0, fs=2000.0, noise=0.01, seed=7)
    row = reduce_record(t, z, F, spec, f, window_s=10.0)
    assert row["E_norm_MPa"] == pytest.approx(E_MPa, rel=1e-3)
    assert row["phase_deg"] == pytest.approx(phi_deg, abs=0.02)
    assert row["z0_m"] == pytest.approx(63e-6, rel=1e-3)
    assert 0 < row["psi_deg"] < 90
    assert row["window_start_s"] == pytest.approx(20.0, abs=1e-3)
    for key in ("F0_N", "z0_m", "psi_deg", "gamma_per_mm", "mu_g", "E1_MPa", "E2_MPa", "E_norm_MPa", "phase_deg"):
        assert key in row


def test_last_cycle_window_of_a_simulation_record():
    spec = Specimen2PB()
    f = 40.0
    t, z, F = synthetic_record(8000.0, 12.0, f, spec, duration=5 / f, fs=f * 500)
    row = reduce_record(t, z, F, spec, f, window_cycles=1)
    assert row["n_samples"] == pytest.approx(501, abs=1)
    assert row["E_norm_MPa"] == pytest.approx(8000.0, rel=1e-6)
    assert row["phase_deg"] == pytest.approx(12.0, abs=1e-6)


def test_window_options_are_checked():
    t = np.linspace(0, 1, 100)
    with pytest.raises(ValueError, match="not both"):
        reduce_record(t, np.sin(t), np.sin(t), None, 3.0, window_s=0.5, window_cycles=1)
    with pytest.raises(ValueError, match="longer than the record"):
        reduce_record(t, np.sin(t), np.sin(t), None, 3.0, window_s=10.0)


def write_record(tmp_path, meta_update=None, drop_column=None):
    spec = Specimen2PB()
    t, z, F = synthetic_record(12000.0, 20.0, 10.0, spec, duration=12.0, fs=1000.0, noise=0.005, seed=3)
    frame = pd.DataFrame({"time_s": t, "displacement_m": z, "force_N": F})
    if drop_column:
        frame = frame.drop(columns=drop_column)
    csv = tmp_path / "rec.csv"
    frame.to_csv(csv, index=False, float_format="%.12g")
    meta = {**spec.as_dict(), "temperature_C": 20.0, "frequency_Hz": 10.0, **(meta_update or {})}
    meta = {k: v for k, v in meta.items() if v is not None}
    js = tmp_path / "rec.json"
    js.write_text(json.dumps(meta))
    return csv, js


def test_cli_reduce_writes_one_row(tmp_path):
    csv, js = write_record(tmp_path)
    out = tmp_path / "out" / "reduced.csv"
    assert main(["reduce", str(csv), "--meta", str(js), "--window-s", "10", "-o", str(out)]) == 0
    row = pd.read_csv(out)
    assert len(row) == 1
    for key in ("F0_N", "z0_m", "psi_deg", "gamma_per_mm", "mu_g", "E1_MPa", "E2_MPa", "E_norm_MPa", "phase_deg"):
        assert key in row.columns
    assert row["E_norm_MPa"].iloc[0] == pytest.approx(12000.0, rel=1e-3)
    assert row["temperature_C"].iloc[0] == 20.0


@pytest.mark.parametrize(
    "update, key",
    [
        ({"h_mm": None}, "h_mm"),
        ({"M_kg": -1}, "M_kg"),
        ({"frequency_Hz": "ten"}, "frequency_Hz"),
        ({"temperature_C": None}, "temperature_C"),
    ],
)
def test_bad_sidecar_names_file_and_key(tmp_path, update, key):
    csv, js = write_record(tmp_path, meta_update=update)
    out = tmp_path / "reduced.csv"
    with pytest.raises(InputError, match=key) as info:
        read_record(csv, js)
    assert "rec.json" in str(info.value)
    assert main(["reduce", str(csv), "--meta", str(js), "-o", str(out)]) == 2
    assert not out.exists()


def test_bad_record_csv_names_column(tmp_path):
    csv, js = write_record(tmp_path, drop_column="force_N")
    with pytest.raises(InputError, match="force_N"):
        read_record(csv, js)


def test_specimen_from_json_rejects_non_object(tmp_path):
    path = tmp_path / "spec.json"
    path.write_text("[1, 2]")
    with pytest.raises(InputError, match="spec.json"):
        Specimen2PB.from_json(path)
    path.write_text(json.dumps({**Specimen2PB().as_dict(), "b_mm": 60.0}))
    with pytest.raises(InputError, match="b_mm"):
        Specimen2PB.from_json(path)
