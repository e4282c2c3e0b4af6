"""Write the fixed regression tables of tests/data (run from the repository root:
``python tests/data/make_regression_tables.py``); tests check the committed files equal
this script's output.

Every table is drawn from a 2S2P1D + WLF truth (parameters below, in the ranges published
for mixes; the extreme-phase one binder-rich) with a log-normal |E*| factor per specimen,
point noise on ln|E*| and Phi, seed 20261121. They are synthetic and say so in their
``specimen`` names (``syn-``); none is a real laboratory table.

* ``ampt_like_3x3x6.csv`` — the class of the second real mix that crashed ``diagnose``: an
  AMPT (AASHTO PP 61) uniaxial table, 3 specimens x 3 temperatures (4, 21, 37 degC) x 6
  frequencies (25, 10, 5, 1, 0.5, 0.1 Hz) with a strain column (AMPT targets 75-125
  microstrain), no test order; sidecar ``ampt_like_3x3x6.test.json`` (100 x 150 mm cylinder);
* ``three_frequencies.csv`` — 2 specimens x 4 temperatures x 3 frequencies (10, 1, 0.1 Hz),
  with a test order;
* ``unbalanced.csv`` — AASHTO T 342 schedule, 3 specimens, the cell (37 degC, 0.5 Hz)
  missing for every specimen, one row (S2, -10 degC, 25 Hz) missing, and 0.01 Hz tested at
  54 degC only;
* ``extreme_phase.csv`` — binder-rich truth over -10..60 degC and 0.01-100 Hz: phase angles
  from about 1 to 58 deg, |E*| from 2 MPa to 34 GPa, one specimen.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
SEED = 20261121
MIX = dict(
    E0_MPa=33000.0,
    E00_MPa=80.0,
    delta=2.2,
    k=0.19,
    h=0.58,
    beta=800.0,
    tau_ref_s=0.08,
    C1=26.0,
    C2_K=175.0,
    T_ref_C=15.0,
)
BINDER_RICH = dict(
    E0_MPa=35000.0,
    E00_MPa=2.0,
    delta=2.0,
    k=0.22,
    h=0.62,
    beta=300.0,
    tau_ref_s=0.05,
    C1=28.0,
    C2_K=180.0,
    T_ref_C=15.0,
)


def _table(rng, truth, temps, freqs, n_spec, strain=None, order=False, drop=()):
    from asphalt_nscd.diagnosis.synthetic import truth_modulus

    rows = []
    for s in range(n_spec):
        c = rng.normal(0.0, 0.03)
        k = 0
        for T in temps:
            for f in sorted(freqs, reverse=True):
                k += 1
                if (f"S{s + 1}", T, f) in drop or ("*", T, f) in drop:
                    continue
                E = complex(truth_modulus(truth, f, T))
                row = {
                    "specimen": f"syn-S{s + 1}",
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa": round(float(abs(E) * np.exp(c + rng.normal(0.0, 0.01))), 2),
                    "phase_deg": round(float(np.degrees(np.angle(E)) + rng.normal(0.0, 0.2)), 2),
                }
                if strain is not None:
                    row["strain_microstrain"] = round(float(rng.uniform(*strain)), 1)
                if order:
                    row["test_order"] = k
                rows.append(row)
    return pd.DataFrame(rows)


def tables() -> dict:
    """{file name: DataFrame} of every regression table."""
    rng = np.random.default_rng(SEED)
    out = {}
    out["ampt_like_3x3x6.csv"] = _table(
        rng, MIX, [4.0, 21.0, 37.0], [25.0, 10.0, 5.0, 1.0, 0.5, 0.1], 3, strain=(75.0, 125.0)
    )
    out["three_frequencies.csv"] = _table(rng, MIX, [-10.0, 10.0, 25.0, 40.0], [10.0, 1.0, 0.1], 2, order=True)
    unb = _table(
        rng,
        MIX,
        [-10.0, 4.0, 21.0, 37.0, 54.0],
        [25.0, 10.0, 5.0, 1.0, 0.5, 0.1],
        3,
        order=True,
        drop={("*", 37.0, 0.5), ("S2", -10.0, 25.0)},
    )
    extra = _table(rng, MIX, [54.0], [0.01], 3)
    extra["test_order"] = 31
    out["unbalanced.csv"] = pd.concat([unb, extra], ignore_index=True)
    out["extreme_phase.csv"] = _table(
        rng, BINDER_RICH, [-10.0, 0.0, 20.0, 40.0, 60.0], [100.0, 10.0, 1.0, 0.1, 0.01], 1
    )
    return out


SIDECARS = {
    "ampt_like_3x3x6.test.json": {
        "test": "uniaxial_cylinder",
        "diameter_mm": 100.0,
        "height_mm": 150.0,
        "moving_mass_kg": None,
        "description": "synthetic AMPT-like table (AASHTO PP 61 specimen 100 mm x 150 mm)",
        "source": "tests/data/make_regression_tables.py",
    }
}


def main() -> int:
    import json

    for name, frame in tables().items():
        frame.to_csv(HERE / name, index=False)
    for name, obj in SIDECARS.items():
        (HERE / name).write_text(json.dumps(obj, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
