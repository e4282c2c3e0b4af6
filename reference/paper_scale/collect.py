"""Collect the paper-scale run (README.md of this folder) into small tables.

Usage, from the run's working directory (a clone at the commit of the README, after the
Snakemake targets of the README have run):

    .venv/bin/python /path/to/reference/paper_scale/collect.py [--pcheck DIR] OUT_DIR

Writes into OUT_DIR:
  samples.csv        one row per prepared sample: spheres, layer height, solid fractions,
                     density, bonds, preparation CPU (results/samples/s*_summary.json)
  jobs.csv           one row per finished 2PB job of the reading modes (results/sim/paper*/...)
  table4.csv         MRE of |E*| and Phi per reading, temperature and sample against Table 3's
                     Burger's model under that reading, their mean and standard deviation over
                     the samples whose isotherm has all 5 frequencies, beside the paper's
                     Table 4
  costs.csv          CPU time of the jobs per reading and sample (sum of the jobs' own times)
  periodic_check.csv, periodic_check_cycles.csv   the periodic-check tables of --pcheck DIR
  resolution*.csv    the network-factor resolution study (results/harmonic/resolution*.csv)
  fig09_isotherms_{Pa,kPa}.png, fig10_phase_{Pa,kPa}.png   the paper's Figs. 9-10 of each
                     reading: the finished jobs of every sample against Table 3's model
"""

from __future__ import annotations

import argparse
import glob
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.campaign import study

SAMPLE_KEYS = ["n_spheres_layer", "n_spheres", "layer_height_after_deposition_mm", "layer_height_after_vibration_mm",
               "layer_top_after_vibration_mm", "solid_fraction_layer", "solid_fraction_bulk", "porosity_before_shrink",
               "density_kg_m3", "n_bonds", "bonds_per_sphere"]
#: frequencies of an isotherm of the paper's protocol (3, 6, 10, 25, 40 Hz)
N_FREQUENCIES = 5
JOB_KEYS = ["mode", "sample", "temperature_C", "frequency_Hz", "table3_units", "start", "n_cycles_simulated", "dt_s",
            "n_steps", "n_spheres", "n_bonds", "E_norm_MPa", "phase_deg", "n_nlgs_steps", "iterations_mean",
            "cpu_time_s", "wall_time_s", "cpu_per_sphere_step_s", "n_broken_total"]


def periodic_summary(cases: pd.DataFrame, cycles: pd.DataFrame, first_converged: int = 6) -> pd.DataFrame:
    """One row per periodic-check case: the one measured cycle after the periodic start against
    the from-rest cycles from ``first_converged`` on (the cycles after the paper's 5), as their
    median, and the from-rest cycle-to-cycle scatter (largest departure of one cycle from that
    median; closing contacts and the slow creep under gravity make single cycles jump)."""
    rows = []
    for (mode, T, f), g in cycles.groupby(["mode", "temperature_C", "frequency_Hz"]):
        c = cases[(cases["mode"] == mode) & np.isclose(cases["temperature_C"], T) & np.isclose(cases["frequency_Hz"], f)]
        late = g[g["cycle"] >= first_converged]
        E_med, P_med = float(late["E_norm_MPa"].median()), float(late["phase_deg"].median())
        dE = 100 * (late["E_norm_MPa"] / E_med - 1)
        dP = late["phase_deg"] - P_med
        E_per, P_per = float(c["E_periodic_MPa"].iloc[0]), float(c["phase_periodic_deg"].iloc[0])
        E_rest, P_rest = float(c["E_rest_MPa"].iloc[0]), float(c["phase_rest_deg"].iloc[0])
        rows.append({
            "mode": mode, "temperature_C": T, "frequency_Hz": f, "from_rest_cycles": int(g["cycle"].max()),
            "E_periodic_MPa": E_per, "phase_periodic_deg": P_per, "E_from_rest_median_MPa": E_med,
            "phase_from_rest_median_deg": P_med,
            "dE_periodic_pct": 100 * (E_per / E_med - 1), "dphase_periodic_deg": P_per - P_med,
            "dE_rest5_pct": 100 * (E_rest / E_med - 1), "dphase_rest5_deg": P_rest - P_med,
            "scatter_E_pct": float(np.max(np.abs(dE))), "scatter_phase_deg": float(np.max(np.abs(dP))),
            "cycles_within_0.1pct_0.05deg": int(np.sum((np.abs(dE) <= 0.1) & (np.abs(dP) <= 0.05))),
            "n_cycles_compared": len(late)})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--pcheck", type=Path, default=None, help="directory of the periodic-check outputs")
    args = ap.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)

    rows = []
    for path in sorted(glob.glob("results/samples/s*_summary.json")):
        d = json.loads(Path(path).read_text())
        rows.append({"sample": f"s{d['seed']}", **{k: d[k] for k in SAMPLE_KEYS},
                     "cpu_s": d["cpu_s"]["total_s"], "cpu_deposition_s": d["cpu_s"]["deposition_s"],
                     "cpu_vibration_s": d["cpu_s"]["vibration_s"], "cpu_stabilisation_s": d["cpu_s"]["stabilisation_s"]})
    pd.DataFrame(rows).to_csv(out / "samples.csv", index=False)

    jobs = [pd.read_csv(p) for p in sorted(glob.glob("results/sim/paper*/s*/*.csv"))]
    if not jobs:
        return
    jobs = pd.concat(jobs, ignore_index=True)
    jobs = jobs[[k for k in JOB_KEYS if k in jobs.columns]].sort_values(["mode", "sample", "temperature_C",
                                                                          "frequency_Hz"])
    jobs.to_csv(out / "jobs.csv", index=False)
    jobs.groupby(["mode", "sample"]).agg(n_jobs=("cpu_time_s", "size"), n_steps=("n_steps", "sum"),
                                         cpu_s=("cpu_time_s", "sum")).reset_index().to_csv(out / "costs.csv", index=False)

    paper4 = pd.read_csv("data/paper/table4_mre.csv")
    t4 = []
    for (mode, units), g in jobs.groupby(["mode", "table3_units"]):
        table = study.parameter_table("data/paper/table3_burgers.csv", units)
        ref = study.burgers_reference(table, g["temperature_C"], g["frequency_Hz"])
        g = g.reset_index(drop=True)
        g["eE"] = np.abs(g["E_norm_MPa"].to_numpy() / ref["E_norm_MPa_ref"].to_numpy() - 1)
        g["eP"] = np.abs(g["phase_deg"].to_numpy() - ref["phase_deg_ref"].to_numpy()) / ref["phase_deg_ref"].to_numpy()
        per = g.groupby(["temperature_C", "sample"]).agg(mre_E=("eE", "mean"), mre_P=("eP", "mean"),
                                                          n_f=("eE", "size")).reset_index()
        # Table 4 averages over the 5 frequencies: a sample enters a temperature's row only with
        # all of them (the jobs of incomplete isotherms stay in jobs.csv)
        per = per[per["n_f"] == N_FREQUENCIES]
        for T, h in per.groupby("temperature_C"):
            p = paper4[np.isclose(paper4["temperature_C"], T)]
            t4.append({"reading": units, "mode": mode, "temperature_C": T, "n_samples": len(h),
                       "n_frequencies": int(h["n_f"].min()),
                       "mre_E_norm_pct_mean": 100 * h["mre_E"].mean(), "mre_E_norm_pct_sd": 100 * h["mre_E"].std(ddof=1),
                       "mre_phase_pct_mean": 100 * h["mre_P"].mean(), "mre_phase_pct_sd": 100 * h["mre_P"].std(ddof=1),
                       **{f"mre_{q}_pct_{s}": 100 * v for q, col in (("E_norm", "mre_E"), ("phase", "mre_P"))
                          for s, v in zip(h["sample"], h[col])},
                       "paper_mre_E_norm_pct": float(p.iloc[0, 1]) if len(p) else np.nan,
                       "paper_mre_phase_pct": float(p.iloc[0, 2]) if len(p) else np.nan})
    pd.DataFrame(t4).to_csv(out / "table4.csv", index=False)

    # the paper's Figs. 9-10 per reading: every finished job of every sample against Table 3's
    # Burger's model under that reading (asphalt-nscd campaign-isotherms)
    with tempfile.TemporaryDirectory() as tmp:
        for (mode, units), g in jobs.groupby(["mode", "table3_units"]):
            rows = sorted(glob.glob(f"results/sim/{mode}/s*/*.csv"))
            subprocess.run([sys.executable, "-m", "asphalt_nscd", "campaign-isotherms", "--rows", *rows,
                            "--parameters", "data/paper/table3_burgers.csv", "--table3-units", units,
                            "--paper-table4", "data/paper/table4_mre.csv", "--isotherms", f"{tmp}/iso.csv",
                            "--table4", f"{tmp}/t4.csv", "--figure-modulus", str(out / f"fig09_isotherms_{units}.png"),
                            "--figure-phase", str(out / f"fig10_phase_{units}.png"),
                            "--title", f"paper scale, Table 3 read in {units}"], check=True)

    if args.pcheck is not None:
        for kind in ("", "_cycles"):
            parts = [pd.read_csv(p) for p in sorted(args.pcheck.glob(f"*[0-9]{kind}.csv"))]
            if parts:
                pd.concat(parts, ignore_index=True).to_csv(out / f"periodic_check{kind}.csv", index=False)
        if (out / "periodic_check_cycles.csv").exists():
            periodic_summary(pd.read_csv(out / "periodic_check.csv"),
                             pd.read_csv(out / "periodic_check_cycles.csv")).to_csv(
                out / "periodic_check_summary.csv", index=False)
    for name in ("resolution.csv", "resolution_summary.csv", "resolution_fits.csv"):
        src = Path("results/harmonic") / name
        if src.exists():
            pd.read_csv(src).to_csv(out / name, index=False)


if __name__ == "__main__":
    main()
