"""Campaign tables (isotherms, Table 4 analogue, sensitivity, units question) and the CLI."""

from cli_options import set_options
import json
import math

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd import config
from asphalt_nscd.campaign import study
from asphalt_nscd.cli import main
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.calibration import load_table3
from asphalt_nscd.sample.store import read_sample, write_sample

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
            out.append(
                {
                    "temperature_C": T,
                    "frequency_Hz": r["frequency_Hz"],
                    "sample": s,
                    "E_norm_MPa": E,
                    "phase_deg": P,
                    "E1_MPa": E * math.cos(math.radians(P)),
                    "E2_MPa": E * math.sin(math.radians(P)),
                    "F0_N": E,
                    "z0_m": 63e-6,
                    "dt_s": 5e-5,
                }
            )
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
    write_sample(path, lattice_sample(30, seed=1))
    sample = read_sample(path)
    rows = {}
    for units, k in (("Pa", 1.0), ("kPa", 1e3)):
        r = _rows(load_table3(TABLE3, units), 15, [3.0, 40.0], samples=("s1",))
        rows[units] = r.assign(F0_N=r["E_norm_MPa"] * 1e-3)
    micro = {"grain_mass_kg": 2.86e-5, "r_min_mm": [1.0], "l0_mm": [2.0]}
    out = study.units_question(TABLE3, rows, sample, 15, micro).set_index("table3_units")
    assert out.loc["Pa", "dt_e_paper_s"] == pytest.approx(2.74e-5, rel=0.01)  # data/paper/SOURCE.md
    assert out.loc["Pa", "dt_e_paper_s"] / out.loc["kPa", "dt_e_paper_s"] == pytest.approx(math.sqrt(1e3))
    assert out.loc["kPa", "first_resonance_Em_Hz"] / out.loc["Pa", "first_resonance_Em_Hz"] == pytest.approx(
        math.sqrt(1e3)
    )
    assert out.loc["Pa", "mre_E_norm_pct"] == pytest.approx(0.0, abs=1e-9)
    # head stiffness from the 2PB form factor: Em / gamma (MPa / (1/mm) = N/mm)
    assert out.loc["Pa", "head_stiffness_Em_N_m"] == pytest.approx(24.3 / out.loc["Pa", "gamma_per_mm"] * 1e3)


def test_reading_evidence_is_computed_under_each_reading(tmp_path):
    """The evidence table of the units question: dt_e agrees with the paper (2e-5 s) only in
    Pa, the Burger's |E*| is a mix's only in kPa, the resonance leaves the 3-40 Hz band only
    in kPa, intact bonds only where none broke; what Table 3 does not enter supports both,
    and the 63 um bending strain of the trapezoid is the paper's "below 50e-6"."""
    path = tmp_path / "s.h5"
    write_sample(path, lattice_sample(30, seed=1))
    rows = {}
    for units in ("Pa", "kPa"):
        r = _rows(load_table3(TABLE3, units), 15, [3.0, 40.0], samples=("s1",))
        # the head stiffness of a 2PB cantilever of the Burger's modulus: F0 / z0 = |E*| / gamma
        rows[units] = r.assign(
            F0_N=r["E_norm_MPa"] / 25.1 * 1e3 * r["z0_m"], n_bonds=100, n_broken_total=0 if units == "Pa" else 2
        )
    micro = {"grain_mass_kg": 2.86e-5, "r_min_mm": [1.0], "l0_mm": [2.0]}
    units = study.units_question(TABLE3, rows, read_sample(path), 15, micro)
    ev = study.reading_evidence(units, mix_E_MPa=1.5e4)

    def row(start):
        hit = ev[ev["evidence"].str.startswith(start)]
        assert len(hit) == 1, start
        return hit.iloc[0]

    assert row("time scale dt_e")["supports"] == "Pa"
    assert row("time scale dt_g")["supports"] == "both"
    assert row("grain mass")["supports"] == "both"
    assert row("bonds intact")["supports"] == "Pa"
    assert row("|E*|")["supports"] == "kPa"
    res = row("first resonance")
    assert res["Pa"] < 40 < 80 < res["kPa"] and res["supports"] == "kPa"
    strain = row("largest bending strain")
    assert strain["supports"] == "both" and 4e-5 < strain["Pa"] < 5e-5
    with pytest.raises(InputError, match="rows 'Pa' and 'kPa'"):
        study.reading_evidence(units[units["table3_units"] == "Pa"])


def test_mix_modulus_at_interpolates_between_isotherms():
    from asphalt_nscd.lab.measured import summarize

    # the summary's own schema (two tests per cell, averaged)
    measured = pd.DataFrame(
        {
            "temperature_C": [10.0, 10.0, 20.0, 20.0] * 2,
            "frequency_Hz": [1.0, 100.0] * 4,
            "E_norm_MPa": [0.9e4, 0.9e4 * 100, 0.9e3, 0.9e3 * 100, 1.1e4, 1.1e4 * 100, 1.1e3, 1.1e3 * 100],
            "phase_deg": [10.0] * 8,
            "test": ["a"] * 4 + ["b"] * 4,
        }
    )
    summary = summarize(measured)
    assert study.mix_modulus_at(summary, 15.0, 10.0) == pytest.approx(math.sqrt(1e4 * 1e3) * 10, rel=1e-12)
    with pytest.raises(InputError, match="bracket"):
        study.mix_modulus_at(summary, 25.0, 10.0)
    with pytest.raises(InputError, match="bracket"):
        study.mix_modulus_at(summary, 15.0, 1000.0)


def test_cli_run_2pb_and_bad_input(tmp_path):
    sample = tmp_path / "s1.h5"
    write_sample(sample, lattice_sample(30, seed=2, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    settings = json.dumps(
        {"n_cycles": 2, "dt_policy": "steps_per_cycle", "steps_per_cycle": 40, "dt_max_s": 0.02, "checkpoint_every": 0}
    )
    base = [
        "run-2pb",
        "--sample",
        str(sample),
        "--parameters",
        TABLE3,
        "--table3-units",
        "Pa",
        "--temperature",
        "20",
        "--frequency",
        "10",
        *set_options(settings),
        "--no-progress",
        "-o",
        str(tmp_path / "r.h5"),
        "--row",
        str(tmp_path / "r.csv"),
    ]
    assert main(base + ["--factor", "Em=1.5", "--mode", "sensitivity"]) == 0
    row = pd.read_csv(tmp_path / "r.csv").iloc[0]
    assert row["sample"] == "s1" and row["mode"] == "sensitivity" and row["parameter"] == "Em"
    assert row["Em_MPa"] == pytest.approx(1.5 * 20.2) and row["n_steps"] == 80
    assert main(base + ["--factor", "Em=big"]) == 2
    assert main(base[:-4] + ["--set", "dt=1", "-o", "x.h5", "--row", "x.csv"]) == 2


def test_cli_aggregation_and_figures(tmp_path):
    sample = tmp_path / "s1.h5"
    write_sample(sample, lattice_sample(30, seed=4, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    settings = json.dumps(
        {
            "n_cycles": 2,
            "dt_policy": "steps_per_cycle",
            "steps_per_cycle": 40,
            "dt_max_s": 0.02,
            "checkpoint_every": 0,
            "profile_instants": 4,
        }
    )
    rows, recs = [], []
    for f in (3, 40):
        rec, row = tmp_path / f"20C_{f}Hz.h5", tmp_path / f"20C_{f}Hz.csv"
        assert (
            main(
                [
                    "run-2pb",
                    "--sample",
                    str(sample),
                    "--parameters",
                    TABLE3,
                    "--table3-units",
                    "Pa",
                    "--temperature",
                    "20",
                    "--frequency",
                    str(f),
                    *set_options(settings),
                    "--no-progress",
                    "-o",
                    str(rec),
                    "--row",
                    str(row),
                ]
            )
            == 0
        )
        rows.append(str(row))
        recs.append(str(rec))
    out = tmp_path / "out"
    assert (
        main(
            [
                "campaign-isotherms",
                "--rows",
                *rows,
                "--parameters",
                TABLE3,
                "--table3-units",
                "Pa",
                "--paper-table4",
                "data/paper/table4_mre.csv",
                "--isotherms",
                str(out / "iso.csv"),
                "--table4",
                str(out / "t4.csv"),
                "--figure-modulus",
                str(out / "f9.png"),
                "--figure-phase",
                str(out / "f10.png"),
            ]
        )
        == 0
    )
    t4 = pd.read_csv(out / "t4.csv")
    assert list(t4["temperature_C"]) == [20.0] and t4["n_frequencies"].iloc[0] == 2
    assert (
        main(
            [
                "campaign-last-cycle",
                "--record",
                recs[1],
                "--figure-cycle",
                str(out / "f7.png"),
                "--figure-profile",
                str(out / "f8.png"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "campaign-dt-study",
                "--records",
                *recs[:1],
                "--rows",
                *rows[:1],
                "--parameters",
                TABLE3,
                "--table3-units",
                "Pa",
                "--table",
                str(out / "dt.csv"),
                "--figure",
                str(out / "f6.png"),
            ]
        )
        == 0
    )
    for name in ("f6", "f7", "f8", "f9", "f10"):
        assert (out / f"{name}.png").stat().st_size > 1000


def test_projection_counts_the_workflow_jobs():
    """The projection enumerates the same jobs as workflow/rules/campaign.smk (smoke: 16)."""
    from asphalt_nscd.campaign.bench import campaign_jobs, project_campaign

    cfg = config.load(["config/smoke.yaml"])  # merged over config/config.yaml, as Snakemake
    jobs = campaign_jobs(cfg["campaign"], len(cfg["sample"]["seeds"]))
    # paper 1 + measured 1 + extended 1 + dt study 2 + sensitivity 8 + its x1 baseline (20 degC,
    # 40 Hz, outside the paper schedule) 1 + units kPa 1 + kPa unbreakable 1 = `snakemake -n` run_2pb
    assert sum(j["n_samples"] for j in jobs) == 16
    ext = [j for j in jobs if j["mode"] == "extended"]
    meas = [j for j in jobs if j["mode"] == "measured"]
    assert [(j["temperature_C"], j["frequency_Hz"], j["dt_s"]) for j in ext] == [
        (j["temperature_C"], j["frequency_Hz"], j["dt_s"]) for j in meas
    ]
    p = project_campaign(cfg["campaign"], 1, s_per_step=1e-3, overhead_s=0.0)
    assert p["total_core_h"] * 3600 == pytest.approx(p["n_steps_total"] * 1e-3)
    assert p["wall_h"]["2"] == pytest.approx(max(p["total_core_h"] / 2, p["longest_job_h"]))


def test_projection_counts_the_periodic_start_and_the_preparation():
    """Measured and extended jobs of config/smoke.yaml start periodic: 1 cycle (500 steps) plus
    one periodic solve each instead of n_cycles = 2 from rest; the samples' preparation is
    added once per sample."""
    from asphalt_nscd.campaign.bench import campaign_jobs, project_campaign

    cfg = config.load(["config/smoke.yaml"])  # merged over config/config.yaml, as Snakemake
    camp = cfg["campaign"]
    jobs = {j["mode"]: j for j in campaign_jobs(camp, 1)}
    assert jobs["measured"]["start"] == jobs["extended"]["start"] == "periodic"
    assert jobs["measured"]["n_steps"] == 500 and jobs["paper"]["start"] == "rest"
    rest = {j["mode"]: j for j in campaign_jobs(camp, 1, start="rest")}
    assert rest["measured"]["n_steps"] == 1000 and rest["measured"]["start"] == "rest"
    kw = dict(s_per_step=1e-3, overhead_s=0.0, prepare_s_per_sample=100.0)
    conf = project_campaign(camp, 1, periodic_solve_s=2.0, **kw)
    before = project_campaign(camp, 1, periodic_solve_s=2.0, start="rest", **kw)
    assert conf["prepare_core_h"] * 3600 == pytest.approx(100.0)
    assert conf["total_core_h"] * 3600 == pytest.approx(conf["n_steps_total"] * 1e-3 + 2 * 2.0 + 100.0)
    assert before["total_core_h"] * 3600 == pytest.approx(before["n_steps_total"] * 1e-3 + 100.0)
    assert before["n_steps_total"] - conf["n_steps_total"] == 2 * 500
    assert conf["steps_per_job_by_mode"]["measured"] == 500
    assert conf["start_by_mode"] == {**before["start_by_mode"], "measured": "periodic", "extended": "periodic"}
    # a per-job cost function
    p = project_campaign(camp, 1, s_per_step=lambda j: 1e-3 if j["mode"] == "paper" else 0.0, overhead_s=0.0)
    assert p["total_core_h"] * 3600 == pytest.approx(p["n_steps_by_mode"]["paper"] * 1e-3)


def test_campaign_bench_per_job_on_a_sample(tmp_path):
    """campaign-bench --per-job times every job class of a config with the job's law and start
    and projects before (all from rest) and after (configured starts)."""
    import yaml

    sample = tmp_path / "s1.h5"
    write_sample(sample, lattice_sample(60, seed=2, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    params = tmp_path / "burgers.csv"
    pd.DataFrame(
        [{"temperature_C": 21.0, "Em_MPa": 1.0e4, "eta_m_MPa_s": 1.2e4, "Ek_MPa": 7.7e3, "eta_k_MPa_s": 830.0}]
    ).to_csv(params, index=False)
    law = tmp_path / "law.json"
    law.write_text(
        json.dumps(
            {"temperatures": {"21": {"Em": 1e10, "eta_m": 1e10, "Ek": [8e9, 2e10], "eta_k": [8e8, 1e8], "E_inf": 5e7}}}
        )
    )
    cfg = config.load(["config/smoke.yaml"])  # merged over config/config.yaml, as Snakemake
    cfg["campaign"]["dt_study"]["dt_s"] = [2.0e-4]
    cfg_path = tmp_path / "smoke.yaml"
    cfg_path.write_text(yaml.safe_dump(cfg))
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"timings_s": {"total_s": 360.0}}))
    out = tmp_path / "bench.json"
    assert (
        main(
            [
                "campaign-bench",
                "--sample",
                str(sample),
                "--steps",
                "3",
                "--config",
                str(cfg_path),
                "--per-job",
                "--job-steps",
                "2",
                "--table3",
                TABLE3,
                "--parameters",
                str(params),
                "--law-json",
                str(law),
                "--prepare-json",
                str(summary),
                "-o",
                str(out),
            ]
        )
        == 0
    )
    res = json.loads(out.read_text())
    proj = res["projections"][str(cfg_path)]
    assert res["prepare_s_per_sample"] == 360.0
    assert proj["configured"]["prepare_core_h"] == pytest.approx(0.1)
    costs = proj["job_costs"]
    periodic = [c for c in costs if c["start"] == "periodic"]
    assert {c["mode"] for c in periodic} == {"measured", "extended"}
    assert all(c["start_used"] == "periodic" and c["solve_s"] > 0 for c in periodic)
    # the direct solver of the measured and extended modes reports no iterations on linear steps
    assert all(c["s_per_step"] > 0 and c["iterations_mean"] >= 0 for c in costs)
    assert all(c["iterations_mean"] > 0 for c in costs if c["mode"] not in ("measured", "extended"))
    assert proj["configured"]["n_steps_total"] < proj["rest"]["n_steps_total"]
    assert "single_law" in proj
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"total": 1.0}))
    args = ["campaign-bench", "--steps", "1", "--n-spheres", "20", "--prepare-json", str(bad), "-o", str(out)]
    from asphalt_nscd.campaign.cli import _prepare_seconds
    from asphalt_nscd.cli import build_parser

    with pytest.raises(InputError, match="timings_s.total_s"):
        _prepare_seconds(build_parser().parse_args(args))


def test_campaign_bench_same_run_baseline_and_modes(tmp_path, capsys):
    """--modes restricts the timed jobs and the projection; --baseline-set times
    a second simulation of each job class in the same run (speedup = baseline / configured);
    bad values are refused naming the option."""
    import yaml

    sample = tmp_path / "s1.h5"
    write_sample(sample, lattice_sample(60, seed=2, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    cfg = config.load(["config/smoke.yaml"])  # merged over config/config.yaml, as Snakemake
    cfg_path = tmp_path / "smoke.yaml"
    cfg_path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "bench.json"
    base = [
        "campaign-bench",
        "--sample",
        str(sample),
        "--steps",
        "2",
        "--config",
        str(cfg_path),
        "--per-job",
        "--job-steps",
        "3",
        "--table3",
        TABLE3,
        "-o",
        str(out),
    ]
    assert main(base + ["--modes", "paper", "--job-warmup", "1", "--baseline-set", "linear_solver=direct"]) == 0
    proj = json.loads(out.read_text())["projections"][str(cfg_path)]
    costs = proj["job_costs"]
    assert costs and {c["mode"] for c in costs} == {"paper"}
    assert set(proj["configured"]["n_steps_by_mode"]) == {"paper"}
    for c in costs:
        assert c["s_per_step_baseline"] > 0 and c["speedup"] == pytest.approx(
            c["s_per_step_baseline"] / c["s_per_step"]
        )
    assert main(base + ["--modes", "nonsense"]) == 2
    assert "--modes ['nonsense']: no such jobs" in capsys.readouterr().err
    assert main(base + ["--job-warmup", "-1"]) == 2
    assert "--job-warmup >= 0" in capsys.readouterr().err
    assert main(base + ["--baseline-set", "no_such_setting=1"]) == 2
    assert "--baseline-set: unknown setting(s) ['no_such_setting']" in capsys.readouterr().err
    assert main(base + ["--baseline-set", "linear_solver"]) == 2
    assert "--baseline-set 'linear_solver': expected KEY=VALUE" in capsys.readouterr().err
