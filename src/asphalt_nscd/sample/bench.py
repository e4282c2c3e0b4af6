"""Benchmark of one sample preparation (``asphalt-nscd prepare-bench``; JSON, never a timed test).

The record times one run of :func:`.prepare.prepare_sample` phase by phase (process CPU
time and wall-clock time, the machine being shared: the 1-min load average is recorded)
and puts the sample's descriptors beside the paper's (Section 3.2.1, Table 2):

* ``phases``: for each phase, ``cpu_s`` and ``wall_s``: lattice, deposition, vibration
  (``shaking`` and ``settling`` split it, from the per-stage statistics), cut_flip,
  plates_shrink (plates, shrink, density), bonds, stabilisation, total;
* ``nscd``: per dynamic stage, steps, mean NLGS sweeps (over the NLGS steps), unconverged
  steps, linear fast-path steps and their mean conjugate-gradient iterations, CPU time per
  particle and step;
* ``table2``: sphere counts of the layer per diameter beside the paper's Table 2
  (11798 / 1588 / 492 / 211 / 71) with the relative difference, and ``table2_max_abs_pct``;
* ``sample``: spheres in the trapezoid (paper: "about 12000"), bonds (sphere-sphere and
  sphere-plate), bonds per sphere, porosity, density (paper: 3415 kg/m³) and mass (paper:
  0.6 kg), coordination number.
"""

from __future__ import annotations

import os
import platform

from . import psd

#: Paper values beside which the record puts ours (Section 3.2.1).
PAPER = {"n_spheres_sample": 12000, "density_kg_m3": 3415.0, "sample_mass_kg": 0.6}


def _stage(info: dict, n: int) -> dict:
    steps = int(info.get("steps", 0))
    cpu = float(info.get("cpu_s", 0.0))
    return {
        "steps": steps,
        "time_step_s": info.get("time_step_s"),
        "mean_nlgs_iterations": info.get("mean_iterations"),
        "max_nlgs_iterations": info.get("max_iterations"),
        "unconverged_steps": info.get("unconverged_steps"),
        "linear_steps": info.get("linear_steps"),
        "mean_linear_iterations": info.get("mean_linear_iterations"),
        "cpu_s": cpu,
        "wall_s": float(info.get("wall_clock_s", 0.0)),
        "s_per_particle_step": cpu / (steps * n) if steps and n else None,
    }


def bench_record(summary: dict) -> dict:
    """The JSON record of one preparation from its summary (:func:`.prepare.prepare_sample`).

    Parameters
    ----------
    summary : dict, ``PreparedSample.summary``.

    Returns
    -------
    dict (module docstring).
    """
    cpu, wall = summary["cpu_s"], summary["timings_s"]
    phases = {k[:-2]: {"cpu_s": cpu[k], "wall_s": wall[k]} for k in cpu}
    n_layer = summary["n_spheres_layer"]
    vib = summary["vibration"]
    nscd = {"deposition": _stage(summary["deposition"], n_layer)}
    for part in ("shaking", "settling"):
        if part in vib:
            nscd[f"vibration_{part}"] = _stage(vib[part], n_layer)
            phases[f"vibration_{part}"] = {"cpu_s": vib[part]["cpu_s"], "wall_s": vib[part]["wall_clock_s"]}
    if summary["stabilisation"].get("steps"):
        nscd["stabilisation"] = _stage(summary["stabilisation"], summary["n_spheres"])
    table = []
    worst = 0.0
    for d_mm, n_paper in psd.TABLE2_COUNTS.items():
        n_ours = summary["counts_layer"].get(f"{d_mm:g}")
        rel = 100.0 * (n_ours - n_paper) / n_paper if n_ours is not None else None
        if rel is not None:
            worst = max(worst, abs(rel))
        table.append(
            {
                "diameter_mm": d_mm,
                "n_paper": n_paper,
                "n_layer": n_ours,
                "n_sample": summary["counts_sample"].get(f"{d_mm:g}"),
                "rel_diff_pct": rel,
            }
        )
    sample = {
        "n_spheres": summary["n_spheres"],
        "n_spheres_paper": PAPER["n_spheres_sample"],
        "n_bonds": summary["n_bonds"],
        "n_bonds_sphere_sphere": summary["n_bonds_sphere_sphere"],
        "n_bonds_bottom_plate": summary["n_bonds_bottom_plate"],
        "n_bonds_top_plate": summary["n_bonds_top_plate"],
        "bonds_per_sphere": summary["bonds_per_sphere"],
        "porosity": summary["porosity"],
        "porosity_before_shrink": summary["porosity_before_shrink"],
        "density_kg_m3": summary["density_kg_m3"],
        "density_paper_kg_m3": PAPER["density_kg_m3"],
        "sample_mass_kg": summary["sample_mass_kg"],
        "sample_mass_paper_kg": PAPER["sample_mass_kg"],
        "coordination_number": summary["coordination_number"],
        "layer_height_after_vibration_mm": summary["layer_height_after_vibration_mm"],
        "layer_height_paper_mm": 60.0,
        "max_overlap_after_vibration_mm": summary["max_overlap_after_vibration_mm"],
        "broken_bonds_stabilisation": summary["stabilisation"].get("broken_bonds"),
        "bonded_contact": summary["stabilisation"].get("bonded_contact"),
    }
    return {
        "case": "prepare",
        "seed": summary["seed"],
        "scale": summary["scale"],
        "psd_cut_mm": summary["psd_cut_mm"],
        "n_spheres_layer": n_layer,
        "phases": phases,
        "total_cpu_s": cpu["total_s"],
        "total_wall_s": wall["total_s"],
        "nscd": nscd,
        "table2": table,
        "table2_max_abs_pct": worst,
        "sample": sample,
        "load_average_1min": float(os.getloadavg()[0]),
        "cpu": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
