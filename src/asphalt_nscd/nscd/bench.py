"""Benchmarks of the NSCD core (``asphalt-nscd bench``; JSON output, never timed tests).

Cases (:func:`run_bench`):

``bonded``
    A 2PB-like bonded sample generated here (:func:`bonded_sample`: a jittered cubic lattice
    of N spheres in the bounding box of the EN 12697-26 trapezoid, Table 3's Burger's law at
    15 degC read in Pa, head driven at 40 Hz, dt = 5e-5 s, theta = 0.5). The production path
    (linear fast path) is timed against NLGS (``baseline_*``) and SuperLU (``direct_*``) on
    the same sample; ``start`` 'rest' (under gravity) or 'periodic' (the periodic steady
    state, no gravity); with ``linear_solver`` 'cg_ssor' the block-Jacobi 'cg' runs the same
    steps on a copy, alternating chunks of 5 steps (``speedup_vs_cg``).
``granular``
    A frictional bed of N spheres under gravity in a box of 5 walls (:func:`granular_sample`,
    friction 0.2, dt = 2e-4 s, NLGS at ``tolerance``): settled first (``settle_*``, until
    the largest speed is below ``settle_speed``), then ``steps`` timed steps of the bed at rest.

``threads`` > 1 also times the bonded steps with one thread (wall times, ``thread_speedup``).
Times are process CPU time per particle and step, with the wall time and the load average
(the machine is shared). The JSON fields: docs/design.md, NSCD core: kernels, fast path,
benchmark records. Cases and choices (the settled granular bed, same-run alternation of the
solvers): docs/choices.md, NSCD core.
"""

from __future__ import annotations

import os
import platform
import resource
import time
from typing import Any

import numpy as np

from ..io import InputError, read_json
from ..rheology.laws import GeneralizedBurgers
from .detection import plate_pairs, sphere_pairs
from .moreau_jean import Simulation
from .state import HEAD_AMPLITUDE_M, Bonds, NSCDParameters, Plate, Plates, Spheres

LAW_15C = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
BOX = (0.056, 0.025, 0.250)  # m: bounding box of the trapezoid (B, e, h)
DRIVE_HZ = 40.0  # Hz: head motion of the bonded case (amplitude HEAD_AMPLITUDE_M)


def bonded_sample(
    n: int, seed: int = 0, d_min: float = 2e-3, law=LAW_15C, density: float = 3415.0
) -> tuple[Spheres, Plates, Bonds]:
    """Spheres, plates and bonds of the bench's 2PB-like sample (see module docstring)."""
    rng = np.random.default_rng(seed)
    vol = BOX[0] * BOX[1] * BOX[2]
    pitch = (vol / n) ** (1.0 / 3.0)
    dims = np.maximum(np.round(np.array(BOX) / pitch).astype(int), 1)
    while np.prod(dims) < n:
        dims[2] += 1
    idx = np.array(np.unravel_index(np.arange(n), dims[::-1]))[::-1].T  # x fastest
    pos = (idx + 0.5) * pitch + rng.uniform(-0.05, 0.05, (n, 3)) * pitch
    rad = rng.uniform(0.35, 0.45, n) * pitch
    s = Spheres.from_density(pos, rad, density)
    # top plate just above the highest sphere (the last lattice layer may be partial)
    z_top = float((pos[:, 2] + rad).max()) + 0.1 * pitch
    omega, amp = 2 * np.pi * DRIVE_HZ, HEAD_AMPLITUDE_M
    plates = Plates(
        [
            Plate([0, 0, 0], [0, 0, 1]),
            Plate(
                [0, 0, z_top],
                [0, 0, -1],
                mode="driven",
                mass=0.235,
                displacement=lambda t: np.array([amp * np.sin(omega * t), 0.0, 0.0]),
            ),
        ]
    )
    i, j, _ = sphere_pairs(s.position, s.radius, d_min)
    pi_, pk, _ = plate_pairs(s.position, s.radius, plates.point, plates.normal, d_min)
    bonds = Bonds.create(s, plates, np.concatenate([i, pi_]), np.concatenate([j, -1 - pk]), law)
    return s, plates, bonds


def granular_sample(n: int, seed: int = 0, density: float = 2600.0):
    """Spheres on a loose jittered cubic lattice in a 5-wall box (open top)."""
    rng = np.random.default_rng(seed)
    r_max = 1.5e-3
    pitch = 2.02 * r_max
    nx = max(int(round(1.5 * n ** (1 / 3))), 1)
    ny = nx
    nz = int(np.ceil(n / (nx * ny)))
    idx = np.array(np.unravel_index(np.arange(n), (nz, ny, nx)))[::-1].T
    pos = (idx + 0.5) * pitch + rng.uniform(-0.005, 0.005, (n, 3)) * pitch
    rad = rng.uniform(1e-3, r_max, n)
    s = Spheres.from_density(pos, rad, density)
    lx, ly = nx * pitch, ny * pitch
    plates = Plates(
        [
            Plate([0, 0, 0], [0, 0, 1]),
            Plate([0, 0, 0], [1, 0, 0]),
            Plate([lx, 0, 0], [-1, 0, 0]),
            Plate([0, 0, 0], [0, 1, 0]),
            Plate([0, ly, 0], [0, -1, 0]),
        ]
    )
    return s, plates


def _at_rest(start, rec):
    """The Simulation constructor of the bonded case's runs started at rest (the default
    ``starter`` of :func:`run_bench`).

    Raises
    ------
    InputError for any ``start`` but 'rest': the periodic start needs the harmonic solver,
    :func:`asphalt_nscd.campaign.bench.bench_starter` (what ``asphalt-nscd bench`` uses).
    """
    if start != "rest":
        raise InputError(f"--start {start} needs the starter asphalt_nscd.campaign.bench.bench_starter")
    return Simulation


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def compile_time() -> float:
    """Time (s) of a first call of every kernel on a tiny problem (compile or cache load)."""
    t = time.perf_counter()
    s, plates, bonds = bonded_sample(30, seed=1)
    sim = Simulation(s, plates, bonds, NSCDParameters(dt=5e-5, fast_path=True))
    sim.run(2)
    sim = Simulation(*bonded_sample(30, seed=1), NSCDParameters(dt=5e-5, fast_path=False))
    sim.run(2)
    s, plates = granular_sample(30, seed=1)
    Simulation(s, plates, None, NSCDParameters(dt=1e-4, friction=0.2)).run(2)
    return time.perf_counter() - t


def _timed(sim, steps):
    """Run ``steps`` steps; returns (CPU seconds of this process, wall seconds, stats,
    fraction of the step time per phase). CPU time is reported because the machine is
    shared: wall time grows with the load of other jobs."""
    for k in sim.timings:
        sim.timings[k] = 0.0
    t = time.perf_counter()
    c = time.process_time()
    df = sim.run(steps)
    cpu = time.process_time() - c
    wall = time.perf_counter() - t
    total = sum(sim.timings.values()) or 1.0
    breakdown = {k: v / total for k, v in sim.timings.items()}
    return cpu, wall, df, breakdown


def _timed_alternating(sims, steps, chunk=5):
    """Run ``steps`` steps of each simulation in alternating chunks (same machine load for
    all); returns the process CPU seconds and the mean step iterations of each."""
    cpu = [0.0] * len(sims)
    its = [[] for _ in sims]
    done = 0
    while done < steps:
        k = min(chunk, steps - done)
        for m, sim in enumerate(sims):
            c = time.process_time()
            for _ in range(k):
                its[m].append(sim.step().iterations)
            cpu[m] += time.process_time() - c
        done += k
    return cpu, [float(np.mean(x)) for x in its]


def run_bench(
    case: str,
    n: int,
    steps: int = 20,
    baseline_steps: int = 5,
    tolerance: float = 1e-7,
    settle_steps: int = 5000,
    seed: int = 0,
    linear_tolerance: float = 1e-7,
    bond_kinematics: str = "contact",
    threads: int = 1,
    settle_speed: float = 5e-3,
    linear_solver: str = "cg",
    bonded_contact: str = "after_break",
    start: str = "rest",
    ssor_omega: float | None = None,
    starter=None,
) -> dict:
    """Run one benchmark and return its JSON-able record (see module docstring).

    ``linear_tolerance``: relative residual of the conjugate gradient of the bonded case
    (1e-7, config/config.yaml: changes the phase angle of the driver force at 40 Hz,
    -10 degC, by < 1e-4 degree against the exact direct solve). ``bond_kinematics``: of the
    bonded case (NSCDParameters). ``threads``: NSCDParameters.threads of the timed run.
    ``settle_steps``, ``settle_speed`` (m/s): settling of the granular bed (module
    docstring). ``linear_solver``: of the bonded case's production run ('cg': block-Jacobi
    conjugate gradient; 'cg_ssor': SSOR-preconditioned, nscd/linear/ssor.py); with 'cg_ssor' the same
    steps are also run with 'cg' on a copy of the sample, alternating chunks of 5 steps,
    and ``cg_s_per_particle_step``, ``cg_iterations_mean`` and ``speedup_vs_cg`` (CPU time
    ratio) are reported. ``bonded_contact``: NSCDParameters.bonded_contact of every run of
    the bonded case. ``start`` (bonded case): 'rest' (the sample at rest under gravity, the
    head starting at t = 0: the from-rest transient) or 'periodic' (the 2PB setting without
    gravity, every run started in the periodic steady state of the linear sample under the
    head's motion, :func:`asphalt_nscd.harmonic.periodic.periodic_state`: the regime of a
    2PB job once its transient has died out, or of a job with the periodic start; its
    harmonic solve, CPU s, is reported as ``periodic_solve_s`` and is part of ``setup_s``).
    ``ssor_omega``: NSCDParameters.linear_ssor_omega of 'cg_ssor' (None: its default).
    ``starter``: (start, rec) -> the constructor (spheres, plates, bonds, params) ->
    Simulation of the bonded case's runs, which may add keys to the record ``rec``; default:
    at rest only. :func:`asphalt_nscd.campaign.bench.bench_starter` adds the periodic start.

    Raises
    ------
    InputError (a ValueError) naming the option (``--n`` ...) for an unknown case, n < 2,
    steps < 1, threads outside [1, NUMBA_NUM_THREADS], settle_speed <= 0, an unknown start or ssor_omega outside (0, 2).
    """
    import numba

    if case not in ("bonded", "granular"):
        raise InputError(f"--case must be 'bonded' or 'granular', got {case!r}")
    if start not in ("rest", "periodic"):
        raise InputError(f"--start must be 'rest' or 'periodic', got {start!r}")
    if ssor_omega is not None and not 0 < ssor_omega < 2:
        raise InputError(f"--ssor-omega must lie in (0, 2), got {ssor_omega}")
    if n < 2 or steps < 1:
        raise InputError(f"--n must be >= 2 and --steps >= 1 (got {n}, {steps})")
    max_threads = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # set by numba at run time, undeclared
    if not 1 <= threads <= max_threads:
        raise InputError(f"--threads must lie in [1, {max_threads}] (NUMBA_NUM_THREADS), got {threads}")
    if not settle_speed > 0:
        raise InputError(f"--settle-speed must be > 0 m/s, got {settle_speed}")
    comp = compile_time()
    t0 = time.perf_counter()
    rec: dict = {
        "case": case,
        "n_particles": int(n),
        "steps": int(steps),
        "tolerance": tolerance,
        "threads": int(threads),
        "numba_threads_available": int(max_threads),
        "compile_s": comp,
        "seed": seed,
        "bond_kinematics": bond_kinematics,
        "bonded_contact": bonded_contact,
        "start": start,
        "cpu": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "numba": numba.__version__,
    }
    if case == "bonded":
        gravity = (0.0, 0.0, -9.81) if start == "rest" else (0.0, 0.0, 0.0)
        make_sim = (starter or _at_rest)(start, rec)
        s, plates, bonds = bonded_sample(n, seed=seed)
        ssor: dict[str, Any] = {} if ssor_omega is None else {"linear_ssor_omega": ssor_omega}
        params = NSCDParameters(
            dt=5e-5,
            theta=0.5,
            friction=0.7,
            tolerance=tolerance,
            max_iterations=5000,
            fast_path=True,
            linear_tolerance=linear_tolerance,
            linear_solver=linear_solver,
            bond_kinematics=bond_kinematics,
            threads=threads,
            bonded_contact=bonded_contact,
            gravity=gravity,
            **ssor,
        )
        sim = make_sim(s, plates, bonds, params)
        sim.step()  # first factorisation
        rec["setup_s"] = time.perf_counter() - t0
        nnz = sim._linear.nnz_factor if sim._linear else 0
        rec["factor_nnz"] = None if nnz is None else int(nnz)
        wall, wall_clock, df, br = _timed(sim, steps)
        rec.update(
            n_bonds=int(bonds.n),
            solver=str(df.solver.mode()[0]),
            wall_s_per_particle_step=wall_clock / (steps * n),
            linear_solver=params.linear_solver,
            linear_tolerance=params.linear_tolerance,
            linear_ssor_omega=params.linear_ssor_omega,
            n_contacts=int(df.n_contacts.iloc[-1]),
            n_active_contacts=int(df.n_active_contacts.iloc[-1]),
            s_per_particle_step=wall / (steps * n),
            nlgs_iterations_mean=float(df.iterations.mean()),
            time_breakdown=br,
        )
        rec["peak_rss_mb_production"] = _peak_rss_mb()  # before the references below
        if linear_solver != "cg":  # the block-Jacobi kernel on a copy, alternating chunks
            s5, plates5, bonds5 = bonded_sample(n, seed=seed)
            sim5 = make_sim(
                s5,
                plates5,
                bonds5,
                NSCDParameters(
                    dt=5e-5,
                    theta=0.5,
                    friction=0.7,
                    tolerance=tolerance,
                    max_iterations=5000,
                    fast_path=True,
                    linear_tolerance=linear_tolerance,
                    linear_solver="cg",
                    bond_kinematics=bond_kinematics,
                    threads=threads,
                    bonded_contact=bonded_contact,
                    gravity=gravity,
                ),
            )
            sim5.step()
            s6, plates6, bonds6 = bonded_sample(n, seed=seed)
            sim6 = make_sim(s6, plates6, bonds6, params)
            sim6.step()
            cpu_pair, it_pair = _timed_alternating([sim6, sim5], steps)
            rec.update(
                alternating_s_per_particle_step=cpu_pair[0] / (steps * n),
                cg_s_per_particle_step=cpu_pair[1] / (steps * n),
                cg_iterations_mean=it_pair[1],
                speedup_vs_cg=cpu_pair[1] / cpu_pair[0],
                cg_max_force_difference=float(
                    np.abs(bonds6.force - bonds5.force).max() / (float(np.abs(bonds5.force).max()) or 1.0)
                ),
            )
            del sim5, s5, plates5, bonds5, sim6, s6, plates6, bonds6
        if threads > 1:  # same steps on one thread, wall time compared
            s4, plates4, bonds4 = bonded_sample(n, seed=seed)
            sim4 = make_sim(
                s4,
                plates4,
                bonds4,
                NSCDParameters(
                    dt=5e-5,
                    theta=0.5,
                    friction=0.7,
                    tolerance=tolerance,
                    max_iterations=5000,
                    fast_path=True,
                    linear_tolerance=linear_tolerance,
                    bond_kinematics=bond_kinematics,
                    threads=1,
                    bonded_contact=bonded_contact,
                    gravity=gravity,
                ),
            )
            sim4.step()
            _, wall4, _, _ = _timed(sim4, steps)
            rec.update(
                threads1_wall_s_per_particle_step=wall4 / (steps * n),
                thread_speedup=wall4 / wall_clock,
                threads_max_force_difference=float(
                    np.abs(bonds.force - bonds4.force).max() / (float(np.abs(bonds4.force).max()) or 1.0)
                ),
            )
            del sim4, s4, plates4, bonds4
        # reference: direct (SuperLU) linear solver on the same sample, same steps
        s3, plates3, bonds3 = bonded_sample(n, seed=seed)
        t3 = time.perf_counter()
        sim3 = make_sim(
            s3,
            plates3,
            bonds3,
            NSCDParameters(
                dt=5e-5,
                theta=0.5,
                friction=0.7,
                fast_path=True,
                linear_solver="direct",
                bond_kinematics=bond_kinematics,
                bonded_contact=bonded_contact,
                gravity=gravity,
            ),
        )
        sim3.step()  # factorisation
        direct_setup = time.perf_counter() - t3
        cpu3, _, _, _ = _timed(sim3, steps)
        scale = float(np.abs(bonds3.force).max()) or 1.0
        nnz3 = sim3._linear.nnz_factor
        rec.update(
            direct_setup_s=direct_setup,
            direct_factor_nnz=None if nnz3 is None else int(nnz3),
            direct_factorisation=sim3.params.direct_factorisation,
            direct_s_per_particle_step=cpu3 / (steps * n),
            direct_vs_cg_max_force_difference=float(np.abs(bonds.force - bonds3.force).max() / scale),
        )
        del sim3, s3, plates3, bonds3
        # baseline: NLGS on the same sample, same state
        s2, plates2, bonds2 = bonded_sample(n, seed=seed)
        params2 = NSCDParameters(
            dt=5e-5,
            theta=0.5,
            friction=0.7,
            tolerance=tolerance,
            max_iterations=20000,
            fast_path=False,
            bond_kinematics=bond_kinematics,
            bonded_contact=bonded_contact,
            gravity=gravity,
        )
        sim2 = make_sim(s2, plates2, bonds2, params2)
        wall2, _, df2, br2 = _timed(sim2, baseline_steps)
        rec.update(
            baseline_solver="nlgs",
            baseline_steps=int(baseline_steps),
            baseline_s_per_particle_step=wall2 / (baseline_steps * n),
            baseline_nlgs_iterations_mean=float(df2.iterations.mean()),
            baseline_converged=bool(df2.converged.all()),
            baseline_time_breakdown=br2,
            speedup=(wall2 / (baseline_steps * n)) / (wall / (steps * n)),
        )
    else:
        s, plates = granular_sample(n, seed=seed)
        params = NSCDParameters(
            dt=2e-4, theta=0.5, friction=0.2, tolerance=tolerance, max_iterations=5000, threads=threads
        )
        sim = Simulation(s, plates, None, params)
        done, sweeps, speed = 0, [], np.inf
        c = time.process_time()
        while done < settle_steps:
            k = min(50, settle_steps - done)
            sweeps.extend(sim.run(k).iterations.tolist())
            done += k
            speed = float(np.sqrt((s.velocity**2).sum(1)).max())
            if speed < settle_speed:
                break
        settle_cpu = time.process_time() - c
        rec["setup_s"] = time.perf_counter() - t0
        rec.update(
            settle_steps=int(done),
            settle_speed=settle_speed,
            settled=bool(speed < settle_speed),
            settle_final_speed=speed,
            settle_s_per_particle_step=settle_cpu / max(done, 1) / n,
            settle_nlgs_iterations_mean=float(np.mean(sweeps)) if sweeps else 0.0,
            settle_nlgs_iterations_max=int(max(sweeps)) if sweeps else 0,
        )
        wall, wall_clock, df, br = _timed(sim, steps)
        rec.update(
            n_bonds=0,
            solver="nlgs",
            wall_s_per_particle_step=wall_clock / (steps * n),
            n_contacts=int(df.n_contacts.iloc[-1]),
            n_active_contacts=int(df.n_active_contacts.iloc[-1]),
            s_per_particle_step=wall / (steps * n),
            nlgs_iterations_mean=float(df.iterations.mean()),
            converged_fraction=float(df.converged.mean()),
            time_breakdown=br,
        )
    rec["peak_rss_mb"] = _peak_rss_mb()
    rec["load_average_1min"] = float(os.getloadavg()[0])
    return rec


def summary_table(paths):
    """One row per benchmark JSON record (output of :func:`run_bench`): its scalar keys and
    ``fraction_<phase>`` for each entry of ``time_breakdown``.

    Raises
    ------
    InputError
        naming the file: unreadable or not JSON, or a key ``case``, ``n_particles`` or
        ``s_per_particle_step`` missing.
    """
    import pandas as pd

    rows = []
    for path in paths:
        rec = read_json(path, "bench JSON")
        if not isinstance(rec, dict):
            raise InputError(f"{path}: expected a JSON object (a record of 'asphalt-nscd bench')")
        for key in ("case", "n_particles", "s_per_particle_step"):
            if key not in rec:
                raise InputError(f"{path}: key '{key}' missing")
        flat = {k: v for k, v in rec.items() if not isinstance(v, dict)}
        for k, v in rec.get("time_breakdown", {}).items():
            flat[f"fraction_{k}"] = v
        rows.append(flat)
    return pd.DataFrame(rows)
