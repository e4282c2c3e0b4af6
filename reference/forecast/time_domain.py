"""The forecast's harmonic answer checked in the time domain on prepared samples of a forecast run.

    python reference/forecast/time_domain.py RUN_DIR --constants reference/forecast/default_constants.csv \
        -o reference/forecast/time_domain.csv

For three mixes of the run (the smallest, the median and the largest sample of seed 1, by number of
spheres) at the two corners of the table where the skeleton's share of the bonds' stiffness is
smallest and largest (the coldest temperature at the highest frequency, the hottest at the lowest),
the bonds of ``dem_extended`` with the constants fitted on every mix (``all_mixes`` of the
constants table) and the mix's mortar at that condition are stepped in time by the NSCD core at 100
and 200 steps per cycle (:func:`asphalt_nscd.forecast.dem.time_domain_check`): one row per mix,
condition and time step with the time-domain, harmonic (with the spheres' inertia) and
quasi-static (the forecast's) moduli and their differences. The scheme is second order: halving
dt divides the time-domain difference by about 4.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast.dem import bond_moduli, time_domain_check
from asphalt_nscd.forecast.formulation import phase_volumes
from asphalt_nscd.forecast.mortar import hs_lower_mortar_modulus as mortar_modulus
from asphalt_nscd.forecast.models import read_curves
from asphalt_nscd.forecast.validation import binder_ids, with_binder_route
from asphalt_nscd.io import write_csv
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.sample.store import read_sample


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--constants", required=True, type=Path)
    p.add_argument("--cut-mm", type=float, default=4.0)
    p.add_argument("--steps", type=int, nargs="+", default=[100, 200])
    p.add_argument("--settle", type=float, default=5.0, help="run length in longest bond time constants")
    p.add_argument("-o", "--output", required=True)
    a = p.parse_args(argv)
    res = a.run / "results" / "forecast"
    matched = read_matched(res / "matched.csv")
    table = with_binder_route(matched, read_curves(res / "binder_curves.json"), binder_ids(matched), "curve")
    c = pd.read_csv(a.constants)
    c = c[c["model"] == "dem_extended"].set_index("constant")["all_mixes"]
    state = {k: float(c[k]) for k in ("C_m", "C_a", "C_s", "n_s")}
    sizes = {
        path.name.split("_s1")[0]: json.loads(path.read_text())["n_spheres"]
        for path in sorted((res / "samples").glob("*_s1_summary.json"))
    }
    order = sorted(sizes, key=lambda m: (sizes[m], m))
    mixes = [order[0], order[len(order) // 2], order[-1]]
    T = table["temperature_C"]
    corners = [
        table[(T == T.min())]["frequency_Hz"].max(),
        table[(T == T.max())]["frequency_Hz"].min(),
    ]
    rows = []
    for mix in mixes:
        sample = read_sample(res / "samples" / f"{mix}_s1.h5")
        m = table[table["mix_id"] == mix]
        v = phase_volumes(m.iloc[0], a.cut_mm)
        for temp, freq in ((T.min(), corners[0]), (T.max(), corners[1])):
            cell = m[(m["temperature_C"] == temp) & (m["frequency_Hz"] == freq)].iloc[0]
            e = mortar_modulus(
                np.array([cell["binder_G_mix_MPa"] * 1e6]),
                np.array([cell["binder_delta_mix_deg"]]),
                v["phi_filler"],
                v["phi_fine"],
            )
            e1, zeta = bond_moduli(state, e)
            for steps in a.steps:
                r = time_domain_check(
                    sample, complex(e1[0]), complex(zeta[0]), float(freq), steps_per_cycle=steps, settle_factor=a.settle
                )
                rows.append(
                    {
                        "mix_id": mix,
                        "n_spheres": sizes[mix],
                        "temperature_C": temp,
                        "frequency_Hz": freq,
                        "zeta_abs": float(abs(zeta[0])),
                        **r,
                    }
                )
                print(rows[-1], flush=True)
    write_csv(pd.DataFrame(rows), a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
