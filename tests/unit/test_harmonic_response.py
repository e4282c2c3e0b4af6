"""Harmonic rows through Eqs. 1-5, the time-domain check, and the harmonic subcommands."""

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample, sample_from_bonds
from asphalt_nscd.sample.store import read_sample, specimen_geometry_mm, write_sample
from asphalt_nscd.harmonic.response import harmonic_rows
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.harmonic.timedomain import time_domain_row
from asphalt_nscd.lab.en12697 import Specimen2PB
from asphalt_nscd.rheology.laws import GeneralizedBurgers, bond_scale, tangential_ratio

GEOMETRY = {"b_mm": 25.0, "B_mm": 56.0, "e_mm": 25.0, "h_mm": 250.0}
LAW_30 = GeneralizedBurgers.burgers(Em=1.30e7, eta_m=3.45e5, Ek=9.31e6, eta_k=1.31e5)
A = 63e-6
#: The kinematics of the time-domain NSCD core: bonds at the barycentres, head translating.
BARY = {"bond_kinematics": "barycentre", "head_rotation": "clamped"}
BARY_CLI = ["--bond-kinematics", "barycentre", "--head-rotation", "clamped"]


@pytest.fixture
def column(tmp_path):
    """One sphere (r = 1 mm, 0.1 g) bonded to both plates, 4 mm below the head plate."""
    path = tmp_path / "col.h5"
    write_sample(
        path,
        sample_from_bonds(
            [[0, 0, 6e-3]], [1e-3], [1e-4], [[0, 0, 0], [0, 0, 0.01]], [0, 0], [-1, -2], plate_mass=(np.inf, 0.235)
        ),
    )
    return path


@pytest.fixture
def params_csv(tmp_path):
    path = tmp_path / "params.csv"
    pd.DataFrame(
        {
            "temperature_C": [20.0, 30.0],
            "Em_MPa": [20.2, 13.0],
            "eta_m_MPa_s": [1.79, 0.345],
            "Ek_MPa": [27.2, 9.31],
            "eta_k_MPa_s": [0.461, 0.131],
        }
    ).to_csv(path, index=False)
    return path


def test_quasi_static_row_is_gamma_times_network_stiffness(column):
    # inertia "none": Eq. 1 with mu = 0.135 M + m returns gamma |K| exactly, and the network
    # factor is the closed form gamma RT / (1/a_bottom + 1/a_top) (SI), real, at every f
    system = HarmonicSystem(network_from_sample(read_sample(column)), **BARY)
    a_eff = 1.0 / (1.0 / bond_scale(1e-3, 6e-3) + 1.0 / bond_scale(1e-3, 4e-3))
    gamma = Specimen2PB(**GEOMETRY).gamma_per_mm
    factor = gamma * 1e3 * tangential_ratio(0.35) * a_eff  # gamma in 1/m times a in m
    rows = harmonic_rows(system, LAW_30, 30.0, [0.1, 3.0, 40.0], GEOMETRY, inertia="none")
    for row in rows:
        assert row["mu_g"] == pytest.approx((0.135 * 1e-4 + 0.235) * 1e3)
        assert row["network_factor"] == pytest.approx(float(factor), rel=1e-9)
        assert abs(row["phase_difference_deg"]) < 1e-8
        e_star = LAW_30.complex_modulus(2 * np.pi * row["frequency_Hz"]) * 1e-6
        assert row["E1_MPa"] == pytest.approx(float(factor) * e_star.real, rel=1e-9)
        assert row["E2_MPa"] == pytest.approx(float(factor) * e_star.imag, rel=1e-9)


def test_geometry_from_sample_attributes(tmp_path, column):
    import h5py

    assert specimen_geometry_mm(read_sample(column)) == GEOMETRY
    with h5py.File(column, "a") as h5:
        h5.attrs["h_m"] = 0.175
    assert specimen_geometry_mm(read_sample(column))["h_mm"] == pytest.approx(175.0)


@pytest.mark.parametrize("options", [BARY, {"bond_kinematics": "contact", "head_rotation": "free"}])
@pytest.mark.parametrize("f", [10.0, 40.0])
def test_time_domain_converges_to_the_harmonic_solution(tmp_path, f, options):
    path = tmp_path / "lattice.h5"
    write_sample(path, lattice_sample(12, seed=2, radius_range=(1.0e-3, 1.5e-3)))
    system = HarmonicSystem(network_from_sample(read_sample(path)), **options)
    ref = harmonic_rows(system, LAW_30, 30.0, [f], GEOMETRY, inertia="full", solver="direct")[0]
    errors = []
    for dt in (2e-4, 1e-4):
        td = time_domain_row(path, LAW_30, f, GEOMETRY, dt, **options)
        errors.append((abs(td["E_norm_MPa"] / ref["E_norm_MPa"] - 1), abs(td["phase_deg"] - ref["phase_deg"])))
    assert errors[-1][0] < 5e-3 and errors[-1][1] < 0.1  # the tolerances
    assert errors[-1][0] < errors[0][0]  # and the difference shrinks with dt


def test_harmonic_cli_rows_and_errors(tmp_path, column, params_csv, capsys):
    out = tmp_path / "h.csv"
    assert (
        main(
            [
                "harmonic",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--frequency",
                "3",
                "40",
                "--mode",
                "paper",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    frame = pd.read_csv(out)
    assert len(frame) == 4 and set(frame["mode"]) == {"paper"} and set(frame["sample"]) == {"col"}
    for col in (
        "temperature_C",
        "frequency_Hz",
        "F0_N",
        "z0_m",
        "psi_deg",
        "gamma_per_mm",
        "mu_g",
        "E1_MPa",
        "E2_MPa",
        "E_norm_MPa",
        "phase_deg",
        "network_factor",
    ):
        assert frame[col].notna().all(), col
    summary = tmp_path / "summary.csv"
    pd.DataFrame({"temperature_C": [30.0, 30.0, 5.0], "frequency_Hz": [1.0, 25.0, 1.0]}).to_csv(summary, index=False)
    out2 = tmp_path / "m.csv"
    assert (
        main(
            [
                "harmonic",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--frequencies-from",
                str(summary),
                "-o",
                str(out2),
            ]
        )
        == 0
    )
    frame2 = pd.read_csv(out2)
    assert list(frame2["frequency_Hz"]) == [1.0, 25.0] and set(frame2["temperature_C"]) == {30.0}
    # a temperature the table lacks, and two frequency sources
    assert (
        main(
            [
                "harmonic",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--temperature",
                "15",
                "--frequency",
                "3",
                "-o",
                str(out2),
            ]
        )
        == 2
    )
    assert "temperature_C = 15" in capsys.readouterr().err
    assert (
        main(
            [
                "harmonic",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--frequency",
                "3",
                "--sweep",
                "1",
                "10",
                "3",
                "-o",
                str(out2),
            ]
        )
        == 2
    )


def test_network_factor_plot_and_sensitivity_cli(tmp_path, column, params_csv):
    sweep = tmp_path / "sweep.csv"
    assert (
        main(
            [
                "harmonic",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--sweep",
                "0.1",
                "100",
                "7",
                "--mode",
                "paper",
                "-o",
                str(sweep),
            ]
        )
        == 0
    )
    nf, nfs = tmp_path / "nf.csv", tmp_path / "nfs.csv"
    assert main(["harmonic-network-factor", str(sweep), "-o", str(nf), "--summary", str(nfs)]) == 0
    assert len(pd.read_csv(nf)) == 14 and (pd.read_csv(nfs)["n_samples"] == 1).all()
    figs = {k: tmp_path / f"{k}.png" for k in ("isotherms-modulus", "black", "cole-cole")}
    args = ["harmonic-plot", "--harmonic", str(sweep)]
    for k, p in figs.items():
        args += [f"--{k}", str(p)]
    assert main(args) == 0
    assert all(p.stat().st_size > 0 for p in figs.values())
    sens = tmp_path / "sens.csv"
    assert (
        main(
            [
                "harmonic-sensitivity",
                "--sample",
                str(column),
                "--parameters",
                str(params_csv),
                *BARY_CLI,
                "--temperature",
                "20",
                "--frequency",
                "10",
                "--levels",
                "10",
                "50",
                "--inertia",
                "none",
                "-o",
                str(sens),
                "--figure",
                str(tmp_path / "s.png"),
            ]
        )
        == 0
    )
    frame = pd.read_csv(sens)
    assert len(frame) == 1 + 4 * 4
    # quasi-static: the sample's relative change equals the macro law's
    np.testing.assert_allclose(frame["dE_norm_percent"], frame["macro_dE_norm_percent"], atol=1e-9)
    np.testing.assert_allclose(frame["dphase_deg"], frame["macro_dphase_deg"], atol=1e-9)


def test_bench_cli(tmp_path):
    out = tmp_path / "bench.json"
    assert main(["harmonic-bench", "--n", "100", "--td-steps", "2", "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["n_spheres"] == 100 and result["peak_rss_mb"] > 0
    assert result["first_TF_total_s"] > 0 and result["time_domain_job_s"] > 0
    assert set(result["orderings"]) == {"metis", "mmd", "colamd"}
    assert result["orderings"]["mmd"]["fill_ratio_to_mmd"] == 1.0
    assert all(v["relative_residual"] < 1e-6 for v in result["orderings"].values())
    assert result["baseline"]["converged"] and result["baseline"]["speedup"] > 0
    first = result["per_frequency"][0]
    assert first["new_factorisations"][0]["kind"] == "G - sigma M"
    assert len(result["subsequent_TF_s"]) == len(result["per_frequency"]) - 1
