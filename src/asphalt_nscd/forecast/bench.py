"""Benchmark of the discrete forecast's cost per mix (``asphalt-nscd forecast-bench``; JSON, never a timed test).

For each mix asked for, the process CPU and wall time of: the packing (Section 3.2.1 stages 1-4),
the sample (stages 5-9), the response (one generalized eigen-decomposition, :func:`.dem.sample_response`)
and, as the baseline of the same run, what the response replaces: one sparse complex solve of the
uniaxial test per condition at the table's conditions (``direct_30_solves``), with the ratio of the
two; and the evaluation of the response at those conditions. The machine is shared: the 1-min
load average is recorded.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np


def _timed(func, *args, **kwargs):
    c0, w0 = time.process_time(), time.perf_counter()
    out = func(*args, **kwargs)
    return out, {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0}


def bench_mix(sample_cfg: dict, passing: dict, coarse: float, mix_id: str, seed: int, n_conditions: int) -> dict:
    """The record of one mix (module docstring)."""
    from ..harmonic.network import network_from_sample
    from ..harmonic.solver import HarmonicSystem
    from ..sample.prepare import CONTACT_TOLERANCE, finish, pack
    from . import dem

    packing, t_pack = _timed(pack, sample_cfg, seed, passing)
    result, t_sample = _timed(finish, packing, sample_cfg, seed, None, coarse)
    s = result.sample
    response, t_resp = _timed(dem.sample_response, s, mix_id, seed)
    zeta = np.logspace(-3, 3, n_conditions) * np.exp(-0.5j)
    _, t_eval = _timed(response.factor, zeta)

    def direct():
        system = HarmonicSystem(network_from_sample(s), head_rotation="clamped")
        film = np.maximum(s.bonds["delta0"], CONTACT_TOLERANCE * float(s.attrs["d_min_m"])) + dem.mortar_thickness(s)
        g = np.pi * s.bonds["r_min"] ** 2 / film
        skel = dem.skeleton_bonds(s)
        out = []
        for z in zeta:
            k = g * (1.0 + z * skel)
            out.append(system.solve(k, k * system.t_ratio, 1e-12, amplitude=1.0, inertia="none", axis=2).force[2])
        return np.array(out) / float(s.attrs["h_m"])

    values, t_direct = _timed(direct)
    return {
        "mix_id": mix_id,
        "seed": seed,
        "n_spheres": int(s.radius.size),
        "n_bonds": int(s.bonds["i"].size),
        "n_unknowns": int(response.lam.size),
        "pack": t_pack,
        "sample": t_sample,
        "response": t_resp,
        "response_evaluation": t_eval,
        "direct_solves": t_direct,
        "n_conditions": n_conditions,
        "response_over_direct_cpu": t_resp["cpu_s"] / t_direct["cpu_s"],
        "max_rel_difference_response_direct": float(np.max(np.abs(response.factor(zeta) / values - 1.0))),
    }


def machine() -> dict:
    """What the numbers ran on."""
    return {"platform": platform.platform(), "cpus": os.cpu_count(), "load_1min": os.getloadavg()[0]}
