"""Cost of the numerical 2PB test and projection of a campaign's total time.

:func:`measure_step_cost` times ``n_steps`` steps of the 2PB test (Moreau-Jean, bonds of the
paper's Table 3 at 15 degC read in Pa) on a sample file, or on a bonded lattice sample of
``n_spheres`` spheres (:func:`asphalt_nscd.sample.lattice.lattice_sample`, the stand-in of
a prepared sample with 6-12 bonds per sphere) after ``warmup`` steps (numba compilation).

The cost of a step is not the same in every job: the conjugate gradient of the linear fast
path needs more iterations where the bonds are stiff against the masses over a step (mix-like
moduli of the measured and extended modes, long steps of the steps_per_cycle policy at low
frequency). :func:`measure_job_costs` therefore times every distinct job class (mode, T, f,
dt) of a campaign on the sample with the job's own law (:class:`.study.JobLaws`), from each
start the projection needs (rest, and periodic where the config asks for it, including the
time of the periodic state's harmonic solve).

:func:`project_campaign` multiplies the cost per step by the number of steps of every job
of a ``campaign`` config section (dt policy, start and cycles per mode, schedules, studies),
adds the periodic solves, a per-job start-up and the preparation of the samples, and gives
the wall time on 1 and 2 cores and on a P-core allocation, where each job runs on one core
and the wall time is bounded below by the longest job. ``start='rest'`` projects the paper's
protocol everywhere (the "before" of the periodic start).

:func:`bench_starter` gives the NSCD core benchmark (:func:`asphalt_nscd.nscd.bench.run_bench`,
``asphalt-nscd bench``) its periodic start, which needs the harmonic solver.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..io import InputError
from ..rheology.laws import GeneralizedBurgers
from .twopb import TwoPBSettings, build_simulation, n_steps_of, time_step

LAW_15C_PA = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)


def measure_step_cost(
    sample_path=None,
    n_spheres: int = 2000,
    n_steps: int = 200,
    warmup: int = 5,
    frequency_Hz: float = 3.0,
    settings: TwoPBSettings | None = None,
    seed: int = 0,
) -> dict:
    """Wall time per step (s) of the 2PB test on a sample file or a lattice sample.

    Returns dict: n_spheres, n_bonds, n_steps, s_per_step and s_per_sphere_step (process CPU
    time, robust to a shared machine), wall_s_per_step, linear_fraction (steps solved by the
    linear fast path), dt_s. ``settings`` default: the paper's fixed dt (5e-5 s).
    """
    import tempfile
    from pathlib import Path

    from ..sample.lattice import lattice_sample
    from ..sample.store import read_sample, write_sample

    settings = settings or TwoPBSettings(dt_policy="fixed")
    with tempfile.TemporaryDirectory() as tmp:
        if sample_path is None:
            sample_path = Path(tmp) / "lattice.h5"
            write_sample(sample_path, lattice_sample(n_spheres, seed=seed, radius_range=(0.9e-3, 1.6e-3)))
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
    return {
        "n_spheres": int(n),
        "n_bonds": int(len(sample.bonds["i"])),
        "n_steps": int(n_steps),
        "s_per_step": cpu / n_steps,
        "s_per_sphere_step": cpu / (n_steps * n),
        "wall_s_per_step": wall / n_steps,
        "linear_fraction": linear / n_steps,
        "dt_s": dt,
    }


def campaign_jobs(
    campaign: dict, n_samples_total: int, bond_kinematics: str = "contact", start: str | None = None
) -> list[dict]:
    """Every test job of a ``campaign`` config section: mode, n_samples, T, f, dt, start,
    n_steps.

    As workflow/rules/campaign.smk: the main modes (``campaign.modes``, ``campaign.n_samples``
    samples), the extended mode (the measured schedule and settings on
    ``campaign.extended.n_samples`` samples; always run), the dt study, the sensitivity study
    and the units question, each with its settings (:func:`.twopb.mode_settings`). The
    extended mode's transfer correction changes the law, not the job count or the time steps.
    ``start``: None = each mode's configured start, 'rest' or 'periodic' = that start for
    every job. A periodic start that falls back to rest (bonds that would break) is not
    foreseen here.
    """
    from .twopb import mode_settings

    def ns(n):
        return n_samples_total if n is None else min(int(n), n_samples_total)

    def settings_for(mode):
        cfg = mode_settings(campaign, mode, bond_kinematics)
        if start is not None:
            cfg["start"] = start
        return TwoPBSettings(**{k: v for k, v in cfg.items() if k in TwoPBSettings.__dataclass_fields__})

    jobs = []

    def add(mode, n, T, f, dt=None):
        s = settings_for(mode)
        step = dt if dt is not None else time_step(f, s)
        jobs.append(
            {
                "mode": mode,
                "n_samples": n,
                "temperature_C": T,
                "frequency_Hz": f,
                "dt_s": step,
                "start": s.start,
                "n_steps": n_steps_of(f, step, s),
            }
        )

    for mode in campaign["modes"]:
        sched = campaign["measured" if mode == "measured" else "paper"]
        for T in sched["temperatures_C"]:
            for f in sched["frequencies_Hz"]:
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
    scheduled = (
        {(T, f) for T in paper["temperatures_C"] for f in paper["frequencies_Hz"]}
        if "paper" in campaign["modes"]
        else set()
    )
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


def job_class(job: dict) -> tuple:
    """Key of the cost class of a job: (mode, T, f, dt); the studies' parameter factors are
    not part of it (the base law is timed)."""
    return (job["mode"], float(job["temperature_C"]), float(job["frequency_Hz"]), float(job["dt_s"]))


def measure_job_costs(
    sample_path,
    campaign: dict,
    jobs: list[dict],
    laws,
    n_steps: int = 10,
    warmup: int = 2,
    bond_kinematics: str = "contact",
    starts=("rest", "periodic"),
    linear_solver: str = "cg",
    linear_tolerance: float | None = None,
    baseline: dict | None = None,
    chunk: int = 5,
) -> dict:
    """CPU time per step of every job class of ``jobs`` on a sample file, with the job's law.

    Parameters
    ----------
    laws : :class:`.study.JobLaws` (the law files of the modes).
    starts : starts to time; 'periodic' is timed only for classes whose jobs start periodic.
    n_steps, warmup : timed steps after warm-up steps, per class and start.
    bond_kinematics, linear_solver, linear_tolerance : the core's (config ``nscd``; a mode's own
        solver wins).
    baseline : settings (keys of :class:`.twopb.TwoPBSettings`) that replace the configured
        ones in a second simulation of the same job, timed in the same run: the two are
        stepped by turns, ``chunk`` steps each, so that both see the same machine load
        (e.g. ``{"fast_path_contacts": 0}``: every closing contact to NLGS).

    Returns
    -------
    dict {job_class: {start: {s_per_step, iterations_mean, linear_fraction, solve_s (CPU time
    of the periodic state, 0 from rest)[, s_per_step_baseline, linear_fraction_baseline,
    speedup = s_per_step_baseline / s_per_step]}}}

    Raises
    ------
    ValueError for a baseline key that is not a TwoPBSettings field.
    """
    unknown = set(baseline or {}) - set(TwoPBSettings.__dataclass_fields__)
    if unknown:
        raise ValueError(f"baseline settings: unknown keys {sorted(unknown)}; expected keys of TwoPBSettings")
    import dataclasses

    from ..sample.store import read_sample
    from .twopb import mode_settings, start_test

    sample = read_sample(sample_path)
    out: dict[tuple, dict[str, dict[str, Any]]] = {}
    periodic_classes = {job_class(j) for j in jobs if j["start"] == "periodic"}
    for cls in dict.fromkeys(job_class(j) for j in jobs):
        mode, T, f, dt = cls
        base = TwoPBSettings(
            **{
                k: v
                for k, v in mode_settings(campaign, mode, bond_kinematics, linear_solver, linear_tolerance).items()
                if k in TwoPBSettings.__dataclass_fields__
            }
        )
        law = laws.law(mode, T)
        out[cls] = {}
        for start in starts:
            if start == "periodic" and cls not in periodic_classes:
                continue
            s = dataclasses.replace(base, start=start)
            sim, _ = build_simulation(sample, law, f, dt, s)
            cpu_start = time.process_time()
            info = start_test(sim, law, f, s)
            solve = time.process_time() - cpu_start if start == "periodic" else 0.0
            sims = [sim]
            if baseline:
                s_b = dataclasses.replace(s, **baseline)
                sims.append(build_simulation(sample, law, f, dt, s_b)[0])
                start_test(sims[1], law, f, s_b)
            for sm in sims:
                for _ in range(warmup):
                    sm.step()
            its, cpu, lin = [], [0.0] * len(sims), [0] * len(sims)
            for k0 in range(0, n_steps, chunk):
                for m, sm in enumerate(sims):
                    tic = time.process_time()
                    for _ in range(min(chunk, n_steps - k0)):
                        st = sm.step()
                        lin[m] += st.solver == "linear"
                        if m == 0:
                            its.append(st.iterations)
                    cpu[m] += time.process_time() - tic
            row = {
                "s_per_step": cpu[0] / n_steps,
                "iterations_mean": float(np.mean(its)),
                "linear_fraction": lin[0] / n_steps,
                "solve_s": solve,
                "start_used": info["start"],
            }
            if baseline:
                row.update(
                    s_per_step_baseline=cpu[1] / n_steps,
                    linear_fraction_baseline=lin[1] / n_steps,
                    speedup=cpu[1] / cpu[0],
                )
            out[cls][start] = row
    return out


def project_campaign(
    campaign: dict,
    n_samples_total: int,
    s_per_step,
    overhead_s: float = 3.0,
    cores=(1, 2, 100),
    bond_kinematics: str = "contact",
    start: str | None = None,
    periodic_solve_s=0.0,
    prepare_s_per_sample: float = 0.0,
    modes=None,
) -> dict:
    """Projected time of every test job of a campaign (core-hours and wall hours per core count).

    ``s_per_step``: CPU time of one step, s — a number, or a callable ``job -> s`` (e.g. from
    :func:`measure_job_costs`); ``periodic_solve_s``: the same for the periodic state's solve
    of a periodically started job. ``start``: see :func:`campaign_jobs`. ``overhead_s``:
    per-job start-up (interpreter, imports, numba cache, sample reading).
    ``prepare_s_per_sample``: preparation of one sample (all ``n_samples_total`` samples are
    prepared, in parallel with nothing else: they precede the jobs that use them).
    Wall time on P cores = max(total / P, longest job + one preparation) (one job per core,
    perfect packing). ``modes``: only these modes' jobs (None: all).
    """
    jobs = campaign_jobs(campaign, n_samples_total, bond_kinematics=bond_kinematics, start=start)
    if modes is not None:
        jobs = [j for j in jobs if j["mode"] in modes]

    def cost(fn, job):
        return fn(job) if callable(fn) else float(fn)

    per_job: list[float] = []
    by_mode: dict[str, float] = {}
    steps_by_mode: dict[str, int] = {}
    for j in jobs:
        t = j["n_steps"] * cost(s_per_step, j) + overhead_s
        if j["start"] == "periodic":
            t += cost(periodic_solve_s, j)
        per_job += [t] * j["n_samples"]
        by_mode[j["mode"]] = by_mode.get(j["mode"], 0.0) + j["n_samples"] * t
        steps_by_mode[j["mode"]] = steps_by_mode.get(j["mode"], 0) + j["n_samples"] * j["n_steps"]
    prepare = n_samples_total * prepare_s_per_sample
    total_jobs = float(np.sum(per_job))
    total = total_jobs + prepare
    longest = float(np.max(per_job)) + prepare_s_per_sample
    n_jobs: dict[str, int] = {}
    for j in jobs:
        n_jobs[j["mode"]] = n_jobs.get(j["mode"], 0) + j["n_samples"]
    return {
        "n_jobs": len(per_job),
        "total_core_h": total / 3600,
        "jobs_core_h": total_jobs / 3600,
        "prepare_core_h": prepare / 3600,
        "longest_job_h": float(np.max(per_job)) / 3600,
        "core_h_by_mode": {k: v / 3600 for k, v in by_mode.items()},
        "n_jobs_by_mode": n_jobs,
        "n_steps_by_mode": steps_by_mode,
        "steps_per_job_by_mode": {k: steps_by_mode[k] / n_jobs[k] for k in n_jobs},
        "start_by_mode": {j["mode"]: j["start"] for j in jobs},
        "wall_h": {str(p): max(total / p, longest) / 3600 for p in cores},
        "s_per_step": s_per_step if not callable(s_per_step) else "per job class",
        "overhead_s": overhead_s,
        "prepare_s_per_sample": prepare_s_per_sample,
        "n_steps_total": int(sum(j["n_steps"] * j["n_samples"] for j in jobs)),
    }


def read_prepare_seconds(path, key: str) -> float:
    """Preparation time of one sample, s: the number at the dotted ``key`` (e.g.
    ``timings_s.total``) of the JSON at ``path`` (a sample summary of ``prepare-sample``).

    Raises
    ------
    InputError
        naming the file and the key: unreadable or not JSON, the key absent (with the keys
        available where it stops), or its value not a number >= 0.
    """
    from ..io import read_json

    obj = read_json(path, "preparation JSON")
    for part in key.split("."):
        if not isinstance(obj, dict) or part not in obj:
            keys = sorted(obj) if isinstance(obj, dict) else type(obj).__name__
            raise InputError(f"{path}: key {key!r} not found (at {part!r}; available: {keys})")
        obj = obj[part]
    if isinstance(obj, bool) or not isinstance(obj, (int, float)) or not obj >= 0:
        raise InputError(f"{path}: key {key!r}: expected a time in s >= 0, got {obj!r}")
    return float(obj)


def bench_starter(start: str, rec: dict):
    """The Simulation constructor of the bonded case of :func:`asphalt_nscd.nscd.bench.run_bench`
    (its ``starter``): with ``start`` 'periodic', a simulation of the bench sample (built at
    rest, without gravity) is put in the periodic steady state of the 40 Hz head motion
    (:func:`asphalt_nscd.harmonic.periodic.periodic_state`, clamped head) before its first
    step. The state is computed once (harmonic solve, ``rec['periodic_solve_s']`` CPU s;
    ``rec['periodic_force_ratio']``) and applied to every run: all are built from the same
    seed, hence the same sample. With 'rest': :class:`asphalt_nscd.nscd.Simulation` itself."""
    from ..harmonic.periodic import apply_periodic_state, periodic_state
    from ..nscd.bench import DRIVE_HZ, LAW_15C
    from ..nscd.moreau_jean import Simulation
    from ..nscd.state import HEAD_AMPLITUDE_M

    if start == "rest":
        return Simulation
    cache = {}

    def make(s, plates, bonds, params):
        sim = Simulation(s, plates, bonds, params)
        if "state" not in cache:
            c = time.process_time()
            cache["state"] = periodic_state(sim, LAW_15C, DRIVE_HZ, HEAD_AMPLITUDE_M, head_rotation="clamped")
            rec["periodic_solve_s"] = time.process_time() - c
            rec["periodic_force_ratio"] = float(cache["state"].force_ratio)
        apply_periodic_state(sim, cache["state"])
        return sim

    return make
