"""Time-step study at the paper's scale on the exact orbit: both readings of Table 3, and the
measured and extended modes.

For a job whose linearity certificate holds, the orbit at a time step dt is what the time
stepping gives at that dt (``reference/paper_scale/verification.csv``: the two agree to 1e-4 %
and 1e-5 deg), so the influence of dt on |E*| and Phi is measured here without stepping.

* Table 3's readings (modes paper, paper_kPa): the paper's Fig. 6 case (15 degC, 3 Hz), the
  hottest temperature (30 degC) at 3 Hz and at 40 Hz (the top of the band, nearest the sample's
  first resonance in the Pa reading), at the paper's dt = 5e-5 s and at 25 to 2,000 steps per
  cycle.
* The measured mode (the calibrated Burger's table) and the extended mode (the diagnosis's
  generalized Burger's law, divided by the sample's network factor when
  campaign.extended.transfer_correction is on): the four corners of the measured schedule
  (coldest and warmest temperature at the lowest and highest frequency, the jobs that the
  verification steps in time), at 25 to 2,000 steps per cycle.

A case whose certificate fails is written with its reason and no value.

Usage, from a run's working directory (the paper-scale samples prepared; for the measured and
extended modes also the calibration, the diagnosis's law and the sample's network factor):

    .venv/bin/python /path/to/reference/paper_scale/dt_study.py results/samples/s2.h5 dt_study_orbit.csv
    .venv/bin/python /path/to/reference/paper_scale/dt_study.py results/samples/s2.h5 \
        dt_study_orbit_measured.csv --modes measured extended
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

import pandas as pd

from asphalt_nscd import config, plan
from asphalt_nscd.campaign import study, twopb
from asphalt_nscd.campaign.modes import table3_reading

CASES = [(15.0, 3.0), (30.0, 3.0), (30.0, 40.0)]
STEPS_PER_CYCLE = [25, 50, 100, 200, 500, 1000, 2000]
PAPER_DT_S = 5e-5


def _cases(cfg: dict, mode: str) -> list[tuple[float, float]]:
    """(T degC, f Hz) of the study in ``mode``: CASES for Table 3's readings, the corners of the
    measured schedule for the measured and extended modes."""
    if mode not in ("measured", "extended"):
        return CASES
    sched = cfg["campaign"]["measured"]
    temps, freqs = sched["temperatures_C"], sched["frequencies_Hz"]
    return [(float(T), float(f)) for T in (min(temps), max(temps)) for f in (min(freqs), max(freqs))]


def _job_laws(cfg: dict, mode: str, sample: str) -> study.JobLaws:
    """The laws of ``mode``'s jobs, from the run's files as the workflow passes them to run-2pb
    (asphalt_nscd.plan.mode_parameters, plan.job_transfer)."""
    transfer = plan.job_transfer(cfg, mode, Path(sample).stem)
    return study.JobLaws(
        table3=cfg["calibration"]["table3"],
        table3_units=table3_reading(cfg, "paper"),
        parameters=plan.mode_parameters(cfg, "measured"),
        law_json=plan.LAW_JSON,
        network_factor_json=transfer[0] if transfer else None,
        sample_name=Path(sample).stem,
    )


def main(sample: str, out: str, modes: list[str]) -> None:
    cfg = config.load(["config/paper.yaml"])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mode in modes:
            reading = table3_reading(cfg, mode) or mode
            base = twopb.settings_from(plan.mode_settings(cfg, mode))
            base = dataclasses.replace(base, method="orbit", checkpoint_every=0)
            laws = _job_laws(cfg, mode, sample)
            for T, f in _cases(cfg, mode):
                law = laws.law(mode, T)
                dts = [(str(n), 1.0 / (f * n)) for n in STEPS_PER_CYCLE]
                if mode.startswith("paper"):
                    dts = [("paper", PAPER_DT_S)] + dts
                for label, dt in dts:
                    s = dataclasses.replace(base, dt_policy="fixed", dt_s=dt, time_domain_steps_per_cycle=None)
                    row = {
                        "reading": reading,
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "dt_label": label,
                        "dt_s": dt,
                        "steps_per_cycle": 1.0 / (f * dt),
                    }
                    try:
                        rec = twopb.run_test(sample, law, f, s, Path(tmp) / "job.h5", progress=False)
                        r = twopb.reduce_test(rec, 1)
                        row.update(
                            {
                                "E_norm_MPa": r["E_norm_MPa"],
                                "phase_deg": r["phase_deg"],
                                "cert_min_gap_m": r["cert_min_gap_m"],
                                "cpu_s": r["cpu_time_s"],
                            }
                        )
                    except Exception as exc:  # a certificate that fails: said, not computed
                        row["not_certified"] = str(exc).splitlines()[0]
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    frame = pd.DataFrame(rows)
    ref = frame[frame["dt_label"] == "2000"].set_index(["reading", "temperature_C", "frequency_Hz"])
    key = list(zip(frame["reading"], frame["temperature_C"], frame["frequency_Hz"]))
    if "E_norm_MPa" in frame:
        frame["E_vs_2000_pct"] = [
            100 * (e / ref.loc[k, "E_norm_MPa"] - 1) if k in ref.index else float("nan")
            for e, k in zip(frame["E_norm_MPa"], key)
        ]
        frame["phase_vs_2000_deg"] = [
            p - ref.loc[k, "phase_deg"] if k in ref.index else float("nan") for p, k in zip(frame["phase_deg"], key)
        ]
    frame.to_csv(out, index=False, float_format="%.6g")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sample", help="paper-scale sample (.h5) of the run's working directory")
    parser.add_argument("out", help="output CSV")
    parser.add_argument(
        "--modes",
        nargs="+",
        default=["paper", "paper_kPa"],
        choices=["paper", "paper_kPa", "measured", "extended"],
        help="modes studied (default: Table 3's two readings)",
    )
    args = parser.parse_args()
    main(args.sample, args.out, args.modes)
