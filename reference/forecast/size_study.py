"""Size study of the discrete forecast's sample: the cube's side in largest diameters, and the seeds.

For a few mixes spanning the table's coarse-aggregate fractions, samples prepared at several cube
sizes (side / largest sphere diameter) and seeds (``asphalt-nscd forecast-pack`` and
``forecast-sample`` with ``--size-dmax``); for each, the uniaxial response factor
E*_sample / e_1 at a few values of zeta (skeleton / mortar modulus: 0 = mortar alone, ``dem``;
larger = the skeleton carries more, ``dem_extended``), by the direct sparse harmonic solve
(:meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.solve`, head clamped, driven along the height).
Writes one row per sample and a summary per (mix, size, zeta): mean over seeds, the seeds'
coefficient of variation, and the CPU of a preparation.

    python reference/forecast/size_study.py SAMPLES_DIR -o reference/forecast/size_study.csv \\
        --summary reference/forecast/size_study_summary.csv

SAMPLES_DIR holds <mix>_x<size>_s<seed>.h5 with their .json summaries and .time (``/usr/bin/time -f
"%U %S"`` of forecast-pack).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast import dem
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.io import read_json, write_csv
from asphalt_nscd.sample.prepare import CONTACT_TOLERANCE
from asphalt_nscd.sample.store import read_sample

ZETAS = (0.0, 0.1, 1.0, 10.0)
NAME = re.compile(r"(?P<mix>[^_]+)_x(?P<size>[\d.]+)_s(?P<seed>\d+)\.h5$")


def factors(sample) -> dict:
    """E*_sample / e_1 at each zeta of :data:`ZETAS` (real: the laws are real here)."""
    system = HarmonicSystem(network_from_sample(sample), head_rotation="clamped")
    film = np.maximum(sample.bonds["delta0"], CONTACT_TOLERANCE * sample.attrs["d_min_m"]) + dem.mortar_thickness(
        sample
    )
    g = np.pi * sample.bonds["r_min"] ** 2 / film
    skel = dem.skeleton_bonds(sample)
    out = {}
    for z in ZETAS:
        k = g * (1.0 + z * skel)
        sol = system.solve(k, k * system.t_ratio, 1e-12, amplitude=1.0, inertia="none", axis=2)
        out[f"factor_zeta{z:g}"] = float(sol.force[2].real / float(sample.attrs["h_m"]))
    out["n_skeleton_per_sphere"] = float(skel.sum() / sample.radius.size)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("samples", type=Path)
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--summary", required=True)
    args = p.parse_args(argv)
    rows = []
    for h5 in sorted(args.samples.glob("*.h5")):
        m = NAME.search(h5.name)
        if m is None:
            continue
        s = read_sample(h5)
        summary = read_json(h5.with_suffix(".json"))
        cpu = h5.with_suffix(".time")
        rows.append(
            {
                "mix_id": m["mix"],
                "size_dmax": float(m["size"]),
                "seed": int(m["seed"]),
                "n_spheres": int(s.radius.size),
                "n_bonds": int(s.bonds["i"].size),
                "coarse_volume_fraction": summary["coarse_volume_fraction"],
                "pack_cpu_s": float(sum(map(float, cpu.read_text().split()))) if cpu.exists() else np.nan,
                **factors(s),
            }
        )
    table = pd.DataFrame(rows).sort_values(["mix_id", "size_dmax", "seed"])
    write_csv(table, args.output)
    cols = [c for c in table.columns if c.startswith("factor_")]
    g = table.groupby(["mix_id", "size_dmax"])
    summary = g.agg(
        n_seeds=("seed", "size"),
        n_spheres=("n_spheres", "mean"),
        coarse=("coarse_volume_fraction", "first"),
        pack_cpu_s=("pack_cpu_s", "mean"),
        **{f"{c}_mean": (c, "mean") for c in cols},
        **{f"{c}_cv_pct": (c, lambda v: 100 * np.std(v, ddof=1) / np.mean(v) if len(v) > 1 else np.nan) for c in cols},
    ).reset_index()
    write_csv(summary, args.summary)
    print(summary.round(3).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
