"""Collect the paper-scale run (README.md of this folder) into small tables and figures.

Usage, from the run's working directory (a clone at the commit of the README, after ``make run
CONFIG=config/paper.yaml``):

    .venv/bin/python /path/to/reference/paper_scale/collect.py OUT_DIR

Writes into OUT_DIR:
  samples.csv        one row per prepared sample: spheres, layer height, solid fractions,
                     density, bonds, preparation CPU (results/samples/s*_summary.json)
  jobs.csv           one row per 2PB job (every mode: paper = Table 3 read in Pa, paper_kPa,
                     measured, extended, sensitivity, dt_study, units_*): the path it took
                     (orbit or time_domain) and why, its certificate's margins, |E*|, Phi, its
                     steps and CPU (the job's own, and the process's from Snakemake's benchmark)
  table4.csv         per reading and temperature: MRE of |E*| and Phi against Table 3's Burger's
                     model under that reading, mean and standard deviation over the samples whose
                     isotherm has all 5 frequencies, beside the paper's Table 4
  verification.csv   the verification jobs (always stepped in time): the time domain's and the
                     orbit's |E*| and Phi and their differences
  paths.csv          per mode: jobs on the orbit and in the time domain, and why
  costs.csv          CPU per mode (the jobs' own and the processes'), the 240 jobs of the two
                     readings, and every rule of the run (Snakemake benchmarks), preparations
                     included
  evidence.csv       the paper-scale evidence on Table 3's unit: the bonds' largest force over
                     the literal yield stress 2.7e6 Pa under the kPa moduli at every (T, f), the
                     gravity creep per cycle under the Pa moduli against the head amplitude, and
                     the first resonance of sample + head in each reading (simulated head
                     stiffness at the lowest frequency, EN 12697-26 lumped mass)
  sensitivity.csv, dt_study.csv, dt_policy_*.csv, table4_measured.csv, table4_extended.csv,
  units_question.csv, units_evidence.csv, network_factor*.csv, resolution*.csv
                     the workflow's own tables, copied
  fig06-fig14 *.png  the paper's Figs. 6-14 of this run (both readings for Figs. 9-10)
"""

from __future__ import annotations

import argparse
import glob
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.campaign import study

SAMPLE_KEYS = [
    "n_spheres_layer",
    "n_spheres",
    "layer_height_after_deposition_mm",
    "layer_height_after_vibration_mm",
    "layer_top_after_vibration_mm",
    "solid_fraction_layer",
    "solid_fraction_bulk",
    "porosity_before_shrink",
    "density_kg_m3",
    "n_bonds",
    "bonds_per_sphere",
]
#: frequencies of an isotherm of the paper's protocol (3, 6, 10, 25, 40 Hz)
N_FREQUENCIES = 5
JOB_KEYS = [
    "mode",
    "sample",
    "temperature_C",
    "frequency_Hz",
    "table3_units",
    "variant",
    "parameter",
    "factor",
    "path",
    "path_reason",
    "verification",
    "start",
    "dt_s",
    "n_steps",
    "n_spheres",
    "n_bonds",
    "E_norm_MPa",
    "phase_deg",
    "F0_N",
    "z0_m",
    "E_norm_MPa_orbit",
    "phase_deg_orbit",
    "orbit_vs_time_domain_E_pct",
    "orbit_vs_time_domain_phase_deg",
    "cert_holds",
    "cert_reason",
    "cert_bond_force_ratio",
    "cert_bond_at",
    "cert_min_gap_m",
    "cert_gap_at",
    "cert_gap_start_m",
    "cert_n_pairs",
    "cert_n_closed_at_start",
    "cert_creep_m",
    "cert_amplitude_m",
    "n_nlgs_steps",
    "n_contact_steps",
    "n_broken_total",
    "cpu_time_s",
    "process_cpu_s",
    "wall_time_s",
]
#: the two readings of Table 3 and their campaign modes
READINGS = {"paper": "Pa", "paper_kPa": "kPa"}
#: the literal yield stress of the paper and the kPa reading's (scaled with the moduli), Pa
YIELD_LITERAL_PA, YIELD_KPA_PA = 2.7e6, 2.7e9
HEAD_AMPLITUDE_M = 63e-6


def benchmark_cpu(path: Path) -> float:
    """CPU seconds of a Snakemake benchmark file (its ``cpu_time`` column), NaN if missing."""
    if not path.exists():
        return float("nan")
    b = pd.read_csv(path, sep="\t")
    return float(b["cpu_time"].iloc[-1]) if "cpu_time" in b else float("nan")


def read_jobs() -> pd.DataFrame:
    rows = []
    for p in sorted(glob.glob("results/sim/*/s*/*.csv")):
        r = pd.read_csv(p)
        mode, sample, case = Path(p).parts[-3], Path(p).parts[-2], Path(p).stem
        r["process_cpu_s"] = benchmark_cpu(Path("benchmarks/sim") / mode / sample / f"{case}.tsv")
        rows.append(r)
    jobs = pd.concat(rows, ignore_index=True)
    return (
        jobs[[k for k in JOB_KEYS if k in jobs.columns]]
        .sort_values(["mode", "sample", "temperature_C", "frequency_Hz"])
        .reset_index(drop=True)
    )


def table4(jobs: pd.DataFrame) -> pd.DataFrame:
    paper4 = pd.read_csv("data/paper/table4_mre.csv")
    out = []
    for mode, units in READINGS.items():
        g = jobs[jobs["mode"] == mode].reset_index(drop=True)
        if g.empty:
            continue
        ref = study.burgers_reference(
            study.parameter_table("data/paper/table3_burgers.csv", units), g["temperature_C"], g["frequency_Hz"]
        )
        g["eE"] = np.abs(g["E_norm_MPa"].to_numpy() / ref["E_norm_MPa_ref"].to_numpy() - 1)
        g["eP"] = np.abs(g["phase_deg"].to_numpy() - ref["phase_deg_ref"].to_numpy()) / ref["phase_deg_ref"].to_numpy()
        per = (
            g.groupby(["temperature_C", "sample"])
            .agg(mre_E=("eE", "mean"), mre_P=("eP", "mean"), n_f=("eE", "size"))
            .reset_index()
        )
        per = per[per["n_f"] == N_FREQUENCIES]  # a sample enters a temperature's row with its whole isotherm
        for T, h in per.groupby("temperature_C"):
            p = paper4[np.isclose(paper4["temperature_C"], T)]
            out.append(
                {
                    "reading": units,
                    "mode": mode,
                    "temperature_C": T,
                    "n_samples": len(h),
                    "mre_E_norm_pct_mean": 100 * h["mre_E"].mean(),
                    "mre_E_norm_pct_sd": 100 * h["mre_E"].std(ddof=1),
                    "mre_phase_pct_mean": 100 * h["mre_P"].mean(),
                    "mre_phase_pct_sd": 100 * h["mre_P"].std(ddof=1),
                    **{
                        f"mre_{q}_pct_{s}": 100 * v
                        for q, col in (("E_norm", "mre_E"), ("phase", "mre_P"))
                        for s, v in zip(h["sample"], h[col])
                    },
                    "paper_mre_E_norm_pct": float(p.iloc[0, 1]) if len(p) else np.nan,
                    "paper_mre_phase_pct": float(p.iloc[0, 2]) if len(p) else np.nan,
                }
            )
    return pd.DataFrame(out)


def costs(jobs: pd.DataFrame) -> pd.DataFrame:
    """CPU by mode (job and process), the 240 jobs of the readings, and every rule of the run."""
    rows = []
    for mode, g in jobs.groupby("mode"):
        rows.append(
            {
                "what": f"jobs of mode {mode}",
                "n": len(g),
                "n_orbit": int((g["path"] == "orbit").sum()),
                "job_cpu_s": g["cpu_time_s"].sum(),
                "process_cpu_s": g["process_cpu_s"].sum(),
            }
        )
    main = jobs[jobs["mode"].isin(list(READINGS))]
    rows.append(
        {
            "what": "the 240 jobs: both readings x 4 samples x 6 T x 5 f",
            "n": len(main),
            "n_orbit": int((main["path"] == "orbit").sum()),
            "job_cpu_s": main["cpu_time_s"].sum(),
            "process_cpu_s": main["process_cpu_s"].sum(),
        }
    )
    by_rule = {}
    for p in glob.glob("benchmarks/**/*.tsv", recursive=True):
        rule = Path(p).parts[1]
        by_rule.setdefault(rule, []).append(benchmark_cpu(Path(p)))
    for rule, v in sorted(by_rule.items()):
        rows.append({"what": f"rule folder benchmarks/{rule}", "n": len(v), "process_cpu_s": float(np.nansum(v))})
    total = float(np.nansum([x for v in by_rule.values() for x in v]))
    rows.append(
        {
            "what": "the whole run (every benchmark, preparations included)",
            "n": sum(map(len, by_rule.values())),
            "process_cpu_s": total,
        }
    )
    return pd.DataFrame(rows)


def evidence(jobs: pd.DataFrame) -> pd.DataFrame:
    from asphalt_nscd.sample.store import read_sample, specimen_of

    rows = []
    kpa = jobs[jobs["mode"] == "paper_kPa"]
    for (T, f), g in kpa.groupby(["temperature_C", "frequency_Hz"]):
        r = g["cert_bond_force_ratio"].max() * YIELD_KPA_PA / YIELD_LITERAL_PA
        rows.append(
            {
                "evidence": "largest bond force / R_crit at the literal 2.7e6 Pa, kPa moduli",
                "reading": "kPa",
                "temperature_C": T,
                "frequency_Hz": f,
                "value": r,
                "n_samples": len(g),
                "holds": bool(r < 1.0),
            }
        )
    pa = jobs[jobs["mode"] == "paper"]
    for (T, f), g in pa.groupby(["temperature_C", "frequency_Hz"]):
        c = g["cert_creep_m"].max() / HEAD_AMPLITUDE_M
        rows.append(
            {
                "evidence": "largest gravity creep of a sphere per cycle / head amplitude 63 um, Pa moduli",
                "reading": "Pa",
                "temperature_C": T,
                "frequency_Hz": f,
                "value": c,
                "n_samples": len(g),
                "holds": bool(c < 1.0),
            }
        )
    specs = {}
    for mode, units in READINGS.items():
        g = jobs[jobs["mode"] == mode]
        for (T, s), h in g.groupby(["temperature_C", "sample"]):
            low = h.sort_values("frequency_Hz").iloc[0]
            if s not in specs:
                specs[s] = specimen_of(read_sample(f"results/samples/{s}.h5"))
            k = float(low["F0_N"] / low["z0_m"])
            f1 = study.first_resonance_Hz(k, specs[s]) if k > 0 else np.nan
            rows.append(
                {
                    "evidence": "first resonance of sample + head, Hz (head stiffness at the lowest frequency)",
                    "reading": units,
                    "temperature_C": T,
                    "frequency_Hz": float(low["frequency_Hz"]),
                    "sample": s,
                    "value": f1,
                    "n_samples": 1,
                    "holds": bool(f1 > 80.0),
                }
            )
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path)
    args = ap.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)

    rows = []
    for path in sorted(glob.glob("results/samples/s*_summary.json")):
        d = json.loads(Path(path).read_text())
        s = f"s{d['seed']}"
        rows.append(
            {
                "sample": s,
                **{k: d[k] for k in SAMPLE_KEYS},
                "cpu_s": d["cpu_s"]["total_s"],
                "process_cpu_s": benchmark_cpu(Path("benchmarks/samples") / f"{s}.tsv"),
            }
        )
    pd.DataFrame(rows).to_csv(out / "samples.csv", index=False)

    jobs = read_jobs()
    jobs.to_csv(out / "jobs.csv", index=False)
    table4(jobs).to_csv(out / "table4.csv", index=False)
    jobs[jobs["verification"].fillna(False).astype(bool)].to_csv(out / "verification.csv", index=False)
    jobs.groupby(["mode", "path", "path_reason"], dropna=False).size().rename("n").reset_index().to_csv(
        out / "paths.csv", index=False
    )
    costs(jobs).to_csv(out / "costs.csv", index=False)
    evidence(jobs).to_csv(out / "evidence.csv", index=False)

    copies = {
        "results/campaign/paper/sensitivity.csv": "sensitivity.csv",
        "results/campaign/paper/dt_study.csv": "dt_study.csv",
        "results/campaign/measured/table4_measured.csv": "table4_measured.csv",
        "results/campaign/extended/table4_extended.csv": "table4_extended.csv",
        "results/campaign/units_question.csv": "units_question.csv",
        "results/campaign/units_evidence.csv": "units_evidence.csv",
        "results/harmonic/network_factor.csv": "network_factor.csv",
        "results/harmonic/network_factor_summary.csv": "network_factor_summary.csv",
        "results/harmonic/resolution_summary.csv": "resolution_summary.csv",
        "results/harmonic/resolution_fits.csv": "resolution_fits.csv",
    }
    for mode in READINGS:
        copies[f"results/campaign/{mode}/dt_policy_phase_error.csv"] = f"dt_policy_{mode}.csv"
        copies[f"results/campaign/{mode}/figures/fig09_isotherms_modulus.png"] = f"fig09_isotherms_{READINGS[mode]}.png"
        copies[f"results/campaign/{mode}/figures/fig10_isotherms_phase.png"] = f"fig10_phase_{READINGS[mode]}.png"
    for p in glob.glob("results/campaign/paper/figures/fig0[678]_*.png") + glob.glob(
        "results/campaign/paper/figures/fig1[1-4]_*.png"
    ):
        copies[p] = Path(p).name
    for src, name in copies.items():
        if Path(src).exists():
            shutil.copyfile(src, out / name)


if __name__ == "__main__":
    main()
