"""Time-step study at the paper's scale in both readings of Table 3, on the exact orbit.

For a job whose linearity certificate holds, the orbit at a time step dt is what the time
stepping gives at that dt (``reference/paper_scale/verification.csv``: the two agree to 1e-4 %
and 1e-5 deg), so the influence of dt on |E*| and Phi is measured here without stepping: for the
paper's Fig. 6 case (15 degC, 3 Hz), the hottest temperature (30 degC) at 3 Hz and at 40 Hz (the
top of the band, nearest the sample's first resonance in the Pa reading), in each reading, at
the paper's dt = 5e-5 s and at 25 to 2,000 steps per cycle. A case whose certificate fails is
written with its reason and no value.

Usage, from a run's working directory (the paper-scale samples prepared):

    .venv/bin/python /path/to/reference/paper_scale/dt_study.py results/samples/s2.h5 dt_study_orbit.csv
"""

from __future__ import annotations

import dataclasses
import json
import sys
import tempfile
from pathlib import Path

import pandas as pd

from asphalt_nscd import config, plan
from asphalt_nscd.campaign import study, twopb
from asphalt_nscd.rheology.calibration import burgers_model

CASES = [(15.0, 3.0), (30.0, 3.0), (30.0, 40.0)]
STEPS_PER_CYCLE = [25, 50, 100, 200, 500, 1000, 2000]
PAPER_DT_S = 5e-5


def main(sample: str, out: str) -> None:
    cfg = config.load(["config/paper.yaml"])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("paper", "paper_kPa"):
            units = plan.table3_reading(cfg, mode)
            base = twopb.settings_from(plan.mode_settings(cfg, mode))
            base = dataclasses.replace(base, method="orbit", checkpoint_every=0)
            table = study.parameter_table("data/paper/table3_burgers.csv", units)
            for T, f in CASES:
                law = burgers_model(study.parameters_at(table, T, {}, where="Table 3"))
                dts = [("paper", PAPER_DT_S)] + [(str(n), 1.0 / (f * n)) for n in STEPS_PER_CYCLE]
                for label, dt in dts:
                    s = dataclasses.replace(base, dt_policy="fixed", dt_s=dt)
                    row = {
                        "reading": units,
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
    main(sys.argv[1], sys.argv[2])
