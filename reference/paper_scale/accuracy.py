"""Accuracy of the time-stepping scheme per consistency job: the exact periodic orbit of the
theta-method step map at the job's dt against the continuous-time harmonic answer (dt -> 0).

A consistency job (``campaign.verification: ends``, ``verification.csv``) compares two solutions
of the same discrete scheme at the same dt, the time-stepped run and its exact orbit: it checks
the orbit's algebra and the linearity certificate, not the scheme's accuracy, since both carry
the same time-discretisation error. That error is measured here, for every such job of the run:

* ``E_orbit_dt``, ``phase_orbit_dt``: the orbit at the job's own dt (the job's
  ``E_norm_MPa_orbit``, recomputed: ``E_orbit_vs_recorded_pct`` checks the reproduction);
* ``E_orbit_dt10``, ``E_orbit_dt100``: the orbit at dt / 10 and dt / 100 (the scheme converges
  as (w dt)^2: their errors fall by about 100 and 10,000);
* ``E_continuous``, ``phase_continuous``: the continuous-time steady state of the same linear
  system (the harmonic solution at s = i w of the job's own network, head and inertia, reduced
  by the same EN 12697-26 Eqs. 1-5);
* ``accuracy_E_pct`` = 100 (E_orbit_dt / E_continuous - 1), ``accuracy_phase_deg`` =
  phase_orbit_dt - phase_continuous: the job's time-discretisation error; and the same at dt / 10
  and dt / 100.

Usage, from a working directory of the paper configuration with its samples and laws
(``make run CONFIG=config/paper.yaml`` or its targets ``results/samples/s<k>.h5``, the
calibration, the diagnosis's law and the samples' network factors):

    .venv/bin/python reference/paper_scale/accuracy.py verification.csv accuracy.csv [--samples s2]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import tempfile
import time
from pathlib import Path

import pandas as pd

from asphalt_nscd import config, plan
from asphalt_nscd.campaign import study, twopb
from asphalt_nscd.campaign.modes import table3_reading
from asphalt_nscd.harmonic import periodic
from asphalt_nscd.lab.en12697 import complex_modulus
from asphalt_nscd.sample.store import read_sample, specimen_of

#: refinements of the job's dt at which the orbit is also computed
REFINE = (10, 100)


def job_laws(cfg: dict, mode: str, sample: str) -> study.JobLaws:
    """The laws of ``mode``'s jobs, from the run's files as the workflow passes them to run-2pb."""
    transfer = plan.job_transfer(cfg, mode, sample)
    return study.JobLaws(
        table3=cfg["calibration"]["table3"],
        table3_units=table3_reading(cfg, "paper"),
        parameters=plan.mode_parameters(cfg, "measured"),
        law_json=plan.LAW_JSON,
        network_factor_json=transfer[0] if transfer else None,
        sample_name=sample,
    )


def orbit(sample_path: str, law, f: float, settings, dt: float, tmp: Path, rig_state=None) -> dict:
    """|E*| (MPa) and phase (deg) of the job's exact orbit at step ``dt`` (``rig_state``: the
    sample's rig-state file, as the workflow's jobs read it, or None)."""
    s = dataclasses.replace(settings, method="orbit", dt_policy="fixed", dt_s=dt, time_domain_steps_per_cycle=None)
    rec = twopb.run_test(sample_path, law, f, s, tmp / "job.h5", progress=False, rig_state=rig_state)
    r = twopb.reduce_test(rec, 1)
    return {"E": r["E_norm_MPa"], "phase": r["phase_deg"], "cpu_s": r["cpu_time_s"]}


def continuous(sample_path: str, law, f: float, settings, dt: float, rig_state=None) -> dict:
    """|E*| (MPa) and phase (deg) of the continuous-time steady state of the job's linear system."""
    cpu = time.process_time()
    sample = read_sample(sample_path)
    held, reference = None, None
    if rig_state is not None:
        held, _, reference = twopb.read_rig_state(rig_state, sample_path, settings)
    sim, _ = twopb.build_simulation(sample, law, f, dt, settings, held=held)
    system = periodic.harmonic_system(sim, settings.head_rotation, settings.nu, reference)
    sol = system.solve_law(
        law, f, amplitude=settings.amplitude_m, inertia="full", solver="reuse", laplace=1j * 2.0 * math.pi * f
    )
    red = complex_modulus(sol.F0_N, settings.amplitude_m, sol.psi_deg, f, specimen_of(sample))
    return {"E": red["E_norm_MPa"], "phase": red["phase_deg"], "cpu_s": time.process_time() - cpu}


def main(verification: str, out: str, samples: list[str] | None) -> None:
    cfg = config.load(["config/paper.yaml"])
    jobs = pd.read_csv(verification)
    if samples:
        jobs = jobs[jobs["sample"].isin(samples)]
    rows = []
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for _, j in jobs.iterrows():
            mode, name, T, f, dt = (
                j["mode"],
                j["sample"],
                float(j["temperature_C"]),
                float(j["frequency_Hz"]),
                j["dt_s"],
            )
            sample_path = plan.sample_file(name)
            settings = twopb.settings_from(plan.mode_settings(cfg, mode))
            law = job_laws(cfg, mode, name).law(mode, T)
            rig = plan.rig_state_file(name) if Path(plan.rig_state_file(name)).exists() else None
            row = {"mode": mode, "sample": name, "temperature_C": T, "frequency_Hz": f, "dt_s": dt}
            at = orbit(sample_path, law, f, settings, dt, tmp, rig)
            row.update({"E_orbit_dt": at["E"], "phase_orbit_dt": at["phase"], "cpu_orbit_s": at["cpu_s"]})
            row["E_orbit_vs_recorded_pct"] = 100.0 * (at["E"] / j["E_norm_MPa_orbit"] - 1.0)
            row["phase_orbit_vs_recorded_deg"] = at["phase"] - j["phase_deg_orbit"]
            for k in REFINE:
                r = orbit(sample_path, law, f, settings, dt / k, tmp, rig)
                row.update({f"E_orbit_dt{k}": r["E"], f"phase_orbit_dt{k}": r["phase"]})
            c = continuous(sample_path, law, f, settings, dt, rig)
            row.update({"E_continuous": c["E"], "phase_continuous": c["phase"], "cpu_continuous_s": c["cpu_s"]})
            for suffix in ("dt",) + tuple(f"dt{k}" for k in REFINE):
                tag = "" if suffix == "dt" else f"_{suffix}"
                row[f"accuracy_E_pct{tag}"] = 100.0 * (row[f"E_orbit_{suffix}"] / c["E"] - 1.0)
                row[f"accuracy_phase_deg{tag}"] = row[f"phase_orbit_{suffix}"] - c["phase"]
            rows.append(row)
            print(json.dumps(row), flush=True)
            pd.DataFrame(rows).to_csv(out, index=False, float_format="%.8g")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("verification", help="the run's verification.csv (the consistency jobs)")
    parser.add_argument("out", help="output CSV")
    parser.add_argument("--samples", nargs="+", help="only these samples (default: all in the table)")
    args = parser.parse_args()
    main(args.verification, args.out, args.samples)
