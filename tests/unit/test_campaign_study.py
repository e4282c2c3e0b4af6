"""Campaign tables (isotherms, Table 4 analogue, sensitivity, units question) and the CLI."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.campaign import study
from asphalt_nscd.cli import main
from asphalt_nscd.harmonic.network import lattice_sample, write_sample
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.calibration import load_table3
from asphalt_nscd.sample.store import read_sample

TABLE3 = "data/paper/table3_burgers.csv"


@pytest.fixture(scope="module")
def table():
    return load_table3(TABLE3, units="Pa")


def _rows(table, T, freqs, factor_E=1.0, dphi=0.0, samples=("s1", "s2")):
    ref = study.burgers_reference(table, [T] * len(freqs), freqs)
    out = []
    for s in samples:
        for _, r in ref.iterrows():
            E, P = r["E_norm_MPa_ref"] * factor_E, r["phase_deg_ref"] + dphi
            out.append({"temperature_C": T, "frequency_Hz": r["frequency_Hz"], "sample": s,
                        "E_norm_MPa": E, "phase_deg": P, "E1_MPa": E * math.cos(math.radians(P)),
                        "E2_MPa": E * math.sin(math.radians(P)), "F0_N": E, "z0_m": 63e-6,
                        "dt_s": 5e-5})
    return pd.DataFrame(out)


def test_parameters_at_and_factors(table):
    p = study.parameters_at(table, 20, {"Em": 1.5, "eta_k": 0.5})
    assert p["Em_MPa"] == pytest.approx(1.5 * 20.2)
    assert p["eta_k_MPa_s"] == pytest.approx(0.5 * 0.461)
    assert p["Ek_MPa"] == pytest.approx(27.2)
    with pytest.raises(InputError, match="no Burger's parameters at 17"):
        study.parameters_at(table, 17)
    with pytest.raises(InputError, match="factor 'E1'"):
        study.parameters_at(table, 20, {"E1": 2.0})


def test_isotherms_and_table4_mean_relative_error(table):
    freqs = [3.0, 10.0, 40.0]
    rows = pd.concat([_rows(table, 15, freqs, 1.10, 0.0), _rows(table, 20, freqs, 0.95, 1.0)])
    ref = study.burgers_reference(table, rows["temperature_C"], rows["frequency_Hz"]).drop_duplicates()
    iso = study.numerical_isotherms(rows, ref)
    assert len(iso) == 6 and (iso["n_samples"] == 2).all()
    t4 = study.table4(iso, pd.read_csv("data/paper/table4_mre.csv")).set_index("temperature_C")
    assert t4.loc[15.0, "mre_E_norm_pct"] == pytest.approx(10.0)
    assert t4.loc[15.0, "mre_phase_pct"] == pytest.approx(0.0, abs=1e-9)
    assert t4.loc[20.0, "mre_E_norm_pct"] == pytest.approx(5.0)
    phase20 = iso[iso.temperature_C == 20.0]["phase_deg_ref"]
    assert t4.loc[20.0, "mre_phase_pct"] == pytest.approx(np.mean(100.0 / phase20))
    assert t4.loc[20.0, "paper_mre_E_norm_pct"] == pytest.approx(2.86)
    with pytest.raises(InputError, match="no reference"):
        study.numerical_isotherms(rows, ref[ref.temperature_C == 15.0])


def test_sensitivity_table(table):
    base = _rows(table, 20, [3.0, 40.0], samples=("s1",))
    var = _rows(table, 20, [3.0, 40.0], factor_E=1.2, samples=("s1",)).assign(parameter="Em", factor=1.5)
    out = study.sensitivity_table(var, base)
    em = out[(out.parameter == "Em") & (out.factor == 1.5)]
    np.testing.assert_allclose(em["change_E_norm_pct"], 20.0)
    assert set(out["parameter"]) == set(study.SENSITIVITY_PARAMETERS)
    assert (out[out.factor == 1.0]["change_E_norm_pct"].abs() < 1e-9).all()


def test_units_question_scaling(tmp_path):
    path = tmp_path / "s.h5"
    write_sample(path, **lattice_sample(30, seed=1))
    sample = read_sample(path)
    rows = {}
    for units, k in (("Pa", 1.0), ("kPa", 1e3)):
        r = _rows(load_table3(TABLE3, units), 15, [3.0, 40.0], samples=("s1",))
        rows[units] = r.assign(F0_N=r["E_norm_MPa"] * 1e-3)
    micro = {"grain_mass_kg": 2.86e-5, "r_min_mm": [1.0], "l0_mm": [2.0]}
    out = study.units_question(TABLE3, rows, sample, 15, micro).set_index("table3_units")
    assert out.loc["Pa", "dt_e_paper_s"] == pytest.approx(2.74e-5, rel=0.01)  # data/paper/SOURCE.md
    assert out.loc["Pa", "dt_e_paper_s"] / out.loc["kPa", "dt_e_paper_s"] == pytest.approx(math.sqrt(1e3))
    assert out.loc["kPa", "first_resonance_Em_Hz"] / out.loc["Pa", "first_resonance_Em_Hz"] == \
        pytest.approx(math.sqrt(1e3))
    assert out.loc["Pa", "mre_E_norm_pct"] == pytest.approx(0.0, abs=1e-9)
    # head stiffness from the 2PB form factor: Em / gamma (MPa / (1/mm) = N/mm)
    assert out.loc["Pa", "head_stiffness_Em_N_m"] == pytest.approx(24.3 / out.loc["Pa", "gamma_per_mm"] * 1e3)


def test_cli_run_2pb_and_bad_input(tmp_path):
    sample = tmp_path / "s1.h5"
    write_sample(sample, **lattice_sample(30, seed=2, radius_range=(0.9e-3, 1.5e-3)), plate_mass=(np.inf, 1e-3))
    settings = json.dumps({"n_cycles": 2, "dt_policy": "steps_per_cycle", "steps_per_cycle": 40,
                           "dt_max_s": 0.02, "checkpoint_every": 0})
    base = ["run-2pb", "--sample", str(sample), "--parameters", TABLE3, "--table3-units", "Pa",
            "--temperature", "20", "--frequency", "10", "--settings-json", settings, "--no-progress",
            "-o", str(tmp_path / "r.h5"), "--row", str(tmp_path / "r.csv")]
    assert main(base + ["--factor", "Em=1.5", "--mode", "sensitivity"]) == 0
    row = pd.read_csv(tmp_path / "r.csv").iloc[0]
    assert row["sample"] == "s1" and row["mode"] == "sensitivity" and row["parameter"] == "Em"
    assert row["Em_MPa"] == pytest.approx(1.5 * 20.2) and row["n_steps"] == 80
    assert main(base + ["--factor", "Em=big"]) == 2
    assert main(base[:-4] + ["--settings-json", '{"dt": 1}', "-o", "x.h5", "--row", "x.csv"]) == 2


def test_cli_aggregation_and_figures(tmp_path):
    sample = tmp_path / "s1.h5"
    write_sample(sample, **lattice_sample(30, seed=4, radius_range=(0.9e-3, 1.5e-3)), plate_mass=(np.inf, 1e-3))
    settings = json.dumps({"n_cycles": 2, "dt_policy": "steps_per_cycle", "steps_per_cycle": 40,
                           "dt_max_s": 0.02, "checkpoint_every": 0, "profile_instants": 4})
    rows, recs = [], []
    for f in (3, 40):
        rec, row = tmp_path / f"20C_{f}Hz.h5", tmp_path / f"20C_{f}Hz.csv"
        assert main(["run-2pb", "--sample", str(sample), "--parameters", TABLE3, "--table3-units", "Pa",
                     "--temperature", "20", "--frequency", str(f), "--settings-json", settings,
                     "--no-progress", "-o", str(rec), "--row", str(row)]) == 0
        rows.append(str(row))
        recs.append(str(rec))
    out = tmp_path / "out"
    assert main(["campaign-isotherms", "--rows", *rows, "--parameters", TABLE3, "--table3-units", "Pa",
                 "--paper-table4", "data/paper/table4_mre.csv", "--isotherms", str(out / "iso.csv"),
                 "--table4", str(out / "t4.csv"), "--figure-modulus", str(out / "f9.png"),
                 "--figure-phase", str(out / "f10.png")]) == 0
    t4 = pd.read_csv(out / "t4.csv")
    assert list(t4["temperature_C"]) == [20.0] and t4["n_frequencies"].iloc[0] == 2
    assert main(["campaign-last-cycle", "--record", recs[1], "--figure-cycle", str(out / "f7.png"),
                 "--figure-profile", str(out / "f8.png")]) == 0
    assert main(["campaign-dt-study", "--records", *recs[:1], "--rows", *rows[:1], "--parameters", TABLE3,
                 "--table3-units", "Pa", "--table", str(out / "dt.csv"), "--figure", str(out / "f6.png")]) == 0
    for name in ("f6", "f7", "f8", "f9", "f10"):
        assert (out / f"{name}.png").stat().st_size > 1000


def test_projection_counts_the_workflow_jobs():
    """The projection enumerates the same jobs as workflow/rules/simulation.smk (smoke: 16)."""
    import yaml

    from asphalt_nscd.campaign.bench import campaign_jobs, project_campaign

    with open("config/smoke.yaml") as fh:
        cfg = yaml.safe_load(fh)
    jobs = campaign_jobs(cfg["campaign"], len(cfg["sample"]["seeds"]))
    # paper 1 + measured 1 + extended 1 + dt study 2 + sensitivity 8 + its x1 baseline (20 degC,
    # 40 Hz, outside the paper schedule) 1 + units kPa 1 + kPa unbreakable 1 = `snakemake -n` run_2pb
    assert sum(j["n_samples"] for j in jobs) == 16
    ext = [j for j in jobs if j["mode"] == "extended"]
    meas = [j for j in jobs if j["mode"] == "measured"]
    assert [(j["temperature_C"], j["frequency_Hz"], j["dt_s"]) for j in ext] == \
        [(j["temperature_C"], j["frequency_Hz"], j["dt_s"]) for j in meas]
    p = project_campaign(cfg["campaign"], 1, s_per_step=1e-3, overhead_s=0.0)
    assert p["total_core_h"] * 3600 == pytest.approx(p["n_steps_total"] * 1e-3)
    assert p["wall_h"]["2"] == pytest.approx(max(p["total_core_h"] / 2, p["longest_job_h"]))
