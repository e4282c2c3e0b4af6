"""The physical bond laws' uniform series terms against every bond's own law, on prepared samples.

    python reference/forecast/uniform_series.py RUN_DIR -o reference/forecast/uniform_series.csv

RUN_DIR holds a forecast run (``results/forecast/``: matched table, binder curves, samples). For the
smallest, median and largest sample of the run, at every condition of its mix and at the
constants' defaults (the skeleton through the film) and with the parabolic skeleton of
``dem_p2``/``dem_p3`` (:data:`PARABOLIC`), the forecast |E*| and phase of :mod:`asphalt_nscd.forecast.physical` (the
stones' series terms taken uniform over each class, one eigen-decomposition per sample) against
the sparse direct solve of the uniaxial test with every bond's own series law.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast import dem, physical
from asphalt_nscd.forecast.formulation import film_thickness_m, phase_volumes
from asphalt_nscd.forecast.models import read_curves
from asphalt_nscd.forecast.mortar import Constituents
from asphalt_nscd.forecast.validation import binder_ids, with_binder_route
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.io import write_csv
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.sample.store import read_sample


def per_bond(sample, constants, Em, Gm, film, law: str = "film") -> np.ndarray:
    """E* (Pa) with every bond's own series law, by the sparse direct solve at each condition
    (``law``: the skeleton through the film, or the parabolic skeleton of ``dem_p2``/``dem_p3``)."""
    system = HarmonicSystem(network_from_sample(sample), head_rotation="clamped")
    g, skel = dem.bond_geometry(sample)
    R = dem.contact_radius(sample)
    Es = constants["E_stone_Pa"] / (1 - Constituents().nu_stone ** 2)
    h = constants["film_factor"] * film
    out = []
    for em, gm in zip(Em, Gm):
        k = 1.0 / (1.0 / (g * em) + 1.0 / (sample.bonds["r_min"] * Es))
        if law == "film":
            k = k + skel / (1.0 / (6 * np.pi * gm * R**2 / h) + 1.0 / (np.sqrt(2 * R * h) * Es))
        else:
            n = constants["skeleton_exponent"]
            k = k + skel * g * constants["skeleton_scale"] * Es * np.exp(n * np.log(em / Es))
        sol = system.solve(k, k * system.t_ratio, 1e-12, amplitude=1.0, inertia="none", axis=2)
        out.append(sol.force[2] / float(sample.attrs["h_m"]))
    return np.array(out)


#: the parabolic skeleton's constants of the check (inside their ranges, near those the shipped mixes give)
PARABOLIC = {**{k: v.default for k, v in physical.CONSTANTS.items()}, "skeleton_scale": 0.9, "skeleton_exponent": 0.35}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True)
    a = p.parse_args(argv)
    res = a.run / "results" / "forecast"
    table = read_matched(res / "matched.csv")
    routed = with_binder_route(table, read_curves(res / "binder_curves.json"), binder_ids(table), "curve")
    samples = sorted((res / "samples").glob("*_s1.h5"))
    sizes = sorted((read_sample(s).radius.size, s) for s in samples)
    chosen = [sizes[0][1], sizes[len(sizes) // 2][1], sizes[-1][1]]
    c = {k: v.default for k, v in physical.CONSTANTS.items()}
    rows = []
    for path in chosen:
        mix = path.name.split("_")[0]
        s = read_sample(path)
        r = dem.sample_response(s, mix, 1)
        t = routed[routed["mix_id"] == mix]
        mm = physical.MixMortar(
            t["binder_G_mix_MPa"].to_numpy() * 1e6, t["binder_delta_mix_deg"].to_numpy(), phase_volumes(t.iloc[0], 4.0)
        )
        Em, Gm = mm.moduli(c["fine_packing"], c["E_stone_Pa"])
        film = film_thickness_m(t.iloc[0])
        for law, constants in (("film", c), ("parabolic", PARABOLIC)):
            e1, z = physical.bond_moduli(constants, Em, Gm, film, r, law)
            approx = e1 * r.factor(z, skeleton="film" if law == "film" else "mortar")
            exact = per_bond(s, constants, Em, Gm, film, law)
            for k in range(len(t)):
                rows.append(
                    {
                        "mix_id": mix,
                        "n_spheres": int(s.radius.size),
                        "law": law,
                        "temperature_C": float(t["temperature_C"].iloc[k]),
                        "frequency_Hz": float(t["frequency_Hz"].iloc[k]),
                        "E_exact_MPa": abs(exact[k]) / 1e6,
                        "uniform_minus_exact_logE_pct": float(100 * np.log(abs(approx[k] / exact[k]))),
                        "uniform_minus_exact_phase_deg": float(np.degrees(np.angle(approx[k] / exact[k]))),
                    }
                )
    write_csv(pd.DataFrame(rows).round(6), a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
