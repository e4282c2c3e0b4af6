"""Where the consistency residuals come from: the consistency jobs of some samples (time steps
beside the exact orbit of the same step map) rerun as recorded and with gravity off.

The orbit starts each job in the steady state under gravity plus the periodic state; the time
domain starts from the same state. The steady state's static solve leaves a relative residual
(a few soft rotational modes no refinement resolves, ``harmonic.periodic``), i.e. a force left
unbalanced (``cert_gravity_unbalanced_ratio``: its size over the head force amplitude). The
time domain answers it with a transient that the orbit does not have; with the same weights, the
Pa reading's head force is a thousand times smaller than the kPa reading's, so the same
unbalanced force weighs a thousand times more. Rows: the job as configured and with gravity
off, the orbit-vs-time-domain differences of each and the unbalanced ratio.

Usage, from a working directory of the paper configuration with its samples and laws:

    .venv/bin/python reference/paper_scale/consistency.py verification.csv consistency.csv --samples s2
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

import pandas as pd

from asphalt_nscd import config, plan
from asphalt_nscd.campaign import twopb

from accuracy import job_laws  # noqa: I001 - this folder's script


def main(verification: str, out: str, samples: list[str], modes: list[str]) -> None:
    cfg = config.load(["config/paper.yaml"])
    jobs = pd.read_csv(verification)
    jobs = jobs[jobs["sample"].isin(samples) & jobs["mode"].isin(modes)]
    rows = []
    with tempfile.TemporaryDirectory() as tmpdir:
        for _, j in jobs.iterrows():
            mode, name, T, f = j["mode"], j["sample"], float(j["temperature_C"]), float(j["frequency_Hz"])
            base = twopb.settings_from(plan.mode_settings(cfg, mode))
            law = job_laws(cfg, mode, name).law(mode, T)
            for gravity in (True, False):
                s = dataclasses.replace(base, gravity=gravity, checkpoint_every=0)
                rec = twopb.run_test(
                    plan.sample_file(name), law, f, s, Path(tmpdir) / "job.h5", progress=False, verify=True
                )
                r = twopb.reduce_test(rec, 1)
                row = {
                    "mode": mode,
                    "sample": name,
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "gravity": gravity,
                    "dt_s": r["dt_s"],
                    "n_steps": r["n_steps"],
                    "E_norm_MPa": r["E_norm_MPa"],
                    "orbit_vs_time_domain_E_pct": r["orbit_vs_time_domain_E_pct"],
                    "orbit_vs_time_domain_phase_deg": r["orbit_vs_time_domain_phase_deg"],
                    "gravity_unbalanced_ratio": r.get("cert_gravity_unbalanced_ratio"),
                    "n_contact_steps": r["n_contact_steps"],
                    "n_nlgs_steps": r["n_nlgs_steps"],
                    "cpu_s": r["cpu_time_s"],
                }
                if gravity:
                    row["recorded_orbit_vs_time_domain_E_pct"] = j["orbit_vs_time_domain_E_pct"]
                rows.append(row)
                print(json.dumps(row), flush=True)
                pd.DataFrame(rows).to_csv(out, index=False, float_format="%.8g")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("verification", help="the run's verification.csv (the consistency jobs)")
    parser.add_argument("out", help="output CSV")
    parser.add_argument("--samples", nargs="+", default=["s2"])
    parser.add_argument("--modes", nargs="+", default=["paper", "paper_kPa"])
    args = parser.parse_args()
    main(args.verification, args.out, args.samples, args.modes)
