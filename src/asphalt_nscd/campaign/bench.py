"""Cost of the numerical 2PB test and projection of a campaign's total time.

:func:`measure_step_cost` times ``n_steps`` steps of the 2PB test (Moreau-Jean, bonds of the
paper's Table 3 at 15 degC read in Pa) on a sample file, or on a bonded lattice sample of
``n_spheres`` spheres (:func:`asphalt_nscd.harmonic.network.lattice_sample`, the stand-in of
a prepared sample with 6-12 bonds per sphere) after ``warmup`` steps (numba compilation).
:func:`project_campaign` multiplies the cost per step by the number of steps of every job
of a ``campaign`` config section (dt policy, cycles, schedules, studies) and gives the
wall time on 1 and 2 cores and on a P-core allocation, where each job runs on one core and
the wall time is bounded below by the longest job.
"""

from __future__ import annotations

import time

import numpy as np

from ..rheology.laws import GeneralizedBurgers
from .twopb import TwoPBSettings, build_simulation, n_steps_of, time_step

LAW_15C_PA = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)


def measure_step_cost(sample_path=None, n_spheres: int = 2000, n_steps: int = 200, warmup: int = 5,
                      frequency_Hz: float = 3.0, settings: TwoPBSettings | None = None, seed: int = 0) -> dict:
    """Wall time per step (s) of the 2PB test on a sample file or a lattice sample.

    Returns dict: n_spheres, n_bonds, n_steps, s_per_step and s_per_sphere_step (process CPU
    time, robust to a shared machine), wall_s_per_step, linear_fraction (steps solved by the
    linear fast path), dt_s.
    """
    import tempfile
    from pathlib import Path

    from ..harmonic.network import lattice_sample, write_sample
    from ..sample.store import read_sample

    settings = settings or TwoPBSettings()
    with tempfile.TemporaryDirectory() as tmp:
        if sample_path is None:
            sample_path = Path(tmp) / "lattice.h5"
            write_sample(sample_path, **lattice_sample(n_spheres, seed=seed, radius_range=(0.9e-3, 1.6e-3)))
        sample = read_sample(sample_path)
    dt = time_step(frequency_Hz, settings)
    sim, _ = build_simulation(sample, LAW_15C_PA, frequency_Hz, dt, settings)
    for _ in range(warmup):
        sim.step()
    linear = 0
    tic, cpu_tic = time.perf_counter(), time.process_time()
    for _ in range(n_steps):
        linear += sim.step().solver == "linear"
    wall = time.perf_counter() - tic
    cpu = time.process_time() - cpu_tic
    n = sample.position.shape[0]
    return {"n_spheres": int(n), "n_bonds": int(len(sample.bonds["i"])), "n_steps": int(n_steps),
            "s_per_step": cpu / n_steps, "s_per_sphere_step": cpu / (n_steps * n),
            "wall_s_per_step": wall / n_steps,
            "linear_fraction": linear / n_steps, "dt_s": dt}


def campaign_jobs(campaign: dict, n_samples_total: int) -> list[dict]:
    """Every test job of a ``campaign`` config section: mode, n_samples, T, f, dt, n_steps.

    As workflow/rules/simulation.smk: the main modes (``campaign.modes``, ``campaign.n_samples``
    samples), the extended mode (the measured schedule and settings on
    ``campaign.extended.n_samples`` samples; always run), the dt study, the sensitivity study
    and the units question. The extended mode's transfer correction changes the law, not the
    job count or the time steps.
    """
    def ns(n):
        return n_samples_total if n is None else min(int(n), n_samples_total)

    def settings_for(mode):
        sched = campaign["measured"] if mode in ("measured", "extended") else campaign["paper"]
        cfg = dict(campaign["test"])
        cfg.update({k: sched[k] for k in ("dt_policy", "yield_stress_Pa") if k in sched})
        return TwoPBSettings(**{k: v for k, v in cfg.items() if k in TwoPBSettings.__dataclass_fields__})

    jobs = []

    def add(mode, n, T, f, dt=None):
        s = settings_for(mode)
        step = dt if dt is not None else time_step(f, s)
        jobs.append({"mode": mode, "n_samples": n, "temperature_C": T, "frequency_Hz": f, "dt_s": step,
                     "n_steps": n_steps_of(f, step, s)})

    for mode in campaign["modes"]:
        for T in campaign[mode]["temperatures_C"]:
            for f in campaign[mode]["frequencies_Hz"]:
                add(mode, ns(campaign["n_samples"]), T, f)
    if "extended" in campaign:
        for T in campaign["measured"]["temperatures_C"]:
            for f in campaign["measured"]["frequencies_Hz"]:
                add("extended", ns(campaign["extended"]["n_samples"]), T, f)
    d = campaign["dt_study"]
    for dt in d["dt_s"]:
        add("dt_study", ns(d["n_samples"]), d["temperature_C"], d["frequency_Hz"], dt)
    d = campaign["sensitivity"]
    for _ in range(4 * len(d["factors"])):
        for f in d["frequencies_Hz"]:
            add("sensitivity", ns(d["n_samples"]), d["temperature_C"], f)
    # paper-mode jobs other rules need even when the paper schedule does not hold them (or the
    # paper mode is off): the x1 baseline of the sensitivity study and the last-cycle figure
    paper = campaign["paper"]
    scheduled = {(T, f) for T in paper["temperatures_C"] for f in paper["frequencies_Hz"]} \
        if "paper" in campaign["modes"] else set()
    extra = {(d["temperature_C"], f): ns(d["n_samples"]) for f in d["frequencies_Hz"]}
    last = campaign["last_cycle"]
    key = (last["temperature_C"], last["frequency_Hz"])
    extra[key] = max(extra.get(key, 0), 1)
    for (T, f), n in extra.items():
        if (T, f) not in scheduled:
            add("paper", n, T, f)
    d = campaign["units_question"]
    for mode in ("units_kPa", "units_kPa_nobreak"):
        for f in d["frequencies_Hz"]:
            add(mode, ns(d["n_samples"]), d["temperature_C"], f)
    return jobs


def project_campaign(campaign: dict, n_samples_total: int, s_per_step: float, overhead_s: float = 3.0,
                     cores=(1, 2, 100)) -> dict:
    """Projected wall time (h) of every test job of a campaign on each core count.

    ``overhead_s``: per-job start-up (interpreter, imports, numba cache, sample reading).
    Wall time on P cores = max(total / P, longest job) (one job per core, perfect packing).
    """
    jobs = campaign_jobs(campaign, n_samples_total)
    per_job = [j["n_steps"] * s_per_step + overhead_s for j in jobs for _ in range(j["n_samples"])]
    total = float(np.sum(per_job))
    longest = float(np.max(per_job))
    by_mode = {}
    for j in jobs:
        by_mode[j["mode"]] = by_mode.get(j["mode"], 0.0) + j["n_samples"] * (j["n_steps"] * s_per_step + overhead_s)
    return {"n_jobs": len(per_job), "total_core_h": total / 3600, "longest_job_h": longest / 3600,
            "core_h_by_mode": {k: v / 3600 for k, v in by_mode.items()},
            "wall_h": {str(p): max(total / p, longest) / 3600 for p in cores},
            "s_per_step": s_per_step, "overhead_s": overhead_s,
            "n_steps_total": int(sum(j["n_steps"] * j["n_samples"] for j in jobs))}
