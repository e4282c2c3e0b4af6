"""Studies built on the harmonic solver: sensitivity, time-domain comparison, network factor,
benchmark, figures.

* :func:`sensitivity_table` — the sensitivity study of Section 4.2 (each of Em, eta_m, Ek,
  eta_k changed by +-p % at one temperature) on a finer grid of p, for the discrete sample
  and the macro law.
* :func:`compare_time_domain` — harmonic vs NSCD time-domain rows per (T, f, dt), with the
  harmonic solution at several solver tolerances: separates the integrator's error (dt)
  from the linear solver's (rtol) and from the model (the same for both).
* :func:`network_factor_table` — per (sample, mode, T, f) ratio of the sample's |E*| to the
  macro |E*| and phase difference, and its mean and spread over samples.
* :func:`kinematics_study` — network factor per (bond_kinematics, head_rotation, T, f) of one
  sample: the micro-macro transfer under each modelling choice of :mod:`.solver`.
* :func:`benchmark` — timing and peak memory of one (T, f) on an N-sphere sample.
"""

from __future__ import annotations

import itertools
import resource
import time

import numpy as np
import pandas as pd

from ..rheology.calibration import burgers_model
from ..nscd.state import HEAD_AMPLITUDE_M
from ..rheology.laws import POISSON_RATIO
from .response import PARAM_COLUMNS, harmonic_rows

NETWORK_FACTOR_KEYS = ("sample", "mode", "temperature_C", "frequency_Hz")


def sensitivity_table(
    system, row: pd.Series, frequencies_Hz, levels_percent, geometry_mm, **solve_kwargs
) -> pd.DataFrame:
    """Harmonic |E*|, Phi with each Burger's parameter scaled by (1 +- p/100).

    Parameters
    ----------
    system : HarmonicSystem
    row : parameter row (``temperature_C`` + Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s).
    frequencies_Hz : sequence, Hz.  levels_percent : sequence of p > 0 (e.g. 10 ... 50).
    geometry_mm : ``b_mm, B_mm, e_mm, h_mm``.  solve_kwargs : see ``harmonic_rows``.

    Returns
    -------
    DataFrame: ``parameter`` ("reference" or a column name), ``change_percent`` (signed),
    the harmonic rows, and ``dE_norm_percent, dphase_deg`` (sample, vs the reference) and
    ``macro_dE_norm_percent, macro_dphase_deg`` (macro law).
    """
    if np.any(np.asarray(levels_percent, float) <= 0) or np.any(np.asarray(levels_percent) >= 100):
        raise ValueError(f"levels must lie in (0, 100) %, got {levels_percent}")
    cases = [("reference", 0.0)]
    for name in PARAM_COLUMNS:
        for p in sorted(levels_percent):
            cases += [(name, -float(p)), (name, float(p))]
    frames = []
    for name, change in cases:
        r = row.copy()
        if name != "reference":
            r[name] = float(r[name]) * (1.0 + change / 100.0)
        rows = harmonic_rows(
            system, burgers_model(r), float(row["temperature_C"]), frequencies_Hz, geometry_mm, **solve_kwargs
        )
        frame = pd.DataFrame(rows)
        frame.insert(0, "change_percent", change)
        frame.insert(0, "parameter", name)
        frames.append(frame)
    out = pd.concat(frames, ignore_index=True)
    ref = out[out["parameter"] == "reference"].set_index("frequency_Hz")
    f = out["frequency_Hz"]
    out["dE_norm_percent"] = 100 * (out["E_norm_MPa"].to_numpy() / ref.loc[f, "E_norm_MPa"].to_numpy() - 1)
    out["dphase_deg"] = out["phase_deg"].to_numpy() - ref.loc[f, "phase_deg"].to_numpy()
    out["macro_dE_norm_percent"] = 100 * (
        out["macro_E_norm_MPa"].to_numpy() / ref.loc[f, "macro_E_norm_MPa"].to_numpy() - 1
    )
    out["macro_dphase_deg"] = out["macro_phase_deg"].to_numpy() - ref.loc[f, "macro_phase_deg"].to_numpy()
    return out


def compare_time_domain(
    sample_path, system, params: pd.DataFrame, frequencies_Hz, dts, rtols, geometry_mm, **td_kwargs
) -> pd.DataFrame:
    """Harmonic vs time-domain |E*| and Phi per (T, f, dt) and per harmonic rtol.

    Both use inertia (the time-domain test has it). Rows with ``kind = "time-domain"``
    (one per dt; rtol = the tightest) and ``kind = "harmonic-rtol"`` (one per rtol: the
    harmonic GMRES solution at that tolerance vs the direct complex LU, dt = NaN).

    Returns
    -------
    DataFrame: ``kind, temperature_C, frequency_Hz, dt_s, rtol, E_norm_MPa, phase_deg,
    reference_E_norm_MPa, reference_phase_deg, dE_norm_percent, dphase_deg`` + run details
    (``n_steps, wall_time_s, cpu_per_sphere_step_s, E_norm_MPa_other_reading,
    phase_deg_other_reading``).
    """
    from .timedomain import time_domain_row

    out = []
    for _, prow in params.iterrows():
        law = burgers_model(prow)
        T = float(prow["temperature_C"])
        for f in frequencies_Hz:
            ref = harmonic_rows(system, law, T, [f], geometry_mm, inertia="full", solver="direct")[0]
            base = {
                "temperature_C": T,
                "frequency_Hz": float(f),
                "reference_E_norm_MPa": ref["E_norm_MPa"],
                "reference_phase_deg": ref["phase_deg"],
            }
            for rtol in rtols:
                h = harmonic_rows(system, law, T, [f], geometry_mm, inertia="full", solver="reuse", rtol=rtol)[0]
                out.append(
                    {
                        "kind": "harmonic-rtol",
                        **base,
                        "dt_s": np.nan,
                        "rtol": rtol,
                        "E_norm_MPa": h["E_norm_MPa"],
                        "phase_deg": h["phase_deg"],
                        "wall_time_s": h["solve_time_s"],
                    }
                )
            for dt in dts:
                td = time_domain_row(sample_path, law, float(f), geometry_mm, float(dt), **td_kwargs)
                out.append(
                    {
                        "kind": "time-domain",
                        **base,
                        "dt_s": float(dt),
                        "rtol": np.nan,
                        "E_norm_MPa": td["E_norm_MPa"],
                        "phase_deg": td["phase_deg"],
                        "n_steps": td["n_steps"],
                        "wall_time_s": td["wall_time_s"],
                        "cpu_per_sphere_step_s": td["cpu_per_sphere_step_s"],
                        "E_norm_MPa_other_reading": td["E_norm_MPa_other_reading"],
                        "phase_deg_other_reading": td["phase_deg_other_reading"],
                    }
                )
    frame = pd.DataFrame(out)
    frame["dE_norm_percent"] = 100 * (frame["E_norm_MPa"] / frame["reference_E_norm_MPa"] - 1)
    frame["dphase_deg"] = frame["phase_deg"] - frame["reference_phase_deg"]
    if "E_norm_MPa_other_reading" in frame.columns:
        frame["dE_norm_percent_other_reading"] = 100 * (
            frame["E_norm_MPa_other_reading"] / frame["reference_E_norm_MPa"] - 1
        )
        frame["dphase_deg_other_reading"] = frame["phase_deg_other_reading"] - frame["reference_phase_deg"]
    return frame


def network_factor_table(frames: list[pd.DataFrame]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Network factor per (sample, mode, T, f) and its summary over samples.

    Parameters
    ----------
    frames : harmonic row tables with ``sample`` and ``mode`` columns.

    Returns
    -------
    (table, summary): table has ``sample, mode, temperature_C, frequency_Hz, E_norm_MPa,
    phase_deg, macro_E_norm_MPa, macro_phase_deg, network_factor, phase_difference_deg``;
    summary per (mode, T, f): ``n_samples, network_factor_mean, network_factor_std,
    phase_difference_deg_mean, phase_difference_deg_std``.
    """
    cols = [
        *NETWORK_FACTOR_KEYS,
        "inertia",
        "E_norm_MPa",
        "phase_deg",
        "macro_E_norm_MPa",
        "macro_phase_deg",
        "network_factor",
        "phase_difference_deg",
    ]
    table = pd.concat([f[cols] for f in frames], ignore_index=True)
    table = table.sort_values(list(NETWORK_FACTOR_KEYS)).reset_index(drop=True)
    g = table.groupby(["mode", "inertia", "temperature_C", "frequency_Hz"])
    summary = g.agg(
        n_samples=("sample", "nunique"),
        network_factor_mean=("network_factor", "mean"),
        network_factor_std=("network_factor", "std"),
        phase_difference_deg_mean=("phase_difference_deg", "mean"),
        phase_difference_deg_std=("phase_difference_deg", "std"),
    ).reset_index()
    return table, summary


def kinematics_study(
    network,
    params: pd.DataFrame,
    frequencies_Hz,
    geometry_mm,
    nu: float = POISSON_RATIO,
    inertia_modes=("none", "full"),
    **solve_kwargs,
) -> pd.DataFrame:
    """Network factor and phase difference per (bond_kinematics, head_rotation, inertia, T, f).

    With ``inertia="none"`` the network factor is the real geometric factor of K = E* G
    (independent of T and f); with ``"full"`` it also holds the sample's distributed inertia
    beyond the lumped 0.135 M of Eq. 1 (resonances of the sample + head).

    Parameters
    ----------
    network : BondNetwork
        The sample.
    params : DataFrame
        Burger's parameter rows (``temperature_C`` + MPa, MPa s columns), one per temperature.
    frequencies_Hz : sequence of float, Hz.
    geometry_mm : ``b_mm, B_mm, e_mm, h_mm`` for gamma (Eq. 3).
    nu : Poisson's ratio of Eqs. 8-11.
    inertia_modes : sequence of "none" / "full" (see :mod:`.solver`).
    solve_kwargs : ``amplitude, solver, rtol`` of :func:`harmonic_rows`.

    Returns
    -------
    DataFrame: ``sample, bond_kinematics, head_rotation`` + the harmonic rows (``inertia``)
    (``temperature_C, frequency_Hz, E_norm_MPa, phase_deg, macro_E_norm_MPa,
    macro_phase_deg, network_factor, phase_difference_deg, n_free_dof, ...``).
    """
    from ..nscd.state import BOND_KINEMATICS, HEAD_ROTATIONS
    from .solver import HarmonicSystem

    frames = []
    for kinematics in BOND_KINEMATICS:
        for head in HEAD_ROTATIONS:
            system = HarmonicSystem(network, nu=nu, bond_kinematics=kinematics, head_rotation=head)
            for inertia, (_, prow) in itertools.product(inertia_modes, params.iterrows()):
                rows = harmonic_rows(
                    system,
                    burgers_model(prow),
                    float(prow["temperature_C"]),
                    frequencies_Hz,
                    geometry_mm,
                    inertia=inertia,
                    **solve_kwargs,
                )
                frame = pd.DataFrame(rows)
                frame.insert(0, "head_rotation", head)
                frame.insert(0, "bond_kinematics", kinematics)
                frame.insert(0, "sample", network.name)
                frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def peak_rss_mb() -> float:
    """Peak resident memory of this process, MB (Linux ru_maxrss is in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def benchmark(
    sample_path,
    law,
    frequencies_Hz,
    geometry_mm,
    td_steps: int = 20,
    td_dt: float = 5e-5,
    td_cycles: int = 5,
    bond_kinematics: str = "contact",
    head_rotation: str = "free",
    direct: bool = True,
    orderings=("metis", "mmd", "colamd"),
    baseline: bool = True,
) -> dict:
    """Time the harmonic (T, f) solves on a sample, and the matching time-domain job.

    Harmonic, in this order: reading + preparation (``setup_s``); per frequency the
    ``reuse`` solve with inertia (the first one includes the METIS ordering and the real
    factorisation of G - Re(s) M; later ones reuse it or factorise a new shift, see
    :meth:`.HarmonicSystem.solve_law`), its GMRES iterations and whether the factor was
    reused; the factorisation of G and per frequency the ``reuse`` solve without inertia;
    optionally the ``direct`` complex LU (``direct=False`` skips it: minutes at 10^4 spheres).
    ``first_TF_total_s`` = setup + first solve with inertia; ``peak_rss_mb_solver`` is the peak
    memory at that point (before the comparisons below).

    Same-run comparisons: ``orderings`` — G factorised with each ordering ("metis": this
    module's nested dissection, "mmd": SuperLU MMD(A^T+A), the previous default, "colamd"):
    factor time, fill L.nnz + U.nnz, time of one complex (2-column) solve, and ratios to
    "mmd"; ``baseline`` — the previous inertia path at the first frequency (MMD factor of G,
    GMRES preconditioned by G^-1) and the ratio of its factor + solve time to the new one's.

    Time-domain: mean wall time of ``td_steps`` NSCD steps of the same test, times the steps
    of a ``td_cycles``-cycle job at ``td_dt`` (the paper's 5 cycles at 5e-5 s).

    Returns
    -------
    dict (JSON-ready) with sizes, times in s, fills, ratios, ``peak_rss_mb``.
    """
    from ..sample.store import read_sample
    from .network import network_from_sample
    from .solver import HarmonicSystem

    t0 = time.perf_counter()
    sample = read_sample(sample_path)
    network = network_from_sample(sample)
    system = HarmonicSystem(network, bond_kinematics=bond_kinematics, head_rotation=head_rotation)
    t_setup = time.perf_counter() - t0
    per_f = _bench_inertia_solves(system, law, frequencies_Hz, geometry_mm)
    peak_solver = peak_rss_mb()
    ref, t_factor = _bench_inertia_free_solves(system, law, per_f, geometry_mm)
    g = ref["ff"]
    system._shifted.clear()
    ref.pop("lu", None)
    cmp = _bench_orderings(system, g, orderings)
    base = (
        _bench_previous_inertia_path(system, ref, law, float(frequencies_Hz[0]), per_f[0]["reuse_full_s"])
        if baseline and system.n_free
        else {}
    )
    direct_s = float("nan")
    if direct:
        t0 = time.perf_counter()
        harmonic_rows(system, law, 0.0, [frequencies_Hz[0]], geometry_mm, inertia="full", solver="direct")
        direct_s = time.perf_counter() - t0
    td = (
        _time_domain_step_time(sample, law, float(frequencies_Hz[0]), td_dt, td_steps) if td_steps > 0 else float("nan")
    )
    n_td = int(round(td_cycles / (float(frequencies_Hz[0]) * td_dt)))
    first = per_f[0]
    return {
        "n_spheres": network.n_spheres,
        "n_bonds": network.n_bonds,
        "bond_kinematics": bond_kinematics,
        "head_rotation": head_rotation,
        "n_free_dof": system.n_free,
        "n_load_free": system.n_load_free,
        "ordering": system.ordering,
        "setup_s": t_setup,
        "per_frequency": per_f,
        "first_TF_total_s": t_setup + first["reuse_full_s"],
        "subsequent_TF_s": [e["reuse_full_s"] for e in per_f[1:]],
        "reference_factorisation_s": t_factor,
        "orderings": cmp,
        "baseline": base,
        "direct_first_TF_s": direct_s,
        "time_domain_step_s": td,
        "time_domain_steps": n_td,
        "time_domain_job_s": td * n_td,
        "time_domain_job": f"{td_cycles} cycles at {frequencies_Hz[0]} Hz, dt = {td_dt} s",
        "peak_rss_mb_solver": peak_solver,
        "peak_rss_mb": peak_rss_mb(),
    }


def _bench_inertia_solves(system, law, frequencies_Hz, geometry_mm) -> list[dict]:
    """:func:`benchmark`, first stage: the ``reuse`` solve with inertia per frequency, in order:
    one dict per frequency with its time (s), |E*| (MPa), GMRES iterations and the
    factorisations it made (``system.factor_log``)."""
    per_f = []
    for f in frequencies_Hz:
        n_factors = len(system.factor_log)
        t0 = time.perf_counter()
        row = harmonic_rows(system, law, 0.0, [f], geometry_mm, inertia="full", solver="reuse")[0]
        entry = {
            "frequency_Hz": float(f),
            "reuse_full_s": time.perf_counter() - t0,
            "reuse_full_E_norm_MPa": row["E_norm_MPa"],
            "gmres_iterations": int(system.last_gmres_iterations),
            "new_factorisations": [dict(r) for r in system.factor_log[n_factors:]],
        }
        per_f.append(entry)
    return per_f


def _bench_inertia_free_solves(system, law, per_f: list[dict], geometry_mm) -> tuple[dict, float]:
    """:func:`benchmark`, second stage: the factorisation of G (its time, s) and the ``reuse``
    solve without inertia at each frequency of ``per_f`` (time, s, and |E*|, MPa, added to its
    entries). Returns (the reference system of :meth:`.HarmonicSystem._reference`, factor time)."""
    t0 = time.perf_counter()
    ref = system._reference()
    t_factor = time.perf_counter() - t0
    for entry in per_f:
        t0 = time.perf_counter()
        row = harmonic_rows(system, law, 0.0, [entry["frequency_Hz"]], geometry_mm, inertia="none", solver="reuse")[0]
        entry["reuse_none_s"] = time.perf_counter() - t0
        entry["reuse_none_E_norm_MPa"] = row["E_norm_MPa"]
    return ref, t_factor


def _bench_orderings(system, g, orderings) -> dict:
    """:func:`benchmark`, third stage: G (sparse, n_free x n_free) factorised with each fill-reducing
    ordering ("metis", "mmd", "colamd"): ordering, factor and one complex solve time (s), fill,
    stored entries, relative residual, and with "mmd" the ratios to it."""
    from scipy.sparse.linalg import splu

    from ..nscd.linear import splu_symmetric
    from .solver import _fill

    rng = np.random.default_rng(0)
    b = rng.standard_normal(g.shape[0]) + 1j * rng.standard_normal(g.shape[0])
    cmp = {}
    for name in orderings:
        t0 = time.perf_counter()
        if name == "metis":
            perm = system.permutation()
            t_order = time.perf_counter() - t0
            t0 = time.perf_counter()
            lu = splu_symmetric(g, perm)
        elif name == "mmd":
            t_order = 0.0
            lu = splu_symmetric(g)
        else:
            t_order = 0.0
            lu = splu(g.tocsc(), permc_spec=name.upper(), diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        t_fac = time.perf_counter() - t0
        t0 = time.perf_counter()
        x = lu.solve(b) if name == "metis" else lu.solve(np.ascontiguousarray(np.column_stack([b.real, b.imag])))
        t_sol = time.perf_counter() - t0
        x = x if name == "metis" else x[:, 0] + 1j * x[:, 1]
        cmp[name] = {
            "ordering_s": t_order,
            "factor_s": t_fac,
            "solve_s": t_sol,
            "fill": _fill(lu),
            "stored_entries": int(lu.nnz),
            "relative_residual": float(np.linalg.norm(g @ x - b) / np.linalg.norm(b)),
        }
        del lu
    if "mmd" in cmp:
        for v in cmp.values():
            v["fill_ratio_to_mmd"] = v["fill"] / cmp["mmd"]["fill"]
            v["factor_time_ratio_to_mmd"] = v["factor_s"] / cmp["mmd"]["factor_s"]
            v["solve_time_ratio_to_mmd"] = v["solve_s"] / cmp["mmd"]["solve_s"]
    return cmp


def _bench_previous_inertia_path(system, ref: dict, law, f: float, new_s: float) -> dict:
    """:func:`benchmark`, fourth stage: the previous inertia path at frequency ``f`` (Hz): MMD
    factor of G, GMRES on G - s M preconditioned by G^-1; its factor and GMRES times (s),
    iterations, convergence and speed-up over the ``reuse`` solve's ``new_s`` (s)."""
    import scipy.sparse.linalg as spla

    from ..nscd.linear import splu_symmetric

    g = ref["ff"]
    omega = 2 * np.pi * f
    s = omega**2 / complex(law.complex_modulus(omega))
    up = np.array([HEAD_AMPLITUDE_M, 0.0, 0.0], complex)
    rhs = -(ref["fp"] @ up)
    m = system.mass_free
    t0 = time.perf_counter()
    lu = splu_symmetric(g)
    t_fac = time.perf_counter() - t0

    def g_inv(v):
        v = np.asarray(v).ravel()
        return lu.solve(np.ascontiguousarray(v.real)) + 1j * lu.solve(np.ascontiguousarray(v.imag))

    op = spla.LinearOperator(g.shape, dtype=complex, matvec=lambda v: g @ v - s * (m * v.ravel()))
    prec = spla.LinearOperator(g.shape, dtype=complex, matvec=g_inv)
    count = [0]

    def tick(_):
        count[0] += 1

    t0 = time.perf_counter()
    u, info = spla.gmres(
        op,
        rhs,
        x0=g_inv(rhs),
        rtol=1e-12,
        atol=0.0,
        M=prec,
        restart=50,
        maxiter=200,
        callback=tick,
        callback_type="pr_norm",
    )
    t_gm = time.perf_counter() - t0
    return {
        "method": "MMD(A^T+A) factor of G, GMRES preconditioned by G^-1 (previous)",
        "frequency_Hz": f,
        "factor_s": t_fac,
        "gmres_s": t_gm,
        "gmres_iterations": count[0],
        "converged": bool(info == 0),
        "total_s": t_fac + t_gm,
        "new_total_s": new_s,
        "speedup": (t_fac + t_gm) / new_s,
    }


def _time_domain_step_time(sample, law, frequency_Hz, dt, n_steps) -> float:
    from ..nscd import NSCDParameters
    from .timedomain import simulation

    w = 2 * np.pi * frequency_Hz
    sim = simulation(
        sample,
        law,
        lambda t: (HEAD_AMPLITUDE_M * np.sin(w * t), 0.0, 0.0),
        NSCDParameters(dt=dt, gravity=(0.0, 0.0, 0.0)),
    )
    sim.step()  # JIT compilation and first factorisation excluded
    t0 = time.perf_counter()
    for _ in range(n_steps):
        sim.step()
    return (time.perf_counter() - t0) / n_steps


# ----------------------------------------------------------------------------- figures
